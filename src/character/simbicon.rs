//! SIMBICON (Yin, Loken & van de Panne 2007, "SIMBICON: Simple Biped Locomotion Control",
//! ACM TOG 26(3)) on the planar biped of [`super::biped`].
//!
//! - **Finite-state machine** (§3.1, Fig. 2): state 0 (right leg swings) lasts
//!   [`Gait::duration`]; state 1 ends when the right foot touches the ground; states 2 and 3
//!   mirror them with the left leg. Each strike (1 → 2, 3 → 0) is a step.
//! - **Target poses** (§3.2): per state, the swing hip's angle in the world frame, the swing
//!   knee and ankle, the stance knee and ankle (relative angles), the torso's world angle.
//! - **Balance feedback** (§3.3, eq. 1): the swing hip's target is
//!   `θ_d = θ_d0 + c_d d + c_v v`, with `d` the horizontal distance from the stance ankle to
//!   the centre of mass and `v` the centre of mass's horizontal velocity.
//! - **Torques** (§3.2): PD at every joint, `τ = k_p (θ_d − θ) − k_d θ̇`; the torso and the
//!   swing hip are servoed in the world frame, and the stance hip takes
//!   `τ_A = −τ_torso − τ_B` (`τ_B` the swing hip's torque), so that the hips together
//!   apply `τ_torso` to the torso. Every torque is clamped to `±max_torque`.
//!
//! "World frame" and "horizontal" are taken against gravity, not against the ground: with
//! the gravity of [`Settings::gravity`] turned by α the biped walks on a slope of α.
//!
//! The hip torques are computed once per step at the step's start (explicit PD on the
//! heavy torso and legs). The knees and ankles are servos of the model with the gait's
//! gains, by default stable PD (Tan, Liu & Turk 2011, [`super::servo`]), whose targets the
//! controller sets: the 1 kg feet would need `k_d dt / I ≲ 1` under explicit PD
//! (`dt ≤ 2e-4 s` at the paper's gains).

use super::biped::{planar_biped, LEFT, RIGHT, TORSO};
use super::dynamics::Tree;
use super::model::{Collider, Model, Servo, Settings};
use super::solver::Solver;
use super::state::State;
use crate::error::{Error, Result};
use glam::DVec3;

/// The targets and feedback gains of a pair of mirrored states (§3.2, Table 1 of the paper).
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// Balance feedback on the stance ankle's distance to the centre of mass, `c_d` (rad/m).
    pub cd: f64,
    /// Balance feedback on the centre of mass's velocity, `c_v` (rad s/m).
    pub cv: f64,
    /// Torso angle from the vertical (rad, world frame; positive leans back).
    pub torso: f64,
    /// Swing hip's target angle `θ_d0` (rad, the swing thigh's angle from the vertical in
    /// the world frame; positive forward).
    pub swing_hip: f64,
    /// Swing knee (rad, relative; negative bends).
    pub swing_knee: f64,
    /// Swing ankle (rad, relative; positive lifts the toe).
    pub swing_ankle: f64,
    /// Stance knee (rad, relative).
    pub stance_knee: f64,
    /// Stance ankle (rad, relative).
    pub stance_ankle: f64,
}

/// A SIMBICON gait: the poses of states 0/2 (`lift`) and 1/3 (`strike`), the length of
/// states 0 and 2 and the PD gains. The default is the paper's walk (Table 1, its 2-D
/// gait): upright torso, `k_p = 300` N m/rad and `k_d = 30` N m s/rad at every joint and at
/// the torso.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Gait {
    /// States 0 and 2 (the swing leg lifts).
    pub lift: Pose,
    /// States 1 and 3 (until the swing foot strikes).
    pub strike: Pose,
    /// Duration of states 0 and 2 (s).
    pub duration: f64,
    /// Proportional gain of every joint and of the torso (N m/rad).
    pub kp: f64,
    /// Derivative gain (N m s/rad).
    pub kd: f64,
    /// Proportional gain of the torso's world-frame servo (N m/rad).
    pub torso_kp: f64,
    /// Derivative gain of the torso's servo (N m s/rad).
    pub torso_kd: f64,
    /// Torque limit of every joint (N m).
    pub max_torque: f64,
}

