//! The rod solver: implicit Euler by Newton's method on the banded system, symplectic Euler,
//! and the static equilibrium. It owns every workspace and carries nothing a later step
//! reads: [`Solver::step`] steps a copy of the state and writes it back only when every step
//! succeeded, so a failed call leaves the state exactly as it was.
//!
//! The degrees of freedom are interleaved, `q = (x0, θ0, x1, θ1, …, x_n)` (`4n + 3`), so
//! every stencil lies within 10 of the diagonal and the Newton system is a band of
//! half-bandwidth 10, factored in `O(n)` ([`Band`]). A closed rod's, `(x0, θ0, …, x_{n−1},
//! θ^{n−1})` (`4n`), is cyclic: stored folded, a band of half-bandwidth 19.
//!
//! - **Implicit Euler** (Bergou et al. 2010, sec. 6; Gast et al. 2015's optimisation form):
//!   `q_{k+1}` minimises the incremental potential
//!   `Φ(q) = ½ (q − q̃)ᵀ M (q − q̃) / h² + E(q) − fᵀ (q − q_k)`, `q̃ = q_k + h v_k`, with `M` the lumped
//!   masses and twist inertias, `E` the elastic energy and `f` gravity plus the external
//!   forces; then `v_{k+1} = (q_{k+1} − q_k) / h`. Each Newton iteration solves
//!   `(M/h² + ∇²E) Δ = −∇Φ`; when the band is not positive definite it adds
//!   `λ diag|H|` (`λ` from 1e-8, ×10 until it factors, Levenberg–Marquardt style), and a
//!   backtracking (Armijo) line search on `Φ` halves the step until `Φ` decreases enough,
//!   trying at each length the straight step and the step with its edges bent back to
//!   their first-order lengths (`curve_trial`).
//!   The first iterate is the better of the start of the step and an explicit predictor
//!   (inertia and external forces, edges put back at their rest lengths from the root:
//!   `predict`). Newton stops when a step moves no vertex more than `tolerance`
//!   times the rod's length
//!   and no twist angle more than `tolerance` rad, or when the decrease of `Φ` it predicts
//!   is at the rounding level of `Φ` (`ROUNDING`).
//! - **Static equilibrium**: the same minimisation without the inertial term
//!   (`Φ = E − fᵀ(q − q_k)`).
//! - **Symplectic Euler**: `v += h M⁻¹ (f − ∇E)`, `q += h v`.
//!
//! Pinned vertices and locked twist angles keep their values: their rows and columns are
//! replaced by the identity and their gradient entries by zero. A clamped end the state
//! moves ([`State::move_clamp`]) has its held values set to the goal's for the step (the
//! `k`-th of `m` remaining steps of a call covers `1/(m−k)` of what remains), so its
//! velocity is that of the motion; its twist angle is the angle about the edge's new
//! tangent from its reference director, parallel-transported there, to the goal's `m1`.

use super::band::Band;
use super::contact::{friction, lag, penalty, repel, rub, Lagged, Obstacle, Repulsion};
use super::energy::{elastic, elastic_energy};
use super::frames::{signed_angle, transport, Frames};
use super::inextensible::project;
use super::model::Integrator;
use super::{Model, State, Stats};
use crate::error::{Error, Result};
use glam::DVec3;

/// Half-bandwidth of the interleaved Newton system.
const HALF_BANDWIDTH: usize = 10;
/// Half-bandwidth of a closed rod's, in the folded order ([`Band::reset_folded`]): a stencil
/// spans at most four consecutive vertex blocks of 4.
const FOLDED_HALF_BANDWIDTH: usize = 19;
/// Armijo's sufficient-decrease constant.
const ARMIJO: f64 = 1e-4;
/// The most halvings of one line search.
const HALVINGS: usize = 40;
/// Newton has converged when the decrease of `Φ` it predicts, `−∇Φ·Δ` (twice the distance
/// to the minimum for a quadratic), is below this fraction of `Φ`'s magnitude: the
/// rounding level, below which the gradient's rounding noise (large stretching forces
/// cancelling, amplified by soft bending modes) moves the steps and no step can decrease
/// `Φ` measurably.
const ROUNDING: f64 = 1e-13;

