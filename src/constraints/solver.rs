//! The constraint solver: every workspace of a constrained step (the evaluated rows, the
//! multiplier system's pattern, symbolic factorisation and right-hand side, the conjugate
//! gradient's vectors, the implicit projection's KKT system, the copies a failing step
//! restores, the ODE workspace) and the step itself. It carries nothing that a later step
//! reads, so one solver advances any number of states of one [`Model`], each with its
//! particles.

use super::curve::track_curves;
use super::implicit::Kkt;
use super::multipliers::{assemble, Constrained};
use super::rows::{evaluate, Rows};
use super::{Constraint, ConstraintSolver, Formulation, Model, State};
use crate::error::{Error, Result};
use crate::linalg::SparseCholesky;
use crate::ode::{History, Method, OdeSystem, Workspace};
use crate::particles::Free;
use glam::DVec3;

/// The particles a constrained step advances: a particle model, one of its states and a
/// particle solver (whose hash grid and Jacobian buffers the free equations use).
#[derive(Debug)]
pub struct Particles<'a> {
    /// The particles' model (forces; its colliders and emitters are not applied in a
    /// constrained step).
    pub model: &'a crate::particles::Model,
    /// The particles' state, advanced by the step.
    pub state: &'a mut crate::particles::State,
    /// A particle solver lending its workspaces.
    pub solver: &'a mut crate::particles::Solver,
}

/// Steps constraint states of a [`Model`] (see the module docs).
#[derive(Debug, Default)]
pub struct Solver {
    /// `(particles, constraints)` the multiplier pattern was built for: a model only grows
    /// ([`Model::add`]), so this identifies it.
    fitted: Option<(usize, usize)>,
    pub(super) work: Work,
    /// Stage and Newton buffers of the ODE methods.
    ode: Workspace,
}

/// The multiplier solve's workspaces, sized for the model's rows and particles.
#[derive(Debug, Default)]
pub(super) struct Work {
    pub(super) rows: Rows,
    /// The particles' `[x; v]` before a step, restored when its post-stabilisation or curve
    /// tracking fails.
    pub(super) backup: Vec<f64>,
    /// The right-hand side of the multiplier system, one per row.
    pub(super) b: Vec<f64>,
    /// The diagonal of `J W Jᵀ`, one per row.
    pub(super) diag: Vec<f64>,
    /// `Jᵀ x` per particle (3 per particle) in the matrix-free product of the CG.
    pub(super) scratch: Vec<f64>,
    pub(super) cg: [Vec<f64>; 4],
    /// The state being built by a projection step (`6 n` values).
    pub(super) next: Vec<f64>,
    pub(super) chol: Option<SparseCholesky>,
    /// The implicit projection's KKT system (built at the first projection step).
    pub(super) kkt: Option<Kkt>,
    /// The constraint state before the current step (multipliers, iteration count, tracked
    /// curve parameters), put back when the step fails: a failed step leaves the state
    /// exactly as it was (its multipliers may be huge or NaN and would poison the next solve).
    pub(super) saved: State,
    /// The ODE history (BDF2's previous step, counters) before the current step, put back
    /// with [`Self::saved`].
    pub(super) saved_history: Option<History>,
    /// The values of `J W Jᵀ + εI` on its pattern.
    pub(super) values: Vec<f64>,
    /// (value index, row r, row s, particle) per contribution w_p J_rp · J_sp.
    pub(super) contributions: Vec<(usize, usize, usize, usize)>,
    pub(super) diagonal_index: Vec<usize>,
}

impl Solver {
    /// A solver for the states of `model`; its workspaces are sized at the first step.
    pub fn new(_model: &Model) -> Self {
        Solver::default()
    }

    /// Size the workspaces for `model` on `n` particles: the pattern of `J W Jᵀ` and its
    /// symbolic factorisation when the model or the particle count changed (and Cholesky
    /// solves the multipliers), the per-row and per-particle buffers.
    ///
    /// # Errors
    /// Indices beyond the particles (argument `particles`), a failed symbolic factorisation.
    fn prepare(&mut self, model: &Model, n: usize) -> Result<()> {
        model.check_particles(n)?;
        let key = (n, model.constraints.len());
        if self.fitted != Some(key) {
            self.fitted = None;
            self.work.chol = None;
            self.work.kkt = None;
            if model.solver == ConstraintSolver::Cholesky
                && model.formulation == Formulation::Multipliers
            {
                self.build_pattern(model, n)?;
            }
            self.fitted = Some(key);
        }
        let m = model.rows();
        let w = &mut self.work;
        w.b.resize(m, 0.0);
        w.diag.resize(m, 0.0);
        w.scratch.resize(3 * n, 0.0);
        if model.stabilize
            || model.constraints.iter().any(|c| matches!(c, Constraint::OnCurve { .. }))
        {
            w.backup.resize(6 * n, 0.0);
        }
        Ok(())
    }

