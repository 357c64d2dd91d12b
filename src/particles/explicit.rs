//! Calls of the explicit kernel ([`super::kernel`]): a call either completes or leaves the state
//! at its last good step. Either the call is certified ([`super::certify::step_bound`], from a
//! bound on the state kept by the previous call) and taken without a copy, or its first step
//! copies the state it reads ([`Rollback`]) and a failed step restores the copy and takes the
//! good steps again. What the kernel would otherwise read per slot in every call is kept
//! between calls ([`Summary`]).

use super::emit::emitted_bound;
use super::solver::Step;
use super::*;
use rayon::prelude::*;

/// The most steps of a call that [`Step::certified`] tries to certify (a copy of the state
/// costs less than one step, a small part of the time of a longer call).
const MOST_CERTIFIED: usize = 64;

impl Step<'_> {
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
    pub(super) fn explicit_steps(&mut self, dt: f64, steps: usize, gravity: DVec3) -> Result<()> {
        let n = self.model.n;
        // Without emitters no slot is born, and none dies (lifespans are infinite: only
        // emitted particles have finite ones), so the ages can be advanced after the call.
        let age_each_step = !self.model.emitters.is_empty();
        if age_each_step {
            self.state.settle_ages();
        }
        let (time, bound) = (self.state.time, self.state.summary.state);
        let keep = !self.certified(dt, steps, gravity);
        // Aging and emission follow each good step: a call's first step changes nothing but
        // positions and velocities before it is known good.
        let keep_slots = keep && age_each_step && steps > 1;
        self.solver.rollback.y.resize(6 * n, 0.0);
        if keep_slots {
            let r = &mut self.solver.rollback;
            r.alive.clone_from(&self.state.alive);
            r.age.clone_from(&self.state.age);
            r.lifespan.clone_from(&self.state.lifespan);
            r.mass.clone_from(&self.state.mass);
            r.inv_mass.clone_from(&self.state.inv_mass);
            r.emitters.clone_from(&self.state.emitters);
        }
        let Err((step, index)) = self.explicit_run(dt, steps, gravity, age_each_step, keep) else {
            return Ok(());
        };
        let diverged = Error::Diverged { step, index, reason: "non-finite particle state".into() };
        debug_assert!(keep, "a certified step came out non-finite");
        if !keep {
            // Unreachable if `step_bound` is right: there is no copy to restore.
            self.state.summary.state = None;
            return Err(diverged);
        }
        let r = &self.solver.rollback;
        self.state.y.par_chunks_mut(6 * CHUNK).zip(r.y.par_chunks(6 * CHUNK)).for_each(|(y, r)| {
            y.copy_from_slice(r);
        });
        if keep_slots {
            self.state.alive.copy_from_slice(&r.alive);
            self.state.age.copy_from_slice(&r.age);
            self.state.lifespan.copy_from_slice(&r.lifespan);
            self.state.mass.copy_from_slice(&r.mass);
            self.state.inv_mass.copy_from_slice(&r.inv_mass);
            self.state.emitters.copy_from_slice(&r.emitters);
            if let Some(masses) = &mut self.state.summary.masses {
                masses.uniform = None;
            }
            self.state.summary.slots = None;
        }
        (self.state.time, self.state.summary.state) = (time, bound);
        self.solver.stats = StepStats::default();
        let replayed = self.explicit_run(dt, step, gravity, age_each_step, false);
        debug_assert!(replayed.is_ok(), "steps that were good are good again");
        Err(diverged)
    }

    /// Whether `steps` steps of `dt` from the current state cannot come out non-finite, so
    /// that a call needs no copy to undo them: the bound on the state kept from the last call
    /// carried through each step by [`certify::step_bound`], with the particles the emitters
    /// may make after each step.
    pub(super) fn certified(&mut self, dt: f64, steps: usize, gravity: DVec3) -> bool {
        let Some(mut bound) = self.state.summary.state.filter(|_| steps <= MOST_CERTIFIED) else {
            return false;
        };
        let masses = self.mass_summary();
        let external = *self.state.summary.external.get_or_insert_with(|| {
            self.state.external.par_iter().map(|f| f.abs()).reduce(|| 0.0, f64::max)
        });
        let extremes =
            certify::Extremes { mass: masses.largest.0, inv_mass: masses.largest.1, external };
        let emitted = emitted_bound(&self.model.emitters);
        for _ in 0..steps {
            let (forces, colliders) = (&self.model.forces, &self.model.colliders);
            bound = certify::step_bound(forces, colliders, dt, gravity, extremes, bound);
            bound = bound.max(emitted);
            if bound == f64::INFINITY {
                return false;
            }
        }
        true
    }

    /// The slots' masses ([`Masses`]), from the summary or computed into it.
    pub(super) fn mass_summary(&mut self) -> Masses {
        *self.state.summary.masses.get_or_insert_with(|| {
            Masses::of(
                &self.state.mass,
                &self.state.inv_mass,
                &self.state.alive,
                &self.model.emitters,
            )
        })
    }

    /// `steps` steps of the explicit kernel (see [`ParticleSystem::explicit_steps`]). With
    /// `keep`, the first copies the state into `rollback` and each is checked: the run stops
    /// at the first step that goes non-finite and returns it with the first particle that
    /// did; without, the steps are known not to (certified, or taken before) and are not
    /// checked. With emitters
    /// the kernel runs once per step (emission comes between the steps); without, once for
    /// all of them, each block of particles taking every step while it is in the cache.
    pub(super) fn explicit_run(
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
        let n = self.model.n;
        let uniform = if age_each_step { None } else { self.mass_summary().uniform };
        let (runs, each) = if age_each_step { (steps, 1) } else { (1, steps) };
        for run in 0..runs {
            let model = kernel::Model {
                forces: &self.model.forces,
                colliders: &self.model.colliders,
                mass: &self.state.mass,
                inv_mass: &self.state.inv_mass,
                external: &self.state.external,
                dt,
                gravity,
                uniform,
            };
            let (xs, vs) = self.state.y.split_at_mut(3 * n);
            let kept = &mut self.solver.rollback.y;
            let guard = match (keep, run) {
                (false, _) => kernel::Guard::Certified,
                (true, 0) => kernel::Guard::Copy,
                (true, _) => kernel::Guard::Check,
            };
            let done = kernel::commit(&model, xs, vs, &self.state.alive, kept, guard, each);
            if let Some((s, index)) = done.bad {
                return Err((run + s, index));
            }
            self.state.summary.state = Some(done.bound);
            self.solver.stats.contacts += done.contacts;
            for _ in 0..each {
                self.state.time += dt;
            }
            if age_each_step {
                self.age(dt);
                self.emit(dt);
            }
        }
        if !age_each_step {
            // Added by `settle_ages`, with the pending steps of another `dt` first.
            if self.state.age_pending.1 > 0 && self.state.age_pending.0.to_bits() != dt.to_bits() {
                self.state.settle_ages();
            }
            self.state.age_pending = (dt, self.state.age_pending.1 + steps);
        }
        Ok(())
    }
}

