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
mod reduced;
mod snapshot;

pub use curve::Curve;
pub use implicit::NEWTON_STEP_TOL;
pub use reduced::{ReducedBead, ReducedPendulum};

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

/// A user constraint `C(x) = 0` of `m` scalar rows on `k` particles, given by its value and
/// gradient (for teaching; e.g. Python callables). `J̇ q̇` is obtained by central differences
/// of the gradient along the velocity (see [`Constraint::Custom`]).
pub trait ConstraintFunction: Send + Sync + std::fmt::Debug {
    /// Number of scalar rows `m` >= 1.
    fn rows(&self) -> usize;
    /// Write `C` (`m` values) at the positions `x` (`k x 3` values, the constraint's particles
    /// in order, m) into `value`.
    ///
    /// # Errors
    /// Whatever the function reports (a Python exception, a wrong shape).
    fn value(&self, x: &[f64], value: &mut [f64]) -> Result<()>;
    /// Write `∂C/∂x` (`m x 3k`, row-major: row `r` holds `∂C_r/∂x₀, ∂C_r/∂y₀, ∂C_r/∂z₀,
    /// ∂C_r/∂x₁...`) at `x` into `gradient`.
    ///
    /// # Errors
    /// Whatever the function reports.
    fn gradient(&self, x: &[f64], gradient: &mut [f64]) -> Result<()>;
}

/// A holonomic constraint on particles.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub enum Constraint {
    /// `|x_i - x_j| - length = 0` (a rod).
    Distance {
        /// First particle.
        i: usize,
        /// Second particle.
        j: usize,
        /// Rod length (m) > 0.
        length: f64,
    },
    /// `|x_i - center| - radius = 0` (a bead on a sphere, or on a circle in a plane).
    OnSphere {
        /// Particle.
        i: usize,
        /// Centre (m).
        center: DVec3,
        /// Radius (m) > 0.
        radius: f64,
    },
    /// `n · (x_i - point) = 0`.
    OnPlane {
        /// Particle.
        i: usize,
        /// A point of the plane (m).
        point: DVec3,
        /// Normal (normalised here).
        normal: DVec3,
    },
    /// `x_i - point = 0` (three rows).
    Fixed {
        /// Particle.
        i: usize,
        /// Position (m).
        point: DVec3,
    },
    /// `x_i` on a parametric curve (a bead on a wire), as two rows
    /// `C_k = n_k · (x_i - x(u*))`, `k = 1, 2`, where `u*` is the parameter of the closest
    /// point (tracked from step to step, refined by Newton's method at every evaluation) and
    /// `n₁ = â × t̂ / |â × t̂|`, `n₂ = t̂ × n₁` span the plane normal to the tangent `t̂` (`â` a
    /// reference axis held per step: the circle's normal, else a world axis far from `t̂`).
    /// `C = 0` exactly when the particle is on the curve. `J` is exact
    /// (`J_k = n_k + (d · ∂n_k/∂u) ∇u*`, `d = x_i - x(u*)`, `∇u* = x'/(|x'|² - x''·d)`);
    /// `J̇ q̇` is exact on the curve and drops the terms proportional to `|d|` that would need
    /// the curve's third derivative (they only change how a drift is corrected).
    OnCurve {
        /// Particle.
        i: usize,
        /// The wire.
        curve: Curve,
    },
    /// A user constraint of `function.rows()` rows on `particles` (distinct indices).
    /// `J̇ q̇ = d/dε [∇C(x + ε q̇)] q̇` is taken by central differences with
    /// `ε |q̇|_max = ∛(machine ε) · max(1, |x|_max)` (error ~1e-11 relative, two extra gradient
    /// evaluations per row evaluation).
    #[serde(skip)] // holds a user function: a system with one cannot be saved
    Custom {
        /// The particles the function reads, in order.
        particles: Vec<usize>,
        /// Value and gradient.
        function: Arc<dyn ConstraintFunction>,
    },
}

impl Constraint {
    fn rows(&self) -> usize {
        match self {
            Constraint::Fixed { .. } => 3,
            Constraint::OnCurve { .. } => 2,
            Constraint::Custom { function, .. } => function.rows(),
            _ => 1,
        }
    }

