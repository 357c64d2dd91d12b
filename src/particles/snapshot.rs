//! Particle snapshots: what a decoded [`Model`] and [`State`] must satisfy before they are
//! stepped; the system's snapshot (model and state), and a state's alone, which records the
//! fingerprint of its model ([`Model::fingerprint`]) so that it is restored only onto it.

use super::{Model, ParticleSystem, State};
use crate::error::Result;
use crate::snapshot::{check, finite, Snapshot, Stamped};

impl Model {
    /// Check a decoded model: every force, collider and emitter valid for the capacity.
    fn validate(&self) -> Result<()> {
        for f in &self.forces {
            f.validate(self.n)?;
        }
        for c in &self.colliders {
            check(c.clone().checked().is_ok(), "colliders", || "invalid collider".into())?;
        }
        for e in &self.emitters {
            e.validate()?;
        }
        Ok(())
    }
}

impl Stamped for State {
    const TAG: &'static str = "ParticleState";
    type Model = Model;

    /// Check a decoded state against its model: lengths of the capacity, finite values, masses
    /// with their inverses, an emission count per emitter, a history of the state's size.
    fn validate(&self, model: &Model) -> Result<()> {
        let n = model.n;
        check(self.y.len() == 6 * n, "y", || format!("{} values for {n} slots", self.y.len()))?;
        for (field, len) in [
            ("mass", self.mass.len()),
            ("inv_mass", self.inv_mass.len()),
            ("age", self.age.len()),
            ("lifespan", self.lifespan.len()),
            ("alive", self.alive.len()),
            ("color", self.color.len()),
            ("size", self.size.len()),
        ] {
            check(len == n, field, || format!("{len} entries for {n} slots"))?;
        }
        check(finite(self.y.iter().copied()), "y", || "non-finite state".into())?;
        check(
            self.mass.iter().zip(&self.inv_mass).all(|(&m, &w)| {
                m > 0.0 && w.to_bits() == (if m.is_finite() { 1.0 / m } else { 0.0 }).to_bits()
            }),
            "mass",
            || "masses must be positive (inf pins) with their inverses".into(),
        )?;
        check(
            finite(self.age.iter().copied())
                && self.lifespan.iter().all(|&l| l > 0.0)
                && self.age_pending.0.is_finite()
                && self.age_pending.0 >= 0.0,
            "age",
            || "ages must be finite, lifespans positive".into(),
        )?;
        check(
            self.color.iter().all(|c| c.iter().all(|c| (0.0..=1.0).contains(c)))
                && self.size.iter().all(|s| s.is_finite() && *s > 0.0),
            "appearance",
            || "colour channels must be in [0, 1], sizes finite and > 0".into(),
        )?;
        check(self.time.is_finite(), "time", || "non-finite".into())?;
        check(
            self.emitters.len() == model.emitters.len()
                && self.emitters.iter().all(|(owed, _)| owed.is_finite() && *owed >= 0.0),
            "emitters",
            || "one finite, non-negative emission count per emitter".into(),
        )?;
        check([0, 3 * n].contains(&self.external.len()), "external", || {
            "external forces not of the slots' size".into()
        })?;
        check(finite(self.external.iter().copied()), "external", || "non-finite".into())?;
        if let Some(h) = &self.history {
            h.validate()?;
            check(h.dimension() == 6 * n, "stepper", || "dimension is not 6 x slots".into())?;
        }
        Ok(())
    }
}

impl Snapshot for ParticleSystem {
    const TAG: &'static str = "ParticleSystem";

    fn validate(&self) -> Result<()> {
        self.model.validate()?;
        self.state.validate(&self.model)
    }
}
