//! PD servos and stable PD (Tan, Liu & Turk 2011, "Stable proportional-derivative
//! controllers", IEEE CG&A 31(4)).
//!
//! Explicit PD: `τ = k_p (q̄ ⊖ q) − k_d q̇` from the current state; with a step `dt` it is
//! stable only while `k_p dt² / M_jj` stays small (measured in `tests/character.rs`).
//!
//! Stable PD (their eq. 5–8) evaluates the servo at the next step's position and velocity,
//! `τ = −k_p (q + dt q̇ − q̄) − k_d (q̇ + dt q̈)`, and solves the accelerations together with it:
//! `(M + dt K_d) q̈ = τ_other − C(q, q̇) + k_p (q̄ ⊖ (q ⊕ dt q̇)) − k_d q̇` (eq. 8, with `C` the
//! bias forces of the RNEA and `⊖`, `⊕` the joints' coordinate operations). `M` comes from
//! the CRBA, the dense system is solved by Cholesky. If a torque so found passes its limit,
//! the torques are clamped and the accelerations recomputed by the ABA with them (the
//! implicit damping is lost on that step only for the clamped joints' values).

use super::dynamics::Tree;
use super::joints::{difference, integrate};
use super::model::{Model, Servo};
use nalgebra::DMatrix;

/// Servo workspace (sized on first use).
#[derive(Clone, Debug, Default)]
pub(super) struct ServoWork {
    diff: Vec<f64>,
    q_pred: Vec<f64>,
    bias: Vec<f64>,
    zero: Vec<f64>,
    servo: Vec<f64>,
}

/// The servoed degrees of freedom: `(first dof, count, servo)` per servoed joint.
fn servos(model: &Model) -> impl Iterator<Item = (usize, usize, Servo)> + '_ {
    model
        .bodies()
        .iter()
        .enumerate()
        .filter_map(|(i, b)| b.servo.map(|s| (model.starts(i).1, b.joint.nv(), s)))
}

/// Whether the model has a servo.
pub(super) fn any(model: &Model) -> bool {
    servos(model).next().is_some()
}

/// Explicit PD torques added to `tau`.
pub(super) fn explicit(
    model: &Model,
    q: &[f64],
    qd: &[f64],
    targets: &[f64],
    w: &mut ServoWork,
    tau: &mut [f64],
) {
    w.diff.resize(model.nv(), 0.0);
    difference(model, targets, q, &mut w.diff);
    for (iv, n, s) in servos(model) {
        for k in iv..iv + n {
            tau[k] += (s.kp * w.diff[k] - s.kd * qd[k]).clamp(-s.max_torque, s.max_torque);
        }
    }
}

/// Stable PD: the accelerations `qdd` under the joint forces `tau` (not yet holding the
/// servos) and the servos, at the state of the last [`Tree::kinematics`] with `tree.f_ext`
/// set, for a step `dt`.
#[allow(clippy::too_many_arguments)]
pub(super) fn stable(
    model: &Model,
    q: &[f64],
    qd: &[f64],
    targets: &[f64],
    dt: f64,
    tree: &mut Tree,
    w: &mut ServoWork,
    tau: &mut [f64],
    qdd: &mut [f64],
) {
    let nv = model.nv();
    w.diff.resize(nv, 0.0);
    w.q_pred.resize(q.len(), 0.0);
    w.bias.resize(nv, 0.0);
    w.zero.resize(nv, 0.0);
    w.servo.resize(nv, 0.0);
    integrate(model, q, qd, dt, &mut w.q_pred);
    difference(model, targets, &w.q_pred, &mut w.diff);
    tree.rnea(model, &w.zero, &mut w.bias);
    tree.crba(model);
    w.servo.fill(0.0);
    for (iv, n, s) in servos(model) {
        for (k, &v) in qd.iter().enumerate().skip(iv).take(n) {
            w.servo[k] = s.kp * w.diff[k] - s.kd * v;
            tree.mass_matrix[(k, k)] += dt * s.kd;
        }
    }
    for k in 0..nv {
        qdd[k] = tau[k] - w.bias[k] + w.servo[k];
    }
    if !cholesky(&mut tree.mass_matrix) {
        qdd.fill(f64::NAN);
        return;
    }
    cholesky_substitute(&tree.mass_matrix, qdd);
    let mut clamped = false;
    for (iv, n, s) in servos(model) {
        for (k, &a) in qdd.iter().enumerate().skip(iv).take(n) {
            let t = w.servo[k] - s.kd * dt * a;
            clamped |= t.abs() > s.max_torque;
            w.servo[k] = t.clamp(-s.max_torque, s.max_torque);
        }
    }
    if clamped {
        for (t, s) in tau.iter_mut().zip(&w.servo) {
            *t += s;
        }
        tree.aba(model, tau, qdd);
    }
}

/// Overwrite the lower triangle of symmetric positive definite `a` with its Cholesky factor
/// `L` (`a = L Lᵀ`); `false` if `a` is not positive definite.
pub(super) fn cholesky(a: &mut DMatrix<f64>) -> bool {
    let n = a.nrows();
    for j in 0..n {
        let mut d = a[(j, j)];
        for k in 0..j {
            d -= a[(j, k)] * a[(j, k)];
        }
        if d.is_nan() || d <= 0.0 {
            return false;
        }
        let d = d.sqrt();
        a[(j, j)] = d;
        for i in j + 1..n {
            let mut s = a[(i, j)];
            for k in 0..j {
                s -= a[(i, k)] * a[(j, k)];
            }
            a[(i, j)] = s / d;
        }
    }
    true
}

/// Solve `L Lᵀ x = b` in place (`b` becomes `x`) with the factor `l` of [`cholesky`].
pub(super) fn cholesky_substitute(l: &DMatrix<f64>, b: &mut [f64]) {
    let n = b.len();
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= l[(i, k)] * b[k];
        }
        b[i] = s / l[(i, i)];
    }
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s -= l[(k, i)] * b[k];
        }
        b[i] = s / l[(i, i)];
    }
}
