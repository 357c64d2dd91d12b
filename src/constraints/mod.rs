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

mod curve;
mod implicit;
mod multipliers;
mod projection;
mod reduced;
mod rows;
mod snapshot;

pub use curve::Curve;
pub use implicit::NEWTON_STEP_TOL;
pub use reduced::{ReducedBead, ReducedPendulum};
pub use rows::{Constraint, ConstraintFunction};

use curve::track_curves;
use multipliers::{assemble, Constrained};
use rows::{at_particle, evaluate, Rows};

use crate::error::{Error, Result};
use crate::linalg::{conjugate_gradient, SparseCholesky};
use crate::ode::{Method, OdeSystem, Stepper};
use crate::particles::ParticleSystem;
use glam::DVec3;
use std::sync::Arc;

/// Gauss–Newton position projections of the post-stabilisation per step, at most; a step that
/// needs more fails (see [`ConstrainedSystem::set_stabilization`]).
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

/// Constraints on the particles of a [`ParticleSystem`], stepped with the system's forces.
#[derive(serde::Serialize, serde::Deserialize)]
pub struct ConstrainedSystem {
    constraints: Vec<Constraint>,
    /// Feedback stiffness `k_s` on the drift `C` (1/s²), multiplier formulation.
    pub ks: f64,
    /// Feedback damping `k_d` on `Ċ` (1/s), multiplier formulation.
    pub kd: f64,
    formulation: Formulation,
    solver: ConstraintSolver,
    /// Post-stabilisation after every step (multipliers only; see [`Self::set_stabilization`]).
    stabilize: bool,
    work: Work,
    stepper: Option<Stepper>,
}

/// Workspaces of the multiplier solve, sized when the constraints change.
#[derive(serde::Serialize, serde::Deserialize, Default)]
struct Work {
    rows: Rows,
    /// Per constraint: the tracked curve parameter and frame reference axis (curves only).
    curves: Vec<(f64, DVec3)>,
    /// The state before a step, restored when its post-stabilisation or curve tracking fails.
    backup: Vec<f64>,
    b: Vec<f64>,
    lambda: Vec<f64>,
    diag: Vec<f64>,
    scratch: Vec<f64>,
    cg: [Vec<f64>; 4],
    /// The state being built by a projection step.
    #[serde(skip)]
    next: Vec<f64>,
    #[serde(skip)] // rebuilt by `prepare` (same pattern, same factor)
    chol: Option<SparseCholesky>,
    /// The multipliers (N) of the last implicit projection, the next one's starting guess.
    #[serde(default)]
    implicit_lambda: Vec<f64>,
    /// The implicit projection's KKT system (built at the first projection step).
    #[serde(skip)]
    kkt: Option<implicit::Kkt>,
    /// The CG warm start `lambda` and `iterations` before the current step, put back when it
    /// fails (a failed step's multipliers may be huge or NaN and would poison the next solve).
    #[serde(skip)]
    saved: (Vec<f64>, usize),
    values: Vec<f64>,
    /// (value index, row r, row s, particle) per contribution w_p J_rp · J_sp.
    contributions: Vec<(usize, usize, usize, usize)>,
    diagonal_index: Vec<usize>,
    iterations: usize,
}

impl std::fmt::Debug for ConstrainedSystem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "ConstrainedSystem({} constraints, {:?}, ks = {}, kd = {}, stabilize = {})",
            self.constraints.len(),
            self.formulation,
            self.ks,
            self.kd,
            self.stabilize
        )
    }
}

impl ConstrainedSystem {
    /// No constraints yet, multiplier formulation with feedback gains `ks`, `kd` (0 turns
    /// feedback off) and post-stabilisation on ([`Self::set_stabilization`]).
    ///
    /// # Errors
    /// Negative or non-finite gains.
    pub fn new(ks: f64, kd: f64, solver: ConstraintSolver) -> Result<Self> {
        if !(ks.is_finite() && kd.is_finite() && ks >= 0.0 && kd >= 0.0) {
            return Err(Error::invalid("ks", "feedback gains must be finite and >= 0"));
        }
        Ok(ConstrainedSystem {
            constraints: Vec::new(),
            ks,
            kd,
            formulation: Formulation::Multipliers,
            solver,
            stabilize: true,
            work: Work::default(),
            stepper: None,
        })
    }

    /// No constraints yet, penalty formulation: every row adds the force
    /// `-stiffness C ∇C - damping Ċ ∇C` (N) instead of a multiplier solve.
    ///
    /// # Errors
    /// A stiffness that is not positive and finite, a negative or non-finite damping.
    pub fn penalty(stiffness: f64, damping: f64) -> Result<Self> {
        if !(stiffness.is_finite() && stiffness > 0.0) {
            return Err(Error::invalid(
                "stiffness",
                format!("must be positive and finite, got {stiffness}"),
            ));
        }
        if !(damping.is_finite() && damping >= 0.0) {
            return Err(Error::invalid(
                "damping",
                format!("must be finite and >= 0, got {damping}"),
            ));
        }
        let mut system = ConstrainedSystem::new(0.0, 0.0, ConstraintSolver::Cholesky)?;
        system.formulation = Formulation::Penalty { stiffness, damping };
        system.stabilize = false;
        Ok(system)
    }

