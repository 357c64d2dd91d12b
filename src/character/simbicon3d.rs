//! SIMBICON in 3-D (Yin, Loken & van de Panne 2007, §5 "3D walking") on the biped of
//! [`super::biped3d`]: the planar controller's finite-state machine, poses and gains
//! ([`Gait`], [`super::simbicon`]) in the sagittal plane, and balance feedback applied
//! independently in the coronal plane ([`Coronal`]).
//!
//! - **Swing hip** (eq. 1 in each plane): the swing thigh's target orientation in the world
//!   is `R_z(θ_s) R_x(−θ_c)` with `θ_s = θ_s0 + c_d d_s + c_v v_s` (sagittal, from the
//!   ground's normal, positive forward) and `θ_c = ±θ_c0 + c_dc d_c + c_vc v_c` (coronal,
//!   positive moves the foot to +z, the right; `θ_c0` abducts: + for the right leg, − for
//!   the left). `d` is the horizontal vector from the stance ankle to the centre of mass,
//!   `v` the centre of mass's velocity, in the directions forward (`_s`) and z (`_c`).
//!   The target has no twist: the swing thigh keeps facing forward.
//! - **Torso** and **stance hip** (§3.2, in 3-D): the torso is servoed in the world frame
//!   towards `R_z(2α + θ_torso)` (on a slope α, leaning by α against gravity, below;
//!   heading +x, `θ_torso` the pose's lean), `τ_torso = k_p log(R̄ Rᵀ) − k_d ω` (world vectors); the swing hip's torque is
//!   the same PD on the swing thigh's world orientation, `τ_B`; the stance hip takes
//!   `τ_A = −τ_torso − τ_B` (world), so that the hips apply `τ_torso` to the torso. The
//!   torso's yaw is part of `τ_torso`: the stance hip holds the twist (the heading).
//! - **The stance foot's grip** (ours): the stance hip's torque about the stance leg's axis
//!   (from the hip through the foot's centre of pressure) is clamped to half of what the
//!   foot's friction holds against turning about it ([`grip`], [`GRIP_MARGIN`]); the leg
//!   turns about that axis on the hip's torque alone, and without the cap a lightly loaded
//!   stance foot let the leg spin (350 N from behind, the descent), at the full limit a
//!   foot on its edge after a push from the side (measured, docs/character.md).
//! - Hip torques are clamped to `±max_torque` per component in the thigh's axes. Knees
//!   (hinges) and ankles (ball joints, target `R_z(θ)`, no roll or twist) are servos of the
//!   model, stable PD by default, with the gait's gains.
//!
//! The heading is fixed (+x): `d`, `v` and the targets are in world axes. Slopes as in the
//! planar walker (gravity turned about z by the slope, the swing hip's sagittal target from
//! the ground's normal), except the torso: its target leans against gravity by the slope
//! angle, back going down and forward going up, `R_z(2α + θ_torso)` in the ground's frame
//! (with the planar walker's upright torso, `R_z(α + θ_torso)`, the walk fell 3.4 s down
//! 5°; measured, docs/character.md).

use super::biped3d::{biped3d, LEFT_3D, RIGHT_3D, TORSO_3D};
use super::dynamics::Tree;
use super::forces::{contacts, implicit};
use super::model::{Collider, Model, Servo, Settings};
use super::simbicon::{
    advance, check_gravity, ground_velocity, touches, vertical, walk, Gait, Phase,
};
use super::solver::Solver;
use super::spatial::angular;
use super::state::State;
use crate::error::{Error, Result};
use crate::rotation::quat_to_rotvec;
use glam::{DQuat, DVec3};

