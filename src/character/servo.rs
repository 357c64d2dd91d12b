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
//! the CRBA, the system is solved by the LTL factorisation in the tree's sparsity ([`ltl`]). The ground contacts' damping is taken
//! at the next step's velocity in the same solve, `M + dt K_d + dt Σ Jᵀ C J`
//! ([`Tree::crba_with_contacts`]). If a servo torque so found passes its limit, the servo
//! torques are clamped and the accelerations solved again with them fixed, `M + dt Σ Jᵀ C J`
//! (the servos' implicit damping is lost on that step; the contacts' is kept).

use super::dynamics::Tree;
use super::joints::{difference, difference_joint, integrate_joint};
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
    // `q̄ ⊖ (q ⊕ dt q̇)` of the servoed joints only (the others' are not read).
    for (i, b) in model.bodies().iter().enumerate().filter(|(_, b)| b.servo.is_some()) {
        let (iq, iv) = model.starts(i);
        integrate_joint(b.joint, &q[iq..], &qd[iv..], dt, &mut w.q_pred[iq..]);
        difference_joint(b.joint, &targets[iq..], &w.q_pred[iq..], &mut w.diff[iv..]);
    }
    tree.rnea(model, &w.zero, &mut w.bias);
    tree.crba_with_contacts(model, dt);
    w.servo.fill(0.0);
    for (iv, n, s) in servos(model) {
        for (k, &v) in qd.iter().enumerate().skip(iv).take(n) {
            w.servo[k] = s.kp * w.diff[k] - s.kd * v;
            tree.mass_matrix[(k, k)] += dt * s.kd;
        }
    }
    if !solve(tree, w, tau, qdd) {
        return;
    }
    let mut clamped = false;
    for (iv, n, s) in servos(model) {
        for (k, &a) in qdd.iter().enumerate().skip(iv).take(n) {
            let t = w.servo[k] - s.kd * dt * a;
            clamped |= t.abs() > s.max_torque;
            w.servo[k] = t.clamp(-s.max_torque, s.max_torque);
        }
    }
    if clamped {
        // `M + dt Σ Jᵀ C J` again (the factorisation overwrote it; the same operations on
        // the same values as above, and cheaper than keeping a copy on every step).
        tree.crba_with_contacts(model, dt);
        solve(tree, w, tau, qdd);
    }
}

/// `qdd = M⁻¹ (tau - bias + servo)` with the matrix `M` in `tree.mass_matrix`, factored there
/// in place ([`ltl`]); false, and `qdd` NaN, when `M` is not positive definite.
fn solve(tree: &mut Tree, w: &ServoWork, tau: &[f64], qdd: &mut [f64]) -> bool {
    for (((a, &t), &b), &s) in qdd.iter_mut().zip(tau).zip(&w.bias).zip(&w.servo) {
        *a = t - b + s;
    }
    if !ltl(&mut tree.mass_matrix, &tree.dof_paths) {
        qdd.fill(f64::NAN);
        return false;
    }
    ltl_solve(&tree.mass_matrix, &tree.dof_paths, qdd);
    true
}

/// `lambda[i]` of a degree of freedom without a parent (the tree's first).
pub(super) const NO_PARENT: usize = usize::MAX;

/// Every degree of freedom's path to the root: its ancestors `λ(k), λ(λ(k)), …` in
/// Featherstone's expanded parent array (2008, §6.5), stored as runs of consecutive indices
/// (a joint's degrees of freedom and the chain above it are numbered in a row, so the 3-D
/// biped's paths are one or two runs), so that [`ltl`] and [`ltl_solve`] update contiguous
/// slices instead of gathering index by index (bounds-checked loads, no vector code).
#[derive(Clone, Debug, Default)]
pub(super) struct Paths {
    starts: Vec<usize>,
    /// Runs `lo..end`, each read from `end − 1` down to `lo` (nearest ancestor first).
    runs: Vec<(usize, usize)>,
}

impl Paths {
    /// The paths of the parent array `lambda` (`lambda[i] < i`, [`NO_PARENT`] for none).
    pub(super) fn build(&mut self, lambda: &[usize]) {
        self.starts.clear();
        self.runs.clear();
        self.starts.push(0);
        for &parent in lambda {
            let mut j = parent;
            let mut run: Option<(usize, usize)> = None;
            while j != NO_PARENT {
                run = match run {
                    Some((lo, end)) if j + 1 == lo => Some((j, end)),
                    Some(done) => {
                        self.runs.push(done);
                        Some((j, j + 1))
                    }
                    None => Some((j, j + 1)),
                };
                j = lambda[j];
            }
            self.runs.extend(run);
            self.starts.push(self.runs.len());
        }
    }

