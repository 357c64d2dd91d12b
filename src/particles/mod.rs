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

mod certify;
mod collide;
mod dynamics;
mod emit;
mod explicit;
mod forces;
mod grid;
mod jacobian;
mod kernel;
mod snapshot;

pub use collide::Collider;
pub(crate) use dynamics::Dynamics;
pub use emit::{Appearance, Emitter};
pub use forces::{curl_noise, noise_with_gradient, Force};

use emit::{age_live, emitted_bound};
use explicit::{Rollback, Summary};
use forces::{attractor, damping, drag, gravity, particle_force, turbulence, vortex};
use grid::for_each_close_pair;

use crate::error::{filled, reserve, too_large, Error, Result};
use crate::ode::{Method, OdeSystem, SparseJacobian, Stepper};
use glam::DVec3;
use rayon::prelude::*;

/// Particles per parallel chunk.
const CHUNK: usize = 4096;

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

    /// Copy this system's state and parameters into `saved`, reusing `saved`'s buffers (no
    /// allocation once they have the size): a scene's undo point before a frame, cheaper than
    /// a snapshot (no serialisation). Workspaces are not copied. `saved.save_into(self)` puts
    /// the system back in place (same buffers, so views of the state stay valid).
    pub fn save_into(&self, saved: &mut ParticleSystem) {
        // Destructured so that a new field cannot be forgotten here.
        let ParticleSystem {
            n,
            y,
            backup: _,
            rollback: _,
            summary: _,
            mass,
            inv_mass,
            age,
            age_pending,
            lifespan,
            alive,
            color,
            size,
            forces,
            colliders,
            emitters,
            cells: _,
            external,
            stepper,
            jacobian: _,
            time,
            stats,
        } = self;
        saved.n = *n;
        saved.y.clone_from(y);
        saved.mass.clone_from(mass);
        saved.inv_mass.clone_from(inv_mass);
        saved.age.clone_from(age);
        saved.age_pending = *age_pending;
        saved.lifespan.clone_from(lifespan);
        saved.alive.clone_from(alive);
        saved.color.clone_from(color);
        saved.size.clone_from(size);
        saved.forces.clone_from(forces);
        saved.colliders.clone_from(colliders);
        saved.emitters.clone_from(emitters);
        saved.external.clone_from(external);
        saved.stepper.clone_from(stepper);
        saved.time = *time;
        saved.stats = *stats;
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

    /// The most steps of a call that [`ParticleSystem::certified`] tries to certify (a copy of
    /// the state costs less than one step, a small part of the time of a longer call).
    const MOST_CERTIFIED: usize = 64;
}

// The forces on one particle (N) of mass `m` at `x` with velocity `v`, as [`Force`] defines
// them; shared by `particle_force` and the explicit kernel so that both compute alike.

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Material, Plane, Shape};

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
        s.add_collider(Collider {
            shape: Shape::Plane(Plane { point: DVec3::ZERO, normal: DVec3::Y }),
            material: Material { restitution: 0.5, friction: 0.3 },
            velocity: DVec3::ZERO,
            inside: false,
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