impl Default for Gait {
    fn default() -> Self {
        Gait {
            lift: Pose {
                cd: 0.0,
                cv: 0.2,
                torso: 0.0,
                swing_hip: 0.4,
                swing_knee: -1.1,
                swing_ankle: 0.2,
                stance_knee: -0.05,
                stance_ankle: 0.2,
            },
            strike: Pose {
                cd: 2.2,
                cv: 0.0,
                torso: 0.0,
                swing_hip: -0.7,
                swing_knee: -0.05,
                swing_ankle: 0.2,
                stance_knee: -0.1,
                stance_ankle: 0.2,
            },
            duration: 0.3,
            kp: 300.0,
            kd: 30.0,
            torso_kp: 300.0,
            torso_kd: 30.0,
            max_torque: 400.0,
        }
    }
}

impl Gait {
    /// Check every value.
    ///
    /// # Errors
    /// A non-finite pose value (named), a duration, gain or torque limit not finite or
    /// negative (`duration` and `max_torque` must be > 0).
    pub fn check(&self) -> Result<()> {
        for p in [&self.lift, &self.strike] {
            let values = [
                ("cd", p.cd),
                ("cv", p.cv),
                ("torso", p.torso),
                ("swing_hip", p.swing_hip),
                ("swing_knee", p.swing_knee),
                ("swing_ankle", p.swing_ankle),
                ("stance_knee", p.stance_knee),
                ("stance_ankle", p.stance_ankle),
            ];
            if let Some((name, _)) = values.iter().find(|(_, v)| !v.is_finite()) {
                return Err(Error::invalid(*name, "must be finite"));
            }
        }
        for (name, v, positive) in [
            ("duration", self.duration, true),
            ("kp", self.kp, false),
            ("kd", self.kd, false),
            ("torso_kp", self.torso_kp, false),
            ("torso_kd", self.torso_kd, false),
            ("max_torque", self.max_torque, true),
        ] {
            if !(v.is_finite() && (v > 0.0 || (!positive && v == 0.0))) {
                let bound = if positive { "> 0" } else { ">= 0" };
                return Err(Error::invalid(name, format!("must be finite and {bound}")));
            }
        }
        Ok(())
    }
}

/// The controller's state: the FSM state, the time spent in it and the steps taken.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq, Default)]
pub struct Phase {
    /// FSM state 0–3 (0, 1: the right leg swings; 2, 3: the left).
    pub state: u8,
    /// Time in the current FSM state (s).
    pub time: f64,
    /// Foot strikes so far (transitions 1 → 2 and 3 → 0).
    pub steps: u64,
}

/// The planar biped walking under SIMBICON: its model, state, controller phase and gait,
/// and a solver. A snapshot holds the model, the state, the phase and the gait.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub struct Walker {
    pub(super) model: Model,
    pub(super) state: State,
    pub(super) phase: Phase,
    /// The gait (free to change between steps).
    pub gait: Gait,
    #[serde(skip)]
    solver: Solver,
    /// The state at the start of [`Walker::step`] (to put back on error; kept between calls
    /// so that a step allocates nothing).
    #[serde(skip)]
    start: Option<State>,
}

impl Walker {
    /// The biped standing straight with its soles on the ground (sunk by the contact
    /// springs' rest depth), moving forward at `speed` (m/s), under `gait`, in FSM state 0,
    /// with `settings` (a ground is needed to walk; gravity gives the vertical).
    ///
    /// # Errors
    /// A gait that [`Gait::check`] refuses; a non-finite `speed` (`speed`); a gravity
    /// without a component in the x–y plane (`gravity`).
    pub fn new(settings: Settings, gait: Gait, speed: f64) -> Result<Self> {
        gait.check()?;
        if !speed.is_finite() {
            return Err(Error::invalid("speed", "must be finite"));
        }
        let model = walker_model(settings, &gait)?;
        let mut state = State::new(&model);
        let mut q = model.neutral();
        q[1] = super::biped::hip_height() - 0.002;
        state.set_q(&model, &q)?;
        let mut qd = vec![0.0; model.nv()];
        qd[0] = speed;
        state.set_qd(&qd)?;
        let solver = Solver::new(&model);
        Ok(Walker { model, state, phase: Phase::default(), gait, solver, start: None })
    }

