//! Cloth: the Baraff–Witkin (1998) "Large Steps in Cloth Simulation" triangle model and a
//! mass-spring model, stepped by implicit Euler with one Newton step (the paper's method),
//! BDF2 (Choi & Ko 2002), or any explicit method of [`crate::ode`] for comparison.
//!
//! An implicit step solves `A Δv = b` with
//! `A = M - h ∂f/∂v - h² ∂f/∂x`, `b = h (f₀ + ∂f/∂x (h v₀ + y))` (Baraff & Witkin 1998,
//! eqs. 15–18; `y` is the collision position correction of §6), assembled into a block-sparse
//! matrix ([`bsr::BlockMatrix`]) whose pattern is built once. BDF2 solves the same system
//! with `h` replaced by `2h/3` and the history terms of Choi & Ko (2002), eq. 12, at a
//! constant step, and with the variable-step coefficients of [`crate::ode::bdf2_weights`]
//! (`γh` and `c (x - x₋)`) after a change of step.
//!
//! Constraints are imposed by mass modification (§5.3): each vertex has a filter `S_i`
//! (identity when free, `I - n̂n̂ᵀ` on a plane, `d̂d̂ᵀ` on a line, 0 when pinned) and a
//! prescribed velocity change `z_i` in the constrained directions. The three solvers:
//! - [`LinearSolver::Cholesky`] (the default): faer's sparse Cholesky on the equivalent SPD
//!   system `(S A S + I - S) y = S (b - A z)`, `Δv = z + y`, whose symbolic factorisation is
//!   computed on first use and reused every step; exact to rounding, and on the hanging sheet
//!   and the drape at the default material 2–5x faster than multigrid PCG at tol 1e-6 from
//!   32² to 256² (docs/cloth.md);
//! - [`LinearSolver::Multigrid`]: the paper's modified preconditioned conjugate gradient,
//!   which keeps every iterate in `z + range(S)`, preconditioned by smoothed aggregation
//!   multigrid (Tamstorf, Jones & McCormick 2015), whose iteration count does not grow with
//!   the resolution or the stiffness;
//! - [`LinearSolver::BlockSsor`]: the same conjugate gradient with the stopping rule
//!   `δ < ε² δ₀` on the preconditioned residual and a block SSOR preconditioner
//!   (over-relaxed symmetric Gauss–Seidel, `ω` growing with the mesh, applied by Eisenstat's
//!   trick) instead of the paper's block-Jacobi: a third of the iterations or fewer at about
//!   the same cost per iteration (the flops of one matrix product).
//!
//! Collisions with planes, spheres and capsules (which may move at constant velocity) become
//! constraints too (§6): a vertex whose predicted position comes within `2 thickness` of a
//! surface is held to end the step at `thickness` from it — a vertex above the surface gets
//! the normal velocity that lands it there, one below moves with the surface and the position
//! correction `y` lifts it out. Coulomb friction is an explicit force: the tangential impulse
//! that would bring the vertex to rest on the surface within the step (against its momentum
//! and gravity), limited to `μ jₙ` with `jₙ` the normal constraint impulse of the last step,
//! read from the residual `A Δv - b` (§5.3) — static friction when the limit is not reached,
//! sliding otherwise. A contact whose normal
//! impulse pulls is released and the solve taken again, once, without it. Vertices dragged into a collider by their neighbours are
//! projected out after the step.
//!
//! Self-collision (off by default) filters the motion of every implicit step after the solve
//! (Bridson, Fedkiw & Anderson 2002): proximity repulsions with friction, continuous collision
//! detection with iterated impulses, and rigid impact zones, on a bounding volume hierarchy
//! refit each step ([`Model::set_self_collision`], [`SelfCollision`]).

//!
//! The cloth takes the shape of every kinema system: a [`Model`] built once from the mesh
//! (topology, masses, elements, material, parameters), a [`State`] of what changes in time
//! (positions, velocities, time, BDF2 history, warm starts, constraints, colliders), and a
//! [`Solver`] that owns every workspace and advances `(model, state)`. [`Cloth`] composes the
//! three for the Python class.

