//! The particle solver: every workspace of a step (the copy of the state a step may have to
//! restore, the explicit kernel's rollback copy, the hash-grid cells, the ODE workspace and
//! the sparse Jacobian's buffers) and the counters of its last call. It carries nothing that a
//! later step reads, so one solver advances any number of states of one [`Model`].

use super::chain::{self, ChainWork};
use super::chain_implicit::{self, ChainImplicit};
use super::explicit::Rollback;
use super::jacobian::JacobianWork;
use super::linear::LinearImplicit;
use super::{Dynamics, Model, State, StepStats, CHUNK};
use crate::error::{reserve, Error, Result};
use crate::ode::{History, Method, Workspace};
use glam::DVec3;
use rayon::prelude::*;

/// Steps states of a particle [`Model`] (see the module docs).
#[derive(Clone, Debug, Default)]
pub struct Solver {
    /// The state at the start of the current step of the general path (`6 capacity` values),
    /// which the contacts read; kept only when the model has colliders.
    pub(super) backup: Vec<f64>,
    /// The pinned and dead slots at the start of the current step of the general path, with
    /// their positions and velocities: a step leaves them exactly as they were.
    pub(super) still: Vec<(usize, [f64; 6])>,
    /// What a call of the explicit kernel restores when one of its steps fails.
    pub(super) rollback: Rollback,
    /// The hash grid's (cell key, slot) pairs, rebuilt by every evaluation that needs them.
    pub(super) cells: Vec<(u64, u32)>,
    /// Stage and Newton buffers of the general path.
    pub(super) work: Workspace,
    /// Buffers of the sparse Jacobian for the implicit methods, rebuilt at every evaluation.
    pub(super) jacobian: JacobianWork,
    /// Implicit Euler of linear models in velocity form, with its kept factorisation.
    pub(super) linear: LinearImplicit,
    /// The explicit methods' buffers for chains of springs ([`chain::takes`]).
    pub(super) chain: ChainWork,
    /// Implicit Euler on chains of linear springs ([`chain_implicit::takes`]), with its kept
    /// factor.
    pub(super) chain_implicit: ChainImplicit,
    /// Counters of the last call (also of the good steps of a call that failed).
    pub(super) stats: StepStats,
}

/// One call of the solver on one state: the three parts a step reads and writes.
pub(super) struct Step<'a> {
    pub(super) model: &'a Model,
    pub(super) state: &'a mut State,
    pub(super) solver: &'a mut Solver,
}

impl Solver {
    /// A solver for states of `model`, with room for the hash grid of every slot.
    ///
    /// # Errors
    /// A capacity too large to allocate (argument `capacity`).
    pub fn new(model: &Model) -> Result<Self> {
        let mut solver = Solver::default();
        reserve("capacity", &mut solver.cells, model.n)?;
        reserve("capacity", &mut solver.still, model.n)?;
        Ok(solver)
    }

    /// Counters of the last call of [`Solver::step`] (of its good steps when it failed).
    pub fn stats(&self) -> StepStats {
        self.stats
    }

    /// Advance `state` by `steps` steps of `dt` seconds with `method`; the implicit methods
    /// factorise the sparse Newton matrix (see [`Solver::step_with_jacobian`]).
    ///
    /// # Errors
    /// A bad `dt`, a state of another model (argument `state`), an integrator failure, or a
    /// non-finite state ([`Error::Diverged`] naming the step and the particle); the state is
    /// left at the last good step.
    pub fn step(
        &mut self,
        model: &Model,
        state: &mut State,
        dt: f64,
        steps: usize,
        method: Method,
    ) -> Result<StepStats> {
        self.step_with_jacobian(model, state, dt, steps, method, true)
    }