    /// The model.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// Add a static collider under the feet ([`Model::add_collider`]; [`Walker::set_collider`]
    /// moves it); the controller takes a foot in it for a foot on the ground. Returns its
    /// index.
    ///
    /// # Errors
    /// Those of [`Model::add_collider`].
    pub fn add_collider(
        &mut self,
        shape: crate::geometry::Shape,
        friction: Option<f64>,
    ) -> Result<usize> {
        self.model.add_collider(shape, friction)
    }

    /// Move collider `index` ([`Model::set_collider`]: a kinematic collider, translating and
    /// turning at constant velocities from `collider.since`). The balance feedback takes the
    /// centre of mass's velocity relative to the surface under the stance foot
    /// ([`ground_velocity`]).
    ///
    /// # Errors
    /// Those of [`Model::set_collider`]; the walker is then unchanged.
    pub fn set_collider(&mut self, index: usize, collider: Collider) -> Result<()> {
        self.model.set_collider(index, collider)
    }

    /// The biped's state (coordinates `[x, y, θ, hip, knee, ankle (right), hip, knee,
    /// ankle (left)]`).
    pub fn state(&self) -> &State {
        &self.state
    }

    /// The model and the state, mutable (to push, or to set coordinates).
    pub fn parts_mut(&mut self) -> (&Model, &mut State) {
        (&self.model, &mut self.state)
    }

    /// The controller's phase.
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// Put back a state and phase saved from this walker (a scene's undo).
    pub fn restore(&mut self, state: &State, phase: Phase) {
        self.state.clone_from(state);
        self.phase = phase;
    }

    /// Put back colliders saved from this walker's model ([`Model::restore_colliders`]).
    pub fn restore_colliders(&mut self, saved: &[Collider]) {
        self.model.restore_colliders(saved);
    }

    /// Advance `steps` steps of `dt` seconds: each runs the FSM's transitions, the
    /// controller's torques, then one solver step.
    ///
    /// # Errors
    /// An invalid gait (named); those of [`Solver::step`]. On error the state and the phase
    /// are as before the call.
    pub fn step(&mut self, dt: f64, steps: usize) -> Result<()> {
        self.gait.check()?;
        let servo = joint_servo(&self.gait);
        if self.model.bodies()[SERVOED[0]].servo != Some(servo) {
            for body in SERVOED {
                self.model.set_servo(body, Some(servo))?;
            }
        }
        let gait = &self.gait;
        let parts = (&self.model, &mut self.state, &mut self.solver, &mut self.phase);
        walk(parts, &mut self.start, dt, steps, |model, phase, tree, state| {
            let down = touches(model, tree, legs(phase.state).0[2], state.time);
            advance(phase, gait, down);
            control(gait, phase, model, tree, state);
        })
    }

    /// Centre of mass (m, world).
    pub fn com(&mut self) -> DVec3 {
        self.solver.kinematics(&self.model, &self.state).com(&self.model)
    }

    /// Whether each foot (right, left) touches the ground.
    pub fn feet_in_contact(&mut self) -> [bool; 2] {
        let tree = self.solver.kinematics(&self.model, &self.state);
        let t = self.state.time;
        [touches(&self.model, tree, RIGHT[2], t), touches(&self.model, tree, LEFT[2], t)]
    }

    /// The kinematics of the current state.
    pub fn kinematics(&mut self) -> &mut Tree {
        self.solver.kinematics(&self.model, &self.state)
    }
}

