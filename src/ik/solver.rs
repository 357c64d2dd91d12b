//! The IK solver: a plan made once per set of effectors (variables, which of them move which
//! effector, buffers sized for the task) and the iterations of the Jacobian methods; CCD
//! and the analytic two-bone method are in the submodules.

mod ccd;
mod two_bone;

use super::model::{self, Var};
use super::{Method, Options, Report, Target};
use crate::error::{Error, Result};
use crate::math::svd::jacobi_rows;
use crate::mocap::Skeleton;
use crate::rotation::quat_to_rotvec;
use glam::{DQuat, DVec3};
use two_bone::{two_bone_plan, TwoBone};

/// Largest change of one dof in one Jacobian step (radians).
const MAX_STEP: f64 = 0.5;
/// Singular values below this fraction of the largest are treated as zero (pseudo-inverse
/// and the null-space projector).
const RANK_TOL: f64 = 1e-9;
/// DLS: damping starts below `σ_min = DLS_EPSILON L` and grows to `λ = DLS_LAMBDA L`.
const DLS_EPSILON: f64 = 0.03;
const DLS_LAMBDA: f64 = 0.03;
/// Step halvings tried before a Jacobian solve is declared stalled.
const HALVINGS: usize = 20;

pub(super) fn check_pose(sk: &Skeleton, pose: &[f64], arg: &str) -> Result<()> {
    if pose.len() != sk.stride() {
        return Err(Error::invalid(
            arg,
            format!("has {} values, the skeleton's poses have {}", pose.len(), sk.stride()),
        ));
    }
    if let Some(i) = pose.iter().position(|v| !v.is_finite()) {
        return Err(Error::invalid(arg, "contains NaN or infinity").at(i));
    }
    Ok(())
}

pub(super) fn check_joint(sk: &Skeleton, joint: usize) -> Result<()> {
    if joint > sk.bones.len() {
        return Err(Error::invalid(
            "targets",
            format!("joint {joint} does not exist; the skeleton has {}", 1 + sk.bones.len()),
        ));
    }
    Ok(())
}

/// An IK solver for one set of end effectors on one skeleton, owning every buffer it needs:
/// [`Solver::solve`] allocates nothing.
#[derive(Clone, Debug)]
pub struct Solver<'a> {
    sk: &'a Skeleton,
    options: Options,
    /// Per effector: joint and whether it has an orientation target.
    effectors: Vec<(usize, bool)>,
    /// Per effector: its reach (sum of the lengths of the bones that move it), the weight of
    /// its orientation rows.
    reach: Vec<f64>,
    /// Largest reach: the length scale of the DLS damping.
    scale: f64,
    vars: Vec<Var>,
    /// `affects[e * n + v]`: variable `v` moves effector `e`.
    affects: Vec<bool>,
    rest: Vec<f64>,
    two_bone: Option<TwoBone>,
    rows: usize,
    // Workspace.
    pos: Vec<DVec3>,
    rot: Vec<DQuat>,
    axis: Vec<DVec3>,
    pivot: Vec<DVec3>,
    trial: Vec<f64>,
    jac: Vec<f64>,
    err: Vec<f64>,
    err_trial: Vec<f64>,
    res: Vec<f64>,
    a: Vec<f64>,
    v: Vec<f64>,
    s2: Vec<f64>,
    dq: Vec<f64>,
    z: Vec<f64>,
    free: Vec<bool>,
    eff_p: Vec<DVec3>,
    eff_r: Vec<DQuat>,
}

/// The targets of [`Solver::new`], checked: at least one, on distinct existing joints, with
/// finite values.
fn check_targets(sk: &Skeleton, targets: &[Target]) -> Result<()> {
    if targets.is_empty() {
        return Err(Error::invalid("targets", "needs at least one target"));
    }
    for (i, t) in targets.iter().enumerate() {
        check_joint(sk, t.joint)?;
        if targets[..i].iter().any(|u| u.joint == t.joint) {
            return Err(Error::invalid("targets", format!("joint {} appears twice", t.joint)));
        }
    }
    check_target_values(targets)
}

