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
/// from the joint's coordinates `q`.
pub(super) fn relative(joint: Joint, q: &[f64]) -> (DQuat, DVec3) {
    match joint {
        Joint::Fixed => (DQuat::IDENTITY, DVec3::ZERO),
        Joint::Revolute { axis } => (DQuat::from_axis_angle(axis, q[0]), DVec3::ZERO),
        Joint::Ball => (quat(q), DVec3::ZERO),
        Joint::Free => (quat(&q[3..7]), DVec3::new(q[0], q[1], q[2])),
        Joint::Planar => (DQuat::from_rotation_z(q[2]), DVec3::new(q[0], q[1], 0.0)),
    }
}

/// `X_J` of the joint, from the parent's joint frame to the body frame.
pub(super) fn transform(joint: Joint, q: &[f64]) -> Transform {
    let (r, p) = relative(joint, q);
    Transform::new(r, p)
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
