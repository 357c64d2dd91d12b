//! The rigid world's [`Solver`]: every workspace of a step, and the step itself — the exact
//! free update when nothing couples the bodies, otherwise the coupled step of
//! [`coupled`] (joint forces, velocities, contacts of [`detect`], sequential impulses,
//! positions, position pass, XPBD) once per step or per XPBD substep.

use super::contact::{self, Contact};
use super::integrate::{kinetic_energy, phi2, rotate};
use super::joint::{JointMethod, Row, SLOTS};
use super::lagrange::Multipliers;
use super::narrow::{Placed, Touch};
use super::{Model, State};
use crate::error::{Error, Result};
use crate::geometry::Solid;
use glam::{DMat3, DQuat, DVec3};

mod coupled;
mod detect;

/// Next-step state (centres of mass, velocities, principal frames, `Π`), committed only when
/// the whole step succeeded.
type Scratch = (Vec<DVec3>, Vec<DVec3>, Vec<DQuat>, Vec<DVec3>);

/// Advances states of one [`Model`]: owns every workspace (the next-step state, this step's
/// contacts, islands, broad-phase pairs, joint rows, the Lagrange joints' multiplier system and
/// its symbolic factorisation) and carries nothing that a later step reads, so one solver can
/// advance any number of states of its model in any interleaving, each bit for bit as with a
/// solver of its own. Its workspaces are sized for the model's bodies and joints at the
/// first step and again whenever the model has grown.
#[derive(Clone, Debug, Default)]
pub struct Solver {
    /// `(bodies, joints)` of the model the workspaces are sized for: a model only grows, so
    /// this identifies the multiplier pattern built for it.
    fitted: Option<(usize, usize)>,
    scratch: Box<Scratch>,
    /// This (sub)step's contacts and, with substeps, the previous substep's, whose impulses
    /// warm-start them (a step's first substep reads its warm starts from the state).
    contacts: Vec<Contact>,
    previous: Vec<Contact>,
    islands: contact::Islands,
    points: Vec<DVec3>,
    omega: Vec<DVec3>,
    /// Each body's inverse inertia tensor in world axes at the current pose (1/(kg m²)).
    inv_inertia: Vec<DMat3>,
    placed: Vec<Placed>,
    dx: Vec<DVec3>,
    dtheta: Vec<DVec3>,
    /// The broad phase's bodies as `(lowest x of the grown bound, body)`, sorted (m).
    order: Vec<(f64, usize)>,
    touches: Vec<(usize, Touch)>,
    /// Body pairs whose bounds overlap, `(min, max)`.
    pairs: Vec<(usize, usize)>,
    /// Each body's bounding radius grown by its motion over the step (m).
    reach: Vec<f64>,
    rows: Vec<Row>,
    row_mass: Vec<f64>,
    /// The impulse joints' accumulated impulses during the step (committed into the state).
    joint_impulse: Vec<f64>,
    multipliers: Multipliers,
    joint_force: Vec<DVec3>,
    joint_torque: Vec<DVec3>,
    acc_free: Vec<DVec3>,
    alpha_free: Vec<DVec3>,
    xpbd_dx: Vec<DVec3>,
    xpbd_dtheta: Vec<DVec3>,
}

impl Solver {
    /// A solver for the states of `model`, its workspaces sized for it.
    ///
    /// # Errors
    /// [`Error::SolverFailed`] when the symbolic factorisation of the Lagrange joints'
    /// multiplier system fails.
    pub fn new(model: &Model) -> Result<Self> {
        let mut solver = Solver::default();
        solver.fit(model)?;
        Ok(solver)
    }

    /// Size the workspaces for `model` (a no-op when they already are): the joint rows and
    /// the pattern and symbolic factorisation of the Lagrange joints' multiplier system.
    ///
    /// # Errors
    /// [`Error::SolverFailed`] when the symbolic factorisation fails.
    pub(super) fn fit(&mut self, model: &Model) -> Result<()> {
        let key = (model.len(), model.joint_count());
        if self.fitted == Some(key) {
            return Ok(());
        }
        self.fitted = None;
        self.multipliers = Multipliers::default();
        if model.joints.iter().any(|j| j.method == JointMethod::Lagrange) {
            self.multipliers.build(&model.joints, model.len())?;
        }
        let slots = model.joint_count() * SLOTS;
        self.rows.resize(slots, Row::INACTIVE);
        self.row_mass.resize(slots, 0.0);
        self.fitted = Some(key);
        Ok(())
    }

