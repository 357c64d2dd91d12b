//! Crowds: agents walking on the ground plane to their goals, avoiding each other and static
//! polygon obstacles, by one of two models:
//!
//! - **ORCA**, optimal reciprocal collision avoidance (van den Berg, Guy, Lin & Manocha 2011,
//!   "Reciprocal n-body collision avoidance"): each step every agent takes the velocity
//!   closest to its preferred one among those its neighbours' half-planes permit (§5; the
//!   2-D linear program, and the 3-D one of least penetration when that is infeasible, in
//!   [`lp`]), obstacles handled as in the RVO2 library (§6; `orca.rs`);
//! - **social forces** (Helbing & Molnár 1995; Helbing, Farkas & Vicsek 2000): a driving term
//!   towards the preferred velocity and exponential, body and sliding-friction interactions
//!   with agents and walls (`social.rs`);
//!
//! and, optionally, a global layer (`navigation.rs`): A* on a visibility graph over the
//! obstacles' convex vertices gives each agent its next waypoint around walls.
//!
//! Coordinates are 2-D, in metres on the ground plane (world `x` and `z`, +Y being up).
//! Neighbours come from the shared hashed uniform grid (`geometry::grid`), rebuilt every
//! step, in parallel and deterministically. [`metrics`] measures collisions, time to goal,
//! path length and flow through a door; the solver keeps running sums in the state.
//!
//! The crowd is split as every system of kinema is: a [`Model`] (settings and obstacles), a
//! [`State`] (agents and running measurements) and a [`Solver`] (grid and scratch), so one
//! model and one solver can advance several states. [`Crowd`] is the three together.

pub mod lp;
pub mod metrics;
mod model;
mod navigation;
mod orca;
mod separation;
mod snapshot;
mod social;
mod solver;
mod state;

pub use model::{Kind, Model, Settings, SocialForce, Vertex};
pub use navigation::Roadmap;
pub use solver::{Solver, Stats};
pub use state::{State, MAX_AGENTS};

use crate::error::Result;
use glam::DVec2;

/// A crowd: a [`Model`] with one [`State`] and a [`Solver`], its methods delegating to them.
/// A snapshot holds the model and the state.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub struct Crowd {
    model: Model,
    state: State,
    #[serde(skip)]
    solver: Solver,
    /// What the last step call did.
    pub stats: Stats,
}

impl Crowd {
    /// An empty crowd of `settings`, without obstacles.
    ///
    /// # Errors
    /// Those of [`Model::new`].
    pub fn new(settings: Settings) -> Result<Self> {
        let model = Model::new(settings)?;
        let state = State::new(&model);
        let solver = Solver::new(&model);
        Ok(Crowd { model, state, solver, stats: Stats::default() })
    }

    /// The model.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The state.
    pub fn state(&self) -> &State {
        &self.state
    }

    /// The state, to change it (e.g. [`State::set_goals`]).
    pub fn state_mut(&mut self) -> &mut State {
        &mut self.state
    }

    /// Add agents ([`State::add_agents`]).
    ///
    /// # Errors
    /// Those of [`State::add_agents`]; the crowd is then unchanged.
    pub fn add_agents(&mut self, positions: &[DVec2], goals: &[DVec2]) -> Result<()> {
        self.state.add_agents(positions, goals)
    }

    /// Add an obstacle polygon ([`Model::add_obstacle`]).
    ///
    /// # Errors
    /// Those of [`Model::add_obstacle`]; the crowd is then unchanged.
    pub fn add_obstacle(&mut self, polygon: &[DVec2]) -> Result<()> {
        self.model.add_obstacle(polygon)
    }

    /// Turn the navigation layer on or off ([`Model::set_navigation`]).
    ///
    /// # Errors
    /// Those of [`Model::set_navigation`]; the crowd is then unchanged.
    pub fn set_navigation(&mut self, clearance: Option<f64>) -> Result<()> {
        self.model.set_navigation(clearance)
    }

    /// Advance `steps` steps of `dt` seconds ([`Solver::step`]); `stats` then describes the
    /// call.
    ///
    /// # Errors
    /// Those of [`Solver::step`]; the crowd is then as it was.
    pub fn step(&mut self, dt: f64, steps: usize) -> Result<()> {
        self.stats = self.solver.step(&self.model, &mut self.state, dt, steps)?;
        Ok(())
    }
}