/// What a call of the explicit kernel restores when one of its steps fails
/// ([`ParticleSystem::explicit_steps`]).
#[derive(Clone, Debug, Default)]
pub(super) struct Rollback {
    /// Positions then velocities (`6 capacity` values), copied by the call's first step.
    pub(super) y: Vec<f64>,
    /// With emitters and more than one step: every slot's alive flag, age, lifespan, mass and
    /// inverse mass, and each emitter's accumulator and random state, copied before the call.
    /// (Colours and sizes are not copied: only emission writes them, and the replay of the
    /// good steps emits the same particles again from the restored random state.)
    pub(super) alive: Vec<bool>,
    pub(super) age: Vec<f64>,
    pub(super) lifespan: Vec<f64>,
    pub(super) mass: Vec<f64>,
    pub(super) inv_mass: Vec<f64>,
    pub(super) emitters: Vec<(f64, u64)>,
}

/// What the explicit kernel would otherwise read every slot for in every call, kept between
/// calls; not part of a snapshot (each part is rebuilt when unknown).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Summary {
    /// A bound on |component| of the position and velocity of every live, movable particle
    /// (m, m/s), known after a call of the explicit kernel and forgotten when the state is
    /// handed out for writing or stepped by another path.
    pub(super) state: Option<f64>,
    /// The slots' masses.
    pub(super) masses: Option<Masses>,
    /// The largest |component| of the external forces (N).
    pub(super) external: Option<f64>,
    /// A key of the slots' masses and live flags ([`crate::ode::fresh_key`]): the same while
    /// they are unchanged, forgotten when emission, retirement or a restore changes them.
    pub(super) slots: Option<u64>,
}

/// The slots' masses as the explicit kernel needs them.
#[derive(Clone, Copy, Debug)]
pub(super) struct Masses {
    /// `(mass, inverse mass)` when every slot is alive and moves with this same mass.
    pub(super) uniform: Option<(f64, f64)>,
    /// The largest mass (kg) and inverse mass (1/kg) of a slot that moves or of a particle an
    /// emitter makes: bounds that stay true as particles die and are emitted.
    pub(super) largest: (f64, f64),
}

impl Masses {
    fn of(mass: &[f64], inv_mass: &[f64], alive: &[bool], emitters: &[Emitter]) -> Self {
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
            emitters.iter().fold(largest, |(a, b), e| (a.max(e.mass), b.max(1.0 / e.mass)));
        Masses { uniform: uniform_mass(mass, inv_mass, alive), largest }
    }
}

/// `(mass, inverse mass)` of every slot if all are alive, movable and of the same mass.
pub(super) fn uniform_mass(mass: &[f64], inv_mass: &[f64], alive: &[bool]) -> Option<(f64, f64)> {
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