    fn particles(&self) -> Vec<usize> {
        match self {
            Constraint::Distance { i, j, .. } => vec![*i, *j],
            Constraint::OnSphere { i, .. }
            | Constraint::OnPlane { i, .. }
            | Constraint::Fixed { i, .. }
            | Constraint::OnCurve { i, .. } => vec![*i],
            Constraint::Custom { particles, .. } => particles.clone(),
        }
    }
}

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

/// One row of `J` (its particle blocks are `Rows::blocks[start..start + count]`), with `C`,
/// `Ċ = J q̇` and `J̇ q̇`.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, Default)]
struct Row {
    start: usize,
    count: usize,
    c: f64,
    cdot: f64,
    jdot_qdot: f64,
}

/// The evaluated rows of `J` and their particle blocks.
#[derive(serde::Serialize, serde::Deserialize, Debug, Default)]
struct Rows {
    rows: Vec<Row>,
    blocks: Vec<(usize, DVec3)>,
    /// Custom constraints: positions, value, gradient and the two shifted gradients.
    scratch: Vec<f64>,
}

impl Rows {
    fn clear(&mut self) {
        self.rows.clear();
        self.blocks.clear();
    }

    fn blocks(&self, r: usize) -> &[(usize, DVec3)] {
        let row = &self.rows[r];
        &self.blocks[row.start..row.start + row.count]
    }

    /// Append a row; `Ċ` is computed as `J q̇` from the velocities `v`.
    fn push(
        &mut self,
        blocks: impl IntoIterator<Item = (usize, DVec3)>,
        c: f64,
        jdot_qdot: f64,
        v: impl Fn(usize) -> DVec3,
    ) {
        let start = self.blocks.len();
        self.blocks.extend(blocks);
        let count = self.blocks.len() - start;
        let cdot = self.blocks[start..].iter().map(|&(p, g)| g.dot(v(p))).sum();
        self.rows.push(Row { start, count, c, cdot, jdot_qdot });
    }
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

/// Attribute an error of a curve search to particle `i`.
fn at_particle(e: Error, i: usize) -> Error {
    match e {
        Error::SolverFailed { reason } => {
            Error::SolverFailed { reason: format!("particle {i} on its curve: {reason}") }
        }
        other => other,
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
        let pos = |i: usize| DVec3::from_slice(&particles.positions()[3 * i..]);
        for p in constraint.particles() {
            if p >= n {
                return Err(Error::invalid(
                    "i",
                    format!("particle {p} out of range ({n} particles)"),
                ));
            }
        }
        let mut curve_state = (0.0, DVec3::ZERO);
        let constraint = match constraint {
            Constraint::Distance { i, j, length } => {
                if i == j {
                    return Err(Error::invalid(
                        "j",
                        "a distance constraint needs two different particles",
                    ));
                }
                if !(length.is_finite() && length > 0.0) {
                    return Err(Error::invalid(
                        "length",
                        format!("must be positive and finite, got {length}"),
                    ));
                }
                if pos(i) == pos(j) {
                    return Err(Error::invalid(
                        "j",
                        format!("particles {i} and {j} coincide; the rod has no direction"),
                    ));
                }
                constraint
            }
            Constraint::OnSphere { center, radius, .. } => {
                if !(center.is_finite() && radius.is_finite() && radius > 0.0) {
                    return Err(Error::invalid(
                        "radius",
                        format!("must be positive with a finite centre, got {radius}"),
                    ));
                }
                constraint
            }
            Constraint::OnPlane { i, point, normal } => {
                if !(point.is_finite() && normal.is_finite() && normal.length() > 0.0) {
                    return Err(Error::invalid("normal", "must be a finite non-zero vector"));
                }
                Constraint::OnPlane { i, point, normal: normal.normalize() }
            }
            Constraint::Fixed { point, .. } => {
                if !point.is_finite() {
                    return Err(Error::invalid("point", "contains NaN or infinity"));
                }
                constraint
            }
            Constraint::OnCurve { i, curve } => {
                let curve = curve.checked()?;
                let x = pos(i);
                let u = curve.closest(x, curve.initial_parameter(x)).map_err(|e| {
                    Error::invalid("curve", format!("no closest point to particle {i}: {e}"))
                })?;
                curve_state = (u, curve.reference(u));
                Constraint::OnCurve { i, curve }
            }
            Constraint::Custom { particles: ids, function } => {
                let k = ids.len();
                let m = function.rows();
                if k == 0 || m == 0 {
                    return Err(Error::invalid(
                        "indices",
                        format!("a custom constraint needs particles and rows, got {k} and {m}"),
                    ));
                }
                if (1..k).any(|a| ids[..a].contains(&ids[a])) {
                    return Err(Error::invalid("indices", "must be distinct"));
                }
                let x: Vec<f64> = ids.iter().flat_map(|&p| pos(p).to_array()).collect();
                let mut value = vec![0.0; m];
                let mut gradient = vec![0.0; 3 * k * m];
                function.value(&x, &mut value)?;
                function.gradient(&x, &mut gradient)?;
                if value.iter().chain(&gradient).any(|v| !v.is_finite()) {
                    return Err(Error::invalid(
                        "value",
                        "the constraint's value or gradient is not finite at the current positions",
                    ));
                }
                Constraint::Custom { particles: ids, function }
            }
        };
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

    /// Advance the particles `steps` steps of `dt` by step and project (Goldenthal et al. 2007,
    /// "Efficient simulation of inextensible cloth", section 4): the free step
    /// `x̃ = x + h (v + h a_free)` is replaced by its closest point on `C(x) = 0` in the mass
    /// metric, and the velocity is `v₁ = (x₁ - x₀) / h`. The constraint impulse acts along the constraints'
    /// directions at the end of the step (an implicit step in the limit of infinite
    /// stiffness), so a rope of any tension is stable at any step; first order and
    /// dissipative. The projection is solved by Newton's method with the constraints'
    /// geometric stiffness (see `implicit.rs`) to [`PROJECTION_TOL`]; with post-stabilisation
    /// on ([`Self::set_stabilization`]) the velocities are then projected onto `J v = 0` at the
    /// new positions. Multiplier formulation only.
    ///
    /// # Errors
    /// A bad `dt`, the penalty formulation, a projection that does not converge (a step so
    /// large that the free motion leaves the constraints beyond the linearisation, or
    /// conflicting constraints), a solver failure, a custom constraint's failure or a
    /// non-finite state; the particles are left at the last good step.
    pub fn step_projection(
        &mut self,
        particles: &mut ParticleSystem,
        dt: f64,
        steps: usize,
    ) -> Result<()> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(Error::invalid("dt", format!("must be positive and finite, got {dt}")));
        }
        if self.formulation != Formulation::Multipliers {
            return Err(Error::invalid(
                "method",
                "projection needs the multiplier formulation, not penalty",
            ));
        }
        let n = particles.capacity();
        self.prepare(n)?;
        let mut next = std::mem::take(&mut self.work.next);
        next.resize(6 * n, 0.0);
        let result = self.projection_steps(particles, dt, steps, &mut next);
        self.work.next = next;
        result
    }

