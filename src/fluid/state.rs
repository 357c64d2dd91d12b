//! The fluid state: what changes in time and what a later step reads — positions,
//! velocities, the time, and the warm starts (the pressures of DFSPH's constant-density
//! solve, the impulses of its divergence-free solve and the implicit viscosity's velocity
//! change of the last substep, from which the next substep's solves start), how far each emitter's fluid has moved since its
//! last layer, and where each collider is and how fast it moves.

use super::collider::{same_body, Collider};
use super::Model;
use crate::error::{reserve, Error, Result};
use glam::DVec3;

/// The state of a fluid of a [`Model`]: `N` particles. `clone_from` reuses every buffer.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, Default, PartialEq)]
pub struct State {
    /// Positions (m), `N`.
    pub(super) positions: Vec<DVec3>,
    /// Velocities (m/s), `N`.
    pub(super) velocities: Vec<DVec3>,
    /// Pressure over rest density `p / ρ₀` (m²/s²), `N`: DFSPH's warm start (the last
    /// substep's constant-density solve); WCSPH's last substep (not read again).
    pub(super) pressure: Vec<f64>,
    /// DFSPH's divergence-free impulse over rest density (m²/s) of the last substep, `N`: the
    /// warm start of the next divergence-free solve.
    pub(super) divergence: Vec<f64>,
    /// The velocity change (m/s) of the last substep's implicit viscosity solve, `N`: the
    /// warm start of the next (0 with XSPH).
    pub(super) viscous: Vec<DVec3>,
    /// Simulated time (s).
    pub(super) time: f64,
    /// Per emitter of the model: the distance (m) its fluid has moved since its last layer
    /// was emitted (a layer is emitted when it reaches the spacing).
    pub(super) emitted: Vec<f64>,
    /// Per collider of the model: its shape where it is now and its velocity.
    pub(super) colliders: Vec<Collider>,
}

impl State {
    /// An empty state of `model` at time 0 (add fluid with [`State::add_block`]).
    pub fn new(model: &Model) -> Self {
        let emitted = vec![model.settings.spacing; model.emitters.len()];
        let colliders =
            model.colliders.iter().map(|b| Collider { shape: b.shape, velocity: DVec3::ZERO });
        State { emitted, colliders: colliders.collect(), ..State::default() }
    }

    /// Fill the box `[lower, upper]` (m) with particles on a cubic lattice of the model's
    /// spacing, the first half a spacing inside `lower`, all moving at `velocity` (m/s),
    /// leaving out the points closer than half a spacing to a collider or inside it (fluid
    /// at rest against a collider is where it would be against a wall). Returns how many
    /// were added.
    ///
    /// # Errors
    /// Non-finite corners or velocity, a box too small for one particle (`upper`), fluid
    /// outside every box wall of the model or overlapping fluid already added, within half a
    /// spacing (`lower`), more particles than memory allows.
    pub fn add_block(
        &mut self,
        model: &Model,
        lower: DVec3,
        upper: DVec3,
        velocity: DVec3,
    ) -> Result<usize> {
        if !lower.is_finite() || !upper.is_finite() {
            return Err(Error::invalid("lower", "the block corners must be finite"));
        }
        if !velocity.is_finite() {
            return Err(Error::invalid("velocity", "must be finite"));
        }
        let s = model.settings.spacing;
        let counts = ((upper - lower) / s + 1e-9).floor();
        if counts.min_element() < 1.0 {
            return Err(Error::invalid("upper", "the block must be at least one spacing wide"));
        }
        let total = counts.x * counts.y * counts.z;
        if total + self.len() as f64 > f64::from(u32::MAX / 4) {
            return Err(Error::invalid("upper", "the block holds too many particles"));
        }
        let inside = |p: DVec3| {
            model.walls.iter().all(|w| !matches!(w, super::Wall::Box { .. }))
                || model
                    .walls
                    .iter()
                    .any(|w| matches!(w, super::Wall::Box { .. }) && w.contains(p, 0.25 * s))
        };
        let last = lower + (counts - 0.5) * s;
        if !inside(lower + 0.5 * s) || !inside(last) {
            return Err(Error::invalid("lower", "the block is not inside a tank of the fluid"));
        }
        let (lo, hi) = (lower - 0.5 * s, lower + counts * s + 0.5 * s);
        if self.positions.iter().any(|p| p.cmpgt(lo).all() && p.cmplt(hi).all()) {
            return Err(Error::invalid(
                "lower",
                "the block overlaps fluid already added (particles would sit on top of each other)",
            ));
        }
        reserve("upper", &mut self.positions, total as usize)?;
        reserve("upper", &mut self.velocities, total as usize)?;
        reserve("upper", &mut self.pressure, total as usize)?;
        reserve("upper", &mut self.divergence, total as usize)?;
        reserve("upper", &mut self.viscous, total as usize)?;
        let [cx, cy, cz] = counts.to_array().map(|c| c as usize);
        let before = self.positions.len();
        let clear = |p: DVec3| self.colliders.iter().all(|c| c.shape.distance(p).0 > 0.499 * s);
        let mut points = Vec::new();
        for k in 0..cz {
            for j in 0..cy {
                for i in 0..cx {
                    let p = lower + DVec3::new(i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5) * s;
                    if clear(p) {
                        points.push(p);
                    }
                }
            }
        }
        self.positions.extend_from_slice(&points);
        let n = self.positions.len() - before;
        self.velocities.resize(self.positions.len(), velocity);
        self.pressure.resize(self.positions.len(), 0.0);
        self.divergence.resize(self.positions.len(), 0.0);
        self.viscous.resize(self.positions.len(), DVec3::ZERO);
        Ok(n)
    }

