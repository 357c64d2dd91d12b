//! Emitters: particles born at a rate into dead slots, with a position and velocity drawn
//! from balls around their means and the rendering properties of Reeves (1983), and ageing
//! and retirement at the end of a lifespan. Random numbers are the emitter's own SplitMix64
//! stream (Steele, Lea & Flood 2014), so emission does not depend on the threads.

use super::solver::Step;
use super::{certify, Result, CHUNK};
use crate::error::Error;
use glam::DVec3;
use rayon::prelude::*;

impl Step<'_> {
    /// Age the particles and retire those past their lifespan ([`age_slots`]).
    pub(super) fn age(&mut self, dt: f64) {
        let n = self.model.n;
        self.solver.stats.expired += self.state.y[3 * n..]
            .par_chunks_mut(3 * CHUNK)
            .zip(self.state.alive.par_chunks_mut(CHUNK))
            .zip(self.state.age.par_chunks_mut(CHUNK).zip(self.state.lifespan.par_chunks(CHUNK)))
            .map(|((vs, alive), (age, lifespan))| age_slots(dt, alive, age, lifespan, vs))
            .sum::<usize>();
        if let Some(masses) =
            self.state.summary.masses.as_mut().filter(|_| self.solver.stats.expired > 0)
        {
            masses.uniform = None;
        }
        if self.solver.stats.expired > 0 {
            self.state.summary.slots = None;
        }
    }

    /// Emit new particles into dead slots: each emitter owes the whole part of its
    /// accumulated `rate dt`; as many as there are dead slots are emitted (lowest slots
    /// first, emitters in the order added) and the rest are counted as dropped at once, so a
    /// step costs O(capacity) whatever the rate (a rate of 1e300 /s fills the free slots).
    pub(super) fn emit(&mut self, dt: f64) {
        let n = self.model.n;
        let mut cursor = 0;
        let (model, state) = (self.model, &mut *self.state);
        for (emitter, (accum, rng)) in model.emitters.iter().zip(&mut state.emitters) {
            *accum += emitter.rate * dt;
            // Subtracting the whole part is exact, as subtracting 1 that many times was.
            let owed = accum.floor();
            *accum = if owed.is_finite() { *accum - owed } else { 0.0 };
            // `as` saturates: more than usize::MAX owed counts as usize::MAX.
            for k in 0..owed as usize {
                while cursor < n && state.alive[cursor] {
                    cursor += 1;
                }
                if cursor == n {
                    self.solver.stats.dropped =
                        self.solver.stats.dropped.saturating_add(owed as usize - k);
                    break;
                }
                let i = cursor;
                let x = emitter.position + emitter.position_spread * uniform_in_ball(rng);
                let v = emitter.velocity + emitter.velocity_spread * uniform_in_ball(rng);
                state.y[3 * i..3 * i + 3].copy_from_slice(&x.to_array());
                state.y[3 * n + 3 * i..3 * n + 3 * i + 3].copy_from_slice(&v.to_array());
                state.alive[i] = true;
                state.age[i] = 0.0;
                state.lifespan[i] = emitter.lifespan;
                state.mass[i] = emitter.mass;
                state.inv_mass[i] = 1.0 / emitter.mass;
                (state.color[i], state.size[i]) = emitter.appearance.draw(rng);
                self.solver.stats.emitted += 1;
            }
        }
        if self.solver.stats.emitted > 0 || self.solver.stats.expired > 0 {
            self.state.state_changed();
            self.state.summary.slots = None;
        }
        if self.solver.stats.emitted > 0 {
            let emitted = emitted_bound(&self.model.emitters);
            self.state.summary.state = self.state.summary.state.map(|b| b.max(emitted));
        }
    }
}

/// Emits particles at a rate into dead slots.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, PartialEq)]
pub struct Emitter {
    /// Particles per second.
    pub rate: f64,
    /// Centre of the emission ball (m).
    pub position: DVec3,
    /// Radius of the emission ball (m); 0 emits from a point.
    pub position_spread: f64,
    /// Mean initial velocity (m/s).
    pub velocity: DVec3,
    /// Radius of the ball of velocity perturbations (m/s).
    pub velocity_spread: f64,
    /// Lifespan of emitted particles (s); infinite: they never expire.
    pub lifespan: f64,
    /// Mass of emitted particles (kg).
    pub mass: f64,
    /// Seed of the emitter's random numbers.
    pub seed: u64,
    /// Colour and size of emitted particles.
    pub appearance: Appearance,
}

/// The rendering properties an emitter gives its particles (Reeves 1983, "Particle systems —
/// a technique for modeling a class of fuzzy objects": each particle carries a colour and a
/// size besides its motion), as a mean and a spread like the emitter's position and velocity.
/// The spreads draw from the emitter's random numbers after the position and the velocity,
/// and only when they are not zero, so constant appearance leaves the motion unchanged.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Appearance {
    /// Mean colour, linear RGBA, each channel in `[0, 1]`.
    pub color: [f64; 4],
    /// Half-width of the uniform spread of each of R, G and B (alpha is kept); the drawn
    /// channel is clamped to `[0, 1]`.
    pub color_spread: f64,
    /// Mean size: the particle's diameter (m), `> 0`.
    pub size: f64,
    /// Half-width of the uniform spread of the size (m), `0 <= size_spread < size`.
    pub size_spread: f64,
}

impl Default for Appearance {
    /// Opaque white, 1 cm, no spread.
    fn default() -> Self {
        Appearance { color: [1.0; 4], color_spread: 0.0, size: 0.01, size_spread: 0.0 }
    }
}

