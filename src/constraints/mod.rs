//! Constrained particle dynamics with Lagrange multipliers (Witkin, "Constrained dynamics",
//! in Witkin & Baraff, *Physically Based Modeling*, SIGGRAPH course notes).
//!
//! Each constraint `C(x) = 0` supplies its value, its Jacobian `J = ∂C/∂x` and the product
//! `J̇ q̇`. Requiring the constraint acceleration to vanish, with Baumgarte-style feedback on the
//! drift, gives the multipliers from
//!
//! `J W Jᵀ λ = -J̇ q̇ - J W Q - k_s C - k_d Ċ`,
//!
//! (`W` the inverse masses, `Q` the applied forces) and the constraint force `Q̂ = Jᵀ λ`, which
//! does no work on any legal velocity (`J q̇ = 0`). The matrix `J W Jᵀ` is sparse (rows couple
//! only when their constraints share a particle); it is solved by a faer sparse Cholesky whose
//! pattern and symbolic analysis are computed once, or by Jacobi-preconditioned conjugate
//! gradient. A relative regularisation `ε = 1e-10 · max(diag, 1)` on the diagonal makes
//! redundant or conflicting constraints solvable (the least-norm compromise) instead of a
//! failure.
//!
//! The constrained equations are integrated by any method of [`crate::ode`]; colliders and
//! emitters of the particle system are not applied in a constrained step.
//!
//! Two other formulations of the same problems are here for comparison: the penalty method
//! ([`Formulation::Penalty`]: a spring `-k C ∇C - c Ċ ∇C` per constraint row instead of the
//! multiplier solve; the drift falls as `1/k` while the stable step shrinks as `1/√k`) and
//! reduced (generalised) coordinates ([`ReducedBead`], [`ReducedPendulum`]: Lagrangian
//! dynamics in the curve parameter or the angles, with no drift by construction).
//!
//! Constraints: rods ([`Constraint::Distance`]), spheres, planes, fixed points, points on a
//! parametric [`Curve`] ([`Constraint::OnCurve`]), and user constraints given as value and
//! gradient functions ([`Constraint::Custom`], [`ConstraintFunction`]).

//! The system is split as every system of kinema is: a [`Model`] (the constraints, gains,
//! formulation, solver kind and post-stabilisation: built once, read by every step), a
//! [`State`] (the curves' tracked parameters, the multipliers that warm-start the next solve,
//! the ODE history) beside the particles' own state, and a [`Solver`] (workspaces only), so
//! that one model and one solver can advance several states. A step advances a particle
//! state and a constraint state together ([`Particles`] names the particle side).
//! [`ConstrainedSystem`] is the three together, on a [`ParticleSystem`].
//!
//! ```
//! use glam::DVec3;
//! use kinema::constraints::{self, Constraint, ConstraintSolver, Particles};
//! use kinema::ode::Method;
//! use kinema::particles::{self, Force};
//! use kinema::snapshot::Stamped;
//!
//! // One particle model and one constraint model: two rods hanging from a pinned particle.
//! let mut bodies = particles::Model::new(3);
//! bodies.add_force(Force::Gravity { g: DVec3::new(0.0, -9.81, 0.0) })?;
//! let mut rods = constraints::Model::new(0.0, 0.0, ConstraintSolver::Cholesky)?;
//! rods.add(&bodies, Constraint::Distance { i: 0, j: 1, length: 1.0 })?;
//! rods.add(&bodies, Constraint::Distance { i: 1, j: 2, length: 1.0 })?;
//! // Two initial conditions, each a particle state and the constraint state on it.
//! let x = [DVec3::ZERO, DVec3::X, DVec3::new(2.0, 0.0, 0.0)];
//! let masses = [f64::INFINITY, 1.0, 1.0];
//! let pushed = [DVec3::ZERO, DVec3::ZERO, DVec3::new(0.0, 3.0, 0.0)];
//! let mut a = particles::State::new(&bodies, &x, &[DVec3::ZERO; 3], &masses)?;
//! let mut b = particles::State::new(&bodies, &x, &pushed, &masses)?;
//! let mut ca = constraints::State::new(&rods, &a)?;
//! let mut cb = constraints::State::new(&rods, &b)?;
//! // One solver pair advances both, in any order, each as if it had solvers of its own.
//! let mut solvers = (particles::Solver::new(&bodies)?, constraints::Solver::new(&rods));
//! for _ in 0..100 {
//!     for (p, c) in [(&mut a, &mut ca), (&mut b, &mut cb)] {
//!         let particles = Particles { model: &bodies, state: p, solver: &mut solvers.0 };
//!         solvers.1.step(&rods, c, particles, 1e-3, 1, Method::Rk4)?;
//!     }
//! }
//! assert!(b.positions()[7] > a.positions()[7] + 0.2); // the pushed end is higher
//! // A constraint state's snapshot names its model by fingerprint and is refused on another.
//! let bytes = cb.to_snapshot(&rods)?;
//! assert_eq!(constraints::State::from_snapshot(&rods, &bytes)?, cb);
//! # Ok::<(), kinema::Error>(())
//! ```