mod bsr;
mod build;
mod bvh;
mod collide;
mod elements;
mod explicit;
mod forces;
mod implicit;
mod linear;
mod mesh;
mod mesh_collider;
mod model;
mod multigrid;
mod pcg;
mod self_collide;
mod settings;
mod snapshot;
mod solver;
mod state;
mod strain_limit;

pub use bsr::BlockMatrix;
pub use collide::Collider;
pub use elements::dihedral_angle;
pub use mesh::{parse_obj, uv_from_shape, write_obj, Mesh, Topology, Triangulation};
pub use mesh_collider::MeshCollider;
pub use model::Model;
pub use self_collide::MIN_DISTANCE;
pub use settings::{
    Elasticity, LinearSolver, Material, SelfCollision, SolveOptions, StepStats, VertexConstraint,
};
pub use solver::Solver;
pub use state::State;

use crate::error::Result;
use crate::ode::Method;
use collide::ContactState;
use glam::DVec3;

/// A piece of cloth: its [`Model`], one [`State`] and a [`Solver`], the object the Python
/// class `kinema.cloth.Cloth` binds to. Every method delegates to one of the three.
pub struct Cloth {
    model: Model,
    state: State,
    solver: Solver,
}

impl std::fmt::Debug for Cloth {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "Cloth({} vertices, {} triangles, {:?})",
            self.model.len(),
            self.model.triangles.len(),
            self.model.elasticity
        )
    }
}

impl Cloth {
    /// A cloth on `mesh` ([`Model::new`]) in its initial state ([`Model::state`]).
    ///
    /// # Errors
    /// An invalid mesh ([`Mesh::validate`]) or material (negative, non-finite, or zero density
    /// or stretch), or non-finite gravity.
    pub fn new(
        mesh: Mesh,
        elasticity: Elasticity,
        material: Material,
        gravity: DVec3,
    ) -> Result<Cloth> {
        Ok(Cloth::from_model(Model::new(mesh, elasticity, material, gravity)?))
    }

    /// `model` in its initial state, with a new solver.
    pub fn from_model(model: Model) -> Cloth {
        let (state, solver) = (model.state(), Solver::new(&model));
        Cloth { model, state, solver }
    }

    /// The model.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The state.
    pub fn state(&self) -> &State {
        &self.state
    }

    /// The state, to change (e.g. `clone_from` a state of the same model: its buffers are
    /// copied into, so views of the positions and velocities stay valid).
    pub fn state_mut(&mut self) -> &mut State {
        &mut self.state
    }

    /// Number of vertices.
    pub fn len(&self) -> usize {
        self.model.len()
    }

    /// Whether the cloth has no vertices (never: a cloth has at least one triangle).
    pub fn is_empty(&self) -> bool {
        self.model.is_empty()
    }

    /// Vertex positions (m), `(N, 3)`.
    pub fn positions(&self) -> &[DVec3] {
        self.state.positions()
    }

    /// Vertex velocities (m/s), `(N, 3)`.
    pub fn velocities(&self) -> &[DVec3] {
        self.state.velocities()
    }

    /// Vertex masses (kg), `(N,)`.
    pub fn masses(&self) -> &[f64] {
        self.model.masses()
    }

    /// The triangles, `(M, 3)` vertex indices.
    pub fn triangles(&self) -> &[[usize; 3]] {
        self.model.triangles()
    }

    /// The elastic model.
    pub fn elasticity(&self) -> Elasticity {
        self.model.elasticity()
    }