    /// [`Solver::step`] with the choice of the implicit methods' Newton matrix `I - γ h J`:
    /// with `sparse`, the analytic sparse Jacobian of the forces and a sparse LU (cost growing
    /// about linearly with the particles for springs and local forces); without, a dense
    /// Jacobian by forward differences over all `6 capacity` columns and a dense LU
    /// (`O(capacity³)` per step, for comparison and for small systems). All-pairs gravity
    /// ([`super::Force::NBodyGravity`]) couples every particle, so with it the matrix is dense
    /// either way. Explicit methods ignore the choice.
    ///
    /// # Errors
    /// As [`Solver::step`].
    pub fn step_with_jacobian(
        &mut self,
        model: &Model,
        state: &mut State,
        dt: f64,
        steps: usize,
        method: Method,
        sparse: bool,
    ) -> Result<StepStats> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(Error::invalid("dt", format!("must be positive and finite, got {dt}")));
        }
        state.check_fits(model)?;
        if state.history.as_ref().is_none_or(|h| h.method() != method) {
            state.history = Some(History::new(method, 6 * model.n)?);
        }
        self.stats = StepStats::default();
        let gravity = model.gravity();
        let mut step = Step { model, state, solver: self };
        let result = if method == Method::SymplecticEuler && !model.pairwise() {
            step.explicit_steps(dt, steps, gravity)
        } else {
            step.general_steps(dt, steps, gravity, sparse)
        };
        result.map(|()| self.stats)
    }
}

/// The particles as a constrained step advances them ([`Solver::free`]): their free
/// equations of motion and the parts of their state that the constrained equations read and
/// write.
pub(crate) struct Free<'a> {
    /// The free (unconstrained) equations of motion over `[x; v]`.
    pub(crate) dynamics: Dynamics<'a>,
    /// The state's buffer `[x; v]` (`6 capacity` values, m and m/s).
    pub(crate) y: &'a mut [f64],
    /// Inverse masses (1/kg, 0 for pinned particles), one per slot.
    pub(crate) inv_mass: &'a [f64],
    /// The state's time (s).
    pub(crate) time: &'a mut f64,
}

impl Solver {
    /// The particles of `state` under `model` for a system that steps them itself
    /// (constraints): this solver lends the free equations its hash grid and Jacobian
    /// buffers. The state's cached bound is forgotten, since it will be written.
    ///
    /// # Errors
    /// A state of another model (argument `state`).
    pub(crate) fn free<'a>(
        &'a mut self,
        model: &'a Model,
        state: &'a mut State,
    ) -> Result<Free<'a>> {
        state.check_fits(model)?;
        state.summary.state = None;
        let dynamics = Dynamics {
            n: model.n,
            forces: &model.forces,
            mass: &state.mass,
            inv_mass: &state.inv_mass,
            alive: &state.alive,
            external: &state.external,
            cells: &mut self.cells,
            jacobian: Some(&mut self.jacobian),
            constant: None,
        };
        Ok(Free { dynamics, y: &mut state.y, inv_mass: &state.inv_mass, time: &mut state.time })
    }
}