/// Coronal balance of the 3-D walk (the same in every FSM state). The default (`c_d` = 0,
/// `c_v` = 0.3 rad s/m, no abduction) is ours: first chosen on a grid (`c_d` ∈ {−0.5, 0,
/// 0.3}, `c_v` ∈ {0.4, …, 0.8}, `θ_c0` ∈ {−0.05, 0, 0.05}) as the one that walked 20 s and
/// survived the most pushes at dt = 1e-3 s (`c_v` = 0.4), then lowered to 0.3 on a second
/// grid of the largest side push survived at 7 phases (`c_v` ∈ {0.2, …, 0.5}, `c_d` ∈
/// {−0.1, …, 0.2}; session 29): 500–650 N from the sides where 0.4 took 350–550 N, pushes
/// from the front and behind within 50 N of 0.4's (docs/character.md).
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Coronal {
    /// Feedback on the stance ankle's lateral distance to the centre of mass (rad/m).
    pub cd: f64,
    /// Feedback on the centre of mass's lateral velocity (rad s/m).
    pub cv: f64,
    /// The swing thigh's nominal abduction `θ_c0` (rad, positive outwards).
    pub swing_hip: f64,
}

impl Default for Coronal {
    fn default() -> Self {
        Coronal { cd: 0.0, cv: 0.3, swing_hip: 0.0 }
    }
}

impl Gait {
    /// The 3-D walk: the paper's 2-D gait ([`Gait::default`]) with a stiffer torso servo
    /// (`torso_kp` = 1000 N m/rad, `torso_kd` = 100 N m s/rad): at 300 the torso rolls by
    /// 0.27 rad towards the swing leg within 0.3 s and the biped falls sideways (measured).
    pub fn default_3d() -> Gait {
        Gait { torso_kp: 1000.0, torso_kd: 100.0, ..Gait::default() }
    }
}

impl Coronal {
    /// Check every value.
    ///
    /// # Errors
    /// A non-finite value (named).
    pub fn check(&self) -> Result<()> {
        for (name, v) in [
            ("coronal_cd", self.cd),
            ("coronal_cv", self.cv),
            ("coronal_swing_hip", self.swing_hip),
        ] {
            if !v.is_finite() {
                return Err(Error::invalid(name, "must be finite"));
            }
        }
        Ok(())
    }
}

/// The 3-D biped walking under SIMBICON: model, state, controller phase, gait (sagittal
/// poses and gains) and coronal feedback, and a solver.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub struct Walker3d {
    pub(super) model: Model,
    pub(super) state: State,
    pub(super) phase: Phase,
    /// The gait (free to change between steps).
    pub gait: Gait,
    /// The coronal balance feedback (free to change between steps).
    pub coronal: Coronal,
    #[serde(skip)]
    solver: Solver,
    /// The state at the start of [`Walker3d::step`] (to put back on error).
    #[serde(skip)]
    start: Option<State>,
}

/// The bodies whose joints are servos of the model (knees and ankles).
pub(super) const SERVOED_3D: [usize; 4] = [RIGHT_3D[1], RIGHT_3D[2], LEFT_3D[1], LEFT_3D[2]];

impl Walker3d {
    /// The biped standing straight with its soles on the ground (sunk by the contact
    /// springs' rest depth), moving forward (+x) at `speed` (m/s), under `gait` and
    /// `coronal`, in FSM state 0, with `settings`.
    ///
    /// # Errors
    /// A gait or coronal feedback that their `check` refuses; a non-finite `speed`
    /// (`speed`); a gravity without a component in the x–y plane (`gravity`).
    pub fn new(settings: Settings, gait: Gait, coronal: Coronal, speed: f64) -> Result<Self> {
        gait.check()?;
        coronal.check()?;
        if !speed.is_finite() {
            return Err(Error::invalid("speed", "must be finite"));
        }
        check_gravity(&settings)?;
        let mut model = biped3d(settings)?;
        let servo = joint_servo(&gait);
        for body in SERVOED_3D {
            model.set_servo(body, Some(servo))?;
        }
        let mut state = State::new(&model);
        let mut q = model.neutral();
        q[1] = super::biped::hip_height() - 0.002;
        state.set_q(&model, &q)?;
        let mut qd = vec![0.0; model.nv()];
        qd[3] = speed;
        state.set_qd(&qd)?;
        let solver = Solver::new(&model);
        Ok(Walker3d { model, state, phase: Phase::default(), gait, coronal, solver, start: None })
    }