    /// Turn post-stabilisation (Cline & Pai 2003, "Post-stabilization for rigid body
    /// simulation with contact and constraints", ICRA) on or off. On (the default with
    /// multipliers), every step of [`Self::step`] ends by
    /// projecting the positions onto `C(x) = 0` in the mass metric, `(J W Jᵀ) δ = -C`,
    /// `x += W Jᵀ δ` (Gauss–Newton, at most [`PROJECTION_ITERATIONS`] times, until `|C| ≤`
    /// [`PROJECTION_TOL`]), and the velocities onto `J v = 0` at the new positions,
    /// `(J W Jᵀ) μ = -J v`, `v += W Jᵀ μ`, with the same sparse solve as the multipliers. The
    /// corrections are of the size of one step's drift, so the integrator keeps its order,
    /// and the constraints hold to `PROJECTION_TOL` at any step; the velocity projection
    /// removes the kinetic energy of the constraint-violating velocity (at most that of the
    /// drift rate, `½ Ċᵀ (J W Jᵀ)⁻¹ Ċ`). Off, the constraints hold only through `ks`, `kd`
    /// and the accuracy of the integrator. [`Self::step_projection`] always ends on
    /// `C(x) = 0` (its step is a projection); post-stabilisation adds the velocity projection.
    ///
    /// # Errors
    /// `on` with the penalty formulation (whose springs are the constraint model).
    pub fn set_stabilization(&mut self, on: bool) -> Result<()> {
        if on && self.formulation != Formulation::Multipliers {
            return Err(Error::invalid(
                "stabilize",
                "post-stabilisation needs the multiplier formulation, not penalty",
            ));
        }
        self.stabilize = on;
        Ok(())
    }

    /// Whether post-stabilisation is on ([`Self::set_stabilization`]).
    pub fn stabilization(&self) -> bool {
        self.stabilize
    }

    /// How the constraints act.
    pub fn formulation(&self) -> Formulation {
        self.formulation
    }

    /// The constraints, in the order added.
    pub fn constraints(&self) -> &[Constraint] {
        &self.constraints
    }

    /// Whether a [`Constraint::Custom`] is present (its function may need a lock, e.g. the GIL).
    pub fn has_custom(&self) -> bool {
        self.constraints.iter().any(|c| matches!(c, Constraint::Custom { .. }))
    }

    /// The tracked parameter `u` of constraint `k` when it is a [`Constraint::OnCurve`].
    pub fn curve_parameter(&self, k: usize) -> Option<f64> {
        match self.constraints.get(k) {
            Some(Constraint::OnCurve { .. }) => Some(self.work.curves[k].0),
            _ => None,
        }
    }

    /// Conjugate-gradient iterations of the last multiplier solve (0 with Cholesky).
    pub fn iterations(&self) -> usize {
        self.work.iterations
    }

    /// Add a constraint on `particles`.
    ///
    /// # Errors
    /// Indices out of range, a distance constraint between a particle and itself or between
    /// particles that currently coincide (no direction), non-positive lengths or radii, zero
    /// normals, non-finite values, a degenerate curve or one whose closest point to the
    /// particle cannot be found, a custom constraint without particles, with repeated
    /// particles, without rows, or whose function fails or returns non-finite values at the
    /// current positions.
    pub fn add(&mut self, particles: &ParticleSystem, constraint: Constraint) -> Result<()> {
        let n = particles.capacity();
        for p in constraint.particles() {
            if p >= n {
                return Err(Error::invalid(
                    "i",
                    format!("particle {p} out of range ({n} particles)"),
                ));
            }
        }
        let (constraint, curve_state) = constraint.checked(particles.positions())?;
        self.constraints.push(constraint);
        self.work.curves.push(curve_state);
        self.work.chol = None; // the pattern changed
        self.work.kkt = None;
        self.stepper = None;
        Ok(())
    }

    /// Largest `|C|` and `|Ċ|` over all constraint rows at the particles' current state.
    ///
    /// # Errors
    /// A custom constraint's function fails, or a curve's closest point is lost.
    pub fn violation(&mut self, particles: &ParticleSystem) -> Result<(f64, f64)> {
        let n = particles.capacity();
        self.check_particles(n)?;
        let mut y = particles.positions().to_vec();
        y.extend_from_slice(particles.velocities());
        let w = &mut self.work;
        evaluate(&self.constraints, &w.curves, &y, n, &mut w.rows)?;
        Ok(w.rows.rows.iter().fold((0.0, 0.0), |(a, b), r| (a.max(r.c.abs()), b.max(r.cdot.abs()))))
    }