impl Step<'_> {
    /// `steps` steps of the general path (any method through [`Workspace::step`]), each
    /// followed by the collisions, the ageing and the emission; a failed step leaves the
    /// state it started from ([`Workspace::step`] writes nothing when it fails, and nothing
    /// after it can fail) and forgets the multistep history. Without emitters no slot is born
    /// or dies (only emitted particles have finite lifespans), so the ages are advanced after
    /// the call, as the explicit kernel does. Explicit methods on chains without colliders or
    /// emitters ([`chain::takes`]) take [`Step::chain_steps`], bitwise the same steps.
    fn general_steps(&mut self, dt: f64, steps: usize, gravity: DVec3, sparse: bool) -> Result<()> {
        self.state.summary.state = None;
        self.state.settle_ages();
        let age_each_step = !self.model.emitters.is_empty();
        let n = self.model.n;
        // Within a call without emitters the masses and live slots stay as they are. The
        // velocity form's check of the model is skipped when it is set up for this model.
        let history = self.state.history.as_ref().expect("history created in step");
        let (model, method) = (self.model, history.method());
        let slots = *self.state.summary.slots.get_or_insert_with(crate::ode::fresh_key);
        if sparse
            && !age_each_step
            && method == Method::ImplicitEuler
            && self.model.colliders.is_empty()
            && (self.solver.chain_implicit.prepared(model.forces_key, slots, dt)
                || chain_implicit::takes(model))
        {
            return self.chain_implicit_steps(dt, steps, slots);
        }
        let velocity_form = sparse
            && !age_each_step
            && history.method() == Method::ImplicitEuler
            && (self.solver.linear.prepared(model.forces_key, slots, dt) || model.linear());
        let constant = (sparse && !age_each_step && !velocity_form && model.linear())
            .then(crate::ode::fresh_key);
        if velocity_form {
            let state = &*self.state;
            let (mass, inv_mass, alive) = (&state.mass, &state.inv_mass, &state.alive);
            if self.solver.linear.prepare(model, slots, mass, inv_mass, alive, dt)? {
                self.solver.stats.factorizations += 1;
            }
        }
        if velocity_form && self.model.colliders.is_empty() {
            return self.linear_steps(dt, steps);
        }
        // Only the slots that stay put need their state kept; without emitters they and
        // their state are the same at every step of the call, so they are found once.
        let keep_still = |solver: &mut Solver, state: &State| {
            let (x, v) = state.y.split_at(3 * n);
            solver.still.clear();
            solver.still.extend(
                (0..n).filter(|&i| !state.alive[i] || state.inv_mass[i] == 0.0).map(|i| {
                    let mut kept = [0.0; 6];
                    kept[..3].copy_from_slice(&x[3 * i..3 * i + 3]);
                    kept[3..].copy_from_slice(&v[3 * i..3 * i + 3]);
                    (i, kept)
                }),
            );
        };
        let colliders = !self.model.colliders.is_empty();
        if !colliders && !age_each_step {
            keep_still(self.solver, self.state);
            if chain::takes(model, method) {
                return self.chain_steps(dt, steps);
            }
        }
        for s in 0..steps {
            if colliders {
                // The contacts read the state the step started from.
                let (backup, y) = (&mut self.solver.backup, &self.state.y);
                backup.resize(y.len(), 0.0);
                backup
                    .par_chunks_mut(6 * CHUNK)
                    .zip(y.par_chunks(6 * CHUNK))
                    .for_each(|(b, y)| b.copy_from_slice(y));
            } else if age_each_step {
                keep_still(self.solver, self.state);
            }
            if let Err(e) = self.one_step(dt, gravity, sparse, constant, velocity_form) {
                if !age_each_step {
                    self.state.age_pending = (dt, s);
                }
                self.state.state_changed();
                return Err(match e {
                    Error::Diverged { index, reason, .. } => {
                        Error::Diverged { step: s, index: index % n, reason }
                    }
                    other => other,
                });
            }
            if age_each_step {
                self.age(dt);
            }
            self.state.time += dt;
            self.emit(dt);
        }
        if !age_each_step {
            self.state.age_pending = (dt, steps);
        }
        Ok(())
    }

    /// `steps` steps of the velocity form of implicit Euler (`particles/linear.rs`, after its
    /// `prepare`) without colliders or emitters: nothing but the steps, which write nothing to
    /// the slots that stay put and nothing at all when they fail.
    fn linear_steps(&mut self, dt: f64, steps: usize) -> Result<()> {
        let (state, linear) = (&mut *self.state, &mut self.solver.linear);
        let history = state.history.as_mut().expect("history created in step");
        let (forces, external) = (&self.model.forces, &state.external);
        linear.begin(&state.y, dt);
        for s in 0..steps {
            history.nfev += 1;
            if let Err(e) = linear.step(forces, external, dt) {
                linear.end(&mut state.y);
                state.age_pending = (dt, s);
                state.state_changed();
                return Err(match e {
                    Error::Diverged { index, .. } => Error::Diverged {
                        step: s,
                        index: index / 3,
                        reason: "non-finite particle state".into(),
                    },
                    other => other,
                });
            }
            state.time += dt;
        }
        linear.end(&mut state.y);
        state.age_pending = (dt, steps);
        Ok(())
    }

    /// `steps` steps of implicit Euler on a chain ([`chain_implicit::takes`]) without
    /// colliders or emitters, the masses and live slots of key `slots`: nothing but the
    /// steps, which write nothing to the slots that stay put and nothing at all when they
    /// fail.
    fn chain_implicit_steps(&mut self, dt: f64, steps: usize, slots: u64) -> Result<()> {
        let (model, state, solver) = (self.model, &mut *self.state, &mut *self.solver);
        let work = &mut solver.chain_implicit;
        let (mass, inv_mass, alive) = (&state.mass, &state.inv_mass, &state.alive);
        if work.prepare(model, slots, mass, inv_mass, alive, dt)? {
            solver.stats.factorizations += 1;
        }
        work.begin(&state.y, &state.mass, &state.external, dt);
        let (good, result) = work.steps(dt, steps);
        work.end(&mut state.y);
        let history = state.history.as_mut().expect("history created in step");
        history.nfev += good + usize::from(result.is_err());
        for _ in 0..good {
            state.time += dt;
        }
        state.age_pending = (dt, good);
        result.map_err(|e| {
            state.state_changed();
            match e {
                Error::Diverged { index, .. } => Error::Diverged {
                    step: good,
                    index,
                    reason: "non-finite particle state".into(),
                },
                other => other,
            }
        })
    }

    fn one_step(
        &mut self,
        dt: f64,
        gravity: DVec3,
        sparse: bool,
        constant: Option<u64>,
        velocity_form: bool,
    ) -> Result<()> {
        let n = self.model.n;
        let (state, solver) = (&mut *self.state, &mut *self.solver);
        let history = state.history.as_mut().expect("history created in step");
        let mut dynamics = Dynamics {
            n,
            forces: &self.model.forces,
            mass: &state.mass,
            inv_mass: &state.inv_mass,
            alive: &state.alive,
            external: &state.external,
            cells: &mut solver.cells,
            jacobian: sparse.then_some(&mut solver.jacobian),
            constant,
        };
        let before = solver.work.factorizations();
        let result = if velocity_form {
            history.nfev += 1;
            let (forces, external) = (&self.model.forces, &state.external);
            solver.linear.begin(&state.y, dt);
            let stepped = solver.linear.step(forces, external, dt);
            if stepped.is_ok() {
                solver.linear.end(&mut state.y);
            }
            stepped
        } else {
            solver.work.step(history, &mut dynamics, state.time, &mut state.y, dt)
        };
        solver.stats.factorizations += solver.work.factorizations() - before;
        result.map_err(|e| match e {
            Error::Diverged { index, .. } => Error::Diverged {
                step: 0,
                index: (index % (3 * n)) / 3,
                reason: "non-finite particle state".into(),
            },
            other => other,
        })?;
        // Pinned and dead particles keep their state exactly: their equations are
        // x' = v' = 0, which the Newton solve of the implicit methods meets only to rounding
        // and which the drifts of the second-order methods (x += h v) do not read.
        let (xs, vs) = state.y.split_at_mut(3 * n);
        if self.model.colliders.is_empty() {
            for (i, kept) in &solver.still {
                xs[3 * i..3 * i + 3].copy_from_slice(&kept[..3]);
                vs[3 * i..3 * i + 3].copy_from_slice(&kept[3..]);
            }
        } else {
            let (xb, vb) = solver.backup.split_at(3 * n);
            for i in (0..n).filter(|&i| !state.alive[i] || state.inv_mass[i] == 0.0) {
                xs[3 * i..3 * i + 3].copy_from_slice(&xb[3 * i..3 * i + 3]);
                vs[3 * i..3 * i + 3].copy_from_slice(&vb[3 * i..3 * i + 3]);
            }
        }
        // The integrator checked the state; projection and impulses keep finite values finite.
        self.collide(dt, gravity);
        Ok(())
    }
}
