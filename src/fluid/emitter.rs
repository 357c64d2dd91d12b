//! Where fluid enters and leaves: emitters (nozzles) and the kill box.
//!
//! An [`Emitter`] is a disc of `radius` about `position`, facing the unit `direction`, that
//! emits fluid at `speed`: a layer of particles on the square lattice of the spacing clipped
//! to the disc each time the fluid emitted before has moved one spacing (the distance is
//! accumulated per substep in the state). Layers one spacing apart on a lattice of the
//! spacing keep the emitted fluid at the rest density, so the mass flow is `ρ₀ A v` with `A`
//! the lattice's share of the disc (`n s²` for `n` points, `π r²` within a few percent for
//! `r ≥ 3 s`). A point with fluid closer than half a spacing (a blocked nozzle) is skipped:
//! particles are never put on top of each other.
//!
//! The kill box `[lower, upper]` removes every particle that leaves it at the end of a
//! substep, keeping the order of the others (so the result is deterministic).

use crate::error::{Error, Result};
use glam::DVec3;

/// A nozzle that emits fluid (see the module docs).
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Emitter {
    /// Centre of the nozzle's disc (m).
    pub position: DVec3,
    /// Unit direction of the emitted fluid.
    pub direction: DVec3,
    /// Speed of the emitted fluid (m/s).
    pub speed: f64,
    /// Radius of the disc (m), at least half a spacing.
    pub radius: f64,
}

impl Emitter {
    /// Check the emitter against the fluid's `spacing` (m).
    pub(super) fn validate(&self, spacing: f64) -> Result<()> {
        if !self.position.is_finite() {
            return Err(Error::invalid("position", "must be finite"));
        }
        if !self.direction.is_finite() || (self.direction.length() - 1.0).abs() > 1e-9 {
            return Err(Error::invalid("direction", "must be a finite unit vector"));
        }
        if !(self.speed.is_finite() && self.speed > 0.0) {
            return Err(Error::invalid("speed", "must be finite and > 0"));
        }
        if !(self.radius.is_finite() && self.radius >= 0.5 * spacing) {
            return Err(Error::invalid("radius", "must be finite and at least half the spacing"));
        }
        if self.radius > 1e4 * spacing {
            return Err(Error::invalid("radius", "must be at most 10⁴ spacings"));
        }
        Ok(())
    }

    /// Append the layer `distance` (m) ahead of the disc, on the square lattice of `spacing`
    /// (m) within the disc, leaving out points closer than half a spacing to any of `fluid`.
    pub(super) fn layer(&self, spacing: f64, distance: f64, fluid: &[DVec3], out: &mut Vec<DVec3>) {
        let (t1, t2) = self.direction.any_orthonormal_pair();
        let centre = self.position + self.direction * distance;
        let reach = self.radius + spacing;
        let near: Vec<DVec3> =
            fluid.iter().filter(|p| (**p - centre).length() <= reach).copied().collect();
        let m = (self.radius / spacing).floor() as i64;
        let r2 = self.radius * self.radius;
        for j in -m..=m {
            for i in -m..=m {
                let (a, b) = (i as f64 * spacing, j as f64 * spacing);
                let p = centre + t1 * a + t2 * b;
                if a * a + b * b <= r2 * (1.0 + 1e-12)
                    && near.iter().all(|q| (*q - p).length() >= 0.5 * spacing)
                {
                    out.push(p);
                }
            }
        }
    }
}

/// Check a kill box `[lower, upper]` (m): finite, `lower < upper` on every axis.
pub(super) fn validate_kill_box(lower: DVec3, upper: DVec3) -> Result<()> {
    if !lower.is_finite() || !upper.is_finite() {
        return Err(Error::invalid("lower", "the box corners must be finite"));
    }
    if !lower.cmplt(upper).all() {
        return Err(Error::invalid("upper", "must be above lower on every axis"));
    }
    Ok(())
}