mod curve;
mod implicit;
mod model;
mod multipliers;
mod projection;
mod reduced;
mod rows;
mod snapshot;
mod solver;
mod state;

pub use curve::Curve;
pub use implicit::NEWTON_STEP_TOL;
pub use model::Model;
pub use reduced::{ReducedBead, ReducedPendulum};
pub use rows::{Constraint, ConstraintFunction};
pub use solver::{Particles, Solver};
pub use state::State;

use rows::{at_particle, evaluate};

use crate::error::Result;
use crate::ode::Method;
use crate::particles::ParticleSystem;
use glam::DVec3;
/// Gauss–Newton position projections of the post-stabilisation per step, at most; a step that
/// needs more fails (see [`Model::set_stabilization`]).
pub const PROJECTION_ITERATIONS: usize = 30;
/// The post-stabilisation stops when the largest `|C|` (m) is at most this (far from the
/// origin: 64 ulps of the largest coordinate, the rounding floor of `C`).
pub const PROJECTION_TOL: f64 = 1e-10;

/// How the constraints act.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub enum Formulation {
    /// Lagrange multipliers (Witkin) with the drift feedback `ks`, `kd`.
    Multipliers,
    /// Penalty springs: the force `-stiffness C ∇C - damping Ċ ∇C` per row (N), no solve.
    /// `stiffness` in N/m (N per unit of `C`), `damping` in N s/m.
    Penalty {
        /// Spring constant (> 0).
        stiffness: f64,
        /// Damper constant (>= 0).
        damping: f64,
    },
}

/// Which linear solver computes the multipliers.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ConstraintSolver {
    /// faer sparse Cholesky (pattern analysed once).
    Cholesky,
    /// Jacobi-preconditioned conjugate gradient to relative residual 1e-12.
    ConjugateGradient,
}

/// Constraints on the particles of a [`ParticleSystem`], stepped with the system's forces: a
/// [`Model`] with one [`State`] and a [`Solver`], its methods delegating to them. Adding a
/// constraint extends the model and fits the state. A snapshot holds the model and the state
/// (not the particles).
#[derive(serde::Serialize, serde::Deserialize)]
pub struct ConstrainedSystem {
    model: Model,
    state: State,
    #[serde(skip)]
    solver: Solver,
}

impl std::fmt::Debug for ConstrainedSystem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let m = &self.model;
        write!(
            f,
            "ConstrainedSystem({} constraints, {:?}, ks = {}, kd = {}, stabilize = {})",
            m.constraints.len(),
            m.formulation,
            m.ks,
            m.kd,
            m.stabilize
        )
    }
}

/// The particle side of a constrained step of `system`.
fn particles(system: &mut ParticleSystem) -> Particles<'_> {
    let (model, state, solver) = system.parts();
    Particles { model, state, solver }
}

impl ConstrainedSystem {
    /// No constraints yet ([`Model::new`]).
    ///
    /// # Errors
    /// As [`Model::new`].
    pub fn new(ks: f64, kd: f64, solver: ConstraintSolver) -> Result<Self> {
        Ok(Self::of(Model::new(ks, kd, solver)?))
    }

    /// No constraints yet, penalty formulation ([`Model::penalty`]).
    ///
    /// # Errors
    /// As [`Model::penalty`].
    pub fn penalty(stiffness: f64, damping: f64) -> Result<Self> {
        Ok(Self::of(Model::penalty(stiffness, damping)?))
    }

    fn of(model: Model) -> Self {
        ConstrainedSystem { model, state: State::default(), solver: Solver::default() }
    }

    /// The model (constraints, gains, formulation, solver kind, post-stabilisation).
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The state (tracked curve parameters, warm starts, integration history).
    pub fn state(&self) -> &State {
        &self.state
    }

