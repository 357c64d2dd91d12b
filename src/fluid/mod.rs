//! Particle fluids by smoothed particle hydrodynamics (SPH): a liquid as particles of one
//! mass on a lattice of the spacing at rest, kernels of support twice the spacing, solid walls
//! sampled as boundary particles (Akinci et al. 2012), and two pressure solvers:
//!
//! - **DFSPH** (Bender & Koschier 2015, "Divergence-free smoothed particle hydrodynamics";
//!   2017, "Divergence-free SPH for incompressible and viscous fluids"), the default: per
//!   substep a divergence-free solve (the velocity field keeps the density constant), gravity
//!   and viscosity, then a constant-density solve (the predicted density is the rest density
//!   within a tolerance in percent, default 0.05 %);
//! - **WCSPH** (Becker & Teschner 2007, "Weakly compressible SPH for free surface flows"):
//!   pressure from the Tait equation, the simple reference.
//!
//! Viscosity is XSPH (Schechter & Bridson 2012) or the implicit solve of Weiler et al. 2018
//! (`viscosity.rs`, a kinematic viscosity in m²/s). [`surface_mesh`] gives the liquid's
//! surface as a closed triangle mesh (`surface.rs`). Substeps follow the CFL condition
//! ([`Solver::step`]); neighbours come from Verlet lists over a uniform grid, found again when
//! a particle moved half their skin (`neighbours.rs`), in parallel and deterministically (in
//! ascending index order: the same bits for any thread count and any history of the search).
//!
//! Colliders (`collider.rs`) are the shared shapes sampled the same way, fixed or moving
//! with a rigid body (one-way: the fluid feels the body).
//!
//! The fluid is split as every system of kinema is: a [`Model`] (settings, particle volume,
//! walls and boundary particles), a [`State`] (positions, velocities, time, the warm starts
//! of DFSPH and of the implicit viscosity) and a [`Solver`] (neighbour lists, densities, factors, scratch), so one model and
//! one solver can advance several states. [`Fluid`] is the three together.

mod boundary;
mod collider;
mod density;
mod emitter;
mod kernel;
mod model;
mod neighbours;
mod order;
mod snapshot;
mod solver;
mod state;
mod surface;
mod viscosity;

pub use boundary::Wall;
pub use collider::Collider;
pub use emitter::Emitter;
pub use kernel::Kernel;
pub use model::{Model, Pressure, Settings, Viscosity};
pub use solver::Solver;
pub use state::State;
pub use surface::surface_mesh;

use crate::error::Result;
use glam::DVec3;

/// What the last call to [`Solver::step`] did.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, Default, PartialEq)]
pub struct Stats {
    /// Substeps taken.
    pub substeps: usize,
    /// Iterations of the constant-density solve, summed over the substeps (DFSPH).
    pub density_iterations: usize,
    /// Iterations of the divergence-free solve, summed over the substeps (DFSPH).
    pub divergence_iterations: usize,
    /// The largest over the substeps of the mean compression `max(ρ/ρ₀ - 1, 0)` (percent):
    /// the predicted density after the constant-density solve (DFSPH), the density before
    /// the pressure force (WCSPH).
    pub density_error: f64,
    /// The largest compression of any particle in any substep (percent), measured as
    /// `density_error`.
    pub max_density_error: f64,
    /// The largest over the substeps of the mean density change per substep due to the
    /// velocity divergence after the divergence-free solve (percent, DFSPH).
    pub divergence_error: f64,
    /// Conjugate-gradient iterations of the implicit viscosity solve, summed over the
    /// substeps ([`Viscosity::Implicit`]).
    pub viscosity_iterations: usize,
    /// The largest over the substeps of the implicit viscosity solve's relative residual
    /// `|b - A v| / |b|` (percent).
    pub viscosity_error: f64,
}

/// A fluid: a [`Model`] with one [`State`] and a [`Solver`], its methods delegating to them.
/// A snapshot holds the model and the state.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub struct Fluid {
    model: Model,
    state: State,
    #[serde(skip)]
    solver: Solver,
    /// What the last step call did.
    pub stats: Stats,
}

impl Fluid {
    /// An empty fluid of `settings`, without walls.
    ///
    /// # Errors
    /// Those of [`Model::new`].
    pub fn new(settings: Settings) -> Result<Self> {
        let model = Model::new(settings)?;
        let state = State::new(&model);
        let solver = Solver::new(&model);
        Ok(Fluid { model, state, solver, stats: Stats::default() })
    }

    /// The model.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The state.
    pub fn state(&self) -> &State {
        &self.state
    }

    /// The state, to change it (e.g. [`State::set_velocities`]).
    pub fn state_mut(&mut self) -> &mut State {
        &mut self.state
    }