    /// The material.
    pub fn material(&self) -> Material {
        self.model.material()
    }

    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        self.state.time()
    }

    /// Numbers of the last step ([`Solver::stats`]).
    pub fn stats(&self) -> StepStats {
        self.solver.stats()
    }

    /// Stored blocks of the implicit matrix (its sparsity).
    pub fn matrix_blocks(&self) -> usize {
        self.solver.matrix_blocks()
    }

    /// Collision thickness (m): contacts keep vertices this far from collider surfaces.
    pub fn thickness(&self) -> f64 {
        self.model.thickness()
    }

    /// Set the collision thickness (m, >= 0) of the model ([`Model::set_thickness`]).
    ///
    /// # Errors
    /// A negative or non-finite value.
    pub fn set_thickness(&mut self, thickness: f64) -> Result<()> {
        self.model.set_thickness(thickness)
    }

    /// Turn self-collision on with `settings` or off ([`Model::set_self_collision`]).
    ///
    /// # Errors
    /// A negative or non-finite friction.
    pub fn set_self_collision(&mut self, settings: Option<SelfCollision>) -> Result<()> {
        self.model.set_self_collision(settings)
    }

    /// Overwrite positions and velocities, `(N, 3)` each ([`State::set_motion`]; clears the
    /// BDF2 history).
    ///
    /// # Errors
    /// Wrong lengths or non-finite values; the state is then unchanged.
    pub fn set_state(&mut self, positions: &[DVec3], velocities: &[DVec3]) -> Result<()> {
        self.state.set_motion(positions, velocities)
    }

    /// Set or clear (`None`) the constraint of vertices `indices` ([`State::constrain`]).
    ///
    /// # Errors
    /// An index out of range, or a zero / non-finite direction or position.
    pub fn constrain(
        &mut self,
        indices: &[usize],
        constraint: Option<VertexConstraint>,
    ) -> Result<()> {
        self.state.constrain(indices, constraint)
    }

    /// Pin vertices `indices` at `positions` (their current positions when `None`;
    /// [`State::pin`]).
    ///
    /// # Errors
    /// Out-of-range indices, a length mismatch, or non-finite positions.
    pub fn pin(&mut self, indices: &[usize], positions: Option<&[DVec3]>) -> Result<()> {
        self.state.pin(indices, positions)
    }

    /// The constraint of each vertex.
    pub fn constraints(&self) -> &[Option<VertexConstraint>] {
        self.state.constraints()
    }

    /// Add a collider ([`State::add_collider`]); returns its index.
    ///
    /// # Errors
    /// Invalid shape, velocity or friction.
    pub fn add_collider(&mut self, collider: Collider) -> Result<usize> {
        self.state.add_collider(collider)
    }

    /// Replace collider `index` ([`State::set_collider`]).
    ///
    /// # Errors
    /// A bad index or an invalid collider.
    pub fn set_collider(&mut self, index: usize, collider: Collider) -> Result<()> {
        self.state.set_collider(index, collider)
    }

    /// The colliders, at the cloth's current time.
    pub fn colliders(&self) -> &[Collider] {
        self.state.colliders()
    }

    /// Add a triangle-mesh collider ([`State::add_mesh_collider`]); returns its index.
    pub fn add_mesh_collider(&mut self, mesh: MeshCollider) -> usize {
        self.state.add_mesh_collider(mesh)
    }

    /// Set the vertices (m) and velocities (m/s) of mesh collider `index`
    /// ([`State::set_mesh_collider`]).
    ///
    /// # Errors
    /// A bad index, wrong lengths or non-finite values; the collider is then unchanged.
    pub fn set_mesh_collider(
        &mut self,
        index: usize,
        vertices: &[DVec3],
        velocities: &[DVec3],
    ) -> Result<()> {
        self.state.set_mesh_collider(index, vertices, velocities)
    }

    /// The triangle-mesh colliders, at the cloth's current time.
    pub fn mesh_colliders(&self) -> &[MeshCollider] {
        self.state.mesh_colliders()
    }

    /// Total force on every vertex (N), `(N, 3)` ([`Model::forces`]).
    pub fn forces(&self) -> Vec<DVec3> {
        self.model.forces(&self.state)
    }

    /// The fastest mode `(ω rad/s, c 1/s)` about the current shape ([`Model::fastest_mode`]).
    pub fn fastest_mode(&self) -> (f64, f64) {
        self.model.fastest_mode(&self.state)
    }

    /// `(kinetic, gravitational potential, elastic)` energy (J) ([`Model::energy`]).
    pub fn energy(&self) -> (f64, f64, f64) {
        self.model.energy(&self.state)
    }

    /// Advance `steps` steps of `dt` seconds with `method` ([`Solver::step`]).
    ///
    /// # Errors
    /// As [`Solver::step`]; the cloth is then left exactly at the end of the last good step.
    pub fn step(
        &mut self,
        dt: f64,
        steps: usize,
        method: Method,
        options: SolveOptions,
    ) -> Result<()> {
        self.solver.step(&self.model, &mut self.state, dt, steps, method, options)?;
        Ok(())
    }
}