    /// The model.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// Add a static collider under the feet ([`Model::add_collider`]; [`Walker3d::set_collider`]
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
    /// ([`super::simbicon::ground_velocity`], of the heel).
    ///
    /// # Errors
    /// Those of [`Model::set_collider`]; the walker is then unchanged.
    pub fn set_collider(&mut self, index: usize, collider: Collider) -> Result<()> {
        self.model.set_collider(index, collider)
    }

    /// The biped's state (coordinates as [`biped3d`]'s).
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
    /// controller's torques and targets, then one solver step.
    ///
    /// # Errors
    /// An invalid gait or coronal feedback (named); those of [`Solver::step`]. On error the
    /// state and the phase are as before the call.
    pub fn step(&mut self, dt: f64, steps: usize) -> Result<()> {
        self.gait.check()?;
        self.coronal.check()?;
        let servo = joint_servo(&self.gait);
        if self.model.bodies()[SERVOED_3D[0]].servo != Some(servo) {
            for body in SERVOED_3D {
                self.model.set_servo(body, Some(servo))?;
            }
        }
        let (gait, coronal) = (&self.gait, &self.coronal);
        let parts = (&self.model, &mut self.state, &mut self.solver, &mut self.phase);
        walk(parts, &mut self.start, dt, steps, |model, phase, tree, state| {
            let down = foot_down(model, tree, legs(phase.state).0, state.time);
            advance(phase, gait, down);
            control(gait, coronal, phase, model, tree, state, dt);
        })
    }

    /// Centre of mass (m, world).
    pub fn com(&mut self) -> DVec3 {
        self.solver.kinematics(&self.model, &self.state).com(&self.model)
    }

    /// Whether each foot (right, left; heel or toes) touches the ground.
    pub fn feet_in_contact(&mut self) -> [bool; 2] {
        let tree = self.solver.kinematics(&self.model, &self.state);
        let t = self.state.time;
        [foot_down(&self.model, tree, RIGHT_3D, t), foot_down(&self.model, tree, LEFT_3D, t)]
    }

    /// The kinematics of the current state.
    pub fn kinematics(&mut self) -> &mut Tree {
        self.solver.kinematics(&self.model, &self.state)
    }
}

/// The servo of every knee and ankle under `gait`.
fn joint_servo(gait: &Gait) -> Servo {
    Servo { kp: gait.kp, kd: gait.kd, max_torque: gait.max_torque }
}

/// Whether the heel or the toes of `leg` touch the ground (or a collider where it is at
/// `time`).
fn foot_down(model: &Model, tree: &Tree, leg: [usize; 4], time: f64) -> bool {
    touches(model, tree, leg[2], time) || touches(model, tree, leg[3], time)
}

/// The legs as (swing, stance) in FSM state `state`, and the swing side's sign (+1: the
/// right leg, at +z).
fn legs(state: u8) -> ([usize; 4], [usize; 4], f64) {
    if state < 2 {
        (RIGHT_3D, LEFT_3D, 1.0)
    } else {
        (LEFT_3D, RIGHT_3D, -1.0)
    }
}

/// The world-frame PD torque (N m) turning a body of orientation `rot` and world angular
/// velocity `omega` towards `target`.
fn servo_world(kp: f64, kd: f64, target: DQuat, rot: DQuat, omega: DVec3) -> DVec3 {
    kp * DVec3::from_array(quat_to_rotvec(target * rot.conjugate())) - kd * omega
}