/// The options of [`Solver::new`], checked: a positive tolerance, non-negative null-space
/// weights, and those only with a method that has a null space.
fn check_options(o: &Options) -> Result<()> {
    if !(o.tol.is_finite() && o.tol > 0.0) {
        return Err(Error::invalid("tol", format!("must be positive, got {}", o.tol)));
    }
    for (name, w) in [("rest_weight", o.rest_weight), ("limit_weight", o.limit_weight)] {
        if !(w.is_finite() && w >= 0.0) {
            return Err(Error::invalid(name, format!("must be >= 0, got {w}")));
        }
        if w > 0.0 && !matches!(o.method, Method::Dls | Method::PseudoInverse) {
            return Err(Error::invalid(
                name,
                "the null-space objective needs method \"dls\" or \"pseudo_inverse\"",
            ));
        }
    }
    Ok(())
}

/// Which variables move which effector (`affects[e * n + v]`, `n = vars.len()`), and each
/// effector's reach: the summed lengths (m) of the bones from the root to it, 1 at the root.
fn influence(sk: &Skeleton, effectors: &[(usize, bool)], vars: &[Var]) -> (Vec<bool>, Vec<f64>) {
    let n = vars.len();
    let mut affects = vec![false; effectors.len() * n];
    let mut reach = vec![0.0; effectors.len()];
    for (e, &(j, _)) in effectors.iter().enumerate() {
        for (c, v) in vars.iter().enumerate() {
            affects[e * n + c] = model::is_ancestor_or_self(sk, v.joint, j);
        }
        let mut k = j;
        while k > 0 {
            reach[e] += sk.bones[k - 1].length;
            k = model::parent_joint(sk, k);
        }
        if reach[e] == 0.0 {
            reach[e] = 1.0;
        }
    }
    (affects, reach)
}

impl<'a> Solver<'a> {
    /// A solver for the effectors of `targets` (their joints and which have orientations;
    /// the target values may change between solves).
    ///
    /// # Errors
    /// No targets, an unknown or repeated joint, non-finite targets, invalid options, or a
    /// method that cannot serve the targets (two-bone needs one position target on a bone
    /// with one rotational dof whose parent bone has three distinct ones; the null-space
    /// weights need pseudo-inverse or DLS).
    pub fn new(skeleton: &'a Skeleton, targets: &[Target], options: &Options) -> Result<Self> {
        let sk = skeleton;
        check_targets(sk, targets)?;
        let o = options;
        check_options(o)?;
        let rest = match &o.rest {
            Some(r) => {
                check_pose(sk, r, "rest")?;
                r.clone()
            }
            None => vec![0.0; sk.stride()],
        };
        let effectors: Vec<(usize, bool)> =
            targets.iter().map(|t| (t.joint, t.orientation.is_some())).collect();
        let mut vars = model::all_vars(sk, o.free_root, o.joint_limits);
        vars.retain(|v| effectors.iter().any(|&(j, _)| model::is_ancestor_or_self(sk, v.joint, j)));
        let n = vars.len();
        let (affects, reach) = influence(sk, &effectors, &vars);
        let scale = reach.iter().fold(0.0_f64, |m, r| m.max(*r));
        let two_bone = if o.method == Method::TwoBone {
            Some(two_bone_plan(sk, targets, o.joint_limits)?)
        } else {
            None
        };
        let rows: usize = effectors.iter().map(|e| if e.1 { 6 } else { 3 }).sum();
        let joints = 1 + sk.bones.len();
        let stride = sk.stride();
        Ok(Solver {
            sk,
            options: o.clone(),
            reach,
            scale,
            affects,
            rest,
            two_bone,
            rows,
            pos: vec![DVec3::ZERO; joints],
            rot: vec![DQuat::IDENTITY; joints],
            axis: vec![DVec3::ZERO; stride],
            pivot: vec![DVec3::ZERO; stride],
            trial: vec![0.0; stride],
            jac: vec![0.0; rows * n],
            err: vec![0.0; rows],
            err_trial: vec![0.0; rows],
            res: vec![0.0; rows],
            a: vec![0.0; rows * n],
            v: vec![0.0; rows * rows],
            s2: vec![0.0; rows],
            dq: vec![0.0; n],
            z: vec![0.0; n],
            free: vec![true; n],
            eff_p: vec![DVec3::ZERO; effectors.len()],
            eff_r: vec![DQuat::IDENTITY; effectors.len()],
            effectors,
            vars,
        })
    }