    /// The constraint forces (N, world frame) on every particle at the current state, as used
    /// by the next step: `Jᵀ λ` with multipliers, the spring forces with the penalty method.
    ///
    /// # Errors
    /// A solver failure, a custom constraint's failure or a lost curve.
    pub fn constraint_forces(&mut self, particles: &mut ParticleSystem) -> Result<Vec<DVec3>> {
        let n = particles.capacity();
        self.prepare(n)?;
        let (mut system, y, time) = assemble(self, particles);
        let mut dydt = vec![0.0; 6 * n];
        // With penalty forces the rhs fills the rows; with multipliers it also solves for λ.
        system.rhs(*time, y, &mut dydt)?;
        let w = &self.work;
        let mut forces = vec![DVec3::ZERO; n];
        for (r, row) in w.rows.rows.iter().enumerate() {
            let scale = match self.formulation {
                Formulation::Multipliers => w.lambda[r],
                Formulation::Penalty { stiffness, damping } => {
                    -(stiffness * row.c + damping * row.cdot)
                }
            };
            for &(p, g) in w.rows.blocks(r) {
                forces[p] += scale * g;
            }
        }
        Ok(forces)
    }

    fn prepare(&mut self, n: usize) -> Result<()> {
        self.check_particles(n)?;
        if self.work.chol.is_none()
            && self.solver == ConstraintSolver::Cholesky
            && self.formulation == Formulation::Multipliers
        {
            self.build_pattern(n)?;
        }
        let m: usize = self.constraints.iter().map(Constraint::rows).sum();
        let w = &mut self.work;
        for v in [&mut w.b, &mut w.lambda, &mut w.diag, &mut w.implicit_lambda] {
            v.resize(m, 0.0);
        }
        self.work.scratch.resize(3 * n, 0.0);
        if self.stabilize
            || self.constraints.iter().any(|c| matches!(c, Constraint::OnCurve { .. }))
        {
            self.work.backup.resize(6 * n, 0.0);
        }
        Ok(())
    }

    /// Advance the particles `steps` steps of `dt` with `method`, constrained by the
    /// system's formulation.
    ///
    /// # Errors
    /// A bad `dt`, a solver failure, a custom constraint's failure, a lost curve or a
    /// non-finite state; the particles are left at the last good step.
    pub fn step(
        &mut self,
        particles: &mut ParticleSystem,
        dt: f64,
        steps: usize,
        method: Method,
    ) -> Result<()> {
        let n = particles.capacity();
        if self.stepper.as_ref().is_none_or(|s| s.method() != method) {
            self.stepper = Some(Stepper::new(method, 6 * n)?);
        }
        self.prepare(n)?;
        let mut stepper = self.stepper.take().expect("created above");
        let backup = !self.work.backup.is_empty();
        let (mut system, y, time) = assemble(self, particles);
        let mut result = Ok(());
        for s in 0..steps {
            if backup {
                system.work.backup.copy_from_slice(y);
            }
            let w = &mut *system.work;
            w.saved.0.clone_from(&w.lambda);
            w.saved.1 = w.iterations;
            result = stepper.step(&mut system, *time, y, dt);
            if result.is_ok() {
                // The step is committed only when its post-stabilisation and curve tracking
                // succeed; otherwise the state before it comes back.
                result = if system.stabilize {
                    system.project_positions(y).and_then(|()| system.project_velocities(y))
                } else {
                    Ok(())
                }
                .and_then(|()| track_curves(system.constraints, y, &mut system.work.curves));
                if result.is_err() {
                    y.copy_from_slice(&system.work.backup);
                    stepper.reset();
                }
            }
            if let Err(e) = result {
                let w = &mut *system.work;
                w.lambda.clone_from(&w.saved.0);
                w.iterations = w.saved.1;
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
        self.stepper = Some(stepper);
        result
    }

    /// The pattern of `J W Jᵀ` (rows sharing a particle), its symbolic factorisation, and the
    /// list of contributions that refill its values.
    fn build_pattern(&mut self, n: usize) -> Result<()> {
        let mut row_of_particle: Vec<Vec<usize>> = vec![Vec::new(); n];
        let mut r = 0;
        for c in &self.constraints {
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
        self.work.contributions = entries.iter().map(|&(s, r, p)| (index(s, r), r, s, p)).collect();
        self.work.diagonal_index = (0..m).map(|k| index(k, k)).collect();
        self.work.values = vec![0.0; pattern.len()];
        self.work.chol = Some(SparseCholesky::new(m, col_ptr, row_idx)?);
        Ok(())
    }
}
