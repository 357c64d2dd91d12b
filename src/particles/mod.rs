//! Particle systems: state as a struct of arrays, forces, colliders with restitution and
//! Coulomb friction, emitters with age and lifespan, stepped by any fixed-step method of
//! [`crate::ode`].
//!
//! The state is one buffer `y = [x; v]` (positions then velocities, `3 capacity` values each)
//! so that the shared integrators step it directly and Python can view positions and
//! velocities without a copy. The capacity is fixed at construction: emitters recycle dead
//! slots and never reallocate. Pinned particles have infinite mass (inverse mass 0).
//!
//! A step: integrate forces with the chosen method (Witkin & Baraff, *Physically Based
//! Modeling*, SIGGRAPH course notes, "Particle system dynamics"), then resolve collisions by
//! projecting penetrating particles onto the surface and applying a normal impulse with
//! restitution and a Coulomb friction impulse (static when the tangential speed can be
//! cancelled, dynamic otherwise; the same bound `μ × penetration` limits the tangential
//! displacement of the step, as in position-based friction, Macklin et al. 2014), then age
//! particles and emit new ones. Contacts slower than
//! twice the speed gravity adds in one step are treated as resting (no bounce), which keeps
//! resting particles exactly on the surface without jitter.

mod explicit;
mod forces;
mod jacobian;
mod snapshot;

pub use forces::{curl_noise, noise_with_gradient, Force};

use crate::error::{filled, reserve, too_large, Error, Result};
use crate::ode::{Method, OdeSystem, SparseJacobian, Stepper};
use crate::sdf;
use glam::{DQuat, DVec3};
use rayon::prelude::*;

/// Particles per parallel chunk.
const CHUNK: usize = 4096;

/// A surface particles collide with.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, PartialEq)]
pub enum Collider {
    /// The half-space above the plane through `point` with unit `normal` is free.
    Plane {
        /// A point of the plane (m).
        point: DVec3,
        /// Normal pointing to the free side (normalised here).
        normal: DVec3,
        /// Coefficient of restitution in [0, 1].
        restitution: f64,
        /// Coulomb friction coefficient >= 0.
        friction: f64,
    },
    /// A sphere; particles stay outside it, or inside it with `inside`.
    Sphere {
        /// Centre (m).
        center: DVec3,
        /// Radius (m) > 0.
        radius: f64,
        /// Keep particles inside instead of outside.
        inside: bool,
        /// Coefficient of restitution in [0, 1].
        restitution: f64,
        /// Coulomb friction coefficient >= 0.
        friction: f64,
        /// Velocity of the sphere (m/s): restitution and friction act on the particle's
        /// velocity relative to it (a moving collider pushes and drags particles along).
        velocity: DVec3,
    },
    /// A capsule, the points within `radius` of the segment `a`–`b`; particles stay outside.
    Capsule {
        /// One end of the axis (m).
        a: DVec3,
        /// The other end (m); may equal `a` (a sphere).
        b: DVec3,
        /// Radius (m) > 0.
        radius: f64,
        /// Coefficient of restitution in [0, 1].
        restitution: f64,
        /// Coulomb friction coefficient >= 0.
        friction: f64,
        /// Velocity of the capsule (m/s), as for a sphere.
        velocity: DVec3,
    },
    /// A box; particles stay outside.
    Box {
        /// Centre (m).
        center: DVec3,
        /// Orientation (body → world, unit).
        rotation: DQuat,
        /// Half extents along the box's axes (m) > 0.
        half: DVec3,
        /// Coefficient of restitution in [0, 1].
        restitution: f64,
        /// Coulomb friction coefficient >= 0.
        friction: f64,
        /// Velocity of the box (m/s), as for a sphere.
        velocity: DVec3,
    },
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

/// Counters of the last call to [`ParticleSystem::step`].
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, Default, PartialEq)]
pub struct StepStats {
    /// Particles emitted.
    pub emitted: usize,
    /// Emissions dropped for lack of a dead slot.
    pub dropped: usize,
    /// Particles that reached their lifespan.
    pub expired: usize,
    /// Collision responses applied.
    pub contacts: usize,
}

/// What a call of the explicit kernel restores when one of its steps fails
/// ([`ParticleSystem::explicit_steps`]).
#[derive(Clone, Debug, Default)]
struct Rollback {
    /// Positions then velocities (`6 capacity` values), copied by the call's first step.
    y: Vec<f64>,
    /// With emitters and more than one step: every slot's alive flag, age, lifespan, mass and
    /// inverse mass, and each emitter's accumulator and random state, copied before the call.
    /// (Colours and sizes are not copied: only emission writes them, and the replay of the
    /// good steps emits the same particles again from the restored random state.)
    alive: Vec<bool>,
    age: Vec<f64>,
    lifespan: Vec<f64>,
    mass: Vec<f64>,
    inv_mass: Vec<f64>,
    emitters: Vec<(f64, u64)>,
}

/// What the explicit kernel would otherwise read every slot for in every call, kept between
/// calls; not part of a snapshot (each part is rebuilt when unknown).
#[derive(Clone, Debug, Default)]
struct Summary {
    /// A bound on |component| of the position and velocity of every live, movable particle
    /// (m, m/s), known after a call of the explicit kernel and forgotten when the state is
    /// handed out for writing or stepped by another path.
    state: Option<f64>,
    /// The slots' masses.
    masses: Option<Masses>,
    /// The largest |component| of the external forces (N).
    external: Option<f64>,
}

/// The slots' masses as the explicit kernel needs them.
#[derive(Clone, Copy, Debug)]
struct Masses {
    /// `(mass, inverse mass)` when every slot is alive and moves with this same mass.
    uniform: Option<(f64, f64)>,
    /// The largest mass (kg) and inverse mass (1/kg) of a slot that moves or of a particle an
    /// emitter makes: bounds that stay true as particles die and are emitted.
    largest: (f64, f64),
}

impl Masses {
    fn of(
        mass: &[f64],
        inv_mass: &[f64],
        alive: &[bool],
        emitters: &[(Emitter, f64, u64)],
    ) -> Self {
        let movable =
            |(&m, &inv_m): (&f64, &f64)| if inv_m != 0.0 { (m, inv_m) } else { (0.0, 0.0) };
        let largest = mass
            .par_chunks(CHUNK)
            .zip(inv_mass.par_chunks(CHUNK))
            .map(|(m, inv_m)| {
                m.iter()
                    .zip(inv_m)
                    .map(movable)
                    .fold((0.0, 0.0), |(a, b), (m, inv_m)| (f64::max(a, m), f64::max(b, inv_m)))
            })
            .reduce(|| (0.0, 0.0), |(a, b), (c, d)| (a.max(c), b.max(d)));
        let largest =
            emitters.iter().fold(largest, |(a, b), (e, ..)| (a.max(e.mass), b.max(1.0 / e.mass)));
        Masses { uniform: uniform_mass(mass, inv_mass, alive), largest }
    }
}