    /// Solve for `targets` (the same joints, with and without orientation, as given to
    /// [`Solver::new`]), changing `pose` in place. On error `pose` is left untouched.
    ///
    /// # Errors
    /// A pose of the wrong length or with NaN; targets for other effectors; non-finite targets.
    pub fn solve(&mut self, pose: &mut [f64], targets: &[Target]) -> Result<Report> {
        check_pose(self.sk, pose, "pose")?;
        if targets.len() != self.effectors.len()
            || targets
                .iter()
                .zip(&self.effectors)
                .any(|(t, e)| t.joint != e.0 || t.orientation.is_some() != e.1)
        {
            return Err(Error::invalid(
                "targets",
                "must be for the joints (and orientations) the solver was made for",
            ));
        }
        check_target_values(targets)?;
        for v in &self.vars {
            pose[v.index] = pose[v.index].clamp(v.lo, v.hi);
        }
        Ok(match self.options.method {
            Method::TwoBone => self.two_bone(pose, targets),
            Method::Ccd => self.ccd(pose, targets),
            Method::Transpose | Method::PseudoInverse | Method::Dls => {
                self.jacobian_method(pose, targets)
            }
        })
    }

    /// Forward kinematics of `q` into the workspace.
    fn forward(&mut self, q: &[f64]) {
        model::forward(self.sk, q, &mut self.pos, &mut self.rot, &mut self.axis, &mut self.pivot);
    }

    /// Fill `err` (task vector, orientation rows weighted by the reach) from the workspace
    /// FK; returns (squared norm, largest position error, largest orientation error).
    fn errors(&self, targets: &[Target], err: &mut [f64]) -> (f64, f64, f64) {
        let (mut sq, mut ep, mut eo) = (0.0, 0.0_f64, 0.0_f64);
        let mut r = 0;
        for (e, t) in targets.iter().enumerate() {
            let d = t.position - self.pos[t.joint];
            err[r..r + 3].copy_from_slice(&d.to_array());
            sq += d.length_squared();
            ep = ep.max(d.length());
            r += 3;
            if let Some(qt) = t.orientation {
                let w = DVec3::from_array(quat_to_rotvec(qt * self.rot[t.joint].conjugate()));
                eo = eo.max(w.length());
                let w = w * self.reach[e];
                err[r..r + 3].copy_from_slice(&w.to_array());
                sq += w.length_squared();
                r += 3;
            }
        }
        (sq, ep, eo)
    }

    /// The weighted Jacobian of the workspace FK into `jac` (rows x vars).
    fn fill_jacobian(&mut self) {
        let n = self.vars.len();
        self.jac.fill(0.0);
        let mut r = 0;
        for (e, &(j, has_o)) in self.effectors.iter().enumerate() {
            for (c, v) in self.vars.iter().enumerate() {
                if self.affects[e * n + c] {
                    let (lin, ang) = model::column(v, self.pos[j], &self.pivot, &self.axis);
                    for d in 0..3 {
                        self.jac[(r + d) * n + c] = lin[d];
                        if has_o {
                            self.jac[(r + 3 + d) * n + c] = ang[d] * self.reach[e];
                        }
                    }
                }
            }
            r += if has_o { 6 } else { 3 };
        }
    }

    fn report(&self, ep: f64, eo: f64, iterations: usize) -> Report {
        let tol = self.options.tol;
        Report { converged: ep <= tol && eo <= tol, error: ep, orientation_error: eo, iterations }
    }

    fn jacobian_method(&mut self, q: &mut [f64], targets: &[Target]) -> Report {
        let tol = self.options.tol;
        let secondary = self.options.rest_weight > 0.0 || self.options.limit_weight > 0.0;
        self.forward(q);
        let mut err = std::mem::take(&mut self.err);
        let mut err_trial = std::mem::take(&mut self.err_trial);
        let mut state = self.errors(targets, &mut err);
        let mut iterations = 0;
        while iterations < self.options.max_iters && !self.vars.is_empty() {
            let converged = state.1 <= tol && state.2 <= tol;
            if converged && !secondary {
                break;
            }
            self.fill_jacobian();
            let null_step = self.step(q, &err, self.options.method);
            if converged && null_step <= tol {
                break;
            }
            iterations += 1;
            let mut accepted =
                self.line_search(q, targets, &mut err, &mut err_trial, &mut state, converged);
            if !accepted && self.options.method != Method::Transpose {
                // The step does not descend (curvature near a singularity, or the clamping
                // loop): fall back on the projected gradient, which descends unless the
                // pose is a constrained local minimum.
                self.step(q, &err, Method::Transpose);
                accepted =
                    self.line_search(q, targets, &mut err, &mut err_trial, &mut state, converged);
            }
            if !accepted {
                break;
            }
        }
        self.err = err;
        self.err_trial = err_trial;
        self.report(state.1, state.2, iterations)
    }

