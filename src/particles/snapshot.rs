//! Particle snapshots: what a decoded [`ParticleSystem`] must satisfy before it is stepped.

use super::ParticleSystem;
use crate::error::Result;
use crate::snapshot::{check, finite, Snapshot};

impl Snapshot for ParticleSystem {
    const TAG: &'static str = "ParticleSystem";

    fn validate(&self) -> Result<()> {
        let n = self.n;
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
        for f in &self.forces {
            f.validate(n)?;
        }
        for c in &self.colliders {
            check(c.clone().checked().is_ok(), "colliders", || "invalid collider".into())?;
        }
        for (e, accumulated, _) in &self.emitters {
            e.validate()?;
            check(accumulated.is_finite() && *accumulated >= 0.0, "emitters", || {
                "non-finite emission count".into()
            })?;
        }
        check(self.cells.iter().all(|&(_, i)| (i as usize) < n), "cells", || {
            "particle index out of range".into()
        })?;
        check(
            [0, 3 * n].contains(&self.external.len()) && [0, 6 * n].contains(&self.backup.len()),
            "external",
            || "external forces or backup not of the slots' size".into(),
        )?;
        check(finite(self.external.iter().copied()), "external", || "non-finite".into())?;
        if let Some(s) = &self.stepper {
            s.validate()?;
            check(s.dimension() == 6 * n, "stepper", || "dimension is not 6 x slots".into())?;
        }
        Ok(())
    }
}