/// A fixed-capacity particle system.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub struct ParticleSystem {
    n: usize,
    y: Vec<f64>,
    backup: Vec<f64>,
    /// The state at the start of a call of the explicit kernel, rebuilt by each call.
    #[serde(skip)]
    rollback: Rollback,
    #[serde(skip)]
    summary: Summary,
    mass: Vec<f64>,
    inv_mass: Vec<f64>,
    age: Vec<f64>,
    /// Steps `(dt, count)` not yet added to the ages of the live slots: without emitters
    /// nothing reads the ages between calls, so the calls leave them to the next reader
    /// ([`ParticleSystem::settle_ages`]) instead of passing over them.
    age_pending: (f64, usize),
    lifespan: Vec<f64>,
    alive: Vec<bool>,
    /// Colour of each slot (linear RGBA in `[0, 1]`), set by [`Appearance`] on emission.
    color: Vec<[f64; 4]>,
    /// Size of each slot (diameter, m), set by [`Appearance`] on emission.
    size: Vec<f64>,
    forces: Vec<Force>,
    colliders: Vec<Collider>,
    emitters: Vec<(Emitter, f64, u64)>,
    cells: Vec<(u64, u32)>,
    /// Forces set from outside for the next steps (N, 3 per slot), empty when unused.
    external: Vec<f64>,
    stepper: Option<Stepper>,
    /// Buffers of the sparse Jacobian for the implicit methods, rebuilt at every evaluation.
    #[serde(skip)]
    jacobian: jacobian::JacobianWork,
    time: f64,
    /// Counters of the last step call.
    pub stats: StepStats,
}