impl Appearance {
    /// `Ok` when every value is in its range (see the fields), else the argument at fault.
    fn check(&self) -> Result<()> {
        if !self.color.iter().all(|c| (0.0..=1.0).contains(c)) {
            return Err(Error::invalid(
                "color",
                format!("channels must lie in [0, 1], got {:?}", self.color),
            ));
        }
        if !(self.color_spread.is_finite() && self.color_spread >= 0.0) {
            return Err(Error::invalid(
                "color_spread",
                format!("must be finite and >= 0, got {}", self.color_spread),
            ));
        }
        if !(self.size.is_finite() && self.size > 0.0) {
            return Err(Error::invalid(
                "size",
                format!("must be finite and > 0, got {}", self.size),
            ));
        }
        if !(self.size_spread >= 0.0 && self.size_spread < self.size) {
            return Err(Error::invalid(
                "size_spread",
                format!("must lie in [0, size) = [0, {}), got {}", self.size, self.size_spread),
            ));
        }
        Ok(())
    }

    /// A colour and a size drawn from `rng` (nothing drawn for a zero spread).
    fn draw(&self, rng: &mut u64) -> ([f64; 4], f64) {
        let mut color = self.color;
        if self.color_spread > 0.0 {
            for c in &mut color[..3] {
                *c = (*c + self.color_spread * uniform_symmetric(rng)).clamp(0.0, 1.0);
            }
        }
        let mut size = self.size;
        if self.size_spread > 0.0 {
            size += self.size_spread * uniform_symmetric(rng);
        }
        (color, size)
    }
}

impl Emitter {
    /// Check the parameters: rate and spreads finite and >= 0, lifespan > 0 (may be infinite),
    /// mass finite and > 0, position and velocity finite, and the appearance (colour, size) valid.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] naming the field (`rate`, `mass`, ...) that is out of range.
    pub fn validate(&self) -> Result<()> {
        let e = self;
        let finite = |v: f64| v.is_finite() && v >= 0.0;
        for (arg, ok, what) in [
            ("rate", finite(e.rate), "must be finite and >= 0"),
            ("position", e.position.is_finite(), "must be finite"),
            ("velocity", e.velocity.is_finite(), "must be finite"),
            ("position_spread", finite(e.position_spread), "must be finite and >= 0"),
            ("velocity_spread", finite(e.velocity_spread), "must be finite and >= 0"),
            ("lifespan", e.lifespan > 0.0, "must be positive (inf: forever)"),
            ("mass", e.mass.is_finite() && e.mass > 0.0, "must be positive and finite"),
        ] {
            if !ok {
                return Err(Error::invalid(arg, what));
            }
        }
        e.appearance.check()
    }
}

pub(super) fn splitmix(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Uniform in `[-1, 1)`.
pub(super) fn uniform_symmetric(state: &mut u64) -> f64 {
    (splitmix(state) >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
}

pub(super) fn uniform_in_ball(state: &mut u64) -> DVec3 {
    loop {
        let mut u = || uniform_symmetric(state);
        let p = DVec3::new(u(), u(), u());
        if p.length_squared() <= 1.0 {
            return p;
        }
    }
}

/// Age the live slots of `alive` by `dt` and retire those that reach their `lifespan`
/// (velocities `vs`, three per slot, set to zero); returns how many retired. A particle with
/// an infinite lifespan never retires, even if its age overflows to infinity.
#[inline(always)]
pub(super) fn age_slots(
    dt: f64,
    alive: &mut [bool],
    age: &mut [f64],
    lifespan: &[f64],
    vs: &mut [f64],
) -> usize {
    let mut expiring = false;
    for k in 0..alive.len() {
        let older = age[k] + dt;
        age[k] = if alive[k] { older } else { age[k] };
        expiring |= alive[k] & (age[k] >= lifespan[k]) & (lifespan[k] < f64::INFINITY);
    }
    if !expiring {
        return 0;
    }
    let mut expired = 0;
    for k in 0..alive.len() {
        if alive[k] && age[k] >= lifespan[k] && lifespan[k] < f64::INFINITY {
            alive[k] = false;
            expired += 1;
            vs[3 * k..3 * k + 3].fill(0.0);
        }
    }
    expired
}

/// A bound on |component| of the position and velocity of any particle the emitters make
/// (m, m/s).
pub(super) fn emitted_bound(emitters: &[Emitter]) -> f64 {
    let mag = certify::mag;
    emitters.iter().fold(0.0, |b, e| {
        b.max(mag(e.position) + e.position_spread).max(mag(e.velocity) + e.velocity_spread)
    })
}

/// Age the live slots of `alive` by `steps` steps of `dt`: bitwise [`age_slots`] called
/// `steps` times when no lifespan is finite.
pub(super) fn age_live(dt: f64, steps: usize, alive: &[bool], age: &mut [f64]) {
    // Eight slots at a time, each added to `steps` times in registers.
    const LANES: usize = 8;
    age.par_chunks_mut(CHUNK).zip(alive.par_chunks(CHUNK)).for_each(|(age, alive)| {
        for (age, alive) in age.chunks_mut(LANES).zip(alive.chunks(LANES)) {
            let mut older = [0.0; LANES];
            older.iter_mut().zip(&*age).for_each(|(o, a)| *o = *a);
            for _ in 0..steps {
                older.iter_mut().for_each(|o| *o += dt);
            }
            for ((a, older), &live) in age.iter_mut().zip(older).zip(alive) {
                *a = if live { older } else { *a };
            }
        }
    });
}
