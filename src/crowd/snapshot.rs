//! Crowd snapshots: what a decoded [`Model`] must satisfy before it is stepped; the crowd's
//! snapshot (model and state), and a state's alone, stamped with the fingerprint of its
//! model ([`Model::fingerprint`]) so that it is restored only onto it.

use super::{Crowd, Model, State};
use crate::error::Result;
use crate::snapshot::{check, from_stamped, to_stamped, Snapshot, Stamped};

impl Model {
    /// Check a decoded model: settings in range, and the obstacle data exactly what
    /// [`Model::add_obstacle`] makes of the stored polygons.
    fn validate(&self) -> Result<()> {
        let mut fresh = Model::new(self.settings)?;
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

impl State {
    /// The state as bytes, with the fingerprint of `model` (see [`crate::snapshot`]).
    ///
    /// # Errors
    /// None in practice (every part of a state can be encoded).
    pub fn to_snapshot(&self, model: &Model) -> Result<Vec<u8>> {
        to_stamped(self, model.fingerprint())
    }

    /// The state stored by [`State::to_snapshot`], for `model`.
    ///
    /// # Errors
    /// Bytes that are not a crowd state snapshot of this version or are damaged (argument
    /// `data`); a state of a model of another fingerprint (argument `model`).
    pub fn from_snapshot(model: &Model, data: &[u8]) -> Result<State> {
        from_stamped(data, model.fingerprint(), State::validate)
    }
}

impl Stamped for State {
    const TAG: &'static str = "CrowdState";
}

impl Snapshot for Crowd {
    const TAG: &'static str = "Crowd";

    fn validate(&self) -> Result<()> {
        self.model.validate()?;
        self.state.validate()
    }
}
