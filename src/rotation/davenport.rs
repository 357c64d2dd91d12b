//! Davenport angles: a rotation as three turns about given axes `n1, n2, n3` (unit vectors,
//! `n1 ⊥ n2`, `n2 ⊥ n3`), of which Euler angles are the case of coordinate axes (Davenport
//! 1973; Shuster & Markley 2003, "Generalization of the Euler angles").
//!
//! Extrinsic (fixed axes): `q = q_n3(c) q_n2(b) q_n1(a)`; intrinsic (moving axes):
//! `q = q_n1(a) q_n2(b) q_n3(c)`, which is the extrinsic sequence `n3, n2, n1` with the angles
//! reversed.
//!
//! Quaternion to angles by the reduction of Bernardes & Viollet 2022 (sec. 3, arbitrary
//! axes): write the extrinsic sequence as turns about `f` (applied first), `e` and `l` (applied
//! last), with `l = R_e(λ) f` and `λ = atan2(l · (e × f), l · f)`. Then
//! `q_l(c) = q_e(λ) q_f(c) q_e(-λ)`, so `p = q_e(-λ) q = q_f(c) q_e(b - λ) q_f(a)` is the
//! proper sequence `f, e, f`, which [`EulerSequence`] `"xyx"` decomposes in the orthonormal
//! frame `(f, e, f × e)`. When `λ > 0` the axis `e` is replaced by `-e` (and `b` by `-b`), so
//! that the middle angle lies in `[λ - π, λ]` (else `[λ, λ + π]`): for coordinate axes this is
//! exactly the range of [`EulerSequence::from_quat`] (`[-π/2, π/2]` for Tait–Bryan sequences,
//! `[0, π]` for proper ones), and the angles are those of `as_euler`.

use super::euler::EulerSequence;
use crate::batch::{map2, Output};
use crate::error::{Error, Result};
use glam::{DQuat, DVec3};
use std::sync::atomic::{AtomicUsize, Ordering};

/// The angles `[a, b, c]` (rad) of unit quaternion `q` about unit `axes` `[n1, n2, n3]`
/// (consecutive ones orthogonal), extrinsic or intrinsic, and whether the decomposition is
/// gimbal-locked (`b` within [`super::GIMBAL_LOCK_TOL`] of an end of its range; the third
/// angle is then 0, as in [`EulerSequence::from_quat`]). `a` and `c` lie in `(-π, π]`, `b` in
/// the range of width `π` given in the module documentation.
pub fn davenport_from_quat(axes: [DVec3; 3], intrinsic: bool, q: DQuat) -> ([f64; 3], bool) {
    let (f, l) = if intrinsic { (axes[2], axes[0]) } else { (axes[0], axes[2]) };
    let mut e = axes[1];
    let mut lambda = l.dot(e.cross(f)).atan2(l.dot(f));
    let flip = lambda > 0.0;
    if flip {
        (e, lambda) = (-e, -lambda);
    }
    let p = DQuat::from_axis_angle(e, -lambda) * q;
    let v = DVec3::new(p.x, p.y, p.z);
    let in_frame = DQuat::from_xyzw(v.dot(f), v.dot(e), v.dot(f.cross(e)), p.w);
    let seq = EulerSequence { axes: [0, 1, 0], intrinsic };
    let ([a, beta, c], locked) = seq.from_quat(in_frame);
    let b = beta + lambda;
    ([a, if flip { -b } else { b }, c], locked)
}

/// [`davenport_from_quat`] of every quaternion `(w, x, y, z)` of `quats` (unit) with the axes
/// `axes` (row-major `[n1, n2, n3]`, one set for all or one per quaternion) into `out`, in
/// parallel; returns how many are gimbal-locked.
///
/// # Errors
/// The lowest row whose quaternion is not unit (to 1e-12) or whose axes are not unit or not
/// consecutively orthogonal (to 1e-7); lengths that do not broadcast.
pub fn davenport_from_quats(
    axes: &[[f64; 9]],
    intrinsic: bool,
    quats: &[[f64; 4]],
    out: &mut (impl Output<3> + ?Sized),
) -> Result<usize> {
    let locked = AtomicUsize::new(0);
    map2(axes, quats, out, |n, w| {
        let axes = checked_axes(n)?;
        let q = DQuat::from_xyzw(w[1], w[2], w[3], w[0]);
        if !q.is_finite() || (q.length_squared() - 1.0).abs() > 1e-12 {
            return Err(Error::invalid("quat", "must be a unit quaternion"));
        }
        let (angles, lock) = davenport_from_quat(axes, intrinsic, q);
        locked.fetch_add(usize::from(lock), Ordering::Relaxed);
        Ok(angles)
    })?;
    Ok(locked.into_inner())
}