/// A world torque on body `rot`'s joint as joint torques (body axes), clamped per
/// component to `±limit`; returns them and the world torque they make.
fn clamp_joint(world: DVec3, rot: DQuat, limit: f64) -> (DVec3, DVec3) {
    let local = (rot.conjugate() * world).clamp(DVec3::splat(-limit), DVec3::splat(limit));
    (local, rot * local)
}

/// The fraction of the stance foot's Coulomb limit against turning that the stance hip may
/// use ([`grip`]): the hip's torque is not the only load turning the leg (the swing leg's
/// and the leg's own reactions also do), so a hip torque at the full limit let the leg spin
/// after 350 N from a side (measured, docs/character.md: at 1 it fell at 3 of the 14 side
/// and phase pairs, at 0.25 at 4, at 0.5 and 0.75 at none).
const GRIP_MARGIN: f64 = 0.5;

/// What the stance foot's friction holds against the leg turning about its own axis: the
/// unit axis from the hip through the foot's centre of pressure and the largest torque
/// about it (N m), [`GRIP_MARGIN`] times `μ Σ f_n,i ρ_i` over the foot's contacts (`ρ_i` a
/// contact's distance from the axis; the sum: every contact sliding at its Coulomb limit);
/// in the air, the axis from the hip to the ankle and no torque. The whole stance leg
/// (thigh, shin, foot) turns about that axis on the hip's torque alone: its other joints are
/// inside it, the hip's force passes through the axis, and a foot on its toes pivots about
/// them.
fn grip(model: &Model, tree: &Tree, stance: [usize; 4], dt: f64) -> (DVec3, f64) {
    let stiff = implicit(model);
    let [heel, toes] = [stance[2], stance[3]].map(|b| contacts(model, tree, b, dt, stiff));
    let feet = || heel.iter().chain(&toes).flatten();
    let (mut load, mut moment) = (0.0, DVec3::ZERO);
    for (contact, _, force) in feet() {
        load += force.y;
        moment += force.y * contact.point;
    }
    let hip = tree.positions()[stance[0]];
    if load <= 0.0 {
        return ((tree.positions()[stance[2]] - hip).normalize(), 0.0);
    }
    let centre = moment / load;
    let axis = (centre - hip).normalize();
    let mut held = 0.0;
    for (contact, _, force) in feet() {
        held += force.y * (contact.point - centre).reject_from_normalized(axis).length();
    }
    (axis, GRIP_MARGIN * model.settings.friction * held)
}

