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

//! The system is split as every system of kinema is: a [`Model`] (capacity, forces,
//! colliders, emitters: built once, read by every step), a [`State`] (the buffer `[x; v]`, the
//! slots' masses, ages, flags and appearance, the emitters' random states, time, integrator
//! history) and a [`Solver`] (workspaces only), so that one model and one solver can advance
//! several states. [`ParticleSystem`] is the three together.

mod certify;
mod chain;
mod chain_implicit;
mod collide;
mod dynamics;
mod emit;
mod explicit;
mod forces;
mod grid;
mod jacobian;
mod kernel;
mod linear;
mod model;
mod snapshot;
mod solver;
mod state;

pub use collide::Collider;
pub(crate) use dynamics::Dynamics;
pub use emit::{Appearance, Emitter};
pub use forces::{curl_noise, noise_with_gradient, Force};
pub use model::Model;
pub(crate) use solver::Free;
pub use solver::Solver;
pub use state::State;

use forces::{attractor, damping, drag, gravity, particle_force, turbulence, vortex};
use grid::for_each_close_pair;

use crate::error::{Error, Result};
use crate::ode::{Method, OdeSystem, SparseJacobian};
use glam::DVec3;

/// Particles per parallel chunk.
const CHUNK: usize = 4096;

/// Systems of at most this many slots have nothing to share out between threads: every
/// parallel pass of a step (forces, accelerations, copies, collisions, the explicit kernel's
/// tasks) splits its work into chunks of this many particles, so they have one chunk, which
/// rayon runs on the calling thread. Bindings run their calls on the calling thread too,
/// without handing them to a chosen thread pool (which costs a wake-up of a pool thread and a
/// wait for it every call).
pub const SERIAL_CAPACITY: usize = CHUNK;

/// Counters of the last call to [`Solver::step`].
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
    /// Numeric LU factorisations of the implicit methods' Newton matrix: one per Jacobian
    /// update, except when the matrix is bitwise the one already factorised (linear forces at
    /// a constant step keep one factorisation for the whole call; [`crate::ode::Workspace`]).
    pub factorizations: usize,
}