fn checked_axes(n: &[f64; 9]) -> Result<[DVec3; 3]> {
    let axes = [0, 3, 6].map(|k| DVec3::new(n[k], n[k + 1], n[k + 2]));
    if axes.iter().any(|a| !a.is_finite() || (a.length() - 1.0).abs() > 1e-12) {
        return Err(Error::invalid("axes", "must be unit vectors"));
    }
    if axes[0].dot(axes[1]).abs() > 1e-7 || axes[1].dot(axes[2]).abs() > 1e-7 {
        return Err(Error::invalid("axes", "consecutive axes must be orthogonal"));
    }
    Ok(axes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn turns(axes: [DVec3; 3], intrinsic: bool, [a, b, c]: [f64; 3]) -> DQuat {
        let t = |k: usize, x: f64| DQuat::from_axis_angle(axes[k], x);
        if intrinsic {
            t(0, a) * t(1, b) * t(2, c)
        } else {
            t(2, c) * t(1, b) * t(0, a)
        }
    }

    #[test]
    fn coordinate_axes_give_the_euler_angles() {
        let q = DQuat::from_xyzw(0.3, -0.5, 0.2, 0.7).normalize();
        let letters = ["x", "y", "z", "X", "Y", "Z"];
        let mut tried = 0;
        for k in 0..216 {
            let seq = [k / 36, k / 6 % 6, k % 6].map(|i| letters[i]).concat();
            let Ok(s) = EulerSequence::parse(&seq) else { continue };
            tried += 1;
            let axes = s.axes.map(|k| DVec3::AXES[k]);
            let (dav, _) = davenport_from_quat(axes, s.intrinsic, q);
            let (eul, _) = s.from_quat(q);
            for k in 0..3 {
                assert!((dav[k] - eul[k]).abs() < 1e-14, "{seq}: {dav:?} vs {eul:?}");
            }
        }
        assert_eq!(tried, 24);
    }

    #[test]
    fn oblique_axes_round_trip_within_the_middle_range() {
        // n3 = R_n2(λ) n1 for λ over (-π, π]: the middle angle comes back as given when it
        // lies in the documented range, and the turns reproduce the rotation.
        let n1 = DVec3::new(1.0, 2.0, 2.0) / 3.0;
        let n2 = DVec3::new(2.0, 1.0, -2.0) / 3.0;
        for (k, lambda) in [-3.0, -1.2, -0.3, 0.0, 0.4, 1.5, 3.1].into_iter().enumerate() {
            let n3 = DQuat::from_axis_angle(n2, lambda) * n1;
            for intrinsic in [false, true] {
                let axes = if intrinsic { [n3, n2, n1] } else { [n1, n2, n3] };
                let (f, l) = if intrinsic { (axes[2], axes[0]) } else { (axes[0], axes[2]) };
                let lam = l.dot(axes[1].cross(f)).atan2(l.dot(f));
                let low = if lam > 0.0 { lam - std::f64::consts::PI } else { lam };
                let given = [0.7 - 0.2 * k as f64, low + 0.25 + 0.3 * k as f64 / 7.0, -2.0];
                let q = turns(axes, intrinsic, given);
                let (got, locked) = davenport_from_quat(axes, intrinsic, q);
                assert!(!locked);
                for i in 0..3 {
                    assert!((got[i] - given[i]).abs() < 1e-12, "λ={lambda}: {got:?} {given:?}");
                }
            }
        }
    }

    #[test]
    fn gimbal_lock_sets_the_third_angle_and_keeps_the_rotation() {
        let axes = [DVec3::X, DVec3::Y, DVec3::X];
        let q = turns(axes, false, [0.4, 0.0, 0.9]);
        let (got, locked) = davenport_from_quat(axes, false, q);
        assert!(locked);
        assert_eq!(got[2], 0.0);
        assert!(turns(axes, false, got).angle_between(q) < 1e-14);
    }

    #[test]
    fn bad_axes_and_quaternions_are_refused_naming_them() {
        let x = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0];
        let mut out = [[0.0; 3]];
        let e = davenport_from_quats(&[x], false, &[[2.0, 0.0, 0.0, 0.0]], &mut out).unwrap_err();
        assert!(e.to_string().starts_with("quat"));
        let slanted = [1.0, 0.0, 0.0, 0.6, 0.8, 0.0, 1.0, 0.0, 0.0];
        let e =
            davenport_from_quats(&[slanted], false, &[[1.0, 0.0, 0.0, 0.0]], &mut out).unwrap_err();
        assert!(e.to_string().starts_with("axes"), "{e}");
    }
}
