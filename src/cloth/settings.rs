//! The cloth's parameter types: the elastic model, the material, vertex constraints, the
//! options of a step and the numbers a step reports.

use glam::DVec3;

/// The elastic model of the cloth (the force law of its elements).
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Elasticity {
    /// Baraff–Witkin triangle conditions (stretch, shear) and dihedral-angle bending.
    BaraffWitkin,
    /// Stretch and shear springs on edges and across quads, bend springs across the other
    /// interior edges, each with a damper.
    MassSpring,
}

/// Material parameters (Baraff & Witkin 1998, §4; SI units as given per field).
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Areal density (kg/m²).
    pub density: f64,
    /// Stretch stiffness (N/m): membrane stiffness for the triangle model (energy
    /// `stretch/2 · a (‖w‖ - 1)²` per triangle), spring constant for stretch springs.
    pub stretch: f64,
    /// Shear stiffness (N/m), same meaning for the shear condition and shear springs.
    pub shear: f64,
    /// Bending stiffness (N m): hinge stiffness `bend · 3|e|²/(A₁ + A₂)` (the discrete-shells
    /// scaling, Grinspun et al. 2003) for the triangle model, `bend / L²` for bend springs.
    pub bend: f64,
    /// Stiffness-proportional damping (s): every condition gets `k_d = damping · k`.
    pub damping: f64,
    /// Mass-proportional (air) damping (1/s): a force `-air_damping · mᵢ vᵢ` on every vertex.
    /// With `damping` it makes Rayleigh damping `α M + β K`.
    pub air_damping: f64,
}

/// A cotton-like cloth (issue #21): 1 kg/m², stretch 1e4 N/m, shear 1e3 N/m, bending
/// 1e-3 N m, damping 0.1 s, no air damping (as `kinema.cloth.MATERIAL`).
impl Default for Material {
    fn default() -> Self {
        Material {
            density: 1.0,
            stretch: 1e4,
            shear: 1e3,
            bend: 1e-3,
            damping: 0.1,
            air_damping: 0.0,
        }
    }
}

/// The linear solver of the implicit step.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinearSolver {
    /// Prefiltered preconditioned conjugate gradient with the smoothed aggregation multigrid
    /// preconditioner (Tamstorf, Jones & McCormick 2015).
    Multigrid,
    /// Modified preconditioned conjugate gradient with the filter (Baraff & Witkin §5.3) and
    /// the block SSOR preconditioner.
    BlockSsor,
    /// Sparse Cholesky (faer) of the filtered SPD system, exact to rounding ([`SolveOptions`]'
    /// default: faster than multigrid PCG at tol 1e-6 at every measured size, 32² to 256²).
    Cholesky,
}

/// A user constraint on one vertex.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub enum VertexConstraint {
    /// Held at a position (m).
    Pinned(DVec3),
    /// Free to move in the plane through its position with this unit normal.
    Plane(DVec3),
    /// Free to move along the line through its position with this unit direction.
    Line(DVec3),
    /// Moving at a prescribed velocity (m/s).
    Velocity(DVec3),
}

/// Numbers of the last step.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, Default, PartialEq)]
pub struct StepStats {
    /// Conjugate-gradient iterations (0 for Cholesky and explicit steps).
    pub iterations: usize,
    /// Relative residual of the linear solve: `sqrt(δ/δ₀)` for PCG, `‖S(A Δv - b)‖/‖S b‖` for
    /// Cholesky.
    pub residual: f64,
    /// Whether the solve met its tolerance (PCG may stop at its iteration limit).
    pub converged: bool,
    /// Vertices in contact with a collider.
    pub contacts: usize,
    /// Implicit steps taken (more than one when the step was subdivided).
    pub substeps: usize,
    /// Newton iterations (solves beyond the first of a substep, after the release of pulling
    /// contacts) taken where the one linearised solve added energy (issue #21).
    pub newton_iterations: usize,
    /// Seconds spent assembling forces and the matrix.
    pub assemble_seconds: f64,
    /// Seconds in the linear solve.
    pub solve_seconds: f64,
    /// Seconds in collision detection and response against colliders.
    pub collide_seconds: f64,
    /// Self-collision: vertex–triangle and edge–edge pairs closer than the thickness at the
    /// start of the step, given repulsion impulses (Bridson et al. 2002, §7.2).
    pub proximities: usize,
    /// Self-collision: passes of continuous collision detection that found collisions and
    /// applied impulses (§7.3).
    pub ccd_iterations: usize,
    /// Self-collision: rigid impact zones of two or more vertices formed (§7.4; 0 when the
    /// impulses resolved every collision).
    pub impact_zones: usize,
    /// Seconds in self-collision.
    pub self_collision_seconds: f64,
}

/// Self-collision of the cloth (Bridson, Fedkiw & Anderson 2002): proximity repulsions with
/// friction, continuous collision detection with iterated impulses, rigid impact zones. The
/// distances are set by the model's thickness ([`super::Model::thickness`]).
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct SelfCollision {
    /// Coulomb friction coefficient between touching layers of the cloth (>= 0).
    pub friction: f64,
    /// Passes of continuous collision detection with impulses before the remaining collisions
    /// are resolved by rigid impact zones (0 goes straight to impact zones).
    pub iterations: usize,
}

impl Default for SelfCollision {
    fn default() -> Self {
        SelfCollision { friction: 0.1, iterations: 8 }
    }
}

/// Options of an implicit step.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct SolveOptions {
    /// The linear solver.
    pub solver: LinearSolver,
    /// PCG tolerance `ε` (relative, preconditioned norm).
    pub tol: f64,
    /// PCG iteration limit.
    pub max_iterations: usize,
    /// The largest change of any stretch ratio (`‖w_u‖`, `‖w_v‖`, or `l/L` of a spring) one
    /// step may make, measured on the positions it would commit (after the strain limit of
    /// `max_strain`); a step that exceeds it is redone as two half steps (Baraff & Witkin §5:
    /// the step size is cut when a step stretches the cloth too much), down to `h / 32`.
    pub max_strain_change: f64,
    /// Strain limit: after the solve, mesh edges longer than `1 + max_strain` times their rest
    /// length are shortened to it (Provot 1995) in Gauss–Seidel sweeps ordered outward from
    /// the constrained vertices, which move the end farther from them, until none exceeds it
    /// by more than 10⁻⁴ (at most 64 sweeps; 2–16 measured at 128², docs/cloth.md, "Strain
    /// limiting"). Default 0.03, `inf` turns it off.
    pub max_strain: f64,
}

impl Default for SolveOptions {
    fn default() -> Self {
        SolveOptions {
            solver: LinearSolver::Cholesky,
            tol: 1e-6,
            max_iterations: 1000,
            max_strain_change: 0.01,
            max_strain: 0.03,
        }
    }
}
