//! Fluid snapshots: what a decoded [`Model`] must satisfy before it is stepped; the fluid's
//! snapshot (model and state), and a state's alone, which records the fingerprint of its
//! model ([`Model::fingerprint`]) so that it is restored only onto it.

use super::{Fluid, Model, State};
use crate::error::Result;
use crate::snapshot::{check, finite, from_stamped, to_stamped, Snapshot, Stamped};

impl Model {
    /// Check a decoded model: settings in range, the derived sizes those of the settings, a
    /// volume per boundary particle.
    fn validate(&self) -> Result<()> {
        let fresh = Model::new(self.settings)?;
        check(
            fresh.support.to_bits() == self.support.to_bits()
                && fresh.volume.to_bits() == self.volume.to_bits()
                && fresh.offset.to_bits() == self.offset.to_bits(),
            "settings",
            || "derived sizes do not match the settings".into(),
        )?;
        for w in &self.walls {
            w.validate(self.settings.spacing)?;
        }
        check(self.boundary.len() == self.boundary_volume.len(), "boundary", || {
            "one volume per boundary particle".into()
        })?;
        check(
            finite(self.boundary.iter().flat_map(|p| p.to_array()))
                && self.boundary_volume.iter().all(|v| v.is_finite() && *v > 0.0),
            "boundary",
            || "non-finite boundary particle or volume".into(),
        )?;
        for e in &self.emitters {
            e.validate(self.settings.spacing)?;
        }
        if let Some((lower, upper)) = self.kill_box {
            super::emitter::validate_kill_box(lower, upper)?;
        }
        check(self.boundary.len() < u32::MAX as usize / 2, "boundary", || "too large".into())
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
    /// Bytes that are not a fluid state snapshot of this version or are damaged (argument
    /// `data`); a state of a model of another fingerprint (argument `model`).
    pub fn from_snapshot(model: &Model, data: &[u8]) -> Result<State> {
        from_stamped(data, model.fingerprint(), State::validate)
    }
}

impl Stamped for State {
    const TAG: &'static str = "FluidState";
}

impl Snapshot for Fluid {
    const TAG: &'static str = "Fluid";

    fn validate(&self) -> Result<()> {
        self.model.validate()?;
        self.state.validate()?;
        let (have, want) = (self.state.emitted.len(), self.model.emitters.len());
        check(have == want, "emitted", || format!("{have} entries for {want} emitters"))
    }
}
