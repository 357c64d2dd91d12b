//! Mocap tracking: the ragdoll of an ASF or BVH skeleton follows a clip of that skeleton
//! frame by frame with (stable) PD servos on its joints and a "hand of God" on its root, a
//! PD force and torque towards the clip's root whose size is measured and reported.
//!
//! - **Reference.** Frame `k` of the clip gives the ragdoll's coordinates `q̄_k`. ASF: a
//!   hinge its dof's angle (the hinge turns about `C eₐ`, so `C Rₐ(θ) C⁻¹` is a turn by
//!   `θ`), a ball joint `C M C⁻¹` (the bone's rotation in its parent's frame,
//!   [`crate::mocap`]). BVH (every body's frame has world axes at rest, [`super::ragdoll_bvh`]):
//!   a hinge its channel's angle, a ball joint the product of its rotation channels in the
//!   order listed (the joint's rotation in its parent's frame, as BVH's forward kinematics);
//!   position channels below the root are not simulated. The root: its position (m, the
//!   clip's, lifted so that the median over the clip's frames of the lowest capsule point is
//!   on y = 0) and orientation. Rates `q̄̇_k = (q̄_{k+1} ⊖ q̄_k) × frame rate`.
//! - **Looping.** A clip shorter than the run is looped between the frames `a < b` whose
//!   joint coordinates are closest (`a` in the first quarter, `b` in the second half): after
//!   frame `b − 1` come `a, a + 1, …` again, the root moved by the turn about y and the
//!   horizontal shift that take frame `a`'s root to frame `b`'s.
//! - **A frame** `k → k + 1` (`substeps` steps of `1 / (frame rate × substeps)`): the servo
//!   targets are `q̄_{k+1}`; before every step the root gets the generalized force
//!   `τ = m (ω² (q̄ ⊖ q) + 2 ζ ω (q̄̇ − q̇))` on its six rates (`q̄`, `q̄̇` of frame `k + 1`),
//!   `m_j = 1 / (M⁻¹)_jj` the effective inertia of rate `j` at the frame's start (the CRBA's
//!   `M`, the rest of the tree free to respond, as the joint limits'): a world force at the
//!   root's origin and a torque in the root's axes, each rate a critically damped spring of
//!   frequency ω (`assist_frequency`) whatever the pose, so the explicit step stays stable
//!   while `ω dt` is small. (The total mass on the linear rates made a limp ragdoll diverge
//!   within 5 frames, the whole body's rotational inertia on the angular rates the tracking
//!   one within 10: the root alone moves much more easily than the whole body.)
//! - **Reported per frame** (at the end of the frame, against `q̄_{k+1}`): the root's
//!   position error (m), the RMS over the hinge and ball joints of the joint-angle error
//!   `|q̄ ⊖ q|` (rad), and the mean over the frame's steps of the assistance force (N) and
//!   torque (N m).

use super::joints::{difference, quat};
use super::model::{Joint, Servo};
use super::ragdoll::{ragdoll, ragdoll_bvh, RagdollOptions};
use super::servo::{ltl, ltl_solve};
use super::{ArticulatedBody, Settings, State, Tree};
use crate::error::{Error, Result};
use crate::mocap::{BvhSkeleton, Dof, Motion, Skeleton};
use glam::{DQuat, DVec3};

/// Gains and stepping of a [`Tracker`].
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct TrackingOptions {
    /// Servo proportional gain on every hinge and ball joint (N m/rad); 0 leaves the
    /// ragdoll limp (no servos).
    pub kp: f64,
    /// Servo derivative gain (N m s/rad).
    pub kd: f64,
    /// Servo torque limit per degree of freedom (N m).
    pub max_torque: f64,
    /// Natural frequency ω of the root assistance (rad/s); 0 turns it off.
    pub assist_frequency: f64,
    /// Damping ratio ζ of the root assistance.
    pub assist_damping: f64,
    /// Steps per clip frame.
    pub substeps: usize,
}

impl Default for TrackingOptions {
    fn default() -> Self {
        TrackingOptions {
            kp: 300.0,
            kd: 30.0,
            max_torque: f64::INFINITY,
            assist_frequency: 40.0,
            assist_damping: 1.0,
            substeps: 4,
        }
    }
}