fn splitmix(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Uniform in `[-1, 1)`.
fn uniform_symmetric(state: &mut u64) -> f64 {
    (splitmix(state) >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
}

fn uniform_in_ball(state: &mut u64) -> DVec3 {
    loop {
        let mut u = || uniform_symmetric(state);
        let p = DVec3::new(u(), u(), u());
        if p.length_squared() <= 1.0 {
            return p;
        }
    }
}

impl ParticleSystem {
    /// A system of `positions.len()` live particles (and room for `capacity` in all; extra
    /// slots start dead) with the given velocities and masses (kg; `f64::INFINITY` pins a
    /// particle).
    ///
    /// # Errors
    /// Length mismatches, non-finite positions or velocities, masses that are not positive
    /// (or infinite), a capacity below the particle count.
    pub fn new(
        positions: &[DVec3],
        velocities: &[DVec3],
        masses: &[f64],
        capacity: usize,
    ) -> Result<Self> {
        let live = positions.len();
        if velocities.len() != live || masses.len() != live {
            return Err(Error::invalid(
                "velocities",
                "positions, velocities and masses must have the same length",
            ));
        }
        if capacity < live {
            return Err(Error::invalid(
                "capacity",
                format!("{capacity} is below the {live} particles given"),
            ));
        }
        for (arg, v) in [("positions", positions), ("velocities", velocities)] {
            if let Some(i) = v.iter().position(|p| !p.is_finite()) {
                return Err(Error::InvalidInput {
                    arg: arg.into(),
                    index: Some(i),
                    reason: "contains NaN or infinity".into(),
                });
            }
        }
        if let Some(i) = masses.iter().position(|m| m.is_nan() || *m <= 0.0) {
            return Err(Error::InvalidInput {
                arg: "masses".into(),
                index: Some(i),
                reason: format!("must be positive (inf pins), got {}", masses[i]),
            });
        }
        let n = capacity;
        // Every buffer is sized by the capacity: allocate them all or report the capacity.
        let arg = "capacity";
        let mut y = filled(arg, n.checked_mul(6).ok_or_else(|| too_large(arg, n, 48))?, 0.0)?;
        for i in 0..live {
            y[3 * i..3 * i + 3].copy_from_slice(&positions[i].to_array());
            y[3 * n + 3 * i..3 * n + 3 * i + 3].copy_from_slice(&velocities[i].to_array());
        }
        let mut mass = filled(arg, n, 1.0)?;
        mass[..live].copy_from_slice(masses);
        let mut inv_mass = filled(arg, n, 1.0)?;
        for (inv, m) in inv_mass.iter_mut().zip(masses) {
            *inv = if m.is_finite() { 1.0 / m } else { 0.0 };
        }
        let mut alive = filled(arg, n, false)?;
        alive[..live].fill(true);
        let mut cells = Vec::new();
        reserve(arg, &mut cells, n)?;
        Ok(ParticleSystem {
            n,
            backup: Vec::new(),
            rollback: Rollback::default(),
            summary: Summary::default(),
            y,
            inv_mass,
            mass,
            age: filled(arg, n, 0.0)?,
            age_pending: (0.0, 0),
            lifespan: filled(arg, n, f64::INFINITY)?,
            alive,
            color: filled(arg, n, Appearance::default().color)?,
            size: filled(arg, n, Appearance::default().size)?,
            forces: Vec::new(),
            colliders: Vec::new(),
            emitters: Vec::new(),
            cells,
            external: Vec::new(),
            stepper: None,
            jacobian: jacobian::JacobianWork::default(),
            time: 0.0,
            stats: StepStats::default(),
        })
    }

    /// Become `other` (e.g. an earlier [`crate::snapshot::Snapshot`] of this system), copying
    /// its state into this system's state buffer, which stays in place so views of it stay
    /// valid (a scene undoes a failed step this way).
    ///
    /// # Errors
    /// [`Error::InvalidInput`] (argument `"data"`) if `other` has another capacity.
    pub fn restore(&mut self, other: ParticleSystem) -> Result<()> {
        if other.y.len() != self.y.len() {
            return Err(Error::invalid("data", "is a particle system of another capacity"));
        }
        let mut y = std::mem::take(&mut self.y);
        y.copy_from_slice(&other.y);
        *self = ParticleSystem { y, ..other };
        Ok(())
    }

    /// Number of slots (live and dead).
    pub fn capacity(&self) -> usize {
        self.n
    }

    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Positions, `3 capacity` values (x, y, z per slot) (m).
    pub fn positions(&self) -> &[f64] {
        &self.y[..3 * self.n]
    }

    /// Velocities, `3 capacity` values (m/s).
    pub fn velocities(&self) -> &[f64] {
        &self.y[3 * self.n..]
    }

    /// The whole state `[x; v]` for writing; call [`ParticleSystem::state_changed`] after.
    pub fn state_mut(&mut self) -> &mut [f64] {
        self.summary.state = None;
        &mut self.y
    }

    /// The free (unconstrained) equations of motion, the state and the inverse masses, for
    /// systems that step the particles themselves (constraints).
    pub(crate) fn parts(&mut self) -> (Dynamics<'_>, &mut [f64], &[f64], &mut f64) {
        self.summary.state = None;
        let dynamics = Dynamics {
            n: self.n,
            forces: &self.forces,
            mass: &self.mass,
            inv_mass: &self.inv_mass,
            alive: &self.alive,
            external: &self.external,
            cells: &mut self.cells,
            jacobian: Some(&mut self.jacobian),
        };
        (dynamics, &mut self.y, &self.inv_mass, &mut self.time)
    }

    /// Set forces (N, world frame; `3 capacity` values) that act in the following steps, held
    /// constant within each step, for force fields computed outside (e.g. Python callables);
    /// an empty slice removes them.
    ///
    /// # Errors
    /// A wrong length or non-finite values (named by slot).
    pub fn set_external_forces(&mut self, forces: &[f64]) -> Result<()> {
        if !forces.is_empty() && forces.len() != 3 * self.n {
            return Err(Error::invalid(
                "forces",
                format!("expected {} values (capacity x 3), got {}", 3 * self.n, forces.len()),
            ));
        }
        if let Some(i) = forces.iter().position(|f| !f.is_finite()) {
            return Err(Error::InvalidInput {
                arg: "forces".into(),
                index: Some(i / 3),
                reason: "contains NaN or infinity".into(),
            });
        }
        self.external.clear();
        self.external.extend_from_slice(forces);
        self.summary.external = None;
        Ok(())
    }

    /// Forget integrator history after the state was changed from outside.
    pub fn state_changed(&mut self) {
        if let Some(s) = self.stepper.as_mut() {
            s.reset();
        }
    }

    /// Which slots hold live particles.
    pub fn alive(&self) -> &[bool] {
        &self.alive
    }

    /// Age of each slot (s): borrowed, or computed when steps are still to be added to the
    /// ages (see [`ParticleSystem::step`]: calls without emitters leave that to the reader).
    pub fn ages(&self) -> std::borrow::Cow<'_, [f64]> {
        let (dt, steps) = self.age_pending;
        if steps == 0 {
            return std::borrow::Cow::Borrowed(&self.age);
        }
        let mut age = self.age.clone();
        age_live(dt, steps, &self.alive, &mut age);
        std::borrow::Cow::Owned(age)
    }

    /// Add the pending steps to the ages of the live slots ([`age_live`]).
    fn settle_ages(&mut self) {
        let (dt, steps) = std::mem::take(&mut self.age_pending);
        if steps > 0 {
            age_live(dt, steps, &self.alive, &mut self.age);
        }
    }

    /// Mass of each slot (kg; infinite when pinned).
    pub fn masses(&self) -> &[f64] {
        &self.mass
    }

    /// Colour of each slot (linear RGBA in `[0, 1]`; opaque white unless an emitter or
    /// [`ParticleSystem::set_appearance`] set it). Slots are never reordered, so a particle
    /// keeps its colour while others die.
    pub fn colors(&self) -> &[[f64; 4]] {
        &self.color
    }

    /// Size of each slot (diameter, m; [`Appearance::default`]'s 1 cm unless set).
    pub fn sizes(&self) -> &[f64] {
        &self.size
    }

    /// Set the colour (linear RGBA in `[0, 1]`) and size (diameter, m, `> 0`) of every slot
    /// (`capacity` of each), e.g. of the particles given at construction.
    ///
    /// # Errors
    /// Wrong lengths, a channel outside `[0, 1]` (argument `colors`), a size that is not
    /// positive and finite (`sizes`); nothing is changed then.
    pub fn set_appearance(&mut self, colors: &[[f64; 4]], sizes: &[f64]) -> Result<()> {
        for (arg, len) in [("colors", colors.len()), ("sizes", sizes.len())] {
            if len != self.n {
                return Err(Error::invalid(
                    arg,
                    format!("expected {} rows (the capacity), got {len}", self.n),
                ));
            }
        }
        if let Some(i) = colors.iter().position(|c| !c.iter().all(|c| (0.0..=1.0).contains(c))) {
            return Err(Error::InvalidInput {
                arg: "colors".into(),
                index: Some(i),
                reason: "channels must lie in [0, 1]".into(),
            });
        }
        if let Some(i) = sizes.iter().position(|s| !(s.is_finite() && *s > 0.0)) {
            return Err(Error::InvalidInput {
                arg: "sizes".into(),
                index: Some(i),
                reason: format!("must be finite and > 0, got {}", sizes[i]),
            });
        }
        self.color.copy_from_slice(colors);
        self.size.copy_from_slice(sizes);
        Ok(())
    }

    /// Add a force.
    ///
    /// # Errors
    /// Invalid parameters ([`Force::validate`]).
    pub fn add_force(&mut self, force: Force) -> Result<()> {
        force.validate(self.n)?;
        self.forces.push(match force {
            Force::Vortex { center, axis, strength, core } => {
                Force::Vortex { center, axis: axis.normalize(), strength, core }
            }
            f => f,
        });
        Ok(())
    }

    /// Add a collider.
    ///
    /// # Errors
    /// Non-finite or out-of-range parameters (restitution outside [0, 1], negative friction,
    /// zero normal, non-positive radius).
    pub fn add_collider(&mut self, collider: Collider) -> Result<()> {
        let c = Self::checked(collider)?;
        self.colliders.push(c);
        Ok(())
    }

    /// Replace collider `index` (move a collider between steps, e.g. one that follows an
    /// animated or rigid body).
    ///
    /// # Errors
    /// `index` out of range, or the errors of [`ParticleSystem::add_collider`].
    pub fn set_collider(&mut self, index: usize, collider: Collider) -> Result<()> {
        if index >= self.colliders.len() {
            return Err(Error::invalid(
                "index",
                format!("no collider {index}: there are {}", self.colliders.len()),
            ));
        }
        self.colliders[index] = Self::checked(collider)?;
        Ok(())
    }

    /// The collider, validated, with its plane normal made unit.
    fn checked(collider: Collider) -> Result<Collider> {
        let (e, mu) = match &collider {
            Collider::Plane { point, normal, restitution, friction } => {
                if !(point.is_finite() && normal.is_finite() && normal.length() > 0.0) {
                    return Err(Error::invalid(
                        "normal",
                        "plane needs a finite point and a non-zero normal",
                    ));
                }
                (*restitution, *friction)
            }
            Collider::Sphere { center, radius, restitution, friction, velocity, .. } => {
                if !(center.is_finite() && radius.is_finite() && *radius > 0.0) {
                    return Err(Error::invalid(
                        "radius",
                        "sphere needs a finite centre and a positive radius",
                    ));
                }
                if !velocity.is_finite() {
                    return Err(Error::invalid("velocity", "must be finite"));
                }
                (*restitution, *friction)
            }
            Collider::Capsule { a, b, radius, restitution, friction, velocity } => {
                if !(a.is_finite() && b.is_finite() && radius.is_finite() && *radius > 0.0) {
                    return Err(Error::invalid(
                        "radius",
                        "capsule needs finite ends and a positive radius",
                    ));
                }
                if !velocity.is_finite() {
                    return Err(Error::invalid("velocity", "must be finite"));
                }
                (*restitution, *friction)
            }
            Collider::Box { center, rotation, half, restitution, friction, velocity } => {
                if !(center.is_finite() && half.is_finite() && half.min_element() > 0.0) {
                    return Err(Error::invalid(
                        "half_extents",
                        "box needs a finite centre and positive half extents",
                    ));
                }
                if !(rotation.is_finite() && (rotation.length() - 1.0).abs() < 1e-9) {
                    return Err(Error::invalid("orientation", "must be a unit quaternion"));
                }
                if !velocity.is_finite() {
                    return Err(Error::invalid("velocity", "must be finite"));
                }
                (*restitution, *friction)
            }
        };
        if !((0.0..=1.0).contains(&e)) {
            return Err(Error::invalid("restitution", format!("must be in [0, 1], got {e}")));
        }
        if !(mu.is_finite() && mu >= 0.0) {
            return Err(Error::invalid("friction", format!("must be finite and >= 0, got {mu}")));
        }
        Ok(match collider {
            Collider::Plane { point, normal, restitution, friction } => {
                Collider::Plane { point, normal: normal.normalize(), restitution, friction }
            }
            c => c,
        })
    }

    /// Add an emitter.
    ///
    /// # Errors
    /// Negative or non-finite rate, spreads, lifespan or mass, non-finite position or
    /// velocity (each named).
    pub fn add_emitter(&mut self, emitter: Emitter) -> Result<()> {
        emitter.validate()?;
        let seed = emitter.seed;
        self.emitters.push((emitter, 0.0, seed));
        self.summary.masses = None;
        Ok(())
    }

    /// Kinetic energy of the live, unpinned particles (J).
    pub fn kinetic_energy(&self) -> f64 {
        let v = self.velocities();
        (0..self.n)
            .filter(|&i| self.alive[i] && self.inv_mass[i] > 0.0)
            .map(|i| {
                0.5 * self.mass[i]
                    * (v[3 * i].powi(2) + v[3 * i + 1].powi(2) + v[3 * i + 2].powi(2))
            })
            .sum()
    }

    /// Potential energy of the conservative forces (gravity, springs, attractors, n-body
    /// gravity) over live particles (J).
    pub fn potential_energy(&self) -> f64 {
        let x = |i: usize| DVec3::from_slice(&self.y[3 * i..3 * i + 3]);
        let live = |i: usize| self.alive[i] && self.inv_mass[i] > 0.0;
        let mut e = 0.0;
        for f in &self.forces {
            match f {
                Force::Gravity { g } => {
                    e -= (0..self.n)
                        .filter(|&i| live(i))
                        .map(|i| self.mass[i] * g.dot(x(i)))
                        .sum::<f64>()
                }
                Force::Springs { pairs, rest, stiffness, .. } => {
                    e += pairs
                        .iter()
                        .zip(rest)
                        .map(|(p, l)| 0.5 * stiffness * ((x(p[0]) - x(p[1])).length() - l).powi(2))
                        .sum::<f64>()
                }
                Force::Attractor { center, strength, softening } => {
                    e -= (0..self.n)
                        .filter(|&i| live(i))
                        .map(|i| {
                            strength * self.mass[i]
                                / ((x(i) - *center).length_squared() + softening * softening).sqrt()
                        })
                        .sum::<f64>()
                }
                Force::NBodyGravity { constant, softening } => {
                    for i in (0..self.n).filter(|&i| live(i)) {
                        for j in (i + 1..self.n).filter(|&j| live(j)) {
                            e -= constant * self.mass[i] * self.mass[j]
                                / ((x(i) - x(j)).length_squared() + softening * softening).sqrt();
                        }
                    }
                }
                _ => {}
            }
        }
        e
    }

    /// Advance `steps` steps of `dt` seconds with `method`; the implicit methods factorise
    /// the sparse Newton matrix (see [`ParticleSystem::step_with_jacobian`]).
    ///
    /// # Errors
    /// A bad `dt`, an integrator failure, or a non-finite state ([`Error::Diverged`] naming the
    /// step and the particle); the system is left at the last good step.
    pub fn step(&mut self, dt: f64, steps: usize, method: Method) -> Result<()> {
        self.step_with_jacobian(dt, steps, method, true)
    }

    /// [`ParticleSystem::step`] with the choice of the implicit methods' Newton matrix
    /// `I - γ h J`: with `sparse`, the analytic sparse Jacobian of the forces and a sparse LU
    /// (cost growing about linearly with the particles for springs and local forces); without,
    /// a dense Jacobian by forward differences over all `6 capacity` columns and a dense LU
    /// (`O(capacity³)` per step, for comparison and for small systems). All-pairs gravity
    /// ([`Force::NBodyGravity`]) couples every particle, so with it the matrix is dense either
    /// way. Explicit methods ignore the choice.
    ///
    /// # Errors
    /// As [`ParticleSystem::step`].
    pub fn step_with_jacobian(
        &mut self,
        dt: f64,
        steps: usize,
        method: Method,
        sparse: bool,
    ) -> Result<()> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(Error::invalid("dt", format!("must be positive and finite, got {dt}")));
        }
        if self.stepper.as_ref().is_none_or(|s| s.method() != method) {
            self.stepper = Some(Stepper::new(method, 6 * self.n)?);
        }
        self.stats = StepStats::default();
        let gravity: DVec3 = self
            .forces
            .iter()
            .map(|f| if let Force::Gravity { g } = f { *g } else { DVec3::ZERO })
            .sum();
        let pairwise = self.forces.iter().any(|f| {
            matches!(
                f,
                Force::Springs { .. }
                    | Force::NeighborRepulsion { .. }
                    | Force::NBodyGravity { .. }
            )
        });
        if method == Method::SymplecticEuler && !pairwise {
            return self.explicit_steps(dt, steps, gravity);
        }
        self.summary.state = None;
        self.settle_ages();
        for s in 0..steps {
            // Keep a copy of the state to restore.
            self.backup.resize(self.y.len(), 0.0);
            self.backup
                .par_chunks_mut(6 * CHUNK)
                .zip(self.y.par_chunks(6 * CHUNK))
                .for_each(|(b, y)| b.copy_from_slice(y));
            if let Err(e) = self.one_step(dt, gravity, sparse) {
                self.y.copy_from_slice(&self.backup);
                if let Some(st) = self.stepper.as_mut() {
                    st.reset();
                }
                return Err(match e {
                    Error::Diverged { index, reason, .. } => {
                        Error::Diverged { step: s, index: index % self.n, reason }
                    }
                    other => other,
                });
            }
            self.age(dt);
            self.time += dt;
            self.emit(dt);
        }
        Ok(())
    }

    fn one_step(&mut self, dt: f64, gravity: DVec3, sparse: bool) -> Result<()> {
        let n = self.n;
        let stepper = self.stepper.as_mut().expect("stepper created in step");
        let mut dynamics = Dynamics {
            n,
            forces: &self.forces,
            mass: &self.mass,
            inv_mass: &self.inv_mass,
            alive: &self.alive,
            external: &self.external,
            cells: &mut self.cells,
            jacobian: sparse.then_some(&mut self.jacobian),
        };
        stepper.step(&mut dynamics, self.time, &mut self.y, dt).map_err(|e| match e {
            Error::Diverged { index, .. } => Error::Diverged {
                step: 0,
                index: (index % (3 * n)) / 3,
                reason: "non-finite particle state".into(),
            },
            other => other,
        })?;
        // Pinned and dead particles keep their state exactly: their equations are
        // x' = v' = 0, which the Newton solve of the implicit methods meets only to rounding
        // and which the drifts of the second-order methods (x += h v) do not read.
        let (xs, vs) = self.y.split_at_mut(3 * n);
        let (xb, vb) = self.backup.split_at(3 * n);
        for i in (0..n).filter(|&i| !self.alive[i] || self.inv_mass[i] == 0.0) {
            xs[3 * i..3 * i + 3].copy_from_slice(&xb[3 * i..3 * i + 3]);
            vs[3 * i..3 * i + 3].copy_from_slice(&vb[3 * i..3 * i + 3]);
        }
        // The integrator checked the state; projection and impulses keep finite values finite.
        self.collide(dt, gravity);
        Ok(())
    }

    fn collide(&mut self, dt: f64, gravity: DVec3) {
        if self.colliders.is_empty() {
            return;
        }
        let n = self.n;
        let (colliders, alive, inv_mass, backup) =
            (&self.colliders, &self.alive, &self.inv_mass, &self.backup);
        let (xs, vs) = self.y.split_at_mut(3 * n);
        self.stats.contacts += xs
            .par_chunks_mut(3 * CHUNK)
            .zip(vs.par_chunks_mut(3 * CHUNK))
            .enumerate()
            .map(|(c, (xc, vc))| {
                let mut contacts = 0;
                for k in 0..xc.len() / 3 {
                    let i = c * CHUNK + k;
                    if !alive[i] || inv_mass[i] == 0.0 {
                        continue;
                    }
                    let prev = DVec3::from_slice(&backup[3 * i..3 * i + 3]);
                    let (x, v) = (DVec3::from_slice(&xc[3 * k..]), DVec3::from_slice(&vc[3 * k..]));
                    let (x, v, hits) = collide_one(colliders, x, v, prev, dt, gravity);
                    if hits > 0 {
                        xc[3 * k..3 * k + 3].copy_from_slice(&x.to_array());
                        vc[3 * k..3 * k + 3].copy_from_slice(&v.to_array());
                        contacts += hits;
                    }
                }
                contacts
            })
            .sum::<usize>();
    }

    /// `steps` steps of symplectic Euler with the collision response by the explicit kernel
    /// (module `explicit`), for systems without forces between particles. Each step is
    /// computed once and written in place. Unless the steps are certified not to go
    /// non-finite ([`ParticleSystem::certified`]), the first also copies the positions and
    /// velocities it reads into `rollback` (with emitters and more than one step, the slots
    /// and the emitters' state are copied before it too: they change after each good step).
    /// When a step fails, the copy is restored and the good steps before it are taken again,
    /// which gives bitwise the state they had written (a step reads nothing but the state and
    /// the model, and the kernel's results depend neither on the threads nor on how many steps
    /// it takes at once).
    fn explicit_steps(&mut self, dt: f64, steps: usize, gravity: DVec3) -> Result<()> {
        let n = self.n;
        // Without emitters no slot is born, and none dies (lifespans are infinite: only
        // emitted particles have finite ones), so the ages can be advanced after the call.
        let age_each_step = !self.emitters.is_empty();
        if age_each_step {
            self.settle_ages();
        }
        let (time, bound) = (self.time, self.summary.state);
        let keep = !self.certified(dt, steps, gravity);
        // Aging and emission follow each good step: a call's first step changes nothing but
        // positions and velocities before it is known good.
        let keep_slots = keep && age_each_step && steps > 1;
        self.rollback.y.resize(6 * n, 0.0);
        if keep_slots {
            let r = &mut self.rollback;
            r.alive.clone_from(&self.alive);
            r.age.clone_from(&self.age);
            r.lifespan.clone_from(&self.lifespan);
            r.mass.clone_from(&self.mass);
            r.inv_mass.clone_from(&self.inv_mass);
            r.emitters.clear();
            r.emitters.extend(self.emitters.iter().map(|(_, accum, rng)| (*accum, *rng)));
        }
        let Err((step, index)) = self.explicit_run(dt, steps, gravity, age_each_step, keep) else {
            return Ok(());
        };
        let diverged = Error::Diverged { step, index, reason: "non-finite particle state".into() };
        debug_assert!(keep, "a certified step came out non-finite");
        if !keep {
            // Unreachable if `step_bound` is right: there is no copy to restore.
            self.summary.state = None;
            return Err(diverged);
        }
        let r = &self.rollback;
        self.y.par_chunks_mut(6 * CHUNK).zip(r.y.par_chunks(6 * CHUNK)).for_each(|(y, r)| {
            y.copy_from_slice(r);
        });
        if keep_slots {
            self.alive.copy_from_slice(&r.alive);
            self.age.copy_from_slice(&r.age);
            self.lifespan.copy_from_slice(&r.lifespan);
            self.mass.copy_from_slice(&r.mass);
            self.inv_mass.copy_from_slice(&r.inv_mass);
            for ((_, accum, rng), kept) in self.emitters.iter_mut().zip(&r.emitters) {
                (*accum, *rng) = *kept;
            }
            if let Some(masses) = &mut self.summary.masses {
                masses.uniform = None;
            }
        }
        (self.time, self.summary.state) = (time, bound);
        self.stats = StepStats::default();
        let replayed = self.explicit_run(dt, step, gravity, age_each_step, false);
        debug_assert!(replayed.is_ok(), "steps that were good are good again");
        Err(diverged)
    }

    /// The most steps of a call that [`ParticleSystem::certified`] tries to certify (a copy of
    /// the state costs less than one step, a small part of the time of a longer call).
    const MOST_CERTIFIED: usize = 64;

    /// Whether `steps` steps of `dt` from the current state cannot come out non-finite, so
    /// that a call needs no copy to undo them: the bound on the state kept from the last call
    /// carried through each step by [`explicit::step_bound`], with the particles the emitters
    /// may make after each step.
    fn certified(&mut self, dt: f64, steps: usize, gravity: DVec3) -> bool {
        let Some(mut bound) = self.summary.state.filter(|_| steps <= Self::MOST_CERTIFIED) else {
            return false;
        };
        let masses = self.mass_summary();
        let external = *self.summary.external.get_or_insert_with(|| {
            self.external.par_iter().map(|f| f.abs()).reduce(|| 0.0, f64::max)
        });
        let extremes =
            explicit::Extremes { mass: masses.largest.0, inv_mass: masses.largest.1, external };
        let emitted = emitted_bound(&self.emitters);
        for _ in 0..steps {
            let (forces, colliders) = (&self.forces, &self.colliders);
            bound = explicit::step_bound(forces, colliders, dt, gravity, extremes, bound);
            bound = bound.max(emitted);
            if bound == f64::INFINITY {
                return false;
            }
        }
        true
    }

    /// The slots' masses ([`Masses`]), from the summary or computed into it.
    fn mass_summary(&mut self) -> Masses {
        *self.summary.masses.get_or_insert_with(|| {
            Masses::of(&self.mass, &self.inv_mass, &self.alive, &self.emitters)
        })
    }

    /// `steps` steps of the explicit kernel (see [`ParticleSystem::explicit_steps`]). With
    /// `keep`, the first copies the state into `rollback` and each is checked: the run stops
    /// at the first step that goes non-finite and returns it with the first particle that
    /// did; without, the steps are known not to (certified, or taken before) and are not
    /// checked. With emitters
    /// the kernel runs once per step (emission comes between the steps); without, once for
    /// all of them, each block of particles taking every step while it is in the cache.
    fn explicit_run(
        &mut self,
        dt: f64,
        steps: usize,
        gravity: DVec3,
        age_each_step: bool,
        keep: bool,
    ) -> std::result::Result<(), (usize, usize)> {
        if steps == 0 {
            return Ok(());
        }
        let n = self.n;
        let uniform = if age_each_step { None } else { self.mass_summary().uniform };
        let (runs, each) = if age_each_step { (steps, 1) } else { (1, steps) };
        for run in 0..runs {
            let model = explicit::Model {
                forces: &self.forces,
                colliders: &self.colliders,
                mass: &self.mass,
                inv_mass: &self.inv_mass,
                external: &self.external,
                dt,
                gravity,
                uniform,
            };
            let (xs, vs) = self.y.split_at_mut(3 * n);
            let kept = &mut self.rollback.y;
            let guard = match (keep, run) {
                (false, _) => explicit::Guard::Certified,
                (true, 0) => explicit::Guard::Copy,
                (true, _) => explicit::Guard::Check,
            };
            let done = explicit::commit(&model, xs, vs, &self.alive, kept, guard, each);
            if let Some((s, index)) = done.bad {
                return Err((run + s, index));
            }
            self.summary.state = Some(done.bound);
            self.stats.contacts += done.contacts;
            for _ in 0..each {
                self.time += dt;
            }
            if age_each_step {
                self.age(dt);
                self.emit(dt);
            }
        }
        if !age_each_step {
            // Added by `settle_ages`, with the pending steps of another `dt` first.
            if self.age_pending.1 > 0 && self.age_pending.0.to_bits() != dt.to_bits() {
                self.settle_ages();
            }
            self.age_pending = (dt, self.age_pending.1 + steps);
        }
        Ok(())
    }

    /// Age the particles and retire those past their lifespan ([`age_slots`]).
    fn age(&mut self, dt: f64) {
        let n = self.n;
        self.stats.expired += self.y[3 * n..]
            .par_chunks_mut(3 * CHUNK)
            .zip(self.alive.par_chunks_mut(CHUNK))
            .zip(self.age.par_chunks_mut(CHUNK).zip(self.lifespan.par_chunks(CHUNK)))
            .map(|((vs, alive), (age, lifespan))| age_slots(dt, alive, age, lifespan, vs))
            .sum::<usize>();
        if let Some(masses) = self.summary.masses.as_mut().filter(|_| self.stats.expired > 0) {
            masses.uniform = None;
        }
    }

    /// Emit new particles into dead slots: each emitter owes the whole part of its
    /// accumulated `rate dt`; as many as there are dead slots are emitted (lowest slots
    /// first, emitters in the order added) and the rest are counted as dropped at once, so a
    /// step costs O(capacity) whatever the rate (a rate of 1e300 /s fills the free slots).
    fn emit(&mut self, dt: f64) {
        let n = self.n;
        let mut cursor = 0;
        for (emitter, accum, rng) in &mut self.emitters {
            *accum += emitter.rate * dt;
            // Subtracting the whole part is exact, as subtracting 1 that many times was.
            let owed = accum.floor();
            *accum = if owed.is_finite() { *accum - owed } else { 0.0 };
            // `as` saturates: more than usize::MAX owed counts as usize::MAX.
            for k in 0..owed as usize {
                while cursor < n && self.alive[cursor] {
                    cursor += 1;
                }
                if cursor == n {
                    self.stats.dropped = self.stats.dropped.saturating_add(owed as usize - k);
                    break;
                }
                let i = cursor;
                let x = emitter.position + emitter.position_spread * uniform_in_ball(rng);
                let v = emitter.velocity + emitter.velocity_spread * uniform_in_ball(rng);
                self.y[3 * i..3 * i + 3].copy_from_slice(&x.to_array());
                self.y[3 * n + 3 * i..3 * n + 3 * i + 3].copy_from_slice(&v.to_array());
                self.alive[i] = true;
                self.age[i] = 0.0;
                self.lifespan[i] = emitter.lifespan;
                self.mass[i] = emitter.mass;
                self.inv_mass[i] = 1.0 / emitter.mass;
                (self.color[i], self.size[i]) = emitter.appearance.draw(rng);
                self.stats.emitted += 1;
            }
        }
        if self.stats.emitted > 0 || self.stats.expired > 0 {
            self.state_changed();
        }
        if self.stats.emitted > 0 {
            let emitted = emitted_bound(&self.emitters);
            self.summary.state = self.summary.state.map(|b| b.max(emitted));
        }
    }
}