    /// Copy `state`, a state of this system's model (e.g. stepped by another solver, restored
    /// by [`State::from_snapshot`], or an undo point), into this system's state in place (no
    /// allocation when the sizes match).
    ///
    /// # Errors
    /// A state of another model (argument `state`).
    pub fn set_state(&mut self, state: &State) -> Result<()> {
        state.check_model(&self.model)?;
        self.state.clone_from(state);
        Ok(())
    }

    /// Turn post-stabilisation on or off ([`Model::set_stabilization`]).
    ///
    /// # Errors
    /// As [`Model::set_stabilization`].
    pub fn set_stabilization(&mut self, on: bool) -> Result<()> {
        self.model.set_stabilization(on)
    }

    /// Whether post-stabilisation is on ([`Model::set_stabilization`]).
    pub fn stabilization(&self) -> bool {
        self.model.stabilization()
    }

    /// How the constraints act.
    pub fn formulation(&self) -> Formulation {
        self.model.formulation()
    }

    /// The constraints, in the order added.
    pub fn constraints(&self) -> &[Constraint] {
        self.model.constraints()
    }

    /// Whether a [`Constraint::Custom`] is present (its function may need a lock, e.g. the GIL).
    pub fn has_custom(&self) -> bool {
        self.model.has_custom()
    }

    /// The tracked parameter `u` of constraint `k` when it is a [`Constraint::OnCurve`].
    pub fn curve_parameter(&self, k: usize) -> Option<f64> {
        self.state.curve_parameter(&self.model, k)
    }

    /// Conjugate-gradient iterations of the last multiplier solve (0 with Cholesky).
    pub fn iterations(&self) -> usize {
        self.state.iterations()
    }

    /// Add a constraint on `particles` ([`Model::add`]) and fit the state to it at the
    /// particles' positions ([`State::fit`]); nothing changes when it fails.
    ///
    /// # Errors
    /// Those of [`Model::add`] and [`State::new`].
    pub fn add(&mut self, particles: &ParticleSystem, constraint: Constraint) -> Result<()> {
        self.model.add(particles.model(), constraint)?;
        if let Err(e) = self.state.fit(&self.model, particles.positions()) {
            self.model.constraints.pop();
            return Err(e);
        }
        Ok(())
    }

    /// Largest `|C|` and `|Ċ|` over all constraint rows at the particles' current state
    /// ([`Solver::violation`]).
    ///
    /// # Errors
    /// As [`Solver::violation`].
    pub fn violation(&mut self, particles: &ParticleSystem) -> Result<(f64, f64)> {
        self.solver.violation(&self.model, &self.state, particles.state())
    }

    /// The constraint forces (N, world frame) on every particle at the current state
    /// ([`Solver::constraint_forces`]).
    ///
    /// # Errors
    /// As [`Solver::constraint_forces`].
    pub fn constraint_forces(&mut self, particles: &mut ParticleSystem) -> Result<Vec<DVec3>> {
        let (model, state) = (&self.model, &mut self.state);
        self.solver.constraint_forces(model, state, self::particles(particles))
    }

    /// Advance the particles `steps` steps of `dt` with `method` ([`Solver::step`]).
    ///
    /// # Errors
    /// As [`Solver::step`]; the particles are left at the last good step.
    pub fn step(
        &mut self,
        particles: &mut ParticleSystem,
        dt: f64,
        steps: usize,
        method: Method,
    ) -> Result<()> {
        let (model, state) = (&self.model, &mut self.state);
        self.solver.step(model, state, self::particles(particles), dt, steps, method)
    }

    /// Advance the particles `steps` steps of `dt` by step and project
    /// ([`Solver::step_projection`]).
    ///
    /// # Errors
    /// As [`Solver::step_projection`]; the particles are left at the last good step.
    pub fn step_projection(
        &mut self,
        particles: &mut ParticleSystem,
        dt: f64,
        steps: usize,
    ) -> Result<()> {
        let (model, state) = (&self.model, &mut self.state);
        self.solver.step_projection(model, state, self::particles(particles), dt, steps)
    }

    /// Check that the constraints' particles are among the `n` slots of the particle system
    /// the system is used with, and the state's history of that size (a snapshot does not
    /// hold the particles).
    ///
    /// # Errors
    /// [`Error::InvalidInput`](crate::Error::InvalidInput) (argument `particles`).
    pub fn check_particles(&self, n: usize) -> Result<()> {
        self.model.check_particles(n)?;
        self.state.check_particles(n)
    }
}
