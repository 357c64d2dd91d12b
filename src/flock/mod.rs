//! Flocks: Reynolds' boids (1987, "Flocks, herds, and schools: a distributed behavioral
//! model") — separation, alignment and cohesion with weights, a neighbour radius and a field
//! of view — as steering forces bounded by a maximum force and speed (Reynolds 1999,
//! "Steering behaviors for autonomous characters"), in 2-D or 3-D. The boids are sorted by
//! grid cell every step and swept in that order over their neighbours' cells (`cells.rs`),
//! without neighbour lists; the step is parallel and bitwise the same on any number of
//! threads. Reynolds' (1999) steering behaviours
//! (seek, flee, arrive, pursue, evade, wander, obstacle avoidance against the shared shapes)
//! add as weighted forces ([`Steering`], `steering.rs`).
//!
//! The flock is split as every system of kinema is: a [`Model`] (the settings), a [`State`]
//! (positions, velocities, time) and a [`Solver`] (the sorted and the moved boids), so one
//! model and one solver can advance several states. [`Flock`] is the three together.
//! [`polarisation`] is the order parameter of Vicsek et al. (1995), [`cohesion`] the largest
//! cluster's share (Grégoire & Chaté 2004).

mod cells;
mod lanes;
mod model;
mod snapshot;
mod solver;
mod state;
mod steering;

pub use model::{Model, Settings};
pub use solver::Solver;
pub use state::{State, MAX_BOIDS};
pub use steering::{Behaviour, Steering};

use crate::error::{Error, Result};
use glam::DVec3;

/// A flock: a [`Model`] with one [`State`] and a [`Solver`], its methods delegating to them.
/// A snapshot holds the model and the state.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub struct Flock {
    model: Model,
    state: State,
    #[serde(skip)]
    solver: Solver,
}

impl Flock {
    /// A flock of `settings` with boids at `positions` (m) flying at `velocities` (m/s).
    ///
    /// # Errors
    /// Those of [`Model::new`] and [`State::add_boids`].
    pub fn new(settings: Settings, positions: &[DVec3], velocities: &[DVec3]) -> Result<Self> {
        let model = Model::new(settings)?;
        let mut state = State::new(&model);
        state.add_boids(positions, velocities)?;
        let solver = Solver::new(&model);
        Ok(Flock { model, state, solver })
    }

    /// The model.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// Add a weighted steering behaviour ([`Model::add_steering`]).
    ///
    /// # Errors
    /// Those of [`Model::add_steering`]; the flock is then unchanged.
    pub fn add_steering(&mut self, steering: Steering) -> Result<()> {
        self.model.add_steering(steering)
    }

    /// The state.
    pub fn state(&self) -> &State {
        &self.state
    }

    /// The state, to change it.
    pub fn state_mut(&mut self) -> &mut State {
        &mut self.state
    }

    /// Advance `steps` steps of `dt` seconds ([`Solver::step`]).
    ///
    /// # Errors
    /// Those of [`Solver::step`]; the flock is then as it was.
    pub fn step(&mut self, dt: f64, steps: usize) -> Result<()> {
        self.solver.step(&self.model, &mut self.state, dt, steps)
    }
}

/// The polarisation order parameter `φ = |Σ v_i / |v_i|| / N` (Vicsek, Czirók, Ben-Jacob,
/// Cohen & Shochet 1995): 1 when every boid flies the same way, about `1/√N` for random
/// headings. Boids at rest count in `N` with no heading; 0 for no boids.
pub fn polarisation(velocities: &[DVec3]) -> f64 {
    if velocities.is_empty() {
        return 0.0;
    }
    let sum: DVec3 = velocities.iter().map(|v| v.normalize_or_zero()).sum();
    sum.length() / velocities.len() as f64
}

/// The cohesion of a flock: the fraction of its boids in the largest cluster, boids linked
/// when closer than `radius` (m) and clusters the connected sets of links (Grégoire & Chaté
/// 2004, "Onset of collective and cohesive motion"): 1 for one flock, about `1/N` for boids
/// all farther apart than `radius`; 0 for no boids. Neighbours from the shared grid
/// (`geometry/grid.rs`), clusters by union–find.
///
/// # Errors
/// `radius` not finite and positive; a position not finite (`positions`, the lowest index).
pub fn cohesion(positions: &[DVec3], radius: f64) -> Result<f64> {
    if !(radius.is_finite() && radius > 0.0) {
        return Err(Error::invalid("radius", "must be finite and > 0"));
    }
    if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
        return Err(Error::invalid("positions", "contains NaN or infinity").at(i));
    }
    let n = positions.len();
    if n == 0 {
        return Ok(0.0);
    }
    let mut grid = crate::geometry::grid::Grid::default();
    grid.build(positions, n, radius);
    // Union–find with path halving; each cluster's root is its lowest boid.
    let mut parent: Vec<u32> = (0..n as u32).collect();
    let root = |parent: &mut [u32], mut i: u32| {
        while parent[i as usize] != i {
            parent[i as usize] = parent[parent[i as usize] as usize];
            i = parent[i as usize];
        }
        i
    };
    for i in 0..n as u32 {
        for &j in grid.neighbours(i as usize) {
            let (a, b) = (root(&mut parent, i), root(&mut parent, j));
            parent[a.max(b) as usize] = a.min(b);
        }
    }
    let mut size = vec![0u32; n];
    for i in 0..n as u32 {
        size[root(&mut parent, i) as usize] += 1;
    }
    Ok(f64::from(*size.iter().max().unwrap_or(&0)) / n as f64)
}
