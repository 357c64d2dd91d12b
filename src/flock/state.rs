//! The flock state: the boids' positions and velocities and the time.

use super::Model;
use crate::error::{reserve, Error, Result};
use glam::DVec3;

/// Most boids a flock holds (the neighbour grid indexes them with `u32`).
pub const MAX_BOIDS: usize = u32::MAX as usize / 4;

/// The state of a flock of a [`Model`]: `N` boids in 3-D (a 2-D flock has every `z` and
/// velocity `z` zero, and keeps them so). `clone_from` reuses the buffers.
#[derive(serde::Serialize, serde::Deserialize, Debug, Default, PartialEq)]
pub struct State {
    /// Positions (m), `N`.
    pub(super) positions: Vec<DVec3>,
    /// Velocities (m/s), `N`.
    pub(super) velocities: Vec<DVec3>,
    /// Simulated time (s).
    pub(super) time: f64,
}

impl Clone for State {
    fn clone(&self) -> Self {
        let mut s = State::default();
        s.clone_from(self);
        s
    }

    fn clone_from(&mut self, source: &Self) {
        self.positions.clone_from(&source.positions);
        self.velocities.clone_from(&source.velocities);
        self.time = source.time;
    }
}

impl State {
    /// An empty state of `model` at time 0.
    pub fn new(_model: &Model) -> Self {
        State::default()
    }

    /// Add boids at `positions` (m) with `velocities` (m/s).
    ///
    /// # Errors
    /// Lengths that differ (`velocities`), a non-finite value (`positions` or `velocities`,
    /// with the index), more than [`MAX_BOIDS`] boids or memory (`positions`); the state is
    /// then unchanged.
    pub fn add_boids(&mut self, positions: &[DVec3], velocities: &[DVec3]) -> Result<()> {
        if velocities.len() != positions.len() {
            return Err(Error::invalid("velocities", "expected one velocity per position"));
        }
        for (arg, values) in [("positions", positions), ("velocities", velocities)] {
            if let Some(i) = values.iter().position(|p| !p.is_finite()) {
                return Err(Error::invalid(arg, "contains NaN or infinity").at(i));
            }
        }
        if self.len() + positions.len() > MAX_BOIDS {
            return Err(Error::invalid("positions", "too many boids"));
        }
        reserve("positions", &mut self.positions, positions.len())?;
        reserve("positions", &mut self.velocities, positions.len())?;
        self.positions.extend_from_slice(positions);
        self.velocities.extend_from_slice(velocities);
        Ok(())
    }

    /// Number of boids.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Whether there are no boids.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Positions (m), `N`.
    pub fn positions(&self) -> &[DVec3] {
        &self.positions
    }

    /// Velocities (m/s), `N`.
    pub fn velocities(&self) -> &[DVec3] {
        &self.velocities
    }

    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        self.time
    }
}
