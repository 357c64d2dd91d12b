//! The particle state: what changes in time and what a later step reads — the buffer
//! `y = [x; v]`, each slot's mass, age, lifespan, flag, colour and size (set at birth), the
//! emitters' accumulators and random states, the external forces of the next steps, the time,
//! the integrator history and the bound on the state that certifies the next call.

use super::explicit::Summary;
use super::{emit::age_live, Appearance, Force, Model};
use crate::error::{filled, too_large, Error, Result};
use crate::ode::History;
use glam::DVec3;

/// The state of a particle system of a [`Model`] (see the module docs). Slot `i` is a particle
/// when `alive[i]`; its position is `y[3i..3i + 3]` (m) and its velocity
/// `y[3 capacity + 3i..][..3]` (m/s). The buffer's length never changes, so views of it stay
/// valid. `clone_from` reuses every buffer (no allocation once sizes match).
#[derive(serde::Serialize, serde::Deserialize, Debug)]
pub struct State {
    /// Positions then velocities, `6 capacity` values (m, m/s).
    pub(super) y: Vec<f64>,
    /// Mass of each slot (kg; infinite when pinned), `capacity` values.
    pub(super) mass: Vec<f64>,
    /// Inverse mass of each slot (1/kg; 0 when pinned), `capacity` values.
    pub(super) inv_mass: Vec<f64>,
    /// Age of each slot (s), without the pending steps of `age_pending`.
    pub(super) age: Vec<f64>,
    /// Steps `(dt, count)` not yet added to the ages of the live slots: without emitters
    /// nothing reads the ages between calls, so the calls leave them to the next reader
    /// ([`State::settle_ages`]) instead of passing over them.
    pub(super) age_pending: (f64, usize),
    /// Lifespan of each slot (s; infinite unless emitted).
    pub(super) lifespan: Vec<f64>,
    /// Which slots hold live particles.
    pub(super) alive: Vec<bool>,
    /// Colour of each slot (linear RGBA in `[0, 1]`), set by [`Appearance`] on emission.
    pub(super) color: Vec<[f64; 4]>,
    /// Size of each slot (diameter, m), set by [`Appearance`] on emission.
    pub(super) size: Vec<f64>,
    /// Per emitter of the model: the emissions owed (a fraction of a particle) and the
    /// SplitMix64 state of its random numbers.
    pub(super) emitters: Vec<(f64, u64)>,
    /// Forces set from outside for the next steps (N, 3 per slot), empty when unused.
    pub(super) external: Vec<f64>,
    /// Simulated time (s).
    pub(super) time: f64,
    /// The integration history of the general path (method, previous BDF2 step).
    pub(super) history: Option<History>,
    /// Summaries of this state that spare the explicit kernel a pass (the certified bound,
    /// the masses, the largest external force); derived from the state and rebuilt when
    /// unknown, so not stored in snapshots.
    #[serde(skip)]
    pub(super) summary: Summary,
}

impl Clone for State {
    fn clone(&self) -> Self {
        let mut copy = State {
            y: Vec::new(),
            mass: Vec::new(),
            inv_mass: Vec::new(),
            age: Vec::new(),
            age_pending: self.age_pending,
            lifespan: Vec::new(),
            alive: Vec::new(),
            color: Vec::new(),
            size: Vec::new(),
            emitters: Vec::new(),
            external: Vec::new(),
            time: self.time,
            history: None,
            summary: self.summary,
        };
        copy.clone_from(self);
        copy
    }

    fn clone_from(&mut self, source: &Self) {
        // Destructured so that a new field cannot be forgotten here.
        let State {
            y,
            mass,
            inv_mass,
            age,
            age_pending,
            lifespan,
            alive,
            color,
            size,
            emitters,
            external,
            time,
            history,
            summary,
        } = source;
        self.y.clone_from(y);
        self.mass.clone_from(mass);
        self.inv_mass.clone_from(inv_mass);
        self.age.clone_from(age);
        self.age_pending = *age_pending;
        self.lifespan.clone_from(lifespan);
        self.alive.clone_from(alive);
        self.color.clone_from(color);
        self.size.clone_from(size);
        self.emitters.clone_from(emitters);
        self.external.clone_from(external);
        self.time = *time;
        match (&mut self.history, history) {
            (Some(to), Some(from)) => to.clone_from(from),
            (to, from) => to.clone_from(from),
        }
        self.summary = *summary;
    }
}

impl State {
    /// A state of `model` with `positions.len()` live particles in the first slots, with the
    /// given velocities and masses (kg; `f64::INFINITY` pins a particle); the other slots
    /// start dead. Time 0, every emitter at its seed.
    ///
    /// # Errors
    /// Length mismatches, non-finite positions or velocities, masses that are not positive
    /// (or infinite), a capacity below the particle count, or one too large to allocate.
    pub fn new(
        model: &Model,
        positions: &[DVec3],
        velocities: &[DVec3],
        masses: &[f64],
    ) -> Result<Self> {
        let (live, n) = (positions.len(), model.n);
        check_initial(positions, velocities, masses, n)?;
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
        let mut state = State {
            y,
            mass,
            inv_mass,
            age: filled(arg, n, 0.0)?,
            age_pending: (0.0, 0),
            lifespan: filled(arg, n, f64::INFINITY)?,
            alive,
            color: filled(arg, n, Appearance::default().color)?,
            size: filled(arg, n, Appearance::default().size)?,
            emitters: Vec::new(),
            external: Vec::new(),
            time: 0.0,
            history: None,
            summary: Summary::default(),
        };
        state.fit(model);
        Ok(state)
    }