/// The bodies whose joints are servos of the model (knees and ankles), driven towards the
/// controller's targets with the gait's gains.
pub(super) const SERVOED: [usize; 4] = [RIGHT[1], RIGHT[2], LEFT[1], LEFT[2]];

/// The servo of every knee and ankle under `gait`.
fn joint_servo(gait: &Gait) -> Servo {
    Servo { kp: gait.kp, kd: gait.kd, max_torque: gait.max_torque }
}

/// The walker's model: the planar biped with `settings` and `gait`'s servos at its knees
/// and ankles.
///
/// # Errors
/// A gravity without a component in the x–y plane (`gravity`); those of
/// [`planar_biped`] and [`Model::set_servo`].
pub(super) fn walker_model(settings: Settings, gait: &Gait) -> Result<Model> {
    check_gravity(&settings)?;
    let mut model = planar_biped(settings)?;
    for body in SERVOED {
        model.set_servo(body, Some(joint_servo(gait)))?;
    }
    Ok(model)
}

/// A walker's gravity must have a component in the x–y plane (its vertical).
///
/// # Errors
/// Otherwise (`gravity`).
pub(super) fn check_gravity(settings: &Settings) -> Result<()> {
    let g = settings.gravity;
    if g.x.hypot(g.y).partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return Err(Error::invalid("gravity", "must have a component in the x-y plane"));
    }
    Ok(())
}

/// The upward vertical (against gravity) and the forward horizontal, unit vectors in the
/// x–y plane, and the angle (rad, about z) of the vertical from the y axis.
pub(super) fn vertical(model: &Model) -> (DVec3, DVec3, f64) {
    let g = model.settings.gravity;
    let up = DVec3::new(-g.x, -g.y, 0.0).normalize();
    (up, DVec3::new(up.y, -up.x, 0.0), (-up.x).atan2(up.y))
}

/// Whether body `foot`'s capsule reaches below the ground plane or into a collider where it
/// is at `time` (its axis's deepest point closer than its radius).
pub(super) fn touches(model: &Model, tree: &Tree, foot: usize, time: f64) -> bool {
    let Some(c) = model.bodies()[foot].shape else { return false };
    let (pos, rot) = (tree.positions()[foot], tree.orientations()[foot]);
    let (a, b) = (pos + rot * c.a, pos + rot * c.b);
    a.y.min(b.y) < c.radius
        || model
            .colliders()
            .iter()
            .map(|k| k.at(time))
            .any(|k| k.distance(a.lerp(b, k.deepest_on_segment(a, b))).0 < c.radius)
}

/// The velocity (m/s, world) of the surface under body `foot`'s capsule where the colliders
/// are at `time`: that of the collider nearest the capsule's axis (its surface velocity,
/// [`Collider::surface_velocity`], at the point of it nearest the axis's deepest point) when
/// it is nearer than the ground plane (at rest; none without a ground), else zero. The
/// balance feedback takes the centre of mass's velocity relative to it, so that a walk on a
/// platform moving at a constant velocity is the walk on still ground carried along
/// (Galilean invariance; SIMBICON's `v` is against the stance foot's ground).
pub(super) fn ground_velocity(model: &Model, tree: &Tree, foot: usize, time: f64) -> DVec3 {
    let Some(c) = model.bodies()[foot].shape else { return DVec3::ZERO };
    if model.colliders().is_empty() {
        return DVec3::ZERO;
    }
    let (pos, rot) = (tree.positions()[foot], tree.orientations()[foot]);
    let (a, b) = (pos + rot * c.a, pos + rot * c.b);
    let mut nearest = if model.settings.ground { a.y.min(b.y) } else { f64::INFINITY };
    let mut velocity = DVec3::ZERO;
    for collider in model.colliders() {
        let at = collider.at(time);
        let p = a.lerp(b, at.deepest_on_segment(a, b));
        let (d, n) = at.distance(p);
        if d < nearest {
            nearest = d;
            velocity = collider.surface_velocity(&at, p - d * n);
        }
    }
    velocity
}

