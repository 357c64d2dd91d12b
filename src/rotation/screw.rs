//! Rigid transforms as screw motions: exponential coordinates of SE(3) and unit dual
//! quaternions, both to and from row-major 4x4 matrices `[R t; 0 1]`.
//!
//! Exponential coordinates are `(ω, v)`: the rotation vector `ω` (rad) and the translational
//! part `v` (length units) of the twist; `exp` gives `R = exp([ω]×)` and `t = V(ω) v` with
//! `V = I + k₁ [ω]× + k₂ [ω]×²`, `k₁ = (1 - cos θ)/θ²`, `k₂ = (θ - sin θ)/θ³`, `θ = |ω|`
//! (Lynch & Park, *Modern Robotics*, 2017, eq. 3.88; Barfoot, *State Estimation for
//! Robotics*, 2017, eq. 7.86). Dual quaternions are `r + ε d` with `d = ½ (0, t) r`
//! (Kavan et al., "Skinning with dual quaternions", 2007, sec. 3), scalar-first halves.

use super::{quat_from_matrix, quat_from_rotvec, quat_to_matrix, quat_to_rotvec};
use crate::error::{ensure_finite, Error, Result};
use glam::{DQuat, DVec3};

/// Below this angle (rad) the coefficients of `V` and `V⁻¹` are evaluated by their Taylor
/// series, which at 0.1 are exact to rounding (next term below 1e-16 relative).
const SERIES_ANGLE: f64 = 0.1;

fn rigid(q: DQuat, t: DVec3) -> [f64; 16] {
    let r = quat_to_matrix(q);
    let mut m = [0.0; 16];
    for row in 0..3 {
        m[4 * row..4 * row + 3].copy_from_slice(&r[3 * row..3 * row + 3]);
    }
    (m[3], m[7], m[11], m[15]) = (t.x, t.y, t.z, 1.0);
    m
}

/// The rotation and translation of a rigid transform `m`.
///
/// # Errors
/// Non-finite entries, a last row other than `(0, 0, 0, 1)`, or a linear part that is not a
/// rotation within [`super::ROTATION_MATRIX_TOL`] (scaled or sheared transforms).
pub fn rigid_parts(m: &[f64; 16]) -> Result<(DQuat, DVec3)> {
    super::validate_transform(m)?;
    let r = [m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10]];
    Ok((quat_from_matrix(&r, false)?, DVec3::new(m[3], m[7], m[11])))
}

/// `exp` of the twist `xi = (ω, v)` (6,): the rigid transform of the screw motion.
///
/// # Errors
/// Non-finite coordinates.
pub fn transform_from_exp_coords(xi: &[f64; 6]) -> Result<[f64; 16]> {
    ensure_finite("exp_coords", xi)?;
    let w = DVec3::new(xi[0], xi[1], xi[2]);
    let v = DVec3::new(xi[3], xi[4], xi[5]);
    let theta = w.length();
    let (k1, k2) = if theta < SERIES_ANGLE {
        let t2 = theta * theta;
        (
            0.5 - t2 / 24.0 + t2 * t2 / 720.0 - t2 * t2 * t2 / 40320.0,
            1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0 - t2 * t2 * t2 / 362_880.0,
        )
    } else {
        let half = (0.5 * theta).sin() / (0.5 * theta);
        (0.5 * half * half, (theta - theta.sin()) / (theta * theta * theta))
    };
    let wv = w.cross(v);
    let t = v + k1 * wv + k2 * w.cross(wv);
    Ok(rigid(quat_from_rotvec(&[w.x, w.y, w.z])?, t))
}

/// `log` of a rigid transform: the twist `(ω, v)` (6,) with `|ω| <= π`, the inverse of
/// [`transform_from_exp_coords`]; `v = V⁻¹ t` with `V⁻¹ = I - ½ [ω]× + k [ω]×²`,
/// `k = (1 - (θ/2) cot(θ/2))/θ²` (Barfoot 2017, eq. 7.95).
///
/// # Errors
/// As [`rigid_parts`].
pub fn transform_to_exp_coords(m: &[f64; 16]) -> Result<[f64; 6]> {
    let (q, t) = rigid_parts(m)?;
    let rv = quat_to_rotvec(q);
    let w = DVec3::from_array(rv);
    let theta = w.length();
    let k = if theta < SERIES_ANGLE {
        let t2 = theta * theta;
        1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0 + t2 * t2 * t2 / 1_209_600.0
    } else {
        let half = 0.5 * theta;
        (1.0 - half * half.cos() / half.sin()) / (theta * theta)
    };
    let wt = w.cross(t);
    let v = t - 0.5 * wt + k * w.cross(wt);
    Ok([rv[0], rv[1], rv[2], v.x, v.y, v.z])
}