    /// Number of fluid particles.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Whether there is no fluid.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Positions (m), `(N, 3)`.
    pub fn positions(&self) -> &[DVec3] {
        &self.positions
    }

    /// Velocities (m/s), `(N, 3)`.
    pub fn velocities(&self) -> &[DVec3] {
        &self.velocities
    }

    /// Pressure over rest density `p / ρ₀` (m²/s²) of the last substep's constant-density
    /// solve (DFSPH) or equation of state (WCSPH), `N`; multiply by `ρ₀` for pascals.
    pub fn pressures(&self) -> &[f64] {
        &self.pressure
    }

    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        self.time
    }

    /// The colliders where they are now, one per collider of the model.
    pub fn colliders(&self) -> &[Collider] {
        &self.colliders
    }

    /// Move collider `index` of `model` to `collider`'s pose and velocity (between steps; a
    /// scene sets a rigid body's pose each frame). Fluid it now covers is pushed out by the
    /// next substep.
    ///
    /// # Errors
    /// No such collider (`index`); the checks of [`Collider`]'s shape and velocity (named);
    /// another kind or size than the collider added (`shape`; a capsule may change its
    /// length, see the `collider` module). The state is then unchanged.
    pub fn set_collider(&mut self, model: &Model, index: usize, collider: Collider) -> Result<()> {
        let Some(body) = model.colliders.get(index) else {
            return Err(Error::invalid("index", "no such collider"));
        };
        let collider = collider.checked(model.settings.spacing)?;
        if !same_body(&body.shape, &collider.shape) {
            return Err(Error::invalid(
                "shape",
                "a collider keeps its kind and size (only its pose and velocity change)",
            ));
        }
        let Some(slot) = self.colliders.get_mut(index) else {
            return Err(Error::invalid("index", "this state predates the collider"));
        };
        *slot = collider;
        Ok(())
    }

    /// Overwrite the velocities (m/s), e.g. to start a state in motion.
    ///
    /// # Errors
    /// A length other than [`State::len`] or a non-finite value (`velocities`, with index).
    pub fn set_velocities(&mut self, velocities: &[DVec3]) -> Result<()> {
        if velocities.len() != self.len() {
            return Err(Error::invalid("velocities", "expected one per fluid particle"));
        }
        if let Some(i) = velocities.iter().position(|v| !v.is_finite()) {
            return Err(Error::invalid("velocities", "contains NaN or infinity").at(i));
        }
        self.velocities.copy_from_slice(velocities);
        Ok(())
    }
}