    /// The steps of [`Self::step_projection`], with `next` (`6 n` values) for the state being
    /// built.
    fn projection_steps(
        &mut self,
        particles: &mut ParticleSystem,
        dt: f64,
        steps: usize,
        next: &mut [f64],
    ) -> Result<()> {
        let n = particles.capacity();
        let (mut system, y, time) = assemble(self, particles);
        system.ks = 0.0;
        system.kd = 0.0;
        for s in 0..steps {
            let w = &mut *system.work;
            w.saved.0.clone_from(&w.implicit_lambda);
            let result = projection_step(&mut system, *time, y, dt, next).and_then(|()| match next
                .iter()
                .position(|v| !v.is_finite())
            {
                Some(bad) => Err(Error::Diverged {
                    step: s,
                    index: (bad % (3 * n)) / 3,
                    reason: "non-finite state in the constraint projection".into(),
                }),
                None => Ok(()),
            });
            if let Err(e) = result {
                let w = &mut *system.work;
                w.implicit_lambda.clone_from(&w.saved.0);
                return Err(e);
            }
            // On failure the tracked parameters may have moved on: they are only the starting
            // guesses of the closest-point search, so the particles' state is what is kept.
            track_curves(system.constraints, next, &mut system.work.curves)?;
            y.copy_from_slice(next);
            *time += dt;
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

/// The constrained equations of motion over `particles`, with the particle state and clock.
fn assemble<'a>(
    system: &'a mut ConstrainedSystem,
    particles: &'a mut ParticleSystem,
) -> (Constrained<'a>, &'a mut [f64], &'a mut f64) {
    let (free, y, inv_mass, time) = particles.parts();
    let equations = Constrained {
        free,
        constraints: &system.constraints,
        inv_mass,
        ks: system.ks,
        kd: system.kd,
        formulation: system.formulation,
        solver: system.solver,
        stabilize: system.stabilize,
        work: &mut system.work,
    };
    (equations, y, time)
}

/// One step of [`ConstrainedSystem::step_projection`] from `y = [x; v]` at `time` into `next`:
/// the free step `x̃ = x + h (v + h a_free)`, its implicit projection, `v₁ = (x₁ - x₀) / h`,
/// and with post-stabilisation the velocity projection onto `J v = 0`.
fn projection_step(
    system: &mut Constrained<'_>,
    time: f64,
    y: &[f64],
    dt: f64,
    next: &mut [f64],
) -> Result<()> {
    let n = y.len() / 6;
    // next = [v; a_free].
    system.free.rhs(time, y, next)?;
    for k in 0..3 * n {
        next[k] = y[k] + dt * (y[3 * n + k] + dt * next[3 * n + k]);
    }
    system.implicit_projection(next, dt)?;
    for k in 0..3 * n {
        next[3 * n + k] = (next[k] - y[k]) / dt;
    }
    if system.stabilize {
        system.project_velocities(next)?;
    }
    Ok(())
}

/// Move every curve's tracked parameter to the closest point at the state `y`, and pick a new
/// frame reference where the tangent came near the old one.
fn track_curves(constraints: &[Constraint], y: &[f64], curves: &mut [(f64, DVec3)]) -> Result<()> {
    for (c, state) in constraints.iter().zip(curves) {
        if let Constraint::OnCurve { i, curve } = c {
            let x = DVec3::from_slice(&y[3 * i..]);
            let u = curve.closest(x, state.0).map_err(|e| at_particle(e, *i))?;
            let t = curve.eval(u)[1].normalize();
            let reference = if state.1.dot(t).abs() > 0.9 { curve.reference(u) } else { state.1 };
            *state = (u, reference);
        }
    }
    Ok(())
}

/// Evaluate every constraint row at `y = [x; v]`, with the curves' tracked parameters as
/// starting guesses.
fn evaluate(
    constraints: &[Constraint],
    curves: &[(f64, DVec3)],
    y: &[f64],
    n: usize,
    rows: &mut Rows,
) -> Result<()> {
    rows.clear();
    let x = |i: usize| DVec3::from_slice(&y[3 * i..]);
    let v = |i: usize| DVec3::from_slice(&y[3 * n + 3 * i..]);
    for (c, &(guess, reference)) in constraints.iter().zip(curves) {
        match c {
            &Constraint::Distance { i, j, length } => {
                let d = x(i) - x(j);
                let len = d.length();
                let dir = if len > 0.0 { d / len } else { DVec3::X };
                let vij = v(i) - v(j);
                let along = dir.dot(vij);
                let jdot =
                    if len > 0.0 { (vij.length_squared() - along * along) / len } else { 0.0 };
                rows.push([(i, dir), (j, -dir)], len - length, jdot, v);
            }
            &Constraint::OnSphere { i, center, radius } => {
                let d = x(i) - center;
                let len = d.length();
                let dir = if len > 0.0 { d / len } else { DVec3::X };
                let along = dir.dot(v(i));
                let jdot =
                    if len > 0.0 { (v(i).length_squared() - along * along) / len } else { 0.0 };
                rows.push([(i, dir)], len - radius, jdot, v);
            }
            &Constraint::OnPlane { i, point, normal } => {
                rows.push([(i, normal)], normal.dot(x(i) - point), 0.0, v);
            }
            &Constraint::Fixed { i, point } => {
                for k in 0..3 {
                    rows.push([(i, DVec3::AXES[k])], x(i)[k] - point[k], 0.0, v);
                }
            }
            Constraint::OnCurve { i, curve } => {
                let i = *i;
                let u = curve.closest(x(i), guess).map_err(|e| at_particle(e, i))?;
                let [p, dp, ddp] = curve.eval(u);
                let d = x(i) - p;
                let speed2 = dp.length_squared();
                let denom = speed2 - ddp.dot(d);
                if !(denom.is_finite() && denom > 0.0) {
                    return Err(Error::SolverFailed {
                        reason: format!(
                            "particle {i} is farther from its curve than the radius of \
                             curvature; the closest point is not unique"
                        ),
                    });
                }
                let speed = speed2.sqrt();
                let t = dp / speed;
                let t_u = (ddp - t.dot(ddp) * t) / speed; // dt̂/du
                let m = reference.cross(t);
                let m_len = m.length();
                let n1 = m / m_len;
                let w = reference.cross(t_u) / m_len;
                let n1_u = w - n1.dot(w) * n1;
                let n2 = t.cross(n1);
                let n2_u = t_u.cross(n1) + t.cross(n1_u);
                let grad_u = dp / denom;
                let u_dot = grad_u.dot(v(i));
                let d_dot = v(i) - u_dot * dp;
                for (nk, nk_u) in [(n1, n1_u), (n2, n2_u)] {
                    let g = nk + d.dot(nk_u) * grad_u;
                    rows.push([(i, g)], nk.dot(d), u_dot * nk_u.dot(v(i) + d_dot), v);
                }
            }
            Constraint::Custom { particles, function } => {
                let (k, m) = (particles.len(), function.rows());
                let mut scratch = std::mem::take(&mut rows.scratch);
                scratch.resize(3 * k * (1 + 3 * m) + m, 0.0);
                let (xs, rest) = scratch.split_at_mut(3 * k);
                let (value, rest) = rest.split_at_mut(m);
                let (grad, rest) = rest.split_at_mut(3 * k * m);
                let (grad_plus, grad_minus) = rest.split_at_mut(3 * k * m);
                let mut scale = 1.0_f64;
                let mut speed = 0.0_f64;
                for (a, &p) in particles.iter().enumerate() {
                    xs[3 * a..3 * a + 3].copy_from_slice(&x(p).to_array());
                    scale = scale.max(x(p).abs().max_element());
                    speed = speed.max(v(p).abs().max_element());
                }
                let result = custom_rows(
                    function.as_ref(),
                    particles,
                    [xs, value, grad, grad_plus, grad_minus],
                    scale,
                    speed,
                    &v,
                );
                match result {
                    Ok(()) => {
                        for r in 0..m {
                            let blocks = particles
                                .iter()
                                .enumerate()
                                .map(|(a, &p)| (p, DVec3::from_slice(&grad[3 * k * r + 3 * a..])));
                            let jdot: f64 = particles
                                .iter()
                                .enumerate()
                                .map(|(a, &p)| {
                                    let o = 3 * k * r + 3 * a;
                                    (DVec3::from_slice(&grad_plus[o..])
                                        - DVec3::from_slice(&grad_minus[o..]))
                                    .dot(v(p))
                                })
                                .sum();
                            rows.push(blocks, value[r], jdot, v);
                        }
                        rows.scratch = scratch;
                    }
                    Err(e) => {
                        rows.scratch = scratch;
                        return Err(e);
                    }
                }
            }
        }
    }
    Ok(())
}

/// Value and gradient of a custom constraint at `xs`, and `grad_plus`, `grad_minus` =
/// `∇C(x ± εv) / (2ε)`, so that `(grad_plus - grad_minus) · v` is the central difference of
/// `J̇ q̇` (both zero when nothing moves). `xs` is left shifted.
fn custom_rows(
    function: &dyn ConstraintFunction,
    particles: &[usize],
    [xs, value, grad, grad_plus, grad_minus]: [&mut [f64]; 5],
    scale: f64,
    speed: f64,
    v: &impl Fn(usize) -> DVec3,
) -> Result<()> {
    function.value(xs, value)?;
    function.gradient(xs, grad)?;
    if speed > 0.0 {
        let eps = f64::EPSILON.cbrt() * scale / speed;
        let shift = |xs: &mut [f64], by: f64| {
            for (a, &p) in particles.iter().enumerate() {
                for (c, vc) in v(p).to_array().iter().enumerate() {
                    xs[3 * a + c] += by * vc;
                }
            }
        };
        shift(xs, eps);
        function.gradient(xs, grad_plus)?;
        shift(xs, -2.0 * eps);
        function.gradient(xs, grad_minus)?;
        for g in grad_plus.iter_mut().chain(grad_minus.iter_mut()) {
            *g /= 2.0 * eps;
        }
    } else {
        grad_plus.fill(0.0);
        grad_minus.fill(0.0);
    }
    if [&*value, &*grad, &*grad_plus, &*grad_minus].iter().any(|s| s.iter().any(|g| !g.is_finite()))
    {
        return Err(Error::invalid("value", "a custom constraint returned NaN or infinity"));
    }
    Ok(())
}

impl Constrained<'_> {
    /// Post-stabilisation of `y = [x; v]` (Cline & Pai 2003): Gauss–Newton projections of the
    /// positions onto `C(x) = 0` in the mass metric, `(J W Jᵀ + εI) δ = -C`, `x += W Jᵀ δ`,
    /// until `max |C| ≤` [`PROJECTION_TOL`] (or, far from the origin, 64 ulps of the largest
    /// coordinate) over the rows that act on a particle of finite mass, then the velocities onto `J v = 0` at the projected positions,
    /// `(J W Jᵀ + εI) μ = -J v`, `v += W Jᵀ μ`. `y` may be left part-way on failure (the
    /// callers restore it).
    ///
    /// # Errors
    /// No convergence in [`PROJECTION_ITERATIONS`] projections (conflicting constraints, which
    /// have no point with `C = 0`, or a step too large for the linearisation), a solver failure
    /// or a constraint's failure.
    fn project_positions(&mut self, y: &mut [f64]) -> Result<()> {
        let n = y.len() / 6;
        let largest = y[..3 * n].iter().fold(0.0_f64, |a, &b| a.max(b.abs()));
        let tol = PROJECTION_TOL.max(64.0 * f64::EPSILON * largest);
        let inv_mass = self.inv_mass;
        for iteration in 0.. {
            evaluate(self.constraints, &self.work.curves, y, n, &mut self.work.rows)?;
            let w = &mut *self.work;
            // Rows on pinned particles only cannot be moved, so they are not waited for.
            let worst = (0..w.rows.rows.len())
                .filter(|&r| w.rows.blocks(r).iter().any(|&(p, _)| inv_mass[p] > 0.0))
                .fold(0.0_f64, |a, r| a.max(w.rows.rows[r].c.abs()));
            if worst <= tol {
                break;
            }
            if iteration == PROJECTION_ITERATIONS {
                return Err(Error::SolverFailed {
                    reason: format!(
                        "the position projection left max |C| = {worst:.3e} after \
                         {PROJECTION_ITERATIONS} iterations: the constraints conflict, or \
                         the step is too large (lower dt)"
                    ),
                });
            }
            for (b, row) in w.b.iter_mut().zip(&w.rows.rows) {
                *b = -row.c;
            }
            self.apply_correction(y, 0)?;
        }
        Ok(())
    }

    /// Post-stabilisation of the velocities of `y = [x; v]` (Cline & Pai 2003): onto
    /// `J v = 0` at the positions of `y`, `(J W Jᵀ + εI) μ = -J v`, `v += W Jᵀ μ`.
    ///
    /// # Errors
    /// A solver failure or a constraint's failure.
    fn project_velocities(&mut self, y: &mut [f64]) -> Result<()> {
        let n = y.len() / 6;
        evaluate(self.constraints, &self.work.curves, y, n, &mut self.work.rows)?;
        let w = &mut *self.work;
        for (b, row) in w.b.iter_mut().zip(&w.rows.rows) {
            *b = -row.cdot;
        }
        self.apply_correction(y, 3 * n)
    }

    /// Solve for the multipliers of the right-hand side in the workspace and add `W Jᵀ λ` to
    /// the block of `y` at `offset` (0: positions, `3 n`: velocities).
    fn apply_correction(&mut self, y: &mut [f64], offset: usize) -> Result<()> {
        self.solve_multipliers()?;
        let (w, inv_mass) = (&*self.work, self.inv_mass);
        for r in 0..w.rows.rows.len() {
            for &(p, g) in w.rows.blocks(r) {
                let d = inv_mass[p] * w.lambda[r] * g;
                for k in 0..3 {
                    y[offset + 3 * p + k] += d[k];
                }
            }
        }
        Ok(())
    }

    /// Solve `(J W Jᵀ + εI) λ = b` for the rows and right-hand side in the workspace.
    fn solve_multipliers(&mut self) -> Result<()> {
        let inv_mass = self.inv_mass;
        let w = &mut *self.work;
        for r in 0..w.rows.rows.len() {
            w.diag[r] =
                w.rows.blocks(r).iter().map(|&(p, g)| inv_mass[p] * g.length_squared()).sum();
        }
        let eps = 1e-10 * w.diag.iter().fold(1.0_f64, |a, &b| a.max(b));
        match self.solver {
            ConstraintSolver::Cholesky => {
                w.values.fill(0.0);
                let block = |r: usize, p: usize| {
                    w.rows.blocks(r).iter().filter(|b| b.0 == p).map(|b| b.1).sum::<DVec3>()
                };
                for &(idx, r, s, p) in &w.contributions {
                    w.values[idx] += inv_mass[p] * block(r, p).dot(block(s, p));
                }
                for &k in &w.diagonal_index {
                    w.values[k] += eps;
                }
                let chol = w.chol.as_mut().expect("pattern built before stepping");
                chol.factorize(&w.values)?;
                w.lambda.copy_from_slice(&w.b);
                chol.solve_in_place(&mut w.lambda);
                w.iterations = 0;
            }
            ConstraintSolver::ConjugateGradient => {
                let (rows, scratch) = (&w.rows, &mut w.scratch);
                let mut apply = |x: &[f64], out: &mut [f64]| {
                    // out = (J W Jᵀ + εI) x, matrix-free.
                    scratch.fill(0.0);
                    for (r, xr) in x.iter().enumerate() {
                        for &(p, g) in rows.blocks(r) {
                            for k in 0..3 {
                                scratch[3 * p + k] += g[k] * xr;
                            }
                        }
                    }
                    for (r, o) in out.iter_mut().enumerate() {
                        *o = eps * x[r]
                            + rows
                                .blocks(r)
                                .iter()
                                .map(|&(p, g)| {
                                    inv_mass[p] * g.dot(DVec3::from_slice(&scratch[3 * p..]))
                                })
                                .sum::<f64>();
                    }
                };
                let mut pre = std::mem::take(&mut w.cg);
                let mut lambda = std::mem::take(&mut w.lambda);
                let result = conjugate_gradient(
                    &mut apply,
                    &w.b,
                    &w.diag,
                    &mut lambda,
                    1e-12,
                    10 * w.b.len() + 100,
                    &mut pre,
                );
                w.cg = pre;
                w.lambda = lambda;
                w.iterations = result?;
            }
        }
        Ok(())
    }
}

/// The constrained equations of motion as an [`OdeSystem`].
struct Constrained<'a> {
    free: crate::particles::Dynamics<'a>,
    constraints: &'a [Constraint],
    inv_mass: &'a [f64],
    ks: f64,
    kd: f64,
    formulation: Formulation,
    solver: ConstraintSolver,
    stabilize: bool,
    work: &'a mut Work,
}