    /// Try `q + α dq` for `α = 1, 1/2, 1/4...` until the squared error `state.0` decreases
    /// (or, once converged, stays within `tol`); on success update `q`, `err` and `state`.
    fn line_search(
        &mut self,
        q: &mut [f64],
        targets: &[Target],
        err: &mut Vec<f64>,
        err_trial: &mut Vec<f64>,
        state: &mut (f64, f64, f64),
        converged: bool,
    ) -> bool {
        let tol = self.options.tol;
        let mut alpha = 1.0;
        for _ in 0..HALVINGS {
            self.trial.copy_from_slice(q);
            for (v, d) in self.vars.iter().zip(&self.dq) {
                self.trial[v.index] = (q[v.index] + alpha * d).clamp(v.lo, v.hi);
            }
            let trial = std::mem::take(&mut self.trial);
            self.forward(&trial);
            self.trial = trial;
            let next = self.errors(targets, err_trial);
            if next.0 < state.0 || (converged && next.1 <= tol && next.2 <= tol) {
                q.copy_from_slice(&self.trial);
                std::mem::swap(err, err_trial);
                *state = next;
                return true;
            }
            alpha *= 0.5;
        }
        false
    }

    /// One Jacobian step of `method` into `dq` for task error `err`, with the clamping loop:
    /// dofs whose step would cross a limit are clamped to it, taken out, and the rest is
    /// solved again for the residual. Returns the largest null-space component (0 without a
    /// secondary objective).
    fn step(&mut self, q: &[f64], err: &[f64], method: Method) -> f64 {
        let (m, n) = (self.rows, self.vars.len());
        self.free.fill(true);
        self.dq.fill(0.0);
        self.res.copy_from_slice(err);
        let o = &self.options;
        let secondary =
            (o.rest_weight > 0.0 || o.limit_weight > 0.0) && method != Method::Transpose;
        let mut null_step = 0.0;
        loop {
            for r in 0..m {
                for c in 0..n {
                    self.a[r * n + c] = if self.free[c] { self.jac[r * n + c] } else { 0.0 };
                }
            }
            for c in 0..n {
                if self.free[c] {
                    self.dq[c] = 0.0;
                }
            }
            match method {
                Method::Transpose => self.transpose_step(),
                Method::PseudoInverse | Method::Dls => {
                    let cut = self.svd_step(method);
                    if secondary {
                        null_step = self.null_space_step(q, cut);
                    }
                }
                Method::TwoBone | Method::Ccd => unreachable!("not a Jacobian method"),
            }
            if !self.cap_and_clamp(q) {
                return null_step;
            }
            self.res.copy_from_slice(err);
            for c in 0..n {
                if !self.free[c] {
                    for r in 0..m {
                        self.res[r] -= self.jac[r * n + c] * self.dq[c];
                    }
                }
            }
        }
    }

    /// The Jacobian-transpose step on the free dofs: `g = Jᵀ res`, `h = J g`,
    /// `dq = α g` with `α = ⟨res, h⟩ / |h|²` (Buss 2004; see the module docs of `ik`).
    fn transpose_step(&mut self) {
        let (m, n) = (self.rows, self.vars.len());
        for c in 0..n {
            self.z[c] = (0..m).map(|r| self.a[r * n + c] * self.res[r]).sum();
        }
        let (mut num, mut den) = (0.0, 0.0);
        for r in 0..m {
            let h: f64 = (0..n).map(|c| self.a[r * n + c] * self.z[c]).sum();
            num += self.res[r] * h;
            den += h * h;
        }
        let alpha = if den > 0.0 { num / den } else { 0.0 };
        for c in 0..n {
            if self.free[c] {
                self.dq[c] = alpha * self.z[c];
            }
        }
    }