/// The sum of the forces of `forces` that act on one particle alone (gravity, drag, damping,
/// attractor, vortex, turbulence), in the order they were added.
fn particle_force(forces: &[Force], x: DVec3, v: DVec3, m: f64) -> DVec3 {
    let mut acc = DVec3::ZERO;
    for force in forces {
        acc += match *force {
            Force::Gravity { g } => gravity(g, m),
            Force::Drag { linear, quadratic, wind } => drag(linear, quadratic, wind, v),
            Force::Damping { rate } => damping(rate, m, v),
            Force::Attractor { center, strength, softening } => {
                attractor(center, strength, softening, x, m)
            }
            Force::Vortex { center, axis, strength, core } => {
                vortex(center, axis, strength, core, x, m)
            }
            Force::Turbulence { strength, scale, seed } => turbulence(strength, scale, seed, x, m),
            Force::Springs { .. }
            | Force::NeighborRepulsion { .. }
            | Force::NBodyGravity { .. } => DVec3::ZERO,
        };
    }
    acc
}

// The forces on one particle (N) of mass `m` at `x` with velocity `v`, as [`Force`] defines
// them; shared by `particle_force` and the explicit kernel so that both compute alike.

#[inline(always)]
fn gravity(g: DVec3, m: f64) -> DVec3 {
    m * g
}

