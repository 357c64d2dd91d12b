//! The constraint model: what every step reads and no step changes — the constraints, the
//! drift feedback gains, the formulation, the linear solver's kind and whether steps end with
//! post-stabilisation. Built by [`Model::new`] or [`Model::penalty`] and [`Model::add`], each
//! of which validates what it takes.

use super::{Constraint, ConstraintSolver, Formulation};
use crate::error::{Error, Result};

/// A constraint model (see the module docs): read-only during a step (`&Model`); several
/// [`super::State`]s, each with the particle state it constrains, may share it.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub struct Model {
    pub(super) constraints: Vec<Constraint>,
    /// Feedback stiffness `k_s` on the drift `C` (1/s²), multiplier formulation.
    pub(super) ks: f64,
    /// Feedback damping `k_d` on `Ċ` (1/s), multiplier formulation.
    pub(super) kd: f64,
    pub(super) formulation: Formulation,
    pub(super) solver: ConstraintSolver,
    /// Post-stabilisation after every step (multipliers only).
    pub(super) stabilize: bool,
}

impl Model {
    /// No constraints yet, multiplier formulation with feedback gains `ks` (1/s²), `kd` (1/s)
    /// (0 turns feedback off), the linear solver `solver` and post-stabilisation on
    /// ([`Model::set_stabilization`]).
    ///
    /// # Errors
    /// Negative or non-finite gains (argument `ks`).
    pub fn new(ks: f64, kd: f64, solver: ConstraintSolver) -> Result<Self> {
        if !(ks.is_finite() && kd.is_finite() && ks >= 0.0 && kd >= 0.0) {
            return Err(Error::invalid("ks", "feedback gains must be finite and >= 0"));
        }
        Ok(Model {
            constraints: Vec::new(),
            ks,
            kd,
            formulation: Formulation::Multipliers,
            solver,
            stabilize: true,
        })
    }

    /// No constraints yet, penalty formulation: every row adds the force
    /// `-stiffness C ∇C - damping Ċ ∇C` (N; `stiffness` in N/m, `damping` in N s/m) instead
    /// of a multiplier solve; no post-stabilisation.
    ///
    /// # Errors
    /// A stiffness that is not positive and finite, a negative or non-finite damping (each
    /// named).
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
        let mut model = Model::new(0.0, 0.0, ConstraintSolver::Cholesky)?;
        model.formulation = Formulation::Penalty { stiffness, damping };
        model.stabilize = false;
        Ok(model)
    }
}

impl Model {
    /// Turn post-stabilisation (Cline & Pai 2003, "Post-stabilization for rigid body
    /// simulation with contact and constraints", ICRA) on or off. On (the default with
    /// multipliers), every step of [`super::Solver::step`] ends by
    /// projecting the positions onto `C(x) = 0` in the mass metric, `(J W Jᵀ) δ = -C`,
    /// `x += W Jᵀ δ` (Gauss–Newton, at most [`super::PROJECTION_ITERATIONS`] times, until
    /// `|C| ≤` [`super::PROJECTION_TOL`]), and the velocities onto `J v = 0` at the new
    /// positions, `(J W Jᵀ) μ = -J v`, `v += W Jᵀ μ`, with the same sparse solve as the
    /// multipliers. The corrections are of the size of one step's drift, so the integrator
    /// keeps its order, and the constraints hold to `PROJECTION_TOL` at any step; the
    /// velocity projection removes the kinetic energy of the constraint-violating velocity (at
    /// most that of the drift rate, `½ Ċᵀ (J W Jᵀ)⁻¹ Ċ`). Off, the constraints hold only
    /// through `ks`, `kd` and the accuracy of the integrator.
    /// [`super::Solver::step_projection`] always ends on `C(x) = 0` (its step is a
    /// projection); post-stabilisation adds the velocity projection.
    ///
    /// # Errors
    /// `on` with the penalty formulation (whose springs are the constraint model; argument
    /// `stabilize`).
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

    /// Add a constraint on the particles of states of `particles`, checked (a plane's normal
    /// made unit). What depends on where the particles are (a rod between coincident
    /// particles, a curve's closest point, a custom function's value) is checked by
    /// [`super::State::new`].
    ///
    /// # Errors
    /// Indices out of range (argument `i`), a distance constraint between a particle and
    /// itself, non-positive lengths or radii, zero normals, non-finite values, a degenerate
    /// curve, a custom constraint without particles, with repeated particles or without rows.
    pub fn add(
        &mut self,
        particles: &crate::particles::Model,
        constraint: Constraint,
    ) -> Result<()> {
        let n = particles.capacity();
        for p in constraint.particles() {
            if p >= n {
                return Err(Error::invalid(
                    "i",
                    format!("particle {p} out of range ({n} particles)"),
                ));
            }
        }
        self.constraints.push(constraint.checked()?);
        Ok(())
    }

    /// Feedback stiffness `k_s` on the drift `C` (1/s²), multiplier formulation.
    pub fn ks(&self) -> f64 {
        self.ks
    }

    /// Feedback damping `k_d` on `Ċ` (1/s), multiplier formulation.
    pub fn kd(&self) -> f64 {
        self.kd
    }

    /// How the constraints act.
    pub fn formulation(&self) -> Formulation {
        self.formulation
    }

    /// Which linear solver computes the multipliers.
    pub fn solver(&self) -> ConstraintSolver {
        self.solver
    }

    /// Whether post-stabilisation is on ([`Model::set_stabilization`]).
    pub fn stabilization(&self) -> bool {
        self.stabilize
    }

    /// The constraints, in the order added.
    pub fn constraints(&self) -> &[Constraint] {
        &self.constraints
    }

    /// Number of scalar constraint rows (the multipliers of a state).
    pub fn rows(&self) -> usize {
        self.constraints.iter().map(Constraint::rows).sum()
    }

    /// Whether a [`Constraint::Custom`] is present (its function may need a lock, e.g. the GIL).
    pub fn has_custom(&self) -> bool {
        self.constraints.iter().any(|c| matches!(c, Constraint::Custom { .. }))
    }

    /// A deterministic 64-bit hash of the model ([`crate::snapshot::fingerprint`]), recorded
    /// by state snapshots so that a state is not restored onto another model. A model with a
    /// [`Constraint::Custom`] hashes the constraints before the first custom one.
    pub fn fingerprint(&self) -> u64 {
        crate::snapshot::fingerprint(self)
    }

    /// Check that every constraint's particles are among the `n` slots of a particle system.
    /// Allocates nothing: every step calls it.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] (argument `"particles"`) naming the first constraint that
    /// refers to a particle `>= n`.
    pub fn check_particles(&self, n: usize) -> Result<()> {
        let highest = |c: &Constraint| match c {
            Constraint::Distance { i, j, .. } => *i.max(j),
            Constraint::OnSphere { i, .. }
            | Constraint::OnPlane { i, .. }
            | Constraint::Fixed { i, .. }
            | Constraint::OnCurve { i, .. } => *i,
            Constraint::Custom { particles, .. } => particles.iter().copied().max().unwrap_or(0),
        };
        match self.constraints.iter().position(|c| highest(c) >= n) {
            None => Ok(()),
            Some(k) => Err(Error::invalid(
                "particles",
                format!("constraint {k} refers to a particle beyond the {n} slots"),
            )),
        }
    }
}
