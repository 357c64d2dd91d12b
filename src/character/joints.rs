//! Joint kinematics (Featherstone 2008, §4.4, Table 4.1): each joint's transform `X_J(q)`,
//! motion subspace `S(q)` and velocity-product term `c_J = Ṡ q̇`, and the group operations on
//! the coordinates: `q ⊕ h q̇` (a step along the rates; quaternions by the exponential map)
//! and `q̄ ⊖ q` (the rates that move `q` to `q̄` in unit time; quaternions by the log map).

use super::model::{Joint, Model};
use super::spatial::{spatial, SMat, SVec, Transform};
use crate::rotation::quat_to_rotvec;
use glam::{DQuat, DVec3};
use nalgebra::Matrix3;

/// The quaternion stored at `q[0..4]` as `(w, x, y, z)`.
pub(super) fn quat(q: &[f64]) -> DQuat {
    DQuat::from_xyzw(q[1], q[2], q[3], q[0])
}

fn store(q: DQuat, out: &mut [f64]) {
    out.copy_from_slice(&[q.w, q.x, q.y, q.z]);
}

/// The body's orientation relative to its parent and the joint's translation (parent axes),
/// from the joint's coordinates `q` (`X_J` is `Transform::new` of the two).
pub(super) fn relative(joint: Joint, q: &[f64]) -> (DQuat, DVec3) {
    match joint {
        Joint::Fixed => (DQuat::IDENTITY, DVec3::ZERO),
        Joint::Revolute { axis } => (DQuat::from_axis_angle(axis, q[0]), DVec3::ZERO),
        Joint::Ball => (quat(q), DVec3::ZERO),
        Joint::Free => (quat(&q[3..7]), DVec3::new(q[0], q[1], q[2])),
        Joint::Planar => (DQuat::from_rotation_z(q[2]), DVec3::new(q[0], q[1], 0.0)),
    }
}

/// The motion subspace `S` (body coordinates, its `nv` columns padded with zeros to 6) of the
/// joint, given its transform `x_j` (free and planar joints' linear rates are in parent axes,
/// so their `S` turns them by `E`).
pub(super) fn subspace(joint: Joint, x_j: &Transform) -> SMat {
    let mut s = SMat::zeros();
    match joint {
        Joint::Fixed => {}
        Joint::Revolute { axis } => s.set_column(0, &spatial(axis, DVec3::ZERO)),
        Joint::Ball => s.fixed_view_mut::<3, 3>(0, 0).copy_from(&Matrix3::identity()),
        Joint::Free => {
            s.fixed_view_mut::<3, 3>(0, 0).copy_from(&Matrix3::identity());
            let e = Matrix3::from_column_slice(&x_j.rot.to_cols_array());
            s.fixed_view_mut::<3, 3>(3, 3).copy_from(&e);
        }
        Joint::Planar => {
            s.set_column(0, &spatial(DVec3::ZERO, x_j.rot * DVec3::X));
            s.set_column(1, &spatial(DVec3::ZERO, x_j.rot * DVec3::Y));
            s.set_column(2, &spatial(DVec3::Z, DVec3::ZERO));
        }
    }
    s
}

/// Where column `k` of a joint's motion subspace ([`subspace`]) is not zero: every joint's
/// columns are angular only or linear only, and a ball joint's, a free joint's angular and
/// a planar joint's turning column are unit vectors.
enum Column {
    /// The unit vector along spatial axis `r`.
    Unit(usize),
    /// Rows 0–2 only.
    Angular,
    /// Rows 3–5 only.
    Linear,
}

fn column(joint: Joint, k: usize) -> Column {
    match joint {
        Joint::Ball => Column::Unit(k),
        Joint::Free if k < 3 => Column::Unit(k),
        Joint::Planar if k == 2 => Column::Unit(2),
        Joint::Revolute { .. } => Column::Angular,
        Joint::Free | Joint::Planar | Joint::Fixed => Column::Linear,
    }
}

/// `I sₖ`: the 6 × 6 `inertia` times column `k` of `joint`'s motion subspace `s`
/// ([`subspace`]), with the products by the column's zero half left out (the CRBA's
/// `F = I S`, Featherstone 2008 Table 6.2; the same sums as the full product, whose other
/// terms are zeros).
pub(super) fn inertia_times_column(joint: Joint, inertia: &SMat, s: &SMat, k: usize) -> SVec {
    match column(joint, k) {
        Column::Unit(r) => inertia.column(r).into_owned(),
        Column::Angular => inertia.fixed_columns::<3>(0) * s.fixed_view::<3, 1>(0, k),
        Column::Linear => inertia.fixed_columns::<3>(3) * s.fixed_view::<3, 1>(3, k),
    }
}