#[inline(always)]
fn drag(linear: f64, quadratic: f64, wind: DVec3, v: DVec3) -> DVec3 {
    let u = v - wind;
    -(linear + quadratic * u.length()) * u
}

#[inline(always)]
fn damping(rate: f64, m: f64, v: DVec3) -> DVec3 {
    -rate * m * v
}

#[inline(always)]
fn attractor(center: DVec3, strength: f64, softening: f64, x: DVec3, m: f64) -> DVec3 {
    let r = center - x;
    strength * m / (r.length_squared() + softening * softening).powf(1.5) * r
}

#[inline(always)]
fn vortex(center: DVec3, axis: DVec3, strength: f64, core: f64, x: DVec3, m: f64) -> DVec3 {
    let r = x - center;
    let perp = r - r.dot(axis) * axis;
    strength * m / (perp.length() + core) * axis.cross(perp)
}

#[inline(always)]
fn turbulence(strength: f64, scale: f64, seed: u64, x: DVec3, m: f64) -> DVec3 {
    strength * m * forces::curl_noise(seed, x / scale)
}

/// Resolve the contacts of one particle at `x` with velocity `v` that was at `prev` before the
/// step; returns the new position, velocity and the number of contacts.
fn collide_one(
    colliders: &[Collider],
    mut x: DVec3,
    mut v: DVec3,
    prev: DVec3,
    dt: f64,
    gravity: DVec3,
) -> (DVec3, DVec3, usize) {
    let mut contacts = 0;
    for collider in colliders {
        let contact = surface(collider, x);
        if contact.distance >= 0.0 {
            continue;
        }
        contacts += 1;
        (x, v) = respond(&contact, x, v, prev, dt, gravity);
    }
    (x, v, contacts)
}