/// The rigid transform of a dual quaternion `(r, d)` (8,), scalar-first halves. Any
/// non-zero real part is accepted: both halves are divided by `|r|` and `d` is made
/// orthogonal to `r` (`d -= (r·d) r`), the nearest unit dual quaternion in that sense.
///
/// # Errors
/// Non-finite entries or a real part of zero norm (no rotation).
pub fn transform_from_dual_quat(dq: &[f64; 8]) -> Result<[f64; 16]> {
    ensure_finite("dual_quat", dq)?;
    let r = DQuat::from_xyzw(dq[1], dq[2], dq[3], dq[0]);
    let norm = r.length();
    if norm == 0.0 || !norm.is_finite() {
        return Err(Error::invalid("dual_quat", "the real part must be non-zero"));
    }
    let r = r / norm;
    let d = DQuat::from_xyzw(dq[5], dq[6], dq[7], dq[4]) / norm;
    let d = d - r * r.dot(d);
    let t = (d * r.conjugate()) * 2.0;
    Ok(rigid(r, DVec3::new(t.x, t.y, t.z)))
}

/// The unit dual quaternion `(r, ½ (0, t) r)` (8,), scalar-first halves, of a rigid
/// transform; `r` is the rotation's quaternion with `w >= 0` as [`quat_from_matrix`] gives.
///
/// # Errors
/// As [`rigid_parts`].
pub fn transform_to_dual_quat(m: &[f64; 16]) -> Result<[f64; 8]> {
    let (r, t) = rigid_parts(m)?;
    let d = (DQuat::from_xyzw(t.x, t.y, t.z, 0.0) * r) * 0.5;
    Ok([r.w, r.x, r.y, r.z, d.w, d.x, d.y, d.z])
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn close(a: &[f64], b: &[f64], tol: f64) {
        for (x, y) in a.iter().zip(b) {
            assert!((x - y).abs() <= tol, "{a:?} vs {b:?}");
        }
    }

    #[test]
    fn screw_about_z_gives_rotation_and_pitch() {
        // ω = θ ẑ, v = (0, 0, h): a screw along z, pure rotation plus translation h.
        let m = transform_from_exp_coords(&[0.0, 0.0, 0.7, 0.0, 0.0, 2.5]).unwrap();
        let (c, s) = (0.7f64.cos(), 0.7f64.sin());
        close(
            &m,
            &[c, -s, 0.0, 0.0, s, c, 0.0, 0.0, 0.0, 0.0, 1.0, 2.5, 0.0, 0.0, 0.0, 1.0],
            1e-15,
        );
    }

    #[test]
    fn screw_about_offset_axis_fixes_the_axis_point() {
        // Rotation θ about the z axis through q = (1, 0, 0): v = -ω × q, t = (I - R) q.
        let th = 2.0;
        let m = transform_from_exp_coords(&[0.0, 0.0, th, 0.0, -th, 0.0]).unwrap();
        close(&[m[3], m[7], m[11]], &[1.0 - th.cos(), -th.sin(), 0.0], 1e-15);
    }

    #[test]
    fn log_inverts_exp_near_zero_and_pi() {
        for angle in [0.0, 1e-9, 1e-4, 0.0999, 0.1, 0.1001, 1.0, 3.0, PI - 1e-7] {
            let axis = DVec3::new(1.0, -2.0, 0.5).normalize() * angle;
            let xi = [axis.x, axis.y, axis.z, 0.3, -1.1, 2.0];
            let back = transform_to_exp_coords(&transform_from_exp_coords(&xi).unwrap()).unwrap();
            close(&back, &xi, 1e-12);
        }
    }

    #[test]
    fn dual_quat_round_trip_and_translation() {
        let xi = [0.4, -0.2, 1.3, 1.0, 2.0, -3.0];
        let m = transform_from_exp_coords(&xi).unwrap();
        let dq = transform_to_dual_quat(&m).unwrap();
        close(&transform_from_dual_quat(&dq).unwrap(), &m, 1e-14);
        // A pure translation t is (1, 0, 0, 0; 0, t/2).
        let mut t = [0.0; 16];
        (t[0], t[5], t[10], t[15], t[3], t[7], t[11]) = (1.0, 1.0, 1.0, 1.0, 2.0, 4.0, 6.0);
        close(&transform_to_dual_quat(&t).unwrap(), &[1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 2.0, 3.0], 0.0);
    }

    #[test]
    fn bad_input_is_refused() {
        assert!(transform_from_dual_quat(&[0.0; 8]).is_err());
        assert!(transform_from_exp_coords(&[f64::NAN, 0.0, 0.0, 0.0, 0.0, 0.0]).is_err());
        let mut scaled = [0.0; 16];
        (scaled[0], scaled[5], scaled[10], scaled[15]) = (2.0, 1.0, 1.0, 1.0);
        assert!(transform_to_exp_coords(&scaled).is_err());
    }
}