/// The legs as (swing, stance) in FSM state `state`.
fn legs(state: u8) -> ([usize; 3], [usize; 3]) {
    if state < 2 {
        (RIGHT, LEFT)
    } else {
        (LEFT, RIGHT)
    }
}

/// The FSM's transitions (§3.1): states 0 and 2 end after `gait.duration`, states 1 and 3
/// when the swing foot is `down` (touches the ground).
pub(super) fn advance(phase: &mut Phase, gait: &Gait, down: bool) {
    let next = match phase.state {
        0 | 2 => phase.time >= gait.duration,
        _ => down,
    };
    if next {
        if phase.state % 2 == 1 {
            phase.steps += 1;
        }
        phase.state = (phase.state + 1) % 4;
        phase.time = 0.0;
    }
}

/// The step loop both walkers share: `steps` steps of `dt` seconds, each computing the
/// kinematics once, then `control(model, phase, tree, state)` (the FSM's transitions and the
/// controller's torques and targets, at those kinematics), then one solver step that reuses
/// them; on error the state and the phase are put back as they were at the call. `start`
/// keeps the undo state between calls, so that a step allocates nothing.
pub(super) fn walk(
    (model, state, solver, phase): (&Model, &mut State, &mut Solver, &mut Phase),
    start: &mut Option<State>,
    dt: f64,
    steps: usize,
    mut control: impl FnMut(&Model, &mut Phase, &Tree, &mut State),
) -> Result<()> {
    super::solver::check(model, state, dt)?;
    let mut saved = start.take().unwrap_or_else(|| state.clone());
    saved.clone_from(state);
    let saved_phase = *phase;
    let mut result = Ok(());
    for n in 0..steps {
        let tree = solver.kinematics(model, state);
        control(model, phase, tree, state);
        if let Err(e) = solver.step_once(model, state, dt, true, n) {
            state.clone_from(&saved);
            *phase = saved_phase;
            result = Err(e);
            break;
        }
        phase.time += dt;
    }
    *start = Some(saved);
    result
}

/// SIMBICON's controls (§3.2–3.3) into `state`: the hips' torques, and the knees' and
/// ankles' servo targets.
fn control(gait: &Gait, phase: &Phase, model: &Model, tree: &Tree, state: &mut State) {
    let pose = if phase.state.is_multiple_of(2) { &gait.lift } else { &gait.strike };
    let (swing, stance) = legs(phase.state);
    let (_, ahead, tilt) = vertical(model);
    let (q, qd) = (state.q(), state.qd());
    let dof = |body: usize| model.starts(body).1;
    let limit = gait.max_torque;
    let d = (tree.com(model) - tree.positions()[stance[2]]).dot(ahead);
    let v = tree.com_velocity(model).dot(ahead)
        - ground_velocity(model, tree, stance[2], state.time).dot(ahead);
    // The swing hip's target is measured from the ground's normal (the slope adjustment:
    // on a slope of α it is θ_d + α from the vertical), the torso's from the vertical.
    let target_hip = pose.swing_hip + pose.cd * d + pose.cv * v - tilt;
    let (torso, torso_rate) = (q[2] - tilt, qd[2]);
    let mut tau = [0.0; 9];
    let torso_torque = gait.torso_kp * (pose.torso - torso) - gait.torso_kd * torso_rate;
    let sh = dof(swing[0]);
    let swing_torque = gait.kp * (target_hip - torso - q[sh]) - gait.kd * (torso_rate + qd[sh]);
    tau[sh] = swing_torque.clamp(-limit, limit);
    tau[dof(stance[0])] = (-torso_torque - tau[sh]).clamp(-limit, limit);
    debug_assert_eq!((dof(TORSO), model.nv(), model.nq()), (0, tau.len(), tau.len()));
    state.torques.copy_from_slice(&tau);
    for (body, target) in [
        (swing[1], pose.swing_knee),
        (swing[2], pose.swing_ankle),
        (stance[1], pose.stance_knee),
        (stance[2], pose.stance_ankle),
    ] {
        state.targets[model.starts(body).0] = target;
    }
}
