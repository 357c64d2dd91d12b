//! The flock model: the boids' steering parameters (Reynolds 1987, "Flocks, herds, and
//! schools"; the steering-force form of Reynolds 1999, "Steering behaviors for autonomous
//! characters"), read-only during a step.

use super::steering::Steering;
use crate::error::{Error, Result};

/// The parameters shared by every boid.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Weight of separation, steering away from neighbours closer than
    /// [`Settings::separation_distance`] (dimensionless, ≥ 0).
    pub separation: f64,
    /// Weight of alignment, steering towards the neighbours' mean velocity (≥ 0).
    pub alignment: f64,
    /// Weight of cohesion, steering towards the neighbours' centre (≥ 0).
    pub cohesion: f64,
    /// Boids closer than this see each other (m).
    pub neighbour_radius: f64,
    /// Neighbours closer than this are steered away from (m, at most `neighbour_radius`).
    pub separation_distance: f64,
    /// Full angle of the field of view about the velocity (rad, in `(0, 2π]`; `2π` sees all
    /// around). A boid at rest sees all around.
    pub field_of_view: f64,
    /// Largest speed (m/s).
    pub max_speed: f64,
    /// Largest steering acceleration, the bound of Reynolds' (1999) `max_force` per unit mass
    /// (m/s²).
    pub max_force: f64,
}

impl Default for Settings {
    /// Equal weights but separation 1.5, radius 2 m, separation within 1 m, field of view
    /// 270°, speed 2 m/s, force 1 m/s².
    fn default() -> Self {
        Settings {
            separation: 1.5,
            alignment: 1.0,
            cohesion: 1.0,
            neighbour_radius: 2.0,
            separation_distance: 1.0,
            field_of_view: 1.5 * std::f64::consts::PI,
            max_speed: 2.0,
            max_force: 1.0,
        }
    }
}

/// A flock model (see the module docs): several [`super::State`]s may share it.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, PartialEq)]
pub struct Model {
    pub(super) settings: Settings,
    /// The steering behaviours added on top of the flocking rules, in order.
    pub(super) steering: Vec<Steering>,
}

impl Model {
    /// A model of `settings`.
    ///
    /// # Errors
    /// A setting out of its range (named).
    pub fn new(settings: Settings) -> Result<Self> {
        let s = &settings;
        let positive = |v: f64| v.is_finite() && v > 0.0;
        for (arg, v) in
            [("separation", s.separation), ("alignment", s.alignment), ("cohesion", s.cohesion)]
        {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::invalid(arg, "must be finite and >= 0"));
            }
        }
        for (arg, v) in [
            ("neighbour_radius", s.neighbour_radius),
            ("separation_distance", s.separation_distance),
            ("max_speed", s.max_speed),
            ("max_force", s.max_force),
        ] {
            if !positive(v) {
                return Err(Error::invalid(arg, "must be finite and > 0"));
            }
        }
        if s.separation_distance > s.neighbour_radius {
            return Err(Error::invalid("separation_distance", "must be at most neighbour_radius"));
        }
        if !(positive(s.field_of_view) && s.field_of_view <= std::f64::consts::TAU) {
            return Err(Error::invalid("field_of_view", "must be in (0, 2 pi]"));
        }
        Ok(Model { settings, steering: Vec::new() })
    }

    /// Add a weighted steering behaviour ([`Steering`], Reynolds 1999).
    ///
    /// # Errors
    /// A parameter out of its range (named); the model is then unchanged.
    pub fn add_steering(&mut self, steering: Steering) -> Result<()> {
        steering.validate()?;
        self.steering.push(steering);
        Ok(())
    }

    /// The steering behaviours, in the order added.
    pub fn steering(&self) -> &[Steering] {
        &self.steering
    }

    /// The settings.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// A deterministic 64-bit hash of the model ([`crate::snapshot::fingerprint`]).
    pub fn fingerprint(&self) -> u64 {
        crate::snapshot::fingerprint(self)
    }
}