/// The workspaces of a rod step (see the module docs).
#[derive(Clone, Debug, Default)]
pub struct Solver {
    /// The stepped copy of the state.
    work: Option<State>,
    /// Frames of the configuration being evaluated.
    frames: Frames,
    /// The frames the evaluated configurations are transported from (tangents, reference
    /// directors, reference twists): the state's at the start of a step, then each Newton
    /// iterate's.
    base: Vec<DVec3>,
    base_reference: Vec<DVec3>,
    base_twist: Vec<f64>,
    /// Degrees of freedom: start of the step, inertial target, current, trial.
    q0: Vec<f64>,
    target: Vec<f64>,
    q: Vec<f64>,
    trial: Vec<f64>,
    /// Gradient of `Φ` and Newton direction.
    grad: Vec<f64>,
    dir: Vec<f64>,
    /// Mass per degree of freedom (kg or kg m²), external force per degree of freedom.
    mass: Vec<f64>,
    force: Vec<f64>,
    /// Unpacked positions and twists of the configuration evaluated.
    x: Vec<DVec3>,
    theta: Vec<f64>,
    /// The Newton matrix, and its copy before a failed factorisation.
    band: Band,
    copy: Band,
    /// The contacts at the start of the step and the positions there (for friction).
    lagged: Vec<Lagged>,
    start: Vec<DVec3>,
    /// `|diag H|`, the scale of the positive-definiteness shift.
    diag: Vec<f64>,
    /// The sum of the magnitudes of the terms of the last `Φ` evaluated (J): its rounding
    /// error is about `ε` times this.
    scale: f64,
    /// The state's ring seam twist (rad, [`State::twist_ring`]).
    seam: f64,
    /// The edge-length projection's multipliers, one per edge ([`project`]).
    multipliers: Vec<f64>,
}

/// The obstacles of other strands near this one during a step, with their repulsion
/// ([`repel`]; only [`super::Hair`] has any).
type Among<'a> = (&'a [Obstacle], Repulsion);

/// No obstacles.
const NO_OBSTACLES: Among<'static> =
    (&[], Repulsion { stiffness: 0.0, thickness: 0.0, friction: 0.0 });

/// What an evaluation of `Φ` computes.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Need {
    /// `Φ` alone (the elastic part without derivatives; the gradient buffer is then not
    /// meaningful): the predictor, the line search, the commit.
    Value,
    /// `Φ` and its gradient (symplectic Euler).
    Gradient,
    /// `Φ`, its gradient and its Hessian in the band (a Newton iteration).
    Hessian,
}

/// Which minimisation a Newton solve does.
#[derive(Clone, Copy)]
enum Goal {
    /// One implicit Euler step of this length (s).
    Step(f64),
    /// The static equilibrium.
    Static,
}

impl Solver {
    /// A solver for `model` (its buffers are sized on the first step).
    pub fn new(_model: &Model) -> Self {
        Solver::default()
    }

    /// Advance `state` by `steps` steps of `dt` seconds with the model's integrator.
    ///
    /// # Errors
    /// `dt` not finite and positive (`dt`); Newton not converging within `max_iterations`
    /// or a line search failing ([`Error::SolverFailed`]); a non-finite or collapsed
    /// configuration ([`Error::Diverged`], naming the step and the vertex). The state is
    /// then left as it was.
    pub fn step(
        &mut self,
        model: &Model,
        state: &mut State,
        dt: f64,
        steps: usize,
    ) -> Result<Stats> {
        self.run(model, state, dt, steps, NO_OBSTACLES)
    }

    /// One implicit Euler step of `dt` (s) of `state` with the repulsion of `obstacles`
    /// (other strands held where they are, [`repel`]); as [`Solver::step`] otherwise.
    ///
    /// # Errors
    /// As [`Solver::step`]; the state is then left as it was.
    pub(super) fn step_among(
        &mut self,
        model: &Model,
        state: &mut State,
        dt: f64,
        obstacles: &[Obstacle],
        repulsion: Repulsion,
    ) -> Result<Stats> {
        self.run(model, state, dt, 1, (obstacles, repulsion))
    }