/// Where a point stands against a collider: the distance to the surface (negative inside the
/// solid), the outward normal, the material and the collider's velocity.
struct Contact {
    distance: f64,
    normal: DVec3,
    restitution: f64,
    friction: f64,
    velocity: DVec3,
}

/// The contact of the point `x` with `collider`.
fn surface(collider: &Collider, x: DVec3) -> Contact {
    let (distance, normal, restitution, friction, velocity) = match *collider {
        Collider::Plane { point, normal, restitution, friction } => {
            ((x - point).dot(normal), normal, restitution, friction, DVec3::ZERO)
        }
        Collider::Sphere { center, radius, inside, restitution, friction, velocity } => {
            let (d, n) = sdf::sphere(center, radius, x);
            if inside {
                (-d, -n, restitution, friction, velocity)
            } else {
                (d, n, restitution, friction, velocity)
            }
        }
        Collider::Capsule { a, b, radius, restitution, friction, velocity } => {
            let (d, n) = sdf::capsule(a, b, radius, x);
            (d, n, restitution, friction, velocity)
        }
        Collider::Box { center, rotation, half, restitution, friction, velocity } => {
            let (d, n) = sdf::oriented_box(center, rotation, half, x);
            (d, n, restitution, friction, velocity)
        }
    };
    Contact { distance, normal, restitution, friction, velocity }
}