    /// The pseudo-inverse or damped least-squares step `dq = Σ σᵢ/(σᵢ² + λ²) uᵢ vᵢᵀ res` by
    /// the SVD of the free columns (`λ² = 0` for the pseudo-inverse; Chiaverini 1997's
    /// adaptive damping for DLS, see the module docs of `ik`); returns the cut below which
    /// squared singular values count as zero.
    fn svd_step(&mut self, method: Method) -> f64 {
        let (m, n) = (self.rows, self.vars.len());
        jacobi_rows(&mut self.a, m, n, &mut self.v, &mut self.s2);
        let s2max = self.s2[..m].iter().fold(0.0_f64, |a, b| a.max(*b));
        let cut = RANK_TOL * RANK_TOL * s2max;
        let lambda2 = if method == Method::Dls {
            let s2min = self.s2[..m].iter().fold(f64::INFINITY, |a, b| a.min(*b));
            let eps = DLS_EPSILON * self.scale;
            let lmax = DLS_LAMBDA * self.scale;
            if s2min < eps * eps {
                (1.0 - s2min / (eps * eps)) * lmax * lmax
            } else {
                0.0
            }
        } else {
            0.0
        };
        for i in 0..m {
            let s2 = self.s2[i];
            if s2 <= cut || s2 == 0.0 {
                continue;
            }
            let ve: f64 = (0..m).map(|r| self.v[r * m + i] * self.res[r]).sum();
            let coef = ve / (s2 + lambda2);
            for c in 0..n {
                self.dq[c] += coef * self.a[i * n + c];
            }
        }
        cut
    }

    /// Add the secondary objective (towards the rest pose and away from the limits)
    /// projected on the null space of the free Jacobian, `(I - J⁺J) z` (Liégeois 1977), to
    /// `dq`; returns its largest component.
    fn null_space_step(&mut self, q: &[f64], cut: f64) -> f64 {
        let (m, n) = (self.rows, self.vars.len());
        let o = &self.options;
        for (c, v) in self.vars.iter().enumerate() {
            let x = q[v.index];
            let mut z = -o.rest_weight * (x - self.rest[v.index]);
            if v.hi.is_finite() && v.lo.is_finite() && v.hi > v.lo {
                let (mid, half) = (0.5 * (v.hi + v.lo), 0.5 * (v.hi - v.lo));
                z -= o.limit_weight * (x - mid) / (half * half);
            }
            self.z[c] = if self.free[c] { z } else { 0.0 };
        }
        for i in 0..m {
            let s2 = self.s2[i];
            if s2 <= cut || s2 == 0.0 {
                continue;
            }
            let az: f64 = (0..n).map(|c| self.a[i * n + c] * self.z[c]).sum();
            for c in 0..n {
                self.z[c] -= az / s2 * self.a[i * n + c];
            }
        }
        for c in 0..n {
            self.dq[c] += self.z[c];
        }
        self.z.iter().fold(0.0_f64, |a, b| a.max(b.abs()))
    }

    /// Cap the free part of `dq` at `MAX_STEP`, then clamp the dofs that would cross a limit
    /// and take them out; whether any was clamped.
    fn cap_and_clamp(&mut self, q: &[f64]) -> bool {
        let n = self.vars.len();
        let big = (0..n).filter(|&c| self.free[c]).fold(0.0_f64, |a, c| a.max(self.dq[c].abs()));
        if big > MAX_STEP {
            for c in 0..n {
                if self.free[c] {
                    self.dq[c] *= MAX_STEP / big;
                }
            }
        }
        let mut clamped = false;
        for (c, v) in self.vars.iter().enumerate() {
            if !self.free[c] {
                continue;
            }
            let x = q[v.index] + self.dq[c];
            if x > v.hi || x < v.lo {
                self.dq[c] = x.clamp(v.lo, v.hi) - q[v.index];
                self.free[c] = false;
                clamped = true;
            }
        }
        clamped
    }
}

fn check_target_values(targets: &[Target]) -> Result<()> {
    for (i, t) in targets.iter().enumerate() {
        if !t.position.is_finite() {
            return Err(Error::invalid("targets", "position contains NaN or infinity").at(i));
        }
        if let Some(o) = t.orientation {
            if !o.is_finite() || (o.length() - 1.0).abs() > 1e-6 {
                return Err(
                    Error::invalid("targets", "orientation must be a unit quaternion").at(i)
                );
            }
        }
    }
    Ok(())
}