    /// The particles' free equations and state for a call on `state` of `model`, after
    /// checking that the parts belong together and sizing the workspaces ([`Self::prepare`]).
    ///
    /// # Errors
    /// A particle state of another particle model or a constraint state of another model
    /// (argument `state`), those of [`Self::prepare`].
    pub(super) fn start<'a>(
        &mut self,
        model: &Model,
        state: &State,
        particles: Particles<'a>,
    ) -> Result<Free<'a>> {
        let n = particles.model.capacity();
        let free = particles.solver.free(particles.model, particles.state)?;
        state.check_fits(model, n)?;
        self.prepare(model, n)?;
        Ok(free)
    }

    /// The pattern of `J W Jᵀ` (rows sharing a particle), its symbolic factorisation, and the
    /// list of contributions that refill its values.
    fn build_pattern(&mut self, model: &Model, n: usize) -> Result<()> {
        let mut row_of_particle: Vec<Vec<usize>> = vec![Vec::new(); n];
        let mut r = 0;
        for c in &model.constraints {
            let ps = c.particles();
            for _ in 0..c.rows() {
                for &p in &ps {
                    row_of_particle[p].push(r);
                }
                r += 1;
            }
        }
        let m = r;
        let mut entries: Vec<(usize, usize, usize)> = Vec::new(); // (col s, row r >= s, particle)
        for (p, rows) in row_of_particle.iter().enumerate() {
            for &a in rows {
                for &b in rows {
                    if a >= b {
                        entries.push((b, a, p));
                    }
                }
            }
        }
        let mut pattern: Vec<(usize, usize)> = entries.iter().map(|&(s, r, _)| (s, r)).collect();
        pattern.extend((0..m).map(|k| (k, k)));
        pattern.sort_unstable();
        pattern.dedup();
        let mut col_ptr = vec![0usize; m + 1];
        for &(s, _) in &pattern {
            col_ptr[s + 1] += 1;
        }
        for k in 0..m {
            col_ptr[k + 1] += col_ptr[k];
        }
        let row_idx: Vec<usize> = pattern.iter().map(|&(_, r)| r).collect();
        let index = |s: usize, r: usize| pattern.binary_search(&(s, r)).expect("entry in pattern");
        let w = &mut self.work;
        w.contributions = entries.iter().map(|&(s, r, p)| (index(s, r), r, s, p)).collect();
        w.diagonal_index = (0..m).map(|k| index(k, k)).collect();
        w.values = vec![0.0; pattern.len()];
        w.chol = Some(SparseCholesky::new(m, col_ptr, row_idx)?);
        Ok(())
    }

    /// Advance `particles` and `state` (a state of `model` on them) `steps` steps of `dt`
    /// seconds with `method`, constrained by the model's formulation; with
    /// post-stabilisation ([`Model::set_stabilization`]) each step ends on `C(x) = 0` and
    /// `J v = 0`. Colliders and emitters of the particle model are not applied.
    ///
    /// # Errors
    /// A bad `dt`, a particle or constraint state of another model (argument `state`), a
    /// solver failure, a custom constraint's failure, a lost curve or a non-finite state
    /// ([`Error::Diverged`] naming the step and the particle); the particles and `state` are
    /// left at the last good step.
    pub fn step(
        &mut self,
        model: &Model,
        state: &mut State,
        particles: Particles<'_>,
        dt: f64,
        steps: usize,
        method: Method,
    ) -> Result<()> {
        let n = particles.model.capacity();
        let free = self.start(model, state, particles)?;
        if state.history.as_ref().is_none_or(|h| h.method() != method) {
            state.history = Some(History::new(method, 6 * n)?);
        }
        let mut history = state.history.take().expect("created above");
        let backup = !self.work.backup.is_empty();
        let ode = &mut self.ode;
        let (mut system, y, time) = assemble(model, state, &mut self.work, free);
        let mut result = Ok(());
        for s in 0..steps {
            if backup {
                system.work.backup.copy_from_slice(y);
            }
            system.save_state();
            match &mut system.work.saved_history {
                Some(saved) => saved.clone_from(&history),
                empty => *empty = Some(history.clone()),
            }
            result = ode.step(&mut history, &mut system, *time, y, dt);
            if result.is_ok() {
                // The step is committed only when its post-stabilisation and curve tracking
                // succeed; otherwise the state before it comes back.
                result = system.finish_step(y);
                if result.is_err() {
                    y.copy_from_slice(&system.work.backup);
                }
            }
            if let Err(e) = result {
                system.restore_state();
                history.clone_from(system.work.saved_history.as_ref().expect("saved above"));
                result = Err(match e {
                    Error::Diverged { index, reason, .. } => {
                        Error::Diverged { step: s, index: (index % (3 * n)) / 3, reason }
                    }
                    other => other,
                });
                break;
            }
            *time += dt;
        }
        state.history = Some(history);
        result
    }

    /// Largest `|C|` and `|Ċ|` over all constraint rows of `model` at the particles'
    /// `particles` with the curves of `state`.
    ///
    /// # Errors
    /// Particles or a state of another model (arguments `particles`, `state`), a custom
    /// constraint's failure, or a curve's closest point lost.
    pub fn violation(
        &mut self,
        model: &Model,
        state: &State,
        particles: &crate::particles::State,
    ) -> Result<(f64, f64)> {
        let n = particles.capacity();
        model.check_particles(n)?;
        state.check_fits(model, n)?;
        let mut y = particles.positions().to_vec();
        y.extend_from_slice(particles.velocities());
        let rows = &mut self.work.rows;
        evaluate(&model.constraints, &state.curves, &y, n, rows)?;
        Ok(rows.rows.iter().fold((0.0, 0.0), |(a, b), r| (a.max(r.c.abs()), b.max(r.cdot.abs()))))
    }

    /// The constraint forces (N, world frame) on every particle at the current state, as used
    /// by the next step: `Jᵀ λ` with multipliers (whose solve updates the warm start of
    /// `state`), the spring forces with the penalty method.
    ///
    /// # Errors
    /// As [`Solver::step`] without `dt`.
    pub fn constraint_forces(
        &mut self,
        model: &Model,
        state: &mut State,
        particles: Particles<'_>,
    ) -> Result<Vec<DVec3>> {
        let n = particles.model.capacity();
        let free = self.start(model, state, particles)?;
        let (mut system, y, time) = assemble(model, state, &mut self.work, free);
        let mut dydt = vec![0.0; 6 * n];
        // With penalty forces the rhs fills the rows; with multipliers it also solves for λ.
        system.rhs(*time, y, &mut dydt)?;
        let (rows, lambda) = (&system.work.rows, &system.state.lambda);
        let mut forces = vec![DVec3::ZERO; n];
        for (r, row) in rows.rows.iter().enumerate() {
            let scale = match model.formulation {
                Formulation::Multipliers => lambda[r],
                Formulation::Penalty { stiffness, damping } => {
                    -(stiffness * row.c + damping * row.cdot)
                }
            };
            for &(p, g) in rows.blocks(r) {
                forces[p] += scale * g;
            }
        }
        Ok(forces)
    }
}

impl Constrained<'_> {
    /// Keep the constraint state to restore when the coming step fails.
    pub(super) fn save_state(&mut self) {
        self.work.saved.clone_from(self.state);
    }

    /// Put back what [`Self::save_state`] kept.
    pub(super) fn restore_state(&mut self) {
        self.state.clone_from(&self.work.saved);
    }

    /// After a successful integrator step of `y`: the post-stabilisation (when on) and the
    /// tracking of the curves' closest points.
    ///
    /// # Errors
    /// As [`Self::project_positions`], [`Self::project_velocities`], a lost curve.
    fn finish_step(&mut self, y: &mut [f64]) -> Result<()> {
        if self.model.stabilize {
            self.project_positions(y)?;
            self.project_velocities(y)?;
        }
        track_curves(&self.model.constraints, y, &mut self.state.curves)
    }
}