    /// Take on the emitters added to `model` since this state was made (each starts owing
    /// nothing, at its seed).
    pub fn fit(&mut self, model: &Model) {
        let known = self.emitters.len().min(model.emitters.len());
        self.emitters.extend(model.emitters[known..].iter().map(|e| (0.0, e.seed)));
        self.summary.masses = None;
    }

    /// Whether this state has the size and the emitters of `model`.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] (argument `state`) when it belongs to another model.
    pub(super) fn check_fits(&self, model: &Model) -> Result<()> {
        if self.y.len() != 6 * model.n || self.emitters.len() != model.emitters.len() {
            return Err(Error::invalid(
                "state",
                "does not fit the model (another capacity or emitter count; see State::fit)",
            ));
        }
        Ok(())
    }

    /// Number of slots (live and dead).
    pub fn capacity(&self) -> usize {
        self.alive.len()
    }

    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Positions, `3 capacity` values (x, y, z per slot) (m).
    pub fn positions(&self) -> &[f64] {
        &self.y[..3 * self.capacity()]
    }

    /// Velocities, `3 capacity` values (m/s).
    pub fn velocities(&self) -> &[f64] {
        &self.y[3 * self.capacity()..]
    }

    /// The whole buffer `[x; v]` for writing; call [`State::state_changed`] after.
    pub fn y_mut(&mut self) -> &mut [f64] {
        self.summary.state = None;
        &mut self.y
    }

    /// Forget the integrator history after the state was changed from outside.
    pub fn state_changed(&mut self) {
        if let Some(h) = self.history.as_mut() {
            h.reset();
        }
    }

    /// Which slots hold live particles.
    pub fn alive(&self) -> &[bool] {
        &self.alive
    }

    /// Age of each slot (s): borrowed, or computed when steps are still to be added to the
    /// ages (calls without emitters leave that to the reader).
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
    pub(super) fn settle_ages(&mut self) {
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
    /// [`State::set_appearance`] set it). Slots are never reordered, so a particle keeps its
    /// colour while others die.
    pub fn colors(&self) -> &[[f64; 4]] {
        &self.color
    }

    /// Size of each slot (diameter, m; [`Appearance::default`]'s 1 cm unless set).
    pub fn sizes(&self) -> &[f64] {
        &self.size
    }

    /// Set forces (N, world frame; `3 capacity` values) that act in the following steps, held
    /// constant within each step, for force fields computed outside (e.g. Python callables);
    /// an empty slice removes them.
    ///
    /// # Errors
    /// A wrong length or non-finite values (named by slot).
    pub fn set_external_forces(&mut self, forces: &[f64]) -> Result<()> {
        if !forces.is_empty() && forces.len() != 3 * self.capacity() {
            return Err(Error::invalid(
                "forces",
                format!(
                    "expected {} values (capacity x 3), got {}",
                    3 * self.capacity(),
                    forces.len()
                ),
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

    /// Set the colour (linear RGBA in `[0, 1]`) and size (diameter, m, `> 0`) of every slot
    /// (`capacity` of each), e.g. of the particles given at construction.
    ///
    /// # Errors
    /// Wrong lengths, a channel outside `[0, 1]` (argument `colors`), a size that is not
    /// positive and finite (`sizes`); nothing is changed then.
    pub fn set_appearance(&mut self, colors: &[[f64; 4]], sizes: &[f64]) -> Result<()> {
        for (arg, len) in [("colors", colors.len()), ("sizes", sizes.len())] {
            if len != self.capacity() {
                return Err(Error::invalid(
                    arg,
                    format!("expected {} rows (the capacity), got {len}", self.capacity()),
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

    /// Kinetic energy of the live, unpinned particles (J).
    pub fn kinetic_energy(&self) -> f64 {
        let v = self.velocities();
        (0..self.capacity())
            .filter(|&i| self.alive[i] && self.inv_mass[i] > 0.0)
            .map(|i| {
                0.5 * self.mass[i]
                    * (v[3 * i].powi(2) + v[3 * i + 1].powi(2) + v[3 * i + 2].powi(2))
            })
            .sum()
    }

    /// Potential energy of the conservative forces (gravity, springs, attractors, n-body
    /// gravity) over live particles (J).
    pub fn potential_energy(&self, model: &Model) -> f64 {
        let x = |i: usize| DVec3::from_slice(&self.y[3 * i..3 * i + 3]);
        let live = |i: usize| self.alive[i] && self.inv_mass[i] > 0.0;
        let mut e = 0.0;
        for f in &model.forces {
            match f {
                Force::Gravity { g } => {
                    e -= (0..self.capacity())
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
                    e -= (0..self.capacity())
                        .filter(|&i| live(i))
                        .map(|i| {
                            strength * self.mass[i]
                                / ((x(i) - *center).length_squared() + softening * softening).sqrt()
                        })
                        .sum::<f64>()
                }
                Force::NBodyGravity { constant, softening } => {
                    for i in (0..self.capacity()).filter(|&i| live(i)) {
                        for j in (i + 1..self.capacity()).filter(|&j| live(j)) {
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
}

/// Check the initial particles of [`State::new`] against the capacity `n`.
fn check_initial(
    positions: &[DVec3],
    velocities: &[DVec3],
    masses: &[f64],
    n: usize,
) -> Result<()> {
    let live = positions.len();
    if velocities.len() != live || masses.len() != live {
        return Err(Error::invalid(
            "velocities",
            "positions, velocities and masses must have the same length",
        ));
    }
    if n < live {
        return Err(Error::invalid("capacity", format!("{n} is below the {live} particles given")));
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
    Ok(())
}