/// A fixed-capacity particle system: a [`Model`] with one [`State`] and a [`Solver`], its
/// methods delegating to them. Methods that change the model (adding a force, a collider, an
/// emitter) fit the state to it. A snapshot holds the model and the state.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub struct ParticleSystem {
    model: Model,
    state: State,
    #[serde(skip)]
    solver: Solver,
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
        let model = Model::new(capacity);
        let state = State::new(&model, positions, velocities, masses)?;
        let solver = Solver::new(&model)?;
        Ok(ParticleSystem { model, state, solver, stats: StepStats::default() })
    }

    /// The model (forces, colliders, emitters, capacity).
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The state (positions, velocities, slots, time, history).
    pub fn state(&self) -> &State {
        &self.state
    }

    /// Copy `state`, a state of this system's model (e.g. stepped by another solver, restored
    /// by [`State::from_snapshot`], or an undo point), into this system's state in place: its
    /// buffers, and so the views of them, are kept (no allocation when the sizes match).
    ///
    /// # Errors
    /// A state of another capacity or emitter count (argument `state`).
    pub fn set_state(&mut self, state: &State) -> Result<()> {
        state.check_fits(&self.model)?;
        self.state.clone_from(state);
        Ok(())
    }

    /// Put back `saved`, an earlier copy of the model's colliders, reusing the list's room (a
    /// scene's undo of a frame that moved or added colliders).
    pub fn restore_colliders(&mut self, saved: &[Collider]) {
        self.model.restore_colliders(saved);
    }

    /// Number of slots (live and dead).
    pub fn capacity(&self) -> usize {
        self.model.n
    }

    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        self.state.time()
    }

    /// Positions, `3 capacity` values (x, y, z per slot) (m).
    pub fn positions(&self) -> &[f64] {
        self.state.positions()
    }

    /// Velocities, `3 capacity` values (m/s).
    pub fn velocities(&self) -> &[f64] {
        self.state.velocities()
    }

    /// The whole state `[x; v]` for writing; call [`ParticleSystem::state_changed`] after.
    pub fn state_mut(&mut self) -> &mut [f64] {
        self.state.y_mut()
    }

    /// The model, the state and the solver, for systems that step the particles themselves
    /// (constraints, through [`Solver::free`]).
    pub(crate) fn parts(&mut self) -> (&Model, &mut State, &mut Solver) {
        (&self.model, &mut self.state, &mut self.solver)
    }

    /// Set forces (N, world frame; `3 capacity` values) that act in the following steps
    /// ([`State::set_external_forces`]).
    ///
    /// # Errors
    /// A wrong length or non-finite values (named by slot).
    pub fn set_external_forces(&mut self, forces: &[f64]) -> Result<()> {
        self.state.set_external_forces(forces)
    }

    /// Forget integrator history after the state was changed from outside.
    pub fn state_changed(&mut self) {
        self.state.state_changed();
    }

    /// Which slots hold live particles.
    pub fn alive(&self) -> &[bool] {
        self.state.alive()
    }

    /// Age of each slot (s) ([`State::ages`]).
    pub fn ages(&self) -> std::borrow::Cow<'_, [f64]> {
        self.state.ages()
    }

    /// Mass of each slot (kg; infinite when pinned).
    pub fn masses(&self) -> &[f64] {
        self.state.masses()
    }

    /// Colour of each slot ([`State::colors`]).
    pub fn colors(&self) -> &[[f64; 4]] {
        self.state.colors()
    }

    /// Size of each slot ([`State::sizes`]).
    pub fn sizes(&self) -> &[f64] {
        self.state.sizes()
    }

    /// Set the colour and size of every slot ([`State::set_appearance`]).
    ///
    /// # Errors
    /// As [`State::set_appearance`].
    pub fn set_appearance(&mut self, colors: &[[f64; 4]], sizes: &[f64]) -> Result<()> {
        self.state.set_appearance(colors, sizes)
    }

    /// Add a force ([`Model::add_force`]).
    ///
    /// # Errors
    /// Invalid parameters ([`Force::validate`]).
    pub fn add_force(&mut self, force: Force) -> Result<()> {
        self.model.add_force(force)
    }

    /// Add a collider ([`Model::add_collider`]).
    ///
    /// # Errors
    /// Those of [`Collider::checked`].
    pub fn add_collider(&mut self, collider: Collider) -> Result<()> {
        self.model.add_collider(collider)
    }

    /// Replace collider `index` ([`Model::set_collider`]).
    ///
    /// # Errors
    /// `index` out of range, or those of [`Collider::checked`].
    pub fn set_collider(&mut self, index: usize, collider: Collider) -> Result<()> {
        self.model.set_collider(index, collider)
    }

    /// Add an emitter ([`Model::add_emitter`]) and fit the state to it.
    ///
    /// # Errors
    /// As [`Model::add_emitter`].
    pub fn add_emitter(&mut self, emitter: Emitter) -> Result<()> {
        self.model.add_emitter(emitter)?;
        self.state.fit(&self.model);
        Ok(())
    }

    /// Kinetic energy of the live, unpinned particles (J).
    pub fn kinetic_energy(&self) -> f64 {
        self.state.kinetic_energy()
    }

    /// Potential energy of the conservative forces over live particles (J)
    /// ([`State::potential_energy`]).
    pub fn potential_energy(&self) -> f64 {
        self.state.potential_energy(&self.model)
    }

    /// Advance `steps` steps of `dt` seconds with `method` ([`Solver::step`]).
    ///
    /// # Errors
    /// As [`Solver::step`]; the system is left at the last good step.
    pub fn step(&mut self, dt: f64, steps: usize, method: Method) -> Result<()> {
        self.step_with_jacobian(dt, steps, method, true)
    }

    /// [`ParticleSystem::step`] with the choice of the implicit methods' Newton matrix
    /// ([`Solver::step_with_jacobian`]).
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
        let (model, state) = (&self.model, &mut self.state);
        let result = self.solver.step_with_jacobian(model, state, dt, steps, method, sparse);
        self.stats = self.solver.stats();
        result.map(|_| ())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Material, Plane, Shape};

    /// Whether `steps` steps of `dt` from `s`'s state are certified ([`solver::Step::certified`]).
    fn certified(s: &mut ParticleSystem, dt: f64, steps: usize, g: DVec3) -> bool {
        let (model, state, solver) = (&s.model, &mut s.state, &mut s.solver);
        solver::Step { model, state, solver }.certified(dt, steps, g)
    }

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
        assert!(!certified(&mut s, 1e-3, 1, g), "nothing is known before the first call");
        s.step(1e-3, 1, Method::SymplecticEuler).unwrap();
        let bound = s.state.summary.state.unwrap();
        let largest = s.positions()[..6].iter().chain(&s.velocities()[..6]);
        assert_eq!(bound, largest.fold(0.0f64, |m, v| m.max(v.abs())), "live slots only");
        assert!(certified(&mut s, 1e-3, 1, g) && certified(&mut s, 1e-3, 4, g));
        s.state_mut()[0] = 1e200;
        assert!(!certified(&mut s, 1e-3, 1, g), "the state was handed out for writing");
        s.step(1e-3, 1, Method::SymplecticEuler).unwrap();
        assert!(!certified(&mut s, 1e-3, 1, g), "1e200 m is beyond the certificate");
        s.state_mut()[0] = 0.0;
        s.step(1e-3, 1, Method::SymplecticEuler).unwrap();
        assert!(certified(&mut s, 1e-3, 1, g));
        s.set_external_forces(&[1e305; 9]).unwrap();
        assert!(!certified(&mut s, 1e-3, 1, g), "forces beyond the certificate");
    }
}