impl OdeSystem for Constrained<'_> {
    fn dim(&self) -> usize {
        self.free.dim()
    }

    fn rhs(&mut self, t: f64, y: &[f64], dydt: &mut [f64]) -> Result<()> {
        self.free.rhs(t, y, dydt)?;
        let n = y.len() / 6;
        let w = &mut *self.work;
        evaluate(self.constraints, &w.curves, y, n, &mut w.rows)?;
        let (acc, inv_mass) = (&mut dydt[3 * n..], self.inv_mass);
        if let Formulation::Penalty { stiffness, damping } = self.formulation {
            // a += W (-k C - c Ċ) ∇C per row.
            for (r, row) in w.rows.rows.iter().enumerate() {
                let f = -(stiffness * row.c + damping * row.cdot);
                for &(p, g) in w.rows.blocks(r) {
                    let a = inv_mass[p] * f * g;
                    for k in 0..3 {
                        acc[3 * p + k] += a[k];
                    }
                }
            }
            return Ok(());
        }
        // b = -J̇q̇ - J a_free - ks C - kd Ċ.
        for (r, row) in w.rows.rows.iter().enumerate() {
            let ja: f64 = w
                .rows
                .blocks(r)
                .iter()
                .map(|&(p, g)| g.dot(DVec3::from_slice(&acc[3 * p..])))
                .sum();
            w.b[r] = -row.jdot_qdot - ja - self.ks * row.c - self.kd * row.cdot;
        }
        self.solve_multipliers()?;
        let w = &mut *self.work;
        // a += W Jᵀ λ.
        for r in 0..w.rows.rows.len() {
            for &(p, g) in w.rows.blocks(r) {
                let f = inv_mass[p] * w.lambda[r] * g;
                for k in 0..3 {
                    acc[3 * p + k] += f[k];
                }
            }
        }
        Ok(())
    }
}