    /// [`Solver::step`] among obstacles.
    fn run(
        &mut self,
        model: &Model,
        state: &mut State,
        dt: f64,
        steps: usize,
        among: Among<'_>,
    ) -> Result<Stats> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(Error::invalid("dt", "must be finite and > 0"));
        }
        let mut work = self.work.take().unwrap_or_else(|| state.clone());
        work.clone_from(state);
        let mut stats = Stats::default();
        let mut result = Ok(());
        for s in 0..steps {
            result = match model.settings.integrator {
                Integrator::ImplicitEuler => {
                    let goal = Goal::Step(dt);
                    self.newton(model, &mut work, goal, steps - s, &mut stats, among)
                }
                Integrator::SymplecticEuler => self.explicit(model, &mut work, dt, steps - s),
            }
            .map_err(|e| at_step(e, s));
            if result.is_err() {
                break;
            }
            work.time += dt;
            stats.steps += 1;
        }
        if result.is_ok() {
            if steps > 0 {
                work.clamp_goals = [None; 2];
            }
            state.clone_from(&work);
        }
        self.work = Some(work);
        result.map(|()| stats)
    }

    /// Move `state` to the static equilibrium of the model's loads (gravity and the state's
    /// forces) nearest it, by Newton's method on `E − fᵀq`; the velocities become zero.
    ///
    /// # Errors
    /// As [`Solver::step`]; the state is then left as it was.
    pub fn solve_static(&mut self, model: &Model, state: &mut State) -> Result<Stats> {
        let mut work = self.work.take().unwrap_or_else(|| state.clone());
        work.clone_from(state);
        let mut stats = Stats::default();
        let result = self.newton(model, &mut work, Goal::Static, 1, &mut stats, NO_OBSTACLES);
        if result.is_ok() {
            work.clamp_goals = [None; 2];
            work.velocities.fill(DVec3::ZERO);
            work.twist_rates.fill(0.0);
            state.clone_from(&work);
        }
        self.work = Some(work);
        result.map(|()| stats)
    }

    /// The elastic energy of `state` (J).
    pub fn energy(&mut self, model: &Model, state: &State) -> f64 {
        if !state.frames_into(&mut self.frames, &mut self.base) {
            return f64::NAN;
        }
        elastic_energy(model, &self.frames, &state.twists)
    }

    /// The elastic forces `−∂E/∂x` on the vertices (N) and torques `−∂E/∂θ` on the twist
    /// angles (N m) of `state`, into `forces` (`V`) and `torques` (`n`); NaN when an edge
    /// has collapsed.
    pub fn elastic_forces(
        &mut self,
        model: &Model,
        state: &State,
        forces: &mut Vec<DVec3>,
        torques: &mut Vec<f64>,
    ) {
        let n = model.edges();
        self.grad.clear();
        self.grad.resize(model.dofs(), 0.0);
        if state.frames_into(&mut self.frames, &mut self.base) {
            elastic(model, &self.frames, &state.twists, &mut self.grad, None);
        } else {
            self.grad.fill(f64::NAN);
        }
        forces.clear();
        let vertices = 0..model.vertices();
        forces.extend(vertices.map(|i| -DVec3::from_slice(&self.grad[4 * i..4 * i + 3])));
        torques.clear();
        torques.extend((0..n).map(|j| -self.grad[4 * j + 3]));
    }

    /// Size the workspaces and load `work` into them: masses, forces, `q0`, the inertial
    /// target (for a step of `h`; for held degrees of freedom the value they hold, moved
    /// towards the clamp goals over `remaining` steps), the base tangents.
    fn load(&mut self, model: &Model, work: &State, h: Option<f64>, remaining: usize) {
        let n = model.edges();
        let dofs = model.dofs();
        for v in [
            &mut self.q0,
            &mut self.target,
            &mut self.q,
            &mut self.trial,
            &mut self.grad,
            &mut self.dir,
            &mut self.mass,
            &mut self.force,
            &mut self.diag,
        ] {
            v.resize(dofs, 0.0);
        }
        let g = model.settings.gravity;
        for i in 0..model.vertices() {
            let f = model.masses[i] * g + work.forces[i];
            for r in 0..3 {
                self.q0[4 * i + r] = work.positions[i][r];
                self.target[4 * i + r] =
                    work.positions[i][r] + h.unwrap_or(0.0) * work.velocities[i][r];
                self.mass[4 * i + r] = model.masses[i];
                self.force[4 * i + r] = f[r];
            }
            if i < n {
                self.q0[4 * i + 3] = work.twists[i];
                self.target[4 * i + 3] = work.twists[i] + h.unwrap_or(0.0) * work.twist_rates[i];
                self.mass[4 * i + 3] = model.inertias[i];
                if model.settings.quasistatic_twist {
                    // No inertia: the step minimises the energy over the twists.
                    self.target[4 * i + 3] = work.twists[i];
                    self.mass[4 * i + 3] = 0.0;
                }
                self.force[4 * i + 3] = 0.0;
            }
        }
        for (k, fixed) in fixed_dofs(model).enumerate() {
            if fixed {
                self.target[k] = self.q0[k];
            }
        }
        work.tangents_into(&mut self.base);
        self.base_reference.clone_from(&work.reference);
        self.base_twist.clone_from(&work.reference_twist);
        self.seam = work.seam;
        for goal in work.clamp_goals.iter().flatten() {
            self.move_held(goal, remaining as f64, model.vertices());
        }
        if !model.colliders.is_empty() {
            lag(model, &work.positions, &mut self.lagged);
        }
        self.start.clone_from(&work.positions);
    }

    /// Set the held values of a clamped edge `1/remaining` of the way to `goal`: its two
    /// vertices, and its twist angle towards the one that turns its reference director,
    /// transported to the new tangent as [`Frames::update`] does, onto the goal's `m1`.
    fn move_held(&mut self, goal: &super::state::ClampGoal, remaining: f64, vertices: usize) {
        let j = goal.edge;
        let node = |v: usize| 4 * ((j + v) % vertices);
        for (v, p) in goal.positions.iter().enumerate() {
            let k = node(v);
            for r in 0..3 {
                self.target[k + r] += (p[r] - self.q0[k + r]) / remaining;
            }
        }
        let x = |v: usize| DVec3::from_slice(&self.target[node(v)..node(v) + 3]);
        let t = (x(1) - x(0)).normalize();
        let d1 = transport(self.base_reference[j], self.base[j], t);
        let d1 = (d1 - d1.dot(t) * t).normalize();
        let theta = self.q0[4 * j + 3];
        let full = signed_angle(d1, goal.director - goal.director.dot(t) * t, t);
        let full = full + std::f64::consts::TAU * ((theta - full) / std::f64::consts::TAU).round();
        self.target[4 * j + 3] += (full - theta) / remaining;
    }

    /// Transport later configurations from the frames last evaluated.
    fn rebase(&mut self) {
        self.base.clone_from(&self.frames.tangents);
        self.base_reference.clone_from(&self.frames.reference);
        self.base_twist.clone_from(&self.frames.reference_twist);
    }

    /// `Φ` at `q` (`Goal`) and what `need` asks for besides: its gradient into `grad`, its
    /// Hessian into the band (fixed rows and columns replaced by the identity). `None` when
    /// the configuration is unusable (a collapsed edge, a half turn, a non-finite value).
    fn evaluate(
        &mut self,
        model: &Model,
        trial: bool,
        goal: Goal,
        need: Need,
        among: Among<'_>,
    ) -> Option<f64> {
        let hess = need == Need::Hessian;
        let n = model.edges();
        let q = if trial { &self.trial } else { &self.q };
        if !q.iter().all(|v| v.is_finite()) {
            return None;
        }
        self.x.clear();
        self.x.extend((0..model.vertices()).map(|i| DVec3::from_slice(&q[4 * i..4 * i + 3])));
        self.theta.clear();
        self.theta.extend((0..n).map(|j| q[4 * j + 3]));
        if !self.frames.update(
            &self.x,
            &self.theta,
            &self.base,
            &self.base_reference,
            &self.base_twist,
            self.seam,
        ) {
            return None;
        }
        self.grad.fill(0.0);
        if hess && model.closed {
            self.band.reset_folded(q.len(), FOLDED_HALF_BANDWIDTH, 4);
        } else if hess {
            self.band.reset(q.len(), HALF_BANDWIDTH);
        }
        let mut phi = if need == Need::Value {
            elastic_energy(model, &self.frames, &self.theta)
        } else {
            let band = if hess { Some(&mut self.band) } else { None };
            elastic(model, &self.frames, &self.theta, &mut self.grad, band)
        };
        self.scale = phi.abs();
        if !model.colliders.is_empty() {
            let band = if hess { Some(&mut self.band) } else { None };
            let contact = penalty(model, &self.x, &mut self.grad, band);
            let sliding = match goal {
                Goal::Step(h) => {
                    let (eps, band) =
                        (model.settings.friction_velocity * h, hess.then_some(&mut self.band));
                    friction(&self.lagged, &self.x, &self.start, eps, &mut self.grad, band)
                }
                _ => 0.0,
            };
            phi += contact + sliding;
            self.scale += contact + sliding;
        }
        if !among.0.is_empty() {
            let band = if hess { Some(&mut self.band) } else { None };
            let mut repulsion = repel(among.0, among.1, &self.x, &mut self.grad, band);
            if let Goal::Step(h) = goal {
                let (eps, band) =
                    (model.settings.friction_velocity * h, hess.then_some(&mut self.band));
                let (x, x0) = (&self.x, &self.start);
                repulsion += rub(among.0, among.1, x, x0, h, eps, &mut self.grad, band);
            }
            phi += repulsion;
            self.scale += repulsion;
        }
        let inv_h2 = match goal {
            Goal::Step(h) => 1.0 / (h * h),
            Goal::Static => 0.0,
        };
        #[allow(clippy::needless_range_loop)] // six arrays indexed alike
        for k in 0..q.len() {
            let d = q[k] - self.target[k];
            let (inertia, work) =
                (0.5 * self.mass[k] * inv_h2 * d * d, self.force[k] * (q[k] - self.q0[k]));
            phi += inertia - work;
            self.scale += inertia + work.abs();
            self.grad[k] += self.mass[k] * inv_h2 * d - self.force[k];
            if hess {
                self.band.add(k, k, self.mass[k] * inv_h2);
            }
        }
        for (k, fixed) in fixed_dofs(model).enumerate() {
            if fixed {
                self.grad[k] = 0.0;
                if hess {
                    self.band.hold(k);
                }
            }
        }
        phi.is_finite().then_some(phi)
    }

    /// Factor the band, shifting its diagonal by `λ |diag H|` until it is positive definite.
    fn factor(&mut self) -> Result<()> {
        let n = self.band.len();
        for k in 0..n {
            self.diag[k] = self.band.get(k, k).abs().max(f64::MIN_POSITIVE);
        }
        self.copy.clone_from(&self.band);
        let mut lambda = 1e-8;
        while self.band.factor().is_err() {
            if lambda > 1e8 {
                return Err(Error::SolverFailed {
                    reason: "the rod's Newton matrix cannot be made positive definite".into(),
                });
            }
            self.band.clone_from(&self.copy);
            for k in 0..n {
                self.band.add(k, k, lambda * self.diag[k]);
            }
            lambda *= 10.0;
        }
        Ok(())
    }

    /// Minimise `Φ` of `goal` from `work`'s configuration; on success write the result
    /// (positions, twists, velocities for a step, frames) into `work`.
    fn newton(
        &mut self,
        model: &Model,
        work: &mut State,
        goal: Goal,
        remaining: usize,
        stats: &mut Stats,
        among: Among<'_>,
    ) -> Result<()> {
        let h = match goal {
            Goal::Step(h) => Some(h),
            Goal::Static => None,
        };
        self.load(model, work, h, remaining);
        self.q.copy_from_slice(&self.q0);
        for (k, fixed) in fixed_dofs(model).enumerate() {
            if fixed {
                self.q[k] = self.target[k];
            }
        }
        if let Some(h) = h {
            self.predict(model, h, among);
        }
        let length: f64 = model.rest_lengths.iter().sum();
        let tol = model.settings.tolerance;
        for _ in 0..model.settings.max_iterations {
            stats.iterations += 1;
            let phi = self
                .evaluate(model, false, goal, Need::Hessian, among)
                .ok_or_else(|| diverged(&self.q))?;
            // From here on Φ is the energy with frames transported from this iterate, whose
            // exact gradient and Hessian are the analytic ones just evaluated, so the Newton
            // direction descends it. Rebasing leaves Φ at this iterate unchanged, so Φ
            // decreases from iterate to iterate.
            self.rebase();
            self.factor()?;
            for k in 0..self.dir.len() {
                self.dir[k] = -self.grad[k];
            }
            self.band.solve(&mut self.dir);
            let slope: f64 = self.grad.iter().zip(&self.dir).map(|(g, d)| g * d).sum();
            let small = -slope <= ROUNDING * self.scale
                || self.dir.chunks(4).all(|c| {
                    c[..3].iter().all(|d| d.abs() <= tol * length)
                        && c.get(3).is_none_or(|d| d.abs() <= tol)
                });
            if small {
                for k in 0..self.q.len() {
                    self.q[k] += self.dir[k];
                }
                if model.settings.inextensible && h.is_some() {
                    project(
                        model,
                        &mut self.q,
                        &mut self.band,
                        &mut self.multipliers,
                        &mut self.dir,
                    )?;
                }
                return self.commit(model, work, goal, among);
            }
            self.line_search(model, goal, phi, slope, stats, among)?;
        }
        Err(Error::SolverFailed {
            reason: format!(
                "Newton did not converge in {} iterations (lower dt or raise max_iterations)",
                model.settings.max_iterations
            ),
        })
    }

    /// Start an implicit step of `h` from the better (lower `Φ`) of the start of the step
    /// (`q`) and an explicit predictor: the inertial target plus the external forces' push,
    /// `q̃ + h² M⁻¹ f`, with each free vertex then put back at its edge's rest length from
    /// the vertex before it, along the edge's predicted direction ("follow the leader",
    /// Müller, Kim & Chentanez 2012), since stretching is the stiffest mode and a Newton
    /// step from a stretched guess crawls (halved line searches). Held degrees of freedom
    /// are at their goals in both.
    fn predict(&mut self, model: &Model, h: f64, among: Among<'_>) {
        for (k, fixed) in fixed_dofs(model).enumerate() {
            self.trial[k] = if fixed || self.mass[k] == 0.0 {
                self.target[k]
            } else {
                self.target[k] + h * h * self.force[k] / self.mass[k]
            };
        }
        for j in 0..model.vertices() - 1 {
            if model.pinned[j + 1] {
                continue;
            }
            let (a, b) = (4 * j, 4 * j + 4);
            let xa = DVec3::from_slice(&self.trial[a..a + 3]);
            let e = DVec3::from_slice(&self.trial[b..b + 3]) - xa;
            let len = e.length();
            if len > 0.0 {
                let xb = xa + e * (model.rest_lengths[j] / len);
                self.trial[b..b + 3].copy_from_slice(&xb.to_array());
            }
        }
        let goal = Goal::Step(h);
        let start = self.evaluate(model, false, goal, Need::Value, among);
        let predicted = self.evaluate(model, true, goal, Need::Value, among);
        if predicted.is_some_and(|p| start.is_none_or(|s| p < s)) {
            self.q.copy_from_slice(&self.trial);
        }
    }

    /// Move `q` along `dir` (where `Φ = phi` and `∇Φ·dir = slope`) by a step length of 1,
    /// halved until Armijo's condition holds. At each length the straight trial
    /// `q + α dir` is tried first, then the same trial with its edges bent back to the
    /// lengths the step gives them to first order ([`Solver::curve_trial`]): a Newton step
    /// that turns edges stretches them to second order, which the stiff stretching
    /// punishes, so without this the line search halves large turning steps many times.
    fn line_search(
        &mut self,
        model: &Model,
        goal: Goal,
        phi: f64,
        slope: f64,
        stats: &mut Stats,
        among: Among<'_>,
    ) -> Result<()> {
        let mut alpha = 1.0;
        for _ in 0..HALVINGS {
            for k in 0..self.q.len() {
                self.trial[k] = self.q[k] + alpha * self.dir[k];
            }
            for curved in [false, true] {
                if curved {
                    self.curve_trial(model, alpha);
                }
                let bound = phi + ARMIJO * alpha * slope;
                if self.evaluate(model, true, goal, Need::Value, among).is_some_and(|t| t <= bound)
                {
                    self.q.copy_from_slice(&self.trial);
                    return Ok(());
                }
            }
            alpha *= 0.5;
            stats.halvings += 1;
        }
        Err(Error::SolverFailed {
            reason: "the line search found no decrease of the incremental potential".into(),
        })
    }

    /// Bend the trial `q + α dir` so that its edges keep their straight trial's directions
    /// but take the lengths the step gives them to first order, `|e| + α t·(Δx_{j+1} − Δx_j)`
    /// (`e`, `t` at `q`): from the first vertex on, each free vertex is placed at that
    /// length from the (moved) vertex before it; pinned vertices stay. A curvilinear search
    /// path tangent to `dir` at `α = 0`.
    fn curve_trial(&mut self, model: &Model, alpha: f64) {
        let at = |v: &[f64], k: usize| DVec3::from_slice(&v[k..k + 3]);
        for j in 0..model.vertices() - 1 {
            if model.pinned[j + 1] {
                continue;
            }
            let (a, b) = (4 * j, 4 * j + 4);
            let e = at(&self.q, b) - at(&self.q, a);
            let step = at(&self.dir, b) - at(&self.dir, a);
            let length = e.length() + alpha * e.normalize().dot(step);
            let direction = (e + alpha * step).normalize();
            if length > 0.0 && direction.is_finite() {
                let x = at(&self.trial, a) + length * direction;
                self.trial[b..b + 3].copy_from_slice(&x.to_array());
            }
        }
    }

    /// Write the converged `q` into `work`: positions, twists, frames, and (for a step of
    /// `h`) the velocities `(q − q0) / h`.
    fn commit(
        &mut self,
        model: &Model,
        work: &mut State,
        goal: Goal,
        among: Among<'_>,
    ) -> Result<()> {
        self.evaluate(model, false, goal, Need::Value, among).ok_or_else(|| diverged(&self.q))?;
        let n = model.edges();
        for i in 0..model.vertices() {
            let x = DVec3::from_slice(&self.q[4 * i..4 * i + 3]);
            if let Goal::Step(h) = goal {
                work.velocities[i] = (x - work.positions[i]) / h;
            }
            work.positions[i] = x;
        }
        for j in 0..n {
            if let Goal::Step(h) = goal {
                work.twist_rates[j] = (self.q[4 * j + 3] - work.twists[j]) / h;
            }
            work.twists[j] = self.q[4 * j + 3];
        }
        work.reference.copy_from_slice(&self.frames.reference);
        work.reference_twist.copy_from_slice(&self.frames.reference_twist);
        Ok(())
    }

    /// One symplectic Euler step of `h` on `work`, the `remaining`-th last of its call;
    /// held degrees of freedom move to their held values at the rate that takes them there.
    fn explicit(
        &mut self,
        model: &Model,
        work: &mut State,
        h: f64,
        remaining: usize,
    ) -> Result<()> {
        self.load(model, work, Some(0.0), remaining);
        self.q.copy_from_slice(&self.q0);
        let among = NO_OBSTACLES;
        self.evaluate(model, false, Goal::Static, Need::Gradient, among)
            .ok_or_else(|| diverged(&self.q))?;
        for (k, pinned) in fixed_dofs(model).enumerate() {
            let (i, r) = (k / 4, k % 4);
            let rate = if r < 3 { &mut work.velocities[i][r] } else { &mut work.twist_rates[i] };
            if pinned {
                *rate = (self.target[k] - self.q0[k]) / h;
                self.q[k] = self.target[k];
            } else {
                *rate += h * (-self.grad[k] / self.mass[k]);
                self.q[k] += h * *rate;
            }
        }
        if model.settings.inextensible {
            self.trial.copy_from_slice(&self.q);
            project(model, &mut self.q, &mut self.band, &mut self.multipliers, &mut self.dir)?;
            for i in 0..model.vertices() {
                for r in 0..3 {
                    let k = 4 * i + r;
                    work.velocities[i][r] += (self.q[k] - self.trial[k]) / h;
                }
            }
        }
        self.commit(model, work, Goal::Static, among)
    }
}

/// Whether each degree of freedom of `model` (interleaved) is held.
fn fixed_dofs(model: &Model) -> impl Iterator<Item = bool> + '_ {
    (0..model.dofs()).map(move |k| {
        let (i, r) = (k / 4, k % 4);
        if r < 3 {
            model.pinned[i]
        } else {
            model.locked[i]
        }
    })
}

/// The divergence error of a configuration `q` that cannot be evaluated: the vertex of its
/// first non-finite value (or 0).
fn diverged(q: &[f64]) -> Error {
    let index = q.iter().position(|v| !v.is_finite()).map_or(0, |k| k / 4);
    Error::Diverged {
        step: 0,
        index,
        reason: "non-finite or collapsed configuration (an edge of zero length or turned by a half turn)".into(),
    }
}

/// `e` attributed to step `s` of the call.
fn at_step(e: Error, s: usize) -> Error {
    match e {
        Error::Diverged { index, reason, .. } => Error::Diverged { step: s, index, reason },
        other => other,
    }
}