    /// Add a wall ([`Model::add_wall`]).
    ///
    /// # Errors
    /// Those of [`Model::add_wall`]; and, for a box, fluid outside every box wall (`lower`).
    /// The fluid is then unchanged.
    pub fn add_wall(&mut self, wall: Wall) -> Result<()> {
        let mut model = self.model.clone();
        model.add_wall(wall)?;
        let margin = 0.25 * model.settings.spacing;
        let tanks: Vec<&Wall> =
            model.walls.iter().filter(|w| matches!(w, Wall::Box { .. })).collect();
        if !tanks.is_empty()
            && !self.state.positions.iter().all(|p| tanks.iter().any(|w| w.contains(*p, margin)))
        {
            return Err(crate::Error::invalid(
                "lower",
                "fluid particles would be outside the tank",
            ));
        }
        self.model = model;
        Ok(())
    }

    /// Add a collider (the `collider` module) at its shape's pose, moving at its velocity;
    /// returns its index (for [`Fluid::set_collider`]).
    ///
    /// # Errors
    /// Those of the shape ([`crate::geometry::Shape::checked`], named); a plane (`shape`: use
    /// a [`Wall::Plane`]); a radius or half extent under the spacing (`radius`,
    /// `half_extents`); a non-finite velocity (`velocity`); fluid particles inside the
    /// shape (`shape`). The fluid is then unchanged.
    pub fn add_collider(&mut self, collider: Collider) -> Result<usize> {
        let collider = collider.checked(self.model.settings.spacing)?;
        if self.state.positions.iter().any(|&p| collider.shape.distance(p).0 < 0.0) {
            return Err(crate::Error::invalid(
                "shape",
                "fluid particles would be inside the collider (add it before the fluid)",
            ));
        }
        self.model.add_collider(&collider)?;
        self.state.colliders.push(collider);
        Ok(self.model.colliders.len() - 1)
    }

    /// Move collider `index` ([`State::set_collider`]).
    ///
    /// # Errors
    /// Those of [`State::set_collider`]; the fluid is then unchanged.
    pub fn set_collider(&mut self, index: usize, collider: Collider) -> Result<()> {
        self.state.set_collider(&self.model, index, collider)
    }

    /// Remove the colliders added after the first `count` (none if there are at most
    /// `count`): a scene's undo of a frame that added colliders and failed.
    pub fn truncate_colliders(&mut self, count: usize) {
        self.model.truncate_colliders(count);
        self.state.colliders.truncate(count);
    }

    /// Fill `[lower, upper]` (m) with fluid moving at `velocity` (m/s) ([`State::add_block`]);
    /// returns the number of particles added.
    ///
    /// # Errors
    /// Those of [`State::add_block`].
    pub fn add_block(&mut self, lower: DVec3, upper: DVec3, velocity: DVec3) -> Result<usize> {
        self.state.add_block(&self.model, lower, upper, velocity)
    }

    /// Add an emitter ([`Model::add_emitter`]); its first layer comes out in the next
    /// substep.
    ///
    /// # Errors
    /// Those of [`Model::add_emitter`]; the fluid is then unchanged.
    pub fn add_emitter(&mut self, emitter: Emitter) -> Result<()> {
        self.model.add_emitter(emitter)?;
        self.state.emitted.push(self.model.settings.spacing);
        Ok(())
    }

    /// Set the kill box ([`Model::set_kill_box`]).
    ///
    /// # Errors
    /// Those of [`Model::set_kill_box`]; the fluid is then unchanged.
    pub fn kill_box(&mut self, lower: DVec3, upper: DVec3) -> Result<()> {
        self.model.set_kill_box(lower, upper)
    }

    /// Advance `steps` frames of `dt` seconds ([`Solver::step`]); `stats` then describes
    /// the call.
    ///
    /// # Errors
    /// Those of [`Solver::step`]; the fluid is then as it was.
    pub fn step(&mut self, dt: f64, steps: usize) -> Result<()> {
        self.stats = self.solver.step(&self.model, &mut self.state, dt, steps)?;
        Ok(())
    }

    /// Densities (kg/m³) of the particles as they are now, `N`.
    pub fn densities(&mut self) -> Vec<f64> {
        let mut out = Vec::new();
        self.solver.densities_of(&self.model, &self.state, &mut out);
        out
    }

    /// The surface mesh of the fluid sampled every `resolution` metres ([`surface_mesh`]).
    ///
    /// # Errors
    /// Those of [`surface_mesh`].
    pub fn surface_mesh(&self, resolution: f64) -> Result<crate::geometry::isosurface::Mesh> {
        surface_mesh(&self.model, &self.state, resolution)
    }

    /// The boundary particles (m): the walls' ([`Model::boundary_particles`]), then every
    /// collider's where it is now.
    pub fn boundary_particles(&self) -> Vec<DVec3> {
        let mut out = self.model.boundary_particles().to_vec();
        self.model.place_colliders(self.state.colliders(), &mut out);
        out
    }

    /// Pressures (Pa) of the last substep, `N` ([`State::pressures`] times `ρ₀`).
    pub fn pressures(&self) -> Vec<f64> {
        let rho = self.model.settings.rest_density;
        self.state.pressure.iter().map(|p| p * rho).collect()
    }
}