/// The skeleton of a tracked clip: an Acclaim (ASF) skeleton or a BVH hierarchy (with a
/// single root).
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, PartialEq)]
pub enum TrackedSkeleton {
    /// An ASF skeleton ([`super::ragdoll`] builds its ragdoll).
    Asf(Skeleton),
    /// A BVH hierarchy ([`super::ragdoll_bvh`] builds its ragdoll).
    Bvh(BvhSkeleton),
}

impl From<&Skeleton> for TrackedSkeleton {
    fn from(s: &Skeleton) -> Self {
        TrackedSkeleton::Asf(s.clone())
    }
}

impl From<&BvhSkeleton> for TrackedSkeleton {
    fn from(s: &BvhSkeleton) -> Self {
        TrackedSkeleton::Bvh(s.clone())
    }
}

impl From<&TrackedSkeleton> for TrackedSkeleton {
    fn from(s: &TrackedSkeleton) -> Self {
        s.clone()
    }
}

impl TrackedSkeleton {
    /// Values per frame of its motions.
    fn stride(&self) -> usize {
        match self {
            TrackedSkeleton::Asf(s) => s.stride(),
            TrackedSkeleton::Bvh(s) => s.stride(),
        }
    }

    /// The checks of the skeleton's own `validate`, and a BVH hierarchy's single root.
    fn validate(&self) -> Result<()> {
        match self {
            TrackedSkeleton::Asf(s) => s.validate(),
            TrackedSkeleton::Bvh(s) => {
                s.validate()?;
                if s.joints.iter().skip(1).any(|j| j.parent.is_none()) {
                    return Err(Error::invalid("skeleton", "a tracked BVH needs a single root"));
                }
                Ok(())
            }
        }
    }

    /// Its ragdoll.
    fn ragdoll(&self, options: &RagdollOptions, settings: Settings) -> Result<super::Model> {
        match self {
            TrackedSkeleton::Asf(s) => ragdoll(s, options, settings),
            TrackedSkeleton::Bvh(s) => ragdoll_bvh(s, options, settings),
        }
    }
}

/// What one frame of tracking measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameReport {
    /// Simulated time at the end of the frame (s).
    pub time: f64,
    /// Distance of the root from the clip's root (m).
    pub root_error: f64,
    /// RMS over hinge and ball joints of `|q̄ ⊖ q|` (rad).
    pub joint_error: f64,
    /// Mean over the frame's steps of the assistance force's magnitude (N).
    pub assist_force: f64,
    /// Mean over the frame's steps of the assistance torque's magnitude (N m).
    pub assist_torque: f64,
}

/// A ragdoll tracking a clip (module documentation). A snapshot holds what it was built
/// from (skeleton, clip, ragdoll and tracking options), the ragdoll and the frame.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub struct Tracker {
    pub(super) body: ArticulatedBody,
    pub(super) skeleton: TrackedSkeleton,
    pub(super) motion: Motion,
    pub(super) ragdoll: RagdollOptions,
    pub(super) options: TrackingOptions,
    /// Added to the clip's root position (m): the ragdoll's root offset removed, the lift.
    pub(super) shift: DVec3,
    /// Loop: first and one-past-last frame, and the root's turn and shift per loop.
    pub(super) loop_span: (usize, usize),
    pub(super) loop_turn: DQuat,
    pub(super) loop_from: DVec3,
    pub(super) loop_to: DVec3,
    /// The mass of each of the root's six rates (kg m², kg) at the frame's start.
    pub(super) inertia: [f64; 6],
    #[serde(skip)]
    tree: Tree,
    pub(super) frame: usize,
    pub(super) q_ref: Vec<f64>,
    pub(super) q_next: Vec<f64>,
    pub(super) v_ref: Vec<f64>,
    pub(super) diff: Vec<f64>,
    #[serde(skip)]
    saved: Option<State>,
}

