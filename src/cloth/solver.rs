//! The cloth's solver: every workspace of a step — the values of the implicit matrix
//! (Baraff & Witkin 1998, eqs. 15–18), the filter and right-hand side, the PCG's vectors and
//! preconditioner, the Cholesky factorisation, the explicit stepper — and the undo copy of
//! the state a failed step puts back. It carries nothing that a later step reads, so one
//! solver advances any number of states of one [`Model`], in any interleaving, bit for bit as
//! if each had its own.

use super::linear::{CholeskyState, Multigrid};
use super::pcg;
use super::{BlockMatrix, ContactState, Model, SolveOptions, State, StepStats};
use crate::error::{Error, Result};
use crate::ode::{Method, Stepper};
use glam::{DMat3, DVec3};

/// Work vectors of a step, one entry per vertex unless said otherwise; every step writes
/// them before it reads them.
pub(super) struct Scratch {
    pub(super) f: Vec<DVec3>,
    pub(super) ku: Vec<DVec3>,
    pub(super) u: Vec<DVec3>,
    pub(super) b: Vec<DVec3>,
    pub(super) q: Vec<DVec3>,
    pub(super) filter: Vec<DMat3>,
    pub(super) z: Vec<DVec3>,
    pub(super) y: Vec<DVec3>,
    /// The PCG's four-lane vectors and preconditioner, rebuilt by each solve.
    pub(super) pcg: pcg::Work,
    /// The constrained vertices of the step.
    pub(super) constrained: Vec<usize>,
    /// Contacts of the step: vertex, normal, collider velocity, friction coefficient, normal
    /// impulse estimate (N s).
    pub(super) contact_normal: Vec<(usize, DVec3, DVec3, f64, f64)>,
    /// The contact states the step leaves (swapped into the state when it is taken).
    pub(super) states: Vec<ContactState>,
    pub(super) x_new: Vec<DVec3>,
    pub(super) v_new: Vec<DVec3>,
    /// BDF2 history terms `c (x - x₋)`, `c (v - v₋)` with `c` of [`crate::ode::bdf2_weights`]
    /// (`1/3` at a constant step; zero for implicit Euler).
    pub(super) hx: Vec<DVec3>,
    pub(super) hv: Vec<DVec3>,
    /// `y = [x; v]` of the explicit path (`6N`), and its positions and velocities.
    pub(super) flat: Vec<f64>,
    pub(super) ex: Vec<DVec3>,
    pub(super) ev: Vec<DVec3>,
}

impl Scratch {
    /// The work vectors of a cloth of `n` vertices.
    fn new(n: usize) -> Scratch {
        let zero = vec![DVec3::ZERO; n];
        Scratch {
            f: zero.clone(),
            ku: zero.clone(),
            u: zero.clone(),
            b: zero.clone(),
            q: zero.clone(),
            filter: vec![DMat3::IDENTITY; n],
            z: zero.clone(),
            y: zero.clone(),
            pcg: pcg::Work::default(),
            constrained: Vec::with_capacity(n),
            contact_normal: Vec::with_capacity(n),
            states: vec![ContactState::Free; n],
            x_new: zero.clone(),
            v_new: zero.clone(),
            hx: zero.clone(),
            hv: zero.clone(),
            flat: Vec::new(),
            ex: zero.clone(),
            ev: zero,
        }
    }
}

/// The solver of a cloth model (see the module documentation).
pub struct Solver {
    /// The implicit matrix `A` on the model's pattern ([`Model::pattern`]).
    pub(super) matrix: BlockMatrix,
    pub(super) scratch: Scratch,
    /// The Cholesky path's symbolic factorisation (built on first use, reused) and values.
    pub(super) cholesky: Option<CholeskyState>,
    /// The multigrid path's hierarchy (its symbolic setup built on first use, reused) and
    /// vectors.
    pub(super) multigrid: Option<Box<Multigrid>>,
    /// The strain limiter's edges (built on first use from the model) and work vector.
    pub(super) limiter: Option<Box<super::strain_limit::Edges>>,
    /// The explicit path's integrator (its stages; the cloth's explicit methods keep no
    /// history).
    pub(super) stepper: Option<Stepper>,
    /// Self-collision's tree and buffers (built on the first step that needs them).
    pub(super) self_work: Option<Box<super::self_collide::Work>>,
    /// The state before the step being taken, put back when it fails.
    saved: State,
    /// Numbers of the last completed step (a report; no step reads it).
    pub(super) stats: StepStats,
}

impl std::fmt::Debug for Solver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "cloth::Solver({} vertices)", self.matrix.n())
    }
}

impl Solver {
    /// A solver for `model`: its matrix pattern and workspaces allocated once.
    pub fn new(model: &Model) -> Solver {
        Solver {
            matrix: model.pattern(),
            scratch: Scratch::new(model.len()),
            cholesky: None,
            multigrid: None,
            limiter: None,
            stepper: None,
            self_work: None,
            saved: model.state(),
            stats: StepStats::default(),
        }
    }

    /// Numbers of the last completed step.
    pub fn stats(&self) -> StepStats {
        self.stats
    }

    /// Stored blocks of the implicit matrix (its sparsity).
    pub fn matrix_blocks(&self) -> usize {
        self.matrix.blocks.len() - 1
    }

