//! Rod snapshots: the rod's (model and state), and a state's alone, which records the
//! fingerprint of its model ([`Model::fingerprint`]) so that it is restored only onto it.

use super::{Model, Rod, State};
use crate::error::Result;
use crate::snapshot::{from_stamped, to_stamped, Snapshot, Stamped};

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
    /// Bytes that are not a rod state snapshot of this version, are damaged or inconsistent
    /// with `model` (argument `data`); a state of a model of another fingerprint (`model`).
    pub fn from_snapshot(model: &Model, data: &[u8]) -> Result<State> {
        from_stamped(data, model.fingerprint(), |s: &State| s.validate(model))
    }
}

impl Stamped for State {
    const TAG: &'static str = "RodState";
}

impl Snapshot for Rod {
    const TAG: &'static str = "Rod";

    fn validate(&self) -> Result<()> {
        self.model.validate()?;
        self.state.validate(&self.model)
    }
}