impl Tracker {
    /// The ragdoll of `skeleton` (an ASF [`Skeleton`] or a [`BvhSkeleton`]; `ragdoll`
    /// options, `settings`) at the first frame of `motion` with its rates, servos on every
    /// hinge and ball joint.
    ///
    /// # Errors
    /// Bad ragdoll options or settings (named); a BVH hierarchy with several roots
    /// (`skeleton`); a motion of another skeleton or of fewer than 8 frames (`motion`); gains
    /// not finite and >= 0, `max_torque` not >= 0, or `substeps` 0 (named).
    pub fn new(
        skeleton: impl Into<TrackedSkeleton>,
        motion: &Motion,
        ragdoll_options: &RagdollOptions,
        settings: Settings,
        options: TrackingOptions,
    ) -> Result<Tracker> {
        let skeleton = skeleton.into();
        skeleton.validate()?;
        motion.validate()?;
        if motion.stride != skeleton.stride() || motion.frames < 8 {
            return Err(Error::invalid(
                "motion",
                "must be a clip of this skeleton with at least 8 frames",
            ));
        }
        for (name, v) in [
            ("kp", options.kp),
            ("kd", options.kd),
            ("assist_frequency", options.assist_frequency),
            ("assist_damping", options.assist_damping),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::invalid(name, "must be finite and >= 0"));
            }
        }
        if options.max_torque.is_nan() || options.max_torque < 0.0 {
            return Err(Error::invalid("max_torque", "must be >= 0"));
        }
        if options.substeps == 0 {
            return Err(Error::invalid("substeps", "must be >= 1"));
        }
        let mut model = skeleton.ragdoll(ragdoll_options, settings)?;
        model.check_settings()?;
        if options.kp > 0.0 {
            let servo = Servo { kp: options.kp, kd: options.kd, max_torque: options.max_torque };
            for i in 0..model.bodies().len() {
                if matches!(model.bodies()[i].joint, Joint::Revolute { .. } | Joint::Ball) {
                    model.set_servo(i, Some(servo))?;
                }
            }
        }
        let (nq, nv) = (model.nq(), model.nv());
        let shift = -model.bodies()[0].offset;
        let mut t = Tracker {
            body: ArticulatedBody::new(model),
            skeleton,
            motion: motion.clone(),
            ragdoll: *ragdoll_options,
            options,
            shift,
            loop_span: (0, motion.frames),
            loop_turn: DQuat::IDENTITY,
            loop_from: DVec3::ZERO,
            loop_to: DVec3::ZERO,
            inertia: [0.0; 6],
            tree: Tree::default(),
            frame: 0,
            q_ref: vec![0.0; nq],
            q_next: vec![0.0; nq],
            v_ref: vec![0.0; nv],
            diff: vec![0.0; nv],
            saved: None,
        };
        t.lift_to_ground();
        t.find_loop();
        t.start_at(0)?;
        Ok(t)
    }

    /// Put the ragdoll at frame `frame` of the clip: its coordinates, rates and servo
    /// targets become `q̄_k`, `q̄̇_k`, `q̄_k` of that frame, which the next [`Tracker::step`]
    /// tracks from (`new` starts at frame 0). The clip's lift and loop are the whole clip's,
    /// so starting at `k` tracks what a tracker started at 0 tracks from frame `k` on; the
    /// body's time and pushes are kept.
    ///
    /// # Errors
    /// `start_frame` not before the loop's end `b` ([`Tracker::loop_span`]; the frames from
    /// `b` on are not played).
    pub fn start_at(&mut self, frame: usize) -> Result<()> {
        if frame >= self.loop_span.1 {
            return Err(Error::invalid(
                "start_frame",
                format!("must be below the loop's end, frame {}", self.loop_span.1),
            ));
        }
        self.frame = frame;
        self.reference(frame);
        let state = &mut self.body.state;
        state.q.copy_from_slice(&self.q_ref);
        state.qd.copy_from_slice(&self.v_ref);
        state.targets.copy_from_slice(&self.q_ref);
        Ok(())
    }

    /// Shift the clip vertically so that the median over its frames of the ragdoll's lowest
    /// capsule point is at y = 0.
    fn lift_to_ground(&mut self) {
        let mut lowest = Vec::with_capacity(self.motion.frames);
        let mut q = std::mem::take(&mut self.q_ref);
        let (model, mut tree) = (&self.body.model, Tree::default());
        let zero = vec![0.0; model.nv()];
        for k in 0..self.motion.frames {
            self.clip_pose(k, &mut q);
            tree.kinematics(model, &q, &zero);
            let low = model
                .bodies()
                .iter()
                .enumerate()
                .filter_map(|(i, b)| b.shape.map(|c| (i, c)))
                .map(|(i, c)| {
                    let w = tree.world(i);
                    let (ya, yb) = ((w.rot * c.a + w.pos).y, (w.rot * c.b + w.pos).y);
                    ya.min(yb) - c.radius
                })
                .fold(f64::INFINITY, f64::min);
            lowest.push(low);
        }
        self.q_ref = q;
        lowest.sort_by(f64::total_cmp);
        self.shift.y -= lowest[lowest.len() / 2];
    }

    /// The loop `a < b` of the module documentation, and its root transform.
    fn find_loop(&mut self) {
        let n = self.motion.frames;
        let model = self.body.model().clone();
        let poses: Vec<Vec<f64>> = (0..n)
            .map(|k| {
                let mut q = vec![0.0; model.nq()];
                self.clip_pose(k, &mut q);
                q
            })
            .collect();
        let mut diff = vec![0.0; model.nv()];
        let mut best = (f64::INFINITY, 0, n);
        for a in 0..n / 4 {
            for b in n / 2..n {
                difference(&model, &poses[b], &poses[a], &mut diff);
                let d: f64 = diff[6..].iter().map(|v| v * v).sum();
                if d < best.0 {
                    best = (d, a, b);
                }
            }
        }
        let (_, a, b) = best;
        let (qa, qb) = (quat(&poses[a][3..7]), quat(&poses[b][3..7]));
        let (_, twist) = twist_about_y(qb * qa.conjugate());
        let at = |q: &[f64]| DVec3::new(q[0], 0.0, q[2]);
        self.loop_span = (a, b);
        self.loop_turn = twist;
        self.loop_from = at(&poses[a]);
        self.loop_to = at(&poses[b]);
    }

    /// The ragdoll coordinates of clip frame `k` (no looping) into `q`.
    fn clip_pose(&self, k: usize, q: &mut [f64]) {
        let values = &self.motion.values[k * self.motion.stride..(k + 1) * self.motion.stride];
        match &self.skeleton {
            TrackedSkeleton::Asf(sk) => self.asf_pose(sk, values, q),
            TrackedSkeleton::Bvh(sk) => self.bvh_pose(sk, values, q),
        }
    }

    /// The ragdoll coordinates of the BVH frame `values` into `q` (module documentation).
    fn bvh_pose(&self, sk: &BvhSkeleton, values: &[f64], q: &mut [f64]) {
        let model = self.body.model();
        let mut k = 0;
        for (i, joint) in sk.joints.iter().enumerate() {
            let (mut t, mut r, mut first) = (joint.offset, DQuat::IDENTITY, None);
            for c in &joint.channels {
                match *c {
                    Dof::Translation(a) => t[a] = values[k],
                    Dof::Rotation(a) => {
                        r *= DQuat::from_axis_angle(DVec3::AXES[a], values[k]);
                        first.get_or_insert(values[k]);
                    }
                    Dof::Length => {}
                }
                k += 1;
            }
            let at = model.starts(i).0;
            let r = r.normalize();
            match model.bodies()[i].joint {
                Joint::Free => {
                    let p = t * self.ragdoll.scale + self.shift;
                    q[at..at + 3].copy_from_slice(&p.to_array());
                    q[at + 3..at + 7].copy_from_slice(&[r.w, r.x, r.y, r.z]);
                }
                Joint::Revolute { .. } => q[at] = first.unwrap_or(0.0),
                Joint::Ball => q[at..at + 4].copy_from_slice(&[r.w, r.x, r.y, r.z]),
                _ => {}
            }
        }
    }

    /// The ragdoll coordinates of the ASF frame `values` into `q` (module documentation).
    fn asf_pose(&self, sk: &Skeleton, values: &[f64], q: &mut [f64]) {
        let (mut t, mut angles) = (sk.root_position, [0.0; 3]);
        let mut j = 0;
        for dof in &sk.root_order {
            match *dof {
                Dof::Translation(a) => t[a] = values[j],
                Dof::Rotation(a) => angles[a] = values[j],
                Dof::Length => {}
            }
            j += 1;
        }
        let [x, y, z] = sk.root_axis.axes;
        let m = sk.root_axis.to_quat(&[angles[x], angles[y], angles[z]]).expect("finite angles");
        let root = (sk.root_orientation * m).normalize();
        let p = t * self.ragdoll.scale + self.shift;
        q[..3].copy_from_slice(&p.to_array());
        q[3..7].copy_from_slice(&[root.w, root.x, root.y, root.z]);
        let model = self.body.model();
        for (b, bone) in sk.bones.iter().enumerate() {
            let mut m = DQuat::IDENTITY;
            let mut first = None;
            for dof in &bone.dofs {
                if let Dof::Rotation(a) = *dof {
                    m = DQuat::from_axis_angle(DVec3::AXES[a], values[j]) * m;
                    first.get_or_insert(values[j]);
                }
                j += 1;
            }
            let at = model.starts(b + 1).0;
            match model.bodies()[b + 1].joint {
                Joint::Revolute { .. } => q[at] = first.unwrap_or(0.0),
                Joint::Ball => {
                    let r = (bone.axis * m * bone.axis.conjugate()).normalize();
                    q[at..at + 4].copy_from_slice(&[r.w, r.x, r.y, r.z]);
                }
                _ => {}
            }
        }
    }

    /// `q̄_k` and `q̄̇_k` (looped) into `q_ref` and `v_ref`.
    fn reference(&mut self, k: usize) {
        let mut q = std::mem::take(&mut self.q_ref);
        let mut next = std::mem::take(&mut self.q_next);
        self.looped_pose(k, &mut q);
        self.looped_pose(k + 1, &mut next);
        difference(self.body.model(), &next, &q, &mut self.v_ref);
        self.v_ref.iter_mut().for_each(|v| *v *= self.motion.frame_rate);
        (self.q_ref, self.q_next) = (q, next);
    }

    /// Frame `k` of the looped clip into `q`.
    fn looped_pose(&self, k: usize, q: &mut [f64]) {
        let (a, b) = self.loop_span;
        if k < b {
            return self.clip_pose(k, q);
        }
        let loops = 1 + (k - b) / (b - a);
        self.clip_pose(a + (k - b) % (b - a), q);
        let (mut p, mut r) = (DVec3::new(q[0], q[1], q[2]), quat(&q[3..7]));
        for _ in 0..loops {
            let h = DVec3::new(p.x, 0.0, p.z) - self.loop_from;
            p = self.loop_turn * h + self.loop_to + DVec3::new(0.0, p.y, 0.0);
            r = (self.loop_turn * r).normalize();
        }
        q[..3].copy_from_slice(&p.to_array());
        q[3..7].copy_from_slice(&[r.w, r.x, r.y, r.z]);
    }

    /// Track one frame (module documentation) and report it.
    ///
    /// # Errors
    /// A step that diverges ([`Error::Diverged`]); the tracker is then as it was.
    pub fn step(&mut self) -> Result<FrameReport> {
        let saved = self.saved.get_or_insert_with(|| self.body.state().clone());
        saved.clone_from(self.body.state());
        self.reference(self.frame + 1);
        let dt = 1.0 / (self.motion.frame_rate * self.options.substeps as f64);
        let (mut force, mut torque) = (0.0, 0.0);
        self.body.state_mut().targets.copy_from_slice(&self.q_ref);
        self.root_inertias();
        for _ in 0..self.options.substeps {
            let (f, t) = self.assist();
            force += f.length();
            torque += t.length();
            if let Err(e) = self.body.step(dt, 1) {
                let saved = self.saved.as_ref().expect("saved above");
                self.body.state_mut().clone_from(saved);
                return Err(e);
            }
        }
        self.frame += 1;
        let n = self.options.substeps as f64;
        let (root_error, joint_error) = self.errors();
        Ok(FrameReport {
            time: self.body.state().time,
            root_error,
            joint_error,
            assist_force: force / n,
            assist_torque: torque / n,
        })
    }

    /// The effective inertia `1 / (M⁻¹)_jj` of each of the root's six rates at the current
    /// state (CRBA, LTL factorisation); kept from the last frame if `M` is not positive definite.
    fn root_inertias(&mut self) {
        let (model, state, tree) = (&self.body.model, &self.body.state, &mut self.tree);
        tree.kinematics(model, &state.q, &state.qd);
        tree.crba(model);
        if !ltl(&mut tree.mass_matrix, &tree.dof_paths) {
            return;
        }
        for (j, m) in self.inertia.iter_mut().enumerate() {
            tree.column.fill(0.0);
            tree.column[j] = 1.0;
            ltl_solve(&tree.mass_matrix, &tree.dof_paths, &mut tree.column);
            *m = 1.0 / tree.column[j];
        }
    }

    /// Set the root's assistance torques from the current state; return the force (N,
    /// world) and torque (N m, body axes).
    fn assist(&mut self) -> (DVec3, DVec3) {
        let (w, z) = (self.options.assist_frequency, self.options.assist_damping);
        difference(self.body.model(), &self.q_ref, &self.body.state().q, &mut self.diff);
        let state = self.body.state_mut();
        state.torques.iter_mut().for_each(|t| *t = 0.0);
        for k in 0..6 {
            let m = self.inertia[k];
            let rate = self.v_ref[k] - state.qd[k];
            state.torques[k] = m * (w * w * self.diff[k] + 2.0 * z * w * rate);
        }
        let t = &state.torques;
        (DVec3::new(t[3], t[4], t[5]), DVec3::new(t[0], t[1], t[2]))
    }

    /// The root position error (m) and the RMS joint-angle error (rad) against `q_ref`.
    fn errors(&mut self) -> (f64, f64) {
        let model = self.body.model();
        difference(model, &self.q_ref, &self.body.state().q, &mut self.diff);
        let root = DVec3::new(self.diff[3], self.diff[4], self.diff[5]).length();
        let (mut sum, mut count) = (0.0, 0);
        for (i, b) in model.bodies().iter().enumerate() {
            let v = model.starts(i).1;
            let e = match b.joint {
                Joint::Revolute { .. } => self.diff[v] * self.diff[v],
                Joint::Ball => self.diff[v..v + 3].iter().map(|x| x * x).sum(),
                _ => continue,
            };
            sum += e;
            count += 1;
        }
        (root, (sum / count.max(1) as f64).sqrt())
    }

    /// Put back the ragdoll's state and the frame count saved from this tracker (a scene's
    /// undo, `kinema.Scene`); the reference goes back to that frame.
    pub fn restore(&mut self, state: &State, frame: usize) {
        self.body.state.clone_from(state);
        self.frame = frame;
        self.reference(frame);
    }

    /// The clip's frame rate (Hz): a frame lasts its inverse.
    pub fn frame_rate(&self) -> f64 {
        self.motion.frame_rate
    }

    /// The simulated ragdoll.
    pub fn body(&self) -> &ArticulatedBody {
        &self.body
    }

    /// The ragdoll, mutable (to push it, change settings).
    pub fn body_mut(&mut self) -> &mut ArticulatedBody {
        &mut self.body
    }

    /// The reference coordinates `q̄` of the current frame.
    pub fn reference_q(&self) -> &[f64] {
        &self.q_ref
    }

    /// The clip frame the ragdoll is at: the start frame plus the frames tracked.
    pub fn frame(&self) -> usize {
        self.frame
    }

    /// The loop of the clip: `(a, b)`, frames `a..b` repeat after frame `b − 1`.
    pub fn loop_span(&self) -> (usize, usize) {
        self.loop_span
    }
}

/// The twist about y of `q` (swing–twist decomposition): its angle (rad) and rotation.
fn twist_about_y(q: DQuat) -> (f64, DQuat) {
    let angle = 2.0 * q.y.atan2(q.w);
    (angle, DQuat::from_rotation_y(angle))
}