/// SIMBICON's controls in 3-D into the walker's state: the hips' torques, and the knees'
/// and ankles' servo targets, at the state of its last kinematics, for a step `dt`.
#[allow(clippy::too_many_arguments)]
fn control(
    gait: &Gait,
    coronal: &Coronal,
    phase: &Phase,
    model: &Model,
    tree: &Tree,
    state: &mut State,
    dt: f64,
) {
    let pose = if phase.state.is_multiple_of(2) { &gait.lift } else { &gait.strike };
    let (swing, stance, side) = legs(phase.state);
    let (_, ahead, tilt) = vertical(model);
    let vel = tree.com_velocity(model) - ground_velocity(model, tree, stance[2], state.time());
    let r = tree.com(model) - tree.positions()[stance[2]];
    let sagittal = pose.swing_hip + pose.cd * r.dot(ahead) + pose.cv * vel.dot(ahead);
    let lateral = side * coronal.swing_hip + coronal.cd * r.z + coronal.cv * vel.z;
    let thigh_target = DQuat::from_rotation_z(sagittal) * DQuat::from_rotation_x(-lateral);
    // The torso leans against gravity by the slope (back going down, forward going up).
    let torso_target = DQuat::from_rotation_z(2.0 * tilt + pose.torso);
    let rot = tree.orientations();
    let omega = |i: usize| rot[i] * angular(&tree.v[i]);
    let torso =
        servo_world(gait.torso_kp, gait.torso_kd, torso_target, rot[TORSO_3D], omega(TORSO_3D));
    let swing_world = servo_world(gait.kp, gait.kd, thigh_target, rot[swing[0]], omega(swing[0]));
    let (swing_tau, swing_world) = clamp_joint(swing_world, rot[swing[0]], gait.max_torque);
    // The stance hip's torque about the leg's axis turns the leg against the foot's
    // friction alone: no more than the foot holds (none in the air).
    let mut stance_world = -torso - swing_world;
    let (axis, held) = grip(model, tree, stance, dt);
    let about = stance_world.dot(axis);
    stance_world -= (about - about.clamp(-held, held)) * axis;
    let (stance_tau, _) = clamp_joint(stance_world, rot[stance[0]], gait.max_torque);
    state.torques.fill(0.0);
    for (body, tau) in [(swing[0], swing_tau), (stance[0], stance_tau)] {
        let iv = model.starts(body).1;
        state.torques[iv..iv + 3].copy_from_slice(&tau.to_array());
    }
    for (body, angle) in [(swing[1], pose.swing_knee), (stance[1], pose.stance_knee)] {
        state.targets[model.starts(body).0] = angle;
    }
    for (body, angle) in [(swing[2], pose.swing_ankle), (stance[2], pose.stance_ankle)] {
        let t = DQuat::from_rotation_z(angle);
        let iq = model.starts(body).0;
        state.targets[iq..iq + 4].copy_from_slice(&[t.w, t.x, t.y, t.z]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The hips apply the torso servo's world torque to the torso, but for its part about
    /// the stance leg's axis where the stance foot's grip caps it: there the stance hip's
    /// torque about the axis is the grip and the rest is the torso's.
    #[test]
    fn the_hips_apply_the_torso_servo_torque_to_the_torso() {
        let settings = Settings { contact_frequency: 200.0, ..Settings::default() };
        let mut w = Walker3d::new(settings, Gait::default_3d(), Coronal::default(), 0.3).unwrap();
        let (mut checked, mut gripped) = (0, 0);
        for _ in 0..2000 {
            w.step(1e-3, 1).unwrap();
            let tree = w.solver.kinematics(&w.model, &w.state);
            control(&w.gait, &w.coronal, &w.phase, &w.model, tree, &mut w.state, 1e-3);
            let (tree, model, gait) = (w.solver.tree(), &w.model, &w.gait);
            let rot = tree.orientations();
            let pose = if w.phase.state.is_multiple_of(2) { &gait.lift } else { &gait.strike };
            let omega = rot[TORSO_3D] * angular(&tree.v[TORSO_3D]);
            let target = DQuat::from_rotation_z(pose.torso);
            let torso = servo_world(gait.torso_kp, gait.torso_kd, target, rot[TORSO_3D], omega);
            let joint = |b: usize| {
                let iv = model.starts(b).1;
                DVec3::from_slice(&w.state.torques()[iv..iv + 3])
            };
            let (right, left) = (joint(RIGHT_3D[0]), joint(LEFT_3D[0]));
            if right.abs().max(left.abs()).max_element() >= gait.max_torque {
                continue;
            }
            let on_torso = -(rot[RIGHT_3D[0]] * right) - rot[LEFT_3D[0]] * left;
            let stance = legs(w.phase.state).1;
            let (axis, held) = grip(model, tree, stance, 1e-3);
            let stance_hip = if stance == RIGHT_3D { right } else { left };
            if ((rot[stance[0]] * stance_hip).dot(axis).abs() - held).abs() < 1e-9 {
                let off_axis = (on_torso - torso).reject_from_normalized(axis);
                assert!(off_axis.length() < 1e-9, "{on_torso} vs {torso} off the axis {axis}");
                gripped += 1;
            } else {
                assert!((on_torso - torso).length() < 1e-9, "{on_torso} vs {torso}");
                checked += 1;
            }
        }
        assert!(checked > 1500, "{checked} unclamped steps, {gripped} at the grip");
        assert!(gripped > 0, "the grip never held the stance hip");
    }
}