/// The response to a penetrating `contact` (distance < 0) of a particle at `x` with velocity
/// `v` that was at `prev` before the step: the new position and velocity.
fn respond(
    contact: &Contact,
    mut x: DVec3,
    v: DVec3,
    prev: DVec3,
    dt: f64,
    gravity: DVec3,
) -> (DVec3, DVec3) {
    let Contact { distance: d, normal, restitution: e, friction: mu, velocity: vc } = *contact;
    // Project onto the surface, and apply Coulomb friction to the tangential displacement of
    // this step relative to the collider too (at most μ times the penetration), so that a
    // particle held by static friction does not creep.
    x -= d * normal;
    let moved = x - prev - vc * dt;
    let moved_t = moved - moved.dot(normal) * normal;
    let slip = moved_t.length();
    if slip > 0.0 {
        x -= moved_t * (mu * -d / slip).min(1.0);
    }
    let u = v - vc; // velocity relative to the collider
    let vn = u.dot(normal);
    if vn >= 0.0 {
        return (x, v);
    }
    let resting = -vn <= 2.0 * gravity.dot(normal).abs() * dt;
    let jn = -vn * (1.0 + if resting { 0.0 } else { e });
    let vt = u - vn * normal;
    let speed_t = vt.length();
    let vt = if speed_t <= mu * jn { DVec3::ZERO } else { vt * (1.0 - mu * jn / speed_t) };
    (x, vc + (vn + jn) * normal + vt)
}

/// Age the live slots of `alive` by `dt` and retire those that reach their `lifespan`
/// (velocities `vs`, three per slot, set to zero); returns how many retired. A particle with
/// an infinite lifespan never retires, even if its age overflows to infinity.
#[inline(always)]
fn age_slots(
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
fn emitted_bound(emitters: &[(Emitter, f64, u64)]) -> f64 {
    let mag = explicit::mag;
    emitters.iter().fold(0.0, |b, (e, ..)| {
        b.max(mag(e.position) + e.position_spread).max(mag(e.velocity) + e.velocity_spread)
    })
}

/// `(mass, inverse mass)` of every slot if all are alive, movable and of the same mass.
fn uniform_mass(mass: &[f64], inv_mass: &[f64], alive: &[bool]) -> Option<(f64, f64)> {
    let (&m, &inv_m) = (mass.first()?, inv_mass.first()?);
    let same = mass
        .par_chunks(CHUNK)
        .zip(inv_mass.par_chunks(CHUNK))
        .zip(alive.par_chunks(CHUNK))
        .all(|((mass, inv_mass), alive)| {
            let differ =
                mass.iter().zip(inv_mass).zip(alive).fold(false, |differ, ((&a, &b), &live)| {
                    differ | (a != m) | (b != inv_m) | !live
                });
            !differ
        });
    (same && inv_m != 0.0).then_some((m, inv_m))
}

/// Age the live slots of `alive` by `steps` steps of `dt`: bitwise [`age_slots`] called
/// `steps` times when no lifespan is finite.
fn age_live(dt: f64, steps: usize, alive: &[bool], age: &mut [f64]) {
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

/// The externally set force on slot `i` (zero when none is set).
fn external_force(external: &[f64], i: usize) -> DVec3 {
    if external.is_empty() {
        DVec3::ZERO
    } else {
        DVec3::from_slice(&external[3 * i..3 * i + 3])
    }
}

/// The particle equations of motion as an [`OdeSystem`] over `y = [x; v]`.
pub(crate) struct Dynamics<'a> {
    n: usize,
    forces: &'a [Force],
    mass: &'a [f64],
    inv_mass: &'a [f64],
    alive: &'a [bool],
    external: &'a [f64],
    cells: &'a mut Vec<(u64, u32)>,
    /// Buffers of the sparse Jacobian; `None` offers none (the dense path).
    jacobian: Option<&'a mut jacobian::JacobianWork>,
}

fn cell_key(c: [i64; 3]) -> u64 {
    let h = |v: i64| (v as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    h(c[0]) ^ h(c[1]).rotate_left(21) ^ h(c[2]).rotate_left(42)
}

/// Call `f(i, j, d, |d|)` for every pair `i < j` of live particles closer than `radius`
/// (and not coincident), `d = x_i - x_j`, found with a spatial hash grid of cell size `radius`
/// kept in `cells`; pairs come in a fixed order.
fn for_each_close_pair(
    cells: &mut Vec<(u64, u32)>,
    n: usize,
    alive: &[bool],
    x: &[f64],
    radius: f64,
    mut f: impl FnMut(usize, usize, DVec3, f64),
) {
    let p = |i: usize| DVec3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2]);
    let cell = |q: DVec3| {
        [
            (q.x / radius).floor() as i64,
            (q.y / radius).floor() as i64,
            (q.z / radius).floor() as i64,
        ]
    };
    cells.clear();
    cells.extend((0..n).filter(|&i| alive[i]).map(|i| (cell_key(cell(p(i))), i as u32)));
    cells.sort_unstable();
    for i in (0..n).filter(|&i| alive[i]) {
        let c = cell(p(i));
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    // Wrapping: cells of positions beyond ±2⁶³ radii saturate; their keys
                    // may then be wrong but never overflow (no panic on absurd positions).
                    let key = cell_key([
                        c[0].wrapping_add(dx),
                        c[1].wrapping_add(dy),
                        c[2].wrapping_add(dz),
                    ]);
                    let start = cells.partition_point(|e| e.0 < key);
                    for &(k, j) in &cells[start..] {
                        if k != key {
                            break;
                        }
                        let j = j as usize;
                        if j <= i {
                            continue;
                        }
                        let d = p(i) - p(j);
                        let dist = d.length();
                        if dist < radius && dist > 0.0 {
                            f(i, j, d, dist);
                        }
                    }
                }
            }
        }
    }
}

