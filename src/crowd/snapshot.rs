//! Crowd snapshots: what a decoded [`Model`] must satisfy before it is stepped; the crowd's
//! snapshot (model and state), and a state's alone, stamped with the fingerprint of its
//! model ([`Model::fingerprint`]) so that it is restored only onto it.

use super::{Crowd, Model, State, MAX_AGENTS};
use crate::error::Result;
use crate::snapshot::{check, Snapshot, Stamped};

impl Model {
    /// Check a decoded model: settings in range, and the obstacle data exactly what
    /// [`Model::add_obstacle`] makes of the stored polygons.
    fn validate(&self) -> Result<()> {
        let mut fresh = Model::new(self.settings)?;
        fresh.set_navigation(self.navigation.as_ref().map(|n| n.clearance()))?;
        check(
            self.polygons.first() == Some(&0)
                && self.polygons.windows(2).all(|w| w[0] < w[1])
                && self.polygons.last().map(|&l| l as usize) == Some(self.vertices.len()),
            "polygons",
            || "polygon starts do not match the vertices".into(),
        )?;
        for polygon in self.polygon_points() {
            fresh.add_obstacle(&polygon)?;
        }
        check(fresh == *self, "vertices", || "obstacle data do not match the polygons".into())
    }
}

impl State {}

impl Stamped for State {
    const TAG: &'static str = "CrowdState";
    type Model = Model;

    /// Check a decoded state: lengths equal, values finite (arrival times may be infinite,
    /// never NaN or negative), not too many agents.
    fn validate(&self, _: &Model) -> Result<()> {
        use crate::snapshot::{check, finite};
        let n = self.positions.len();
        check(n <= MAX_AGENTS, "positions", || "too many agents".into())?;
        for (field, len) in [
            ("velocities", self.velocities.len()),
            ("goals", self.goals.len()),
            ("preferred", self.preferred.len()),
            ("starts", self.starts.len()),
            ("path_length", self.path_length.len()),
            ("arrival", self.arrival.len()),
        ] {
            check(len == n, field, || format!("{len} entries for {n} agents"))?;
        }
        let vectors =
            [&self.positions, &self.velocities, &self.goals, &self.preferred, &self.starts];
        check(
            finite(vectors.iter().flat_map(|v| v.iter().flat_map(|p| p.to_array()))),
            "positions",
            || "non-finite".into(),
        )?;
        check(self.path_length.iter().all(|l| l.is_finite() && *l >= 0.0), "path_length", || {
            "non-finite or negative".into()
        })?;
        check(self.arrival.iter().all(|t| *t >= 0.0), "arrival", || "NaN or negative".into())?;
        check(self.time.is_finite(), "time", || "non-finite".into())?;
        self.tally.validate()
    }
}

impl Snapshot for Crowd {
    const TAG: &'static str = "Crowd";

    fn validate(&self) -> Result<()> {
        self.model.validate()?;
        self.state.validate(&self.model)
    }
}
