//! Flock snapshots: the flock's (model and state), and a state's alone, stamped with the
//! fingerprint of its model.

use super::{Flock, Model, State, MAX_BOIDS};
use crate::error::Result;
use crate::snapshot::{check, finite, Snapshot, Stamped};

impl Stamped for State {
    const TAG: &'static str = "FlockState";
    type Model = Model;

    /// Check a decoded state: lengths equal, values finite, not too many boids.
    fn validate(&self, _: &Model) -> Result<()> {
        let n = self.positions.len();
        check(n <= MAX_BOIDS, "positions", || "too many boids".into())?;
        let m = self.velocities.len();
        check(m == n, "velocities", || format!("{m} entries for {n} boids"))?;
        let values = self.positions.iter().chain(&self.velocities).flat_map(|p| p.to_array());
        check(finite(values), "positions", || "non-finite".into())?;
        check(self.time.is_finite(), "time", || "non-finite".into())
    }
}

impl Snapshot for Flock {
    const TAG: &'static str = "Flock";

    fn validate(&self) -> Result<()> {
        Model::new(self.model.settings)?;
        self.state.validate(&self.model)
    }
}