/// `sₖᵀ f`: column `k` of `joint`'s motion subspace `s` ([`subspace`]) dotted with the
/// spatial force `f`, reading only the column's non-zero half (the CRBA's `Sᵀ F`).
pub(super) fn column_dot(joint: Joint, s: &SMat, k: usize, f: &SVec) -> f64 {
    match column(joint, k) {
        Column::Unit(r) => f[r],
        Column::Angular => s.fixed_view::<3, 1>(0, k).dot(&f.fixed_rows::<3>(0)),
        Column::Linear => s.fixed_view::<3, 1>(3, k).dot(&f.fixed_rows::<3>(3)),
    }
}

/// `c_J = Ṡ q̇` (body coordinates): zero but for free and planar joints, whose linear rate `v`
/// (parent axes) seen in the turning body axes gives `[0; −ω × E v]`.
pub(super) fn bias(joint: Joint, x_j: &Transform, qd: &[f64]) -> SVec {
    match joint {
        Joint::Free => {
            let w = DVec3::new(qd[0], qd[1], qd[2]);
            let v = x_j.rot * DVec3::new(qd[3], qd[4], qd[5]);
            spatial(DVec3::ZERO, -w.cross(v))
        }
        Joint::Planar => {
            let v = x_j.rot * DVec3::new(qd[0], qd[1], 0.0);
            spatial(DVec3::ZERO, -(qd[2] * DVec3::Z).cross(v))
        }
        _ => SVec::zeros(),
    }
}

/// `out = q ⊕ h q̇` for every joint of `model` ([`integrate_joint`]).
pub fn integrate(model: &Model, q: &[f64], qd: &[f64], h: f64, out: &mut [f64]) {
    for (i, b) in model.bodies().iter().enumerate() {
        let (iq, iv) = model.starts(i);
        integrate_joint(b.joint, &q[iq..], &qd[iv..], h, &mut out[iq..]);
    }
}

/// `out = q ⊕ h q̇` for one joint (its coordinates and rates first in `q`, `qd`, `out`):
/// angles and free- and planar-joint positions by `h q̇`, quaternions by `q exp(h ω / 2)`
/// (ω in body axes), renormalised.
pub(super) fn integrate_joint(joint: Joint, q: &[f64], qd: &[f64], h: f64, out: &mut [f64]) {
    match joint {
        Joint::Fixed => {}
        Joint::Revolute { .. } => out[0] = q[0] + h * qd[0],
        Joint::Ball => store(turn(quat(q), qd, h), &mut out[..4]),
        Joint::Free => {
            for k in 0..3 {
                out[k] = q[k] + h * qd[3 + k];
            }
            store(turn(quat(&q[3..]), qd, h), &mut out[3..7]);
        }
        Joint::Planar => {
            for k in 0..3 {
                out[k] = q[k] + h * qd[k];
            }
        }
    }
}

/// `out = dq/dt` (`nq` values) at `(q, q̇)`: rates of angles and positions as they are,
/// a quaternion's `½ q ⊗ (0, ω)` (ω in body axes). What RK4 combines across its stages:
/// stepping quaternions by `q exp(h Σ bᵢ ωᵢ)` from the step's start drops the stages'
/// commutators and is only second order (measured against MuJoCo, whose RK4 is fourth
/// order on a spinning free body); stepping the components is fourth order.
pub fn coordinate_rates(model: &Model, q: &[f64], qd: &[f64], out: &mut [f64]) {
    for (i, b) in model.bodies().iter().enumerate() {
        let (iq, iv) = model.starts(i);
        let (q, qd, out) = (&q[iq..], &qd[iv..], &mut out[iq..]);
        let spin = |q: &[f64], w: &[f64], out: &mut [f64]| {
            let r = quat(q) * DQuat::from_xyzw(w[0], w[1], w[2], 0.0) * 0.5;
            store(r, out);
        };
        match b.joint {
            Joint::Fixed => {}
            Joint::Revolute { .. } => out[0] = qd[0],
            Joint::Ball => spin(q, qd, &mut out[..4]),
            Joint::Free => {
                out[..3].copy_from_slice(&qd[3..6]);
                spin(&q[3..7], qd, &mut out[3..7]);
            }
            Joint::Planar => out[..3].copy_from_slice(&qd[..3]),
        }
    }
}