impl OdeSystem for Dynamics<'_> {
    fn dim(&self) -> usize {
        6 * self.n
    }

    fn sparse_jacobian(&mut self, _t: f64, y: &[f64], jac: &mut SparseJacobian) -> Result<bool> {
        Ok(jacobian::fill(self, y, jac))
    }

    fn rhs(&mut self, _t: f64, y: &[f64], dydt: &mut [f64]) -> Result<()> {
        let n = self.n;
        let (x, v) = y.split_at(3 * n);
        let (dx, f) = dydt.split_at_mut(3 * n);
        let p = |i: usize| DVec3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2]);
        let vel = |i: usize| DVec3::new(v[3 * i], v[3 * i + 1], v[3 * i + 2]);
        let add = |f: &mut [f64], i: usize, a: DVec3| {
            f[3 * i] += a.x;
            f[3 * i + 1] += a.y;
            f[3 * i + 2] += a.z;
        };
        let (all_forces, mass, alive, external) =
            (self.forces, self.mass, self.alive, self.external);
        // Pass 1, parallel over particles: x' = v and every force acting on one particle alone
        // (each particle's sum in the order the forces were added, whatever the threads).
        dx.par_chunks_mut(3 * CHUNK).zip(f.par_chunks_mut(3 * CHUNK)).enumerate().for_each(
            |(c, (dxc, fc))| {
                for k in 0..dxc.len() / 3 {
                    let i = c * CHUNK + k;
                    dxc[3 * k..3 * k + 3].copy_from_slice(&v[3 * i..3 * i + 3]);
                    let acc = if alive[i] {
                        particle_force(all_forces, p(i), vel(i), mass[i])
                            + external_force(external, i)
                    } else {
                        DVec3::ZERO
                    };
                    fc[3 * k..3 * k + 3].copy_from_slice(&acc.to_array());
                }
            },
        );
        // Pass 2, sequential in a fixed order: forces between particles.
        for force in self.forces {
            match force {
                Force::Springs { pairs, rest, stiffness, damping } => {
                    for (pair, l) in pairs.iter().zip(rest) {
                        let (a, b) = (pair[0], pair[1]);
                        let d = p(a) - p(b);
                        let len = d.length();
                        if len == 0.0 {
                            continue;
                        }
                        let dir = d / len;
                        let fa =
                            -(stiffness * (len - l) + damping * (vel(a) - vel(b)).dot(dir)) * dir;
                        add(f, a, fa);
                        add(f, b, -fa);
                    }
                }
                Force::NeighborRepulsion { radius, stiffness } => {
                    for_each_close_pair(self.cells, n, alive, x, *radius, |i, j, d, dist| {
                        let fi = stiffness * (radius - dist) / dist * d;
                        add(f, i, fi);
                        add(f, j, -fi);
                    });
                }
                Force::NBodyGravity { constant, softening } => {
                    let free = |i: usize| self.alive[i] && self.inv_mass[i] > 0.0;
                    for i in (0..n).filter(|&i| free(i)) {
                        for j in (i + 1..n).filter(|&j| free(j)) {
                            let d = p(j) - p(i);
                            let s = (d.length_squared() + softening * softening).powf(1.5);
                            let fi = constant * self.mass[i] * self.mass[j] / s * d;
                            add(f, i, fi);
                            add(f, j, -fi);
                        }
                    }
                }
                _ => {}
            }
        }
        // Pass 3, parallel: accelerations; pinned (where m g is infinite) and dead slots stay put.
        let inv_mass = self.inv_mass;
        dx.par_chunks_mut(3 * CHUNK).zip(f.par_chunks_mut(3 * CHUNK)).enumerate().for_each(
            |(c, (dxc, fc))| {
                for k in 0..dxc.len() / 3 {
                    let i = c * CHUNK + k;
                    if alive[i] && inv_mass[i] > 0.0 {
                        fc[3 * k..3 * k + 3].iter_mut().for_each(|a| *a *= inv_mass[i]);
                    } else {
                        fc[3 * k..3 * k + 3].fill(0.0);
                        dxc[3 * k..3 * k + 3].fill(0.0);
                    }
                }
            },
        );
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A call of one step is certified once a call has bounded the state, and no longer
    /// when the state is handed out for writing or the forces leave the certificate's range.
    #[test]
    fn one_step_calls_are_certified_from_a_bounded_state() {
        let x = [DVec3::new(0.0, 1.0, 0.0), DVec3::new(2.0, 0.5, -1.0)];
        let v = [DVec3::new(1.0, 0.0, 0.0), DVec3::new(0.0, -3.0, 0.5)];
        let mut s = ParticleSystem::new(&x, &v, &[1.0, 2.0], 3).unwrap();
        let g = DVec3::new(0.0, -9.81, 0.0);
        s.add_force(Force::Gravity { g }).unwrap();
        s.add_force(Force::Drag { linear: 0.0, quadratic: 1e-3, wind: DVec3::ZERO }).unwrap();
        s.add_collider(Collider::Plane {
            point: DVec3::ZERO,
            normal: DVec3::Y,
            restitution: 0.5,
            friction: 0.3,
        })
        .unwrap();
        assert!(!s.certified(1e-3, 1, g), "nothing is known before the first call");
        s.step(1e-3, 1, Method::SymplecticEuler).unwrap();
        let bound = s.summary.state.unwrap();
        let largest = s.positions()[..6].iter().chain(&s.velocities()[..6]);
        assert_eq!(bound, largest.fold(0.0f64, |m, v| m.max(v.abs())), "live slots only");
        assert!(s.certified(1e-3, 1, g) && s.certified(1e-3, 4, g));
        s.state_mut()[0] = 1e200;
        assert!(!s.certified(1e-3, 1, g), "the state was handed out for writing");
        s.step(1e-3, 1, Method::SymplecticEuler).unwrap();
        assert!(!s.certified(1e-3, 1, g), "1e200 m is beyond the certificate");
        s.state_mut()[0] = 0.0;
        s.step(1e-3, 1, Method::SymplecticEuler).unwrap();
        assert!(s.certified(1e-3, 1, g));
        s.set_external_forces(&[1e305; 9]).unwrap();
        assert!(!s.certified(1e-3, 1, g), "forces beyond the certificate");
    }
}