    /// Advance `state` of `model` by `steps` steps of `dt` seconds.
    ///
    /// Applied forces act during the first step and are then cleared. Without planes, joints
    /// and two bodies that could collide (or with `collisions` off) the translation is the
    /// exact update for the constant force and the rotation follows the model's integrator.
    /// Otherwise each step (or each of [`Model::xpbd_substeps`] substeps when a joint uses
    /// XPBD) is: penalty and Lagrange joint forces at the current state, velocities from all
    /// forces (`v += h a`, `Π += h τ`), contacts found at the current pose, sequential
    /// impulses over the contacts and the impulse joints, positions from the new velocities
    /// (`x += h v`) and the rotation by the model's integrator, a position pass removing
    /// penetration and the impulse joints' drift, and the XPBD projection with its velocity
    /// update. A step that produces a non-finite state, or whose multiplier solve fails,
    /// returns an error and leaves `state` at the last good step.
    ///
    /// # Errors
    /// A non-positive or non-finite `dt`; a `state` whose sizes are not the model's;
    /// divergence ([`Error::Diverged`]); a failed factorisation of the joints' multiplier
    /// system ([`Error::SolverFailed`]).
    pub fn step(&mut self, model: &Model, state: &mut State, dt: f64, steps: usize) -> Result<()> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(Error::invalid("dt", format!("must be positive and finite, got {dt}")));
        }
        state.check_sizes(model)?;
        self.fit(model)?;
        let substeps = if model.joints.iter().any(|j| j.method == JointMethod::Xpbd) {
            model.xpbd_substeps.max(1)
        } else {
            1
        };
        let pairs = model.collisions
            && model
                .shape
                .iter()
                .filter(|s| !matches!(s, Solid::Cylinder { .. } | Solid::Mesh { .. }))
                .count()
                > 1;
        let coupled = pairs || !model.planes.is_empty() || !model.joints.is_empty();
        for s in 0..steps {
            self.begin(state);
            if !coupled {
                self.free_step(model, state, dt);
            } else {
                let detect = pairs || !model.planes.is_empty();
                for substep in 0..substeps {
                    self.coupled_step(model, state, dt / substeps as f64, detect, substep)?;
                    if self.first_non_finite(model).is_some() {
                        break; // reported below, before any contact sees the bad state
                    }
                }
            }
            if let Some(i) = self.first_non_finite(model) {
                return Err(diverged(model, s, i));
            }
            self.commit(state, coupled);
        }
        Ok(())
    }

    /// Copy what the step changes of `state` into the scratch: the bodies and the impulse
    /// joints' accumulated impulses. The contacts are not copied: the step's first (sub)step
    /// reads their warm starts from `state` itself and makes new ones.
    fn begin(&mut self, state: &State) {
        let (x, v, q, pi) = &mut *self.scratch;
        x.clone_from(&state.x);
        v.clone_from(&state.v);
        q.clone_from(&state.q);
        pi.clone_from(&state.pi);
        self.joint_impulse.clone_from(&state.joint_impulse);
    }

    /// Make the scratch the new state (buffers exchanged, no copy), with the step's contacts
    /// when it was `coupled` (a free step makes none and leaves the state's), and clear the
    /// applied forces.
    fn commit(&mut self, state: &mut State, coupled: bool) {
        let (x, v, q, pi) = &mut *self.scratch;
        std::mem::swap(&mut state.x, x);
        std::mem::swap(&mut state.v, v);
        std::mem::swap(&mut state.q, q);
        std::mem::swap(&mut state.pi, pi);
        if coupled {
            std::mem::swap(&mut state.contacts, &mut self.contacts);
        }
        std::mem::swap(&mut state.joint_impulse, &mut self.joint_impulse);
        state.force.fill(DVec3::ZERO);
        state.torque.fill(DVec3::ZERO);
    }

    /// The exact step of free bodies under gravity, the applied forces and damping, with the
    /// rotation by the model's integrator (see [`Model::set_damping`] for the damped forms).
    fn free_step(&mut self, model: &Model, state: &State, dt: f64) {
        let (x, v, q, pi) = &mut *self.scratch;
        for i in (0..model.len()).filter(|&i| !model.fixed[i]) {
            let a = model.gravity + state.force[i] / model.mass[i];
            let c = model.linear_damping[i];
            if c == 0.0 {
                x[i] += dt * v[i] + 0.5 * dt * dt * a;
                v[i] += dt * a;
            } else {
                // v̇ = a − c v exactly: v ← e^{−ch} v + s a, x ← x + s v + (h − s)/c a.
                let z = -c * dt;
                let s = -z.exp_m1() / c;
                x[i] += s * v[i] + dt * dt * phi2(z) * a;
                v[i] = z.exp() * v[i] + s * a;
            }
            let tau = q[i].conjugate() * state.torque[i]; // principal frame
            let c = model.angular_damping[i];
            let (qi, pii) = if c == 0.0 {
                rotate(model.integrator, q[i], pi[i], model.moments[i], tau, dt)
            } else {
                // The undamped rotation over s, then the decay (see `set_damping`); a torque's
                // impulse h τ decays with the momentum.
                let z = -c * dt;
                let s = -z.exp_m1() / c;
                let (qi, pii) =
                    rotate(model.integrator, q[i], pi[i], model.moments[i], tau * (dt / s), s);
                (qi, z.exp() * pii)
            };
            q[i] = qi;
            pi[i] = pii;
        }
    }

    /// The first body whose scratch state, or kinetic energy, is not finite.
    fn first_non_finite(&self, model: &Model) -> Option<usize> {
        let (x, v, q, pi) = &*self.scratch;
        (0..model.len()).find(|&i| {
            let (linear, angular) = kinetic_energy(model.mass[i], model.moments[i], v[i], pi[i]);
            !(x[i].is_finite()
                && v[i].is_finite()
                && q[i].is_finite()
                && pi[i].is_finite()
                && (linear + angular).is_finite())
        })
    }
}

/// The divergence error of body `i` at step `s`, with a hint for penalty joints.
fn diverged(model: &Model, s: usize, i: usize) -> Error {
    let penalty = model.joints.iter().any(|j| j.method == JointMethod::Penalty);
    let hint = if penalty {
        "; penalty joints are explicit springs, stable only below a step of about 2/ω of their \
         stiffest coupling: reduce dt, or use another joint method"
    } else {
        ""
    };
    Error::Diverged {
        step: s,
        index: i,
        reason: format!("non-finite body state or kinetic energy{hint}"),
    }
}