    /// Advance `state` of `model` by `steps` steps of `dt` seconds with `method`:
    /// [`Method::ImplicitEuler`] and [`Method::Bdf2`] take the linearised implicit step (one
    /// Newton step, more where it adds energy; `options` choose the linear solver); the explicit methods of
    /// [`crate::ode`] integrate `ẍ = M⁻¹ f` with the filter applied to accelerations and
    /// collisions resolved by projection after each step. Returns the numbers of the last
    /// step.
    ///
    /// # Errors
    /// A bad `dt` or options, a state of another model (argument `"state"`),
    /// [`Method::Trapezoidal`] (not offered for cloth), a failed Cholesky factorisation, or
    /// [`Error::Diverged`]. The state is left exactly at the end of the last good step (with
    /// `steps = 1`, as before the call), also when a subdivided step fails after committing
    /// some of its substeps.
    pub fn step(
        &mut self,
        model: &Model,
        state: &mut State,
        dt: f64,
        steps: usize,
        method: Method,
        options: SolveOptions,
    ) -> Result<StepStats> {
        check_step(dt, options)?;
        state.fits(model)?;
        for s in 0..steps {
            self.saved.clone_from(state);
            let mut stats = StepStats { converged: true, ..StepStats::default() };
            let implicit = |bdf2| Implicit { model, bdf2, options };
            let result = match method {
                Method::ImplicitEuler => {
                    self.adaptive(implicit(false), state, &mut stats, dt, 0, None)
                }
                Method::Bdf2 => self.adaptive(implicit(true), state, &mut stats, dt, 0, None),
                Method::Trapezoidal => Err(Error::invalid(
                    "integrator",
                    "trapezoidal is not offered for cloth; use implicit_euler or bdf2",
                )),
                _ if model.self_collision.is_some() || !state.meshes.is_empty() => {
                    Err(Error::invalid(
                        "integrator",
                        "self-collision and mesh colliders need an implicit integrator \
                         (implicit_euler or bdf2)",
                    ))
                }
                explicit => self.step_explicit(model, state, &mut stats, dt, explicit),
            };
            if let Err(e) = result {
                state.clone_from(&self.saved);
                return Err(match e {
                    Error::Diverged { index, reason, .. } => {
                        Error::Diverged { step: s, index, reason }
                    }
                    other => other,
                });
            }
            self.stats = stats;
        }
        Ok(self.stats)
    }

    /// An implicit step of `h`, redone as two half steps (recursively, at most five times)
    /// when it changes a stretch ratio by more than `options.max_strain_change`. BDF2 keeps its
    /// history through the halving: halving and the steps after it change the step by a ratio
    /// of 1/2 or 2, which the variable-step coefficients take.
    ///
    /// Halving pays only where the change shrinks with the step. The first half of a refused
    /// step starts from the same state; when it changes the stretch ratios by more than
    /// [`JUMP`] times what the refused step did, the change is a jump that no smaller step
    /// resolves (a vertex landing on a collider is stopped within the substep, however short,
    /// and compressed triangles on the 128² drape change by 1.7–6 % at every substep from `h`
    /// to `h/32`), and the half is taken (its second half is checked afresh). Until session 23
    /// such steps were halved down to `h/32` (up to 63 solves a step). `refused` is the change of the
    /// refused step this one is the first half of.
    fn adaptive(
        &mut self,
        how: Implicit,
        state: &mut State,
        stats: &mut StepStats,
        h: f64,
        depth: u32,
        refused: Option<f64>,
    ) -> Result<()> {
        const MAX_HALVINGS: u32 = 5;
        let ceiling = refused.map_or(f64::INFINITY, |change| JUMP * change);
        let check = (depth < MAX_HALVINGS).then_some(ceiling);
        let Some(change) = self.step_implicit(how, state, stats, h, check)? else {
            return Ok(());
        };
        self.adaptive(how, state, stats, 0.5 * h, depth + 1, Some(change))?;
        self.adaptive(how, state, stats, 0.5 * h, depth + 1, None)
    }
}

/// The share of a refused step's change of the stretch ratios above which its first half
/// (from the same state) is taken rather than halved again (see [`Solver::adaptive`]): a
/// change that grows smoothly in time halves with the step (ratio 1/2); one that does not
/// shrink by a quarter is dominated by a jump.
const JUMP: f64 = 0.75;

/// What the implicit substeps of one step share: the model, BDF2 or implicit Euler, and the
/// options.
#[derive(Clone, Copy)]
pub(super) struct Implicit<'a> {
    pub(super) model: &'a Model,
    pub(super) bdf2: bool,
    pub(super) options: SolveOptions,
}

/// The arguments of a step: a positive finite `dt`, a positive finite tolerance with at least
/// one iteration, a positive `max_strain_change`.
fn check_step(dt: f64, options: SolveOptions) -> Result<()> {
    if !(dt.is_finite() && dt > 0.0) {
        return Err(Error::invalid("dt", format!("must be positive and finite, got {dt}")));
    }
    if !(options.tol.is_finite() && options.tol > 0.0) || options.max_iterations == 0 {
        return Err(Error::invalid("tol", "must be positive and finite, with max_iterations >= 1"));
    }
    if options.max_strain_change.is_nan() || options.max_strain_change <= 0.0 {
        return Err(Error::invalid(
            "max_strain_change",
            "must be positive (inf turns the check off)",
        ));
    }
    if options.max_strain.is_nan() || options.max_strain <= 0.0 {
        return Err(Error::invalid(
            "max_strain",
            "must be positive (inf turns strain limiting off)",
        ));
    }
    Ok(())
}