/// `q += h ṙ` component by component, quaternions renormalised (a Runge–Kutta stage or
/// step from the coordinate rates ṙ of [`coordinate_rates`]).
pub(super) fn advance(model: &Model, rates: &[f64], h: f64, out: &mut [f64]) {
    for (o, r) in out.iter_mut().zip(rates) {
        *o += h * r;
    }
    for (i, b) in model.bodies().iter().enumerate() {
        let at = model.starts(i).0 + if b.joint == Joint::Free { 3 } else { 0 };
        if matches!(b.joint, Joint::Ball | Joint::Free) {
            let n = out[at..at + 4].iter().map(|v| v * v).sum::<f64>().sqrt();
            out[at..at + 4].iter_mut().for_each(|v| *v /= n);
        }
    }
}

fn turn(q: DQuat, w: &[f64], h: f64) -> DQuat {
    (q * DQuat::from_scaled_axis(h * DVec3::new(w[0], w[1], w[2]))).normalize()
}

/// `out = target ⊖ q` per degree of freedom of `model` ([`difference_joint`]).
pub fn difference(model: &Model, target: &[f64], q: &[f64], out: &mut [f64]) {
    for (i, b) in model.bodies().iter().enumerate() {
        let (iq, iv) = model.starts(i);
        difference_joint(b.joint, &target[iq..], &q[iq..], &mut out[iv..]);
    }
}

/// `out = t ⊖ q` for one joint (its coordinates first in `t`, `q`, its rates in `out`):
/// angle differences, and for quaternions the rotation vector of `q⁻¹ t` (body axes, angle
/// in `[0, π]`); free joints get the position difference and rotation vector, planar joints
/// the differences of `[x, y, θ]`.
pub(super) fn difference_joint(joint: Joint, t: &[f64], q: &[f64], out: &mut [f64]) {
    match joint {
        Joint::Fixed => {}
        Joint::Revolute { .. } => out[0] = t[0] - q[0],
        Joint::Ball => out[..3].copy_from_slice(&quat_to_rotvec(quat(q).conjugate() * quat(t))),
        Joint::Free => {
            out[..3].copy_from_slice(&quat_to_rotvec(quat(&q[3..]).conjugate() * quat(&t[3..])));
            for k in 0..3 {
                out[3 + k] = t[k] - q[k];
            }
        }
        Joint::Planar => {
            for k in 0..3 {
                out[k] = t[k] - q[k];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The CRBA's products with a motion subspace's non-zero half are bitwise the full
    /// products `I sₖ` and `sₖᵀ f` (the left-out terms are products with zeros), for every
    /// joint kind at a turned pose.
    #[test]
    fn products_with_a_subspace_column_equal_the_full_products() {
        let inertia =
            SMat::from_fn(|r, c| ((r * 6 + c) as f64 * 0.7).sin() + f64::from(u8::from(r == c)));
        let f = SVec::from_fn(|r, _| (r as f64 * 1.3).cos() - 0.2);
        let axis = DVec3::new(0.3, -0.5, 0.8).normalize();
        let q = [0.2, -0.4, 0.6, 0.9, 0.3, -0.2, 0.25];
        let quat = DQuat::from_xyzw(q[4], q[5], q[6], q[3]).normalize();
        let q = [q[0], q[1], q[2], quat.w, quat.x, quat.y, quat.z];
        for joint in [Joint::Revolute { axis }, Joint::Ball, Joint::Free, Joint::Planar] {
            let at = if joint == Joint::Ball { &q[3..] } else { &q[..] };
            let (rel, shift) = relative(joint, at);
            let s = subspace(joint, &Transform::new(rel, shift));
            for k in 0..joint.nv() {
                let full = inertia * s.column(k);
                assert_eq!(inertia_times_column(joint, &inertia, &s, k), full, "{joint:?} {k}");
                assert_eq!(column_dot(joint, &s, k, &f), s.column(k).dot(&f), "{joint:?} {k}");
            }
        }
    }
}
