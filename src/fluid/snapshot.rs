//! Fluid snapshots: what a decoded [`Model`] must satisfy before it is stepped; the fluid's
//! snapshot (model and state), and a state's alone, which records the fingerprint of its
//! model ([`Model::fingerprint`]) so that it is restored only onto it.

use super::{Fluid, Model, State};
use crate::error::Result;
use crate::snapshot::{check, finite, Snapshot, Stamped};

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
        let moving: usize = self.colliders.iter().map(|b| b.points.len()).sum();
        check(self.boundary.len() + moving == self.boundary_volume.len(), "boundary", || {
            "one volume per boundary particle".into()
        })?;
        for b in &self.colliders {
            super::Collider { shape: b.shape, velocity: glam::DVec3::ZERO }
                .checked(self.settings.spacing)?;
            check(finite(b.points.iter().flat_map(|p| p.to_array())), "colliders", || {
                "non-finite boundary particle".into()
            })?;
        }
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

impl State {}

impl Stamped for State {
    const TAG: &'static str = "FluidState";
    type Model = Model;

    /// Check a decoded state: lengths equal, finite values, not too many particles, one
    /// collider of the model's kind and size per collider of the model.
    fn validate(&self, model: &Model) -> Result<()> {
        use crate::snapshot::{check, finite};
        let n = self.positions.len();
        for (field, len) in [
            ("velocities", self.velocities.len()),
            ("pressure", self.pressure.len()),
            ("divergence", self.divergence.len()),
            ("viscous", self.viscous.len()),
        ] {
            check(len == n, field, || format!("{len} entries for {n} particles"))?;
        }
        let vectors = self.positions.iter().chain(&self.velocities).chain(&self.viscous);
        let values = vectors.flat_map(|v| v.to_array());
        check(finite(values), "positions", || "non-finite".into())?;
        check(finite(self.pressure.iter().chain(&self.divergence).copied()), "pressure", || {
            "non-finite".into()
        })?;
        check(self.time.is_finite(), "time", || "non-finite".into())?;
        check(finite(self.emitted.iter().copied()), "emitted", || "non-finite".into())?;
        check(n < u32::MAX as usize / 4, "positions", || "too many particles".into())?;
        let (have, want) = (self.colliders.len(), model.colliders.len());
        check(have == want, "colliders", || format!("{have} entries for {want} colliders"))?;
        for (c, b) in self.colliders.iter().zip(&model.colliders) {
            let c = c.checked(model.settings.spacing)?;
            check(super::collider::same_body(&b.shape, &c.shape), "colliders", || {
                "a collider of another kind or size than the model's".into()
            })?;
        }
        Ok(())
    }
}

impl Snapshot for Fluid {
    const TAG: &'static str = "Fluid";

    fn validate(&self) -> Result<()> {
        self.model.validate()?;
        self.state.validate(&self.model)?;
        let (have, want) = (self.state.emitted.len(), self.model.emitters.len());
        check(have == want, "emitted", || format!("{have} entries for {want} emitters"))
    }
}