    /// The number of degrees of freedom.
    pub(super) fn len(&self) -> usize {
        self.starts.len().saturating_sub(1)
    }

    /// The ancestors of degree of freedom `k` as runs `lo..end`, nearest first.
    fn of(&self, k: usize) -> &[(usize, usize)] {
        &self.runs[self.starts[k]..self.starts[k + 1]]
    }
}

/// Factor symmetric positive definite `a` in place as `a = Lᵀ L`, `L` lower triangular with
/// the tree's branch-induced sparsity: Featherstone's LTL factorisation (2008, §6.5, Table
/// 6.3), along each degree of freedom's path to the root ([`Paths`], `Tree::dof_paths`).
/// `a` must have that sparsity (zeros off the paths, as the CRBA writes it). Step `k` updates
/// only the columns `i` on `k`'s path, `Σ depth` of them instead of `n² / 2` (two legs do
/// not couple); each such column is updated in its rows `0..=i` in one contiguous run, the
/// rows off the path taking `x − L(k, i)·0 = x` (the factor's zeros stay zeros), so the
/// results are bitwise those of updating the path's rows only (the same instructions a step
/// on the 3-D biped, measured, docs/character.md, "Speed"). `false` if `a` is not positive
/// definite.
///
/// Storage (for [`ltl_solve`]): `L(i, j)`, `j < i`, is written at `(j, i)`, in column `i`
/// (contiguous: each update runs down two columns), and the diagonal holds the pivots'
/// reciprocals `1 / L(i, i)`, so that no solve divides (a division's latency sits on the
/// back-substitution's chain of dependent updates).
pub(super) fn ltl(a: &mut DMatrix<f64>, paths: &Paths) -> bool {
    let n = a.nrows();
    let a = a.as_mut_slice();
    for k in (0..paths.len()).rev() {
        let (before, from_k) = a.split_at_mut(k * n);
        let col_k = &mut from_k[..n];
        let d = col_k[k];
        if d.is_nan() || d <= 0.0 {
            return false;
        }
        let r = 1.0 / d.sqrt();
        col_k[k] = r;
        let runs = paths.of(k);
        for &(lo, end) in runs {
            col_k[lo..end].iter_mut().for_each(|v| *v *= r);
        }
        for &(lo, end) in runs {
            for i in lo..end {
                let (lki, col_i) = (col_k[i], &mut before[i * n..=i * n + i]);
                for (y, &x) in col_i.iter_mut().zip(&col_k[..=i]) {
                    *y -= lki * x;
                }
            }
        }
    }
    true
}

