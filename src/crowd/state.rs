//! The crowd state: what changes in time — the agents' positions, velocities, goals and
//! preferred velocities, the time — and the running measurements a later call of
//! [`super::metrics`] reads (start points, path lengths, arrival times, collision tallies).

use super::metrics::Tally;
use super::Model;
use crate::error::{reserve, Error, Result};
use glam::DVec2;

/// Most agents a crowd holds.
pub const MAX_AGENTS: usize = u32::MAX as usize / 4;

/// The state of a crowd of a [`Model`]: `N` agents on the ground plane (2-D coordinates in
/// m: world `x` and `z`). `clone_from` reuses every buffer.
#[derive(serde::Serialize, serde::Deserialize, Debug, Default, PartialEq)]
pub struct State {
    /// Positions (m), `N`.
    pub(super) positions: Vec<DVec2>,
    /// Velocities (m/s), `N`.
    pub(super) velocities: Vec<DVec2>,
    /// Goals (m), `N`.
    pub(super) goals: Vec<DVec2>,
    /// Preferred velocities of the last step (m/s), `N`: towards the goal at the preferred
    /// speed, slower when the goal is nearer than one step.
    pub(super) preferred: Vec<DVec2>,
    /// Where each agent was added (m), `N`.
    pub(super) starts: Vec<DVec2>,
    /// Length walked by each agent (m), `N`.
    pub(super) path_length: Vec<f64>,
    /// Time at which each agent first came within the goal tolerance (s), infinite until
    /// then, `N`.
    pub(super) arrival: Vec<f64>,
    /// Collisions counted after every step.
    pub(super) tally: Tally,
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
        self.goals.clone_from(&source.goals);
        self.preferred.clone_from(&source.preferred);
        self.starts.clone_from(&source.starts);
        self.path_length.clone_from(&source.path_length);
        self.arrival.clone_from(&source.arrival);
        self.tally = source.tally;
        self.time = source.time;
    }
}

impl State {
    /// An empty state of `model` at time 0 (add agents with [`State::add_agents`]).
    pub fn new(_model: &Model) -> Self {
        State::default()
    }

    /// Add agents at `positions` (m), at rest, each walking to its goal in `goals` (m).
    /// Agents may start overlapping, even at one point: ORCA then separates them (along a
    /// direction fixed by their indices where they coincide), social forces push them apart.
    ///
    /// # Errors
    /// Lengths that differ (`goals`), a non-finite value (`positions` or `goals`, with the
    /// index), more than [`MAX_AGENTS`] agents or memory (`positions`).
    pub fn add_agents(&mut self, positions: &[DVec2], goals: &[DVec2]) -> Result<()> {
        if goals.len() != positions.len() {
            return Err(Error::invalid("goals", "expected one goal per position"));
        }
        if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
            return Err(Error::invalid("positions", "contains NaN or infinity").at(i));
        }
        if let Some(i) = goals.iter().position(|p| !p.is_finite()) {
            return Err(Error::invalid("goals", "contains NaN or infinity").at(i));
        }
        let n = positions.len();
        if self.len() + n > MAX_AGENTS {
            return Err(Error::invalid("positions", "too many agents"));
        }
        for v in [
            &mut self.positions,
            &mut self.velocities,
            &mut self.goals,
            &mut self.preferred,
            &mut self.starts,
        ] {
            reserve("positions", v, n)?;
        }
        reserve("positions", &mut self.path_length, n)?;
        reserve("positions", &mut self.arrival, n)?;
        self.positions.extend_from_slice(positions);
        self.starts.extend_from_slice(positions);
        self.goals.extend_from_slice(goals);
        let total = self.positions.len();
        self.velocities.resize(total, DVec2::ZERO);
        self.preferred.resize(total, DVec2::ZERO);
        self.path_length.resize(total, 0.0);
        self.arrival.resize(total, f64::INFINITY);
        Ok(())
    }

    /// Number of agents.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Whether there are no agents.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Positions (m), `N`.
    pub fn positions(&self) -> &[DVec2] {
        &self.positions
    }

    /// Velocities (m/s), `N`.
    pub fn velocities(&self) -> &[DVec2] {
        &self.velocities
    }

    /// Goals (m), `N`.
    pub fn goals(&self) -> &[DVec2] {
        &self.goals
    }

    /// Preferred velocities of the last step (m/s), `N`.
    pub fn preferred_velocities(&self) -> &[DVec2] {
        &self.preferred
    }

    /// Where each agent was added (m), `N`.
    pub fn starts(&self) -> &[DVec2] {
        &self.starts
    }

    /// Length of each agent's path so far (m), `N`.
    pub fn path_lengths(&self) -> &[f64] {
        &self.path_length
    }

    /// Time each agent first came within the goal tolerance (s; infinite if it has not), `N`.
    pub fn arrival_times(&self) -> &[f64] {
        &self.arrival
    }

    /// The collision tallies of every step so far.
    pub fn tally(&self) -> &Tally {
        &self.tally
    }

    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Give the agents new goals (m).
    ///
    /// # Errors
    /// A length other than [`State::len`] or a non-finite value (`goals`, with the index).
    pub fn set_goals(&mut self, goals: &[DVec2]) -> Result<()> {
        if goals.len() != self.len() {
            return Err(Error::invalid("goals", "expected one goal per agent"));
        }
        if let Some(i) = goals.iter().position(|p| !p.is_finite()) {
            return Err(Error::invalid("goals", "contains NaN or infinity").at(i));
        }
        self.goals.copy_from_slice(goals);
        Ok(())
    }
}