/// Solve `Lᵀ L x = b` in place (`b` becomes `x`) with the factor `l` of [`ltl`] (its
/// storage: `L(i, j)` at `(j, i)`, reciprocal pivots on the diagonal) (Featherstone 2008,
/// Table 6.4: back-substitution along each path to the root).
pub(super) fn ltl_solve(l: &DMatrix<f64>, paths: &Paths, b: &mut [f64]) {
    let n = l.nrows();
    let l = l.as_slice();
    for i in (0..paths.len()).rev() {
        let col = &l[i * n..(i + 1) * n];
        let x = b[i] * col[i];
        b[i] = x;
        for &(lo, end) in paths.of(i) {
            for (y, &c) in b[lo..end].iter_mut().zip(&col[lo..end]) {
                *y -= c * x;
            }
        }
    }
    for i in 0..paths.len() {
        let col = &l[i * n..(i + 1) * n];
        let mut x = b[i];
        // Nearest ancestor first.
        for &(lo, end) in paths.of(i) {
            x = col[lo..end].iter().zip(&b[lo..end]).rev().fold(x, |x, (c, v)| x - c * v);
        }
        b[i] = x * col[i];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::character::biped3d::biped3d;
    use crate::character::forces::Contact;
    use crate::character::model::Settings;
    use glam::DVec3;

    /// The 3-D biped in a bent pose, moving with rates `qd`: its kinematics in a tree.
    fn bent_biped(qd: &[f64]) -> (crate::character::model::Model, Tree) {
        let model = biped3d(Settings::default()).unwrap();
        let mut q = model.neutral();
        for (k, v) in q.iter_mut().enumerate() {
            *v += 0.3 * ((k as f64) * 1.7).sin();
        }
        for i in 0..model.bodies().len() {
            if model.bodies()[i].joint.nq() >= 4 {
                let at = model.starts(i).0 + if i == 0 { 3 } else { 0 };
                let n: f64 = q[at..at + 4].iter().map(|v| v * v).sum::<f64>().sqrt();
                q[at..at + 4].iter_mut().for_each(|v| *v /= n);
            }
        }
        let mut tree = Tree::default();
        tree.kinematics(&model, &q, &qd[..model.nv()]);
        (model, tree)
    }

    /// The contacts' terms of the CRBA are `dt Jᵀ C J`: for any rates, `q̇ᵀ (M_c − M) q̇`
    /// equals `dt Σ (c_t |v_t|² + c_n v_n²)` with `v` each contact point's world velocity
    /// from the bodies' velocities of the kinematics (an independent route to `J q̇`) and
    /// `v_n` along the contact's normal (the ground's `+Y`, a collider's tilted one).
    #[test]
    fn the_contacts_damping_adds_dt_jt_c_j_to_the_mass_matrix() {
        let dt = 1e-3;
        let qd: Vec<f64> = (0..20).map(|k| ((k * 7) as f64 * 0.61).sin()).collect();
        let (model, mut tree) = bent_biped(&qd);
        let points = [(3, DVec3::new(0.05, -0.07, 0.05)), (8, DVec3::new(0.1, -0.07, -0.05))];
        let mut expected = 0.0;
        for (n, &(body, local)) in points.iter().enumerate() {
            let (tangent, normal) = (1000.0 * (n + 1) as f64, 300.0 * (n + 2) as f64);
            let point = tree.pos[body] + tree.rot[body] * local;
            // The ground's normal, and a collider's tilted one.
            let direction = [DVec3::Y, DVec3::new(0.3, 1.0, -0.4).normalize()][n];
            tree.contacts.push(Contact { body, point, direction, normal, tangent });
            let v = &tree.v[body];
            let w = DVec3::new(v[0], v[1], v[2]);
            let vel = tree.rot[body] * (DVec3::new(v[3], v[4], v[5]) + w.cross(local));
            let vn = vel.dot(direction);
            expected += dt * (tangent * (vel.length_squared() - vn * vn) + normal * vn * vn);
        }
        tree.crba(&model);
        let plain = tree.mass_matrix.clone();
        tree.crba_with_contacts(&model, dt);
        let x = nalgebra::DVector::from(qd.clone());
        let added = x.dot(&((&tree.mass_matrix - plain) * &x));
        assert!(
            (added - expected).abs() < 1e-12 * expected.abs().max(1.0),
            "{added} vs {expected}"
        );
        assert!(expected > 1e-3, "{expected}");
    }

    /// The LTL factorisation in the tree's sparsity solves the CRBA's `M x = b` as a dense
    /// Cholesky does, on the 3-D biped in a bent pose (two branches, a free root, ball, hinge
    /// and fixed joints).
    #[test]
    fn ltl_solves_the_mass_matrix_as_a_dense_cholesky() {
        let model = biped3d(Settings::default()).unwrap();
        let mut q = model.neutral();
        for (k, v) in q.iter_mut().enumerate() {
            *v += 0.3 * ((k as f64) * 1.7).sin();
        }
        for i in 0..model.bodies().len() {
            let iq = model.starts(i).0;
            if model.bodies()[i].joint.nq() == 4 || i == 0 {
                let at = if i == 0 { 3 } else { iq };
                let n: f64 = q[at..at + 4].iter().map(|v| v * v).sum::<f64>().sqrt();
                q[at..at + 4].iter_mut().for_each(|v| *v /= n);
            }
        }
        let qd = vec![0.0; model.nv()];
        let mut tree = Tree::default();
        tree.kinematics(&model, &q, &qd);
        tree.crba(&model);
        let dense = tree.mass_matrix.clone();
        let b: Vec<f64> = (0..model.nv()).map(|k| ((k * k) as f64 * 0.37).cos()).collect();
        let expected = dense.clone().cholesky().unwrap().solve(&nalgebra::DVector::from(b.clone()));
        assert!(ltl(&mut tree.mass_matrix, &tree.dof_paths));
        let mut x = b.clone();
        ltl_solve(&tree.mass_matrix, &tree.dof_paths, &mut x);
        let err = x.iter().zip(expected.iter()).map(|(a, e)| (a - e).abs()).fold(0.0, f64::max);
        assert!(err < 1e-10 * expected.amax(), "{err}");
        let residual = &dense * nalgebra::DVector::from(x) - nalgebra::DVector::from(b);
        assert!(residual.amax() < 1e-10, "{}", residual.amax());
    }
}
