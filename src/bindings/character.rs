//! `kinema.character`: a compiled articulated model (built body by body) and articulated
//! body (a model with its state and solver), ragdolls from ASF skeletons.

use super::args::Int;
use super::array::{compute, zeroed};
use super::error::detached;
use super::mocap::{PyBvhSkeleton, PySkeleton};
use super::pickle::{reduce, Reduced};
use super::view::view;
use super::walker::walker_class;
use crate::character::{
    link_boxes, ragdoll, ragdoll_bvh, ArticulatedBody as Core, Body, Capsule, Collider, Gait,
    Integrator, Joint, Limits, Model, Pose, RagdollOptions, Servo, ServoMode, Settings, State,
    Tree, Walker as WalkerCore,
};
use crate::error::Error;
use crate::snapshot::Snapshot;
use glam::{DMat3, DQuat, DVec3};
use numpy::PyArrayDyn;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// An articulated model being built; see `kinema.character.Model`.
#[pyclass(module = "kinema._kinema", name = "ArticulatedModel")]
pub struct ArticulatedModel {
    model: Model,
}

fn quat(q: [f64; 4]) -> PyResult<DQuat> {
    let q = DQuat::from_xyzw(q[1], q[2], q[3], q[0]);
    if !(q.is_finite() && q.length() > 1e-12) {
        return Err(Error::invalid("limit_frame", "must be a finite non-zero quaternion").into());
    }
    Ok(q.normalize())
}

#[pymethods]
impl ArticulatedModel {
    /// An empty model with default settings.
    #[new]
    fn new() -> Self {
        ArticulatedModel { model: Model::new(Settings::default()) }
    }

    /// Append a body; returns its index. `joint` is "revolute", "ball", "free", "planar" or
    /// "fixed";
    /// `inertia` the 3x3 inertia about the centre of mass (kg m², rows); `shape` a capsule
    /// `(a, b, radius)` or None; `limits` up to three `(lower, upper)` (rad) or None.
    #[allow(clippy::too_many_arguments)]
    fn add_body(
        &mut self,
        name: String,
        parent: Option<Int>,
        joint: &str,
        axis: [f64; 3],
        offset: [f64; 3],
        mass: f64,
        com: [f64; 3],
        inertia: [[f64; 3]; 3],
        shape: Option<([f64; 3], [f64; 3], f64)>,
        limits: Option<Vec<(f64, f64)>>,
        limit_frame: [f64; 4],
        damping: f64,
    ) -> PyResult<usize> {
        let joint = match joint {
            "revolute" => Joint::Revolute { axis: DVec3::from_array(axis) },
            "ball" => Joint::Ball,
            "free" => Joint::Free,
            "planar" => Joint::Planar,
            "fixed" => Joint::Fixed,
            _ => {
                return Err(Error::invalid(
                    "joint",
                    "expected 'revolute', 'ball', 'free', 'planar' or 'fixed'",
                )
                .into())
            }
        };
        let limits = match limits {
            None => None,
            Some(l) if (1..=3).contains(&l.len()) => {
                let mut ranges = [(0.0, 0.0); 3];
                ranges[..l.len()].copy_from_slice(&l);
                Some(Limits { ranges, frame: quat(limit_frame)? })
            }
            Some(_) => {
                return Err(Error::invalid("limits", "expected 1 to 3 (lower, upper) pairs").into())
            }
        };
        let body = Body {
            name,
            parent: parent.map(|p| p.count("parent")).transpose()?,
            joint,
            offset: DVec3::from_array(offset),
            mass,
            com: DVec3::from_array(com),
            inertia: DMat3::from_cols_array_2d(&inertia).transpose(),
            shape: shape.map(|(a, b, radius)| Capsule {
                a: DVec3::from_array(a),
                b: DVec3::from_array(b),
                radius,
            }),
            limits,
            damping,
            servo: None,
        };
        Ok(self.model.add_body(body)?)
    }

    /// Number of bodies.
    fn __len__(&self) -> usize {
        self.model.bodies().len()
    }
}

/// A capsule as Python sees it: its axis's ends (m, body frame) and radius (m).
pub(super) type CapsuleTuple = ([f64; 3], [f64; 3], f64);

/// A collider as Python sees it: its kind, the shape's parameters, its friction and velocity.
type ColliderTuple = (&'static str, Vec<f64>, Option<f64>, [f64; 3]);

/// Each body's capsule of `model`, or None.
pub(super) fn capsules(model: &Model) -> Vec<Option<CapsuleTuple>> {
    let shape = |b: &Body| b.shape.map(|c| (c.a.to_array(), c.b.to_array(), c.radius));
    model.bodies().iter().map(shape).collect()
}

/// The colliders of `model` where they are at `time` (s).
fn colliders(model: &Model, time: f64) -> Vec<ColliderTuple> {
    let each = |c: &Collider| {
        let (kind, p) = super::geometry::params(&c.at(time));
        (kind, p, c.friction, c.velocity.to_array())
    };
    model.colliders().iter().map(each).collect()
}

/// The world positions of `tree`'s body frames (n, 3) in m, as a new array.
pub(super) fn positions<'py>(
    py: Python<'py>,
    tree: &Tree,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let p = tree.positions();
    compute::<3>(py, p.len(), &[3], |out| {
        let out = zeroed(out);
        out.iter_mut().zip(p).for_each(|(o, v)| *o = v.to_array());
        Ok(())
    })
}

/// The world orientations of `tree`'s body frames (n, 4) as (w, x, y, z), as a new array.
pub(super) fn orientations<'py>(
    py: Python<'py>,
    tree: &Tree,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let r = tree.orientations();
    compute::<4>(py, r.len(), &[4], |out| {
        let out = zeroed(out);
        out.iter_mut().zip(r).for_each(|(o, q)| *o = [q.w, q.x, q.y, q.z]);
        Ok(())
    })
}

/// An articulated body; see `kinema.character.ArticulatedBody` for the API.
#[pyclass(module = "kinema._kinema")]
pub struct ArticulatedBody {
    body: Core,
    /// The state and the colliders at the last `_mark` (a scene's undo point).
    saved: Option<(State, Vec<Collider>)>,
}

/// A collider of the shape of kind `kind` with parameters `p` (`super::geometry::shape`) at
/// time `since` (s, the bodies' clock), moving at `velocity` and turning at
/// `angular_velocity` (each checked finite here, so that adding one cannot fail halfway).
pub(super) fn moving_collider(
    (kind, p): (&str, &[f64]),
    friction: Option<f64>,
    velocity: [f64; 3],
    angular_velocity: [f64; 3],
    since: f64,
) -> PyResult<Collider> {
    let (shape, _) = super::geometry::shape(kind, p, 0)?;
    let (velocity, angular_velocity) =
        (DVec3::from_array(velocity), DVec3::from_array(angular_velocity));
    for (name, v) in [("velocity", velocity), ("angular_velocity", angular_velocity)] {
        if !v.is_finite() {
            return Err(Error::invalid(name, "must be finite").into());
        }
    }
    Ok(Collider { shape, friction, velocity, angular_velocity, since })
}

#[pymethods]
impl ArticulatedBody {
    /// Pickle support: the body as a snapshot (model and state).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Reduced<'py>> {
        reduce(slf, |s| &s.body, vec![])
    }

    /// The object stored by `__reduce__`.
    #[staticmethod]
    fn _from_snapshot(data: &[u8]) -> PyResult<Self> {
        Ok(Self { body: Core::from_snapshot(data)?, saved: None })
    }

    /// The body of `model` (copied) in its zero pose.
    #[new]
    fn new(model: PyRef<'_, ArticulatedModel>) -> PyResult<Self> {
        if model.model.bodies().is_empty() {
            return Err(Error::invalid("model", "has no bodies").into());
        }
        Ok(ArticulatedBody { body: Core::new(model.model.clone()), saved: None })
    }

    /// The ragdoll of an ASF `skeleton` (see `kinema.character.Ragdoll.from_skeleton`).
    #[staticmethod]
    #[allow(clippy::too_many_arguments)]
    fn ragdoll(
        skeleton: PyRef<'_, PySkeleton>,
        density: f64,
        scale: Option<f64>,
        radius_ratio: f64,
        min_radius: f64,
        damping: f64,
        clearance: f64,
    ) -> PyResult<Self> {
        let sk = &skeleton.skeleton;
        let scale = scale.unwrap_or_else(|| sk.metres_per_unit());
        let options =
            RagdollOptions { density, scale, radius_ratio, min_radius, damping, clearance };
        let body = Core::new(ragdoll(sk, &options, Settings::default())?);
        Ok(ArticulatedBody { body, saved: None })
    }

    /// The ragdoll of a BVH `skeleton` (`scale`: metres per file unit, required since BVH
    /// files do not say; see `kinema.character.Ragdoll.from_skeleton`).
    #[staticmethod]
    #[allow(clippy::too_many_arguments)]
    fn ragdoll_bvh(
        skeleton: PyRef<'_, PyBvhSkeleton>,
        density: f64,
        scale: f64,
        radius_ratio: f64,
        min_radius: f64,
        damping: f64,
        clearance: f64,
    ) -> PyResult<Self> {
        let options =
            RagdollOptions { density, scale, radius_ratio, min_radius, damping, clearance };
        let body = Core::new(ragdoll_bvh(&skeleton.skeleton, &options, Settings::default())?);
        Ok(ArticulatedBody { body, saved: None })
    }

    /// Change the settings (every argument as in `kinema.character.ArticulatedBody`).
    #[allow(clippy::too_many_arguments)]
    fn configure(
        &mut self,
        gravity: [f64; 3],
        integrator: &str,
        servo_mode: &str,
        ground: bool,
        self_collision: bool,
        contact_frequency: f64,
        contact_damping: f64,
        friction: f64,
        slip_speed: f64,
        limit_frequency: f64,
        limit_damping: f64,
    ) -> PyResult<()> {
        let integrator = match integrator {
            "symplectic" => Integrator::SymplecticEuler,
            "rk4" => Integrator::Rk4,
            _ => return Err(Error::invalid("integrator", "expected 'symplectic' or 'rk4'").into()),
        };
        let servo_mode = match servo_mode {
            "stable" => ServoMode::Stable,
            "explicit" => ServoMode::Explicit,
            _ => return Err(Error::invalid("servo_mode", "expected 'stable' or 'explicit'").into()),
        };
        let settings = Settings {
            gravity: DVec3::from_array(gravity),
            integrator,
            servo_mode,
            ground,
            self_collision,
            contact_frequency,
            contact_damping,
            friction,
            slip_speed,
            limit_frequency,
            limit_damping,
        };
        let old = std::mem::replace(&mut self.body.model_mut().settings, settings);
        if let Err(e) = self.body.model().check_settings() {
            self.body.model_mut().settings = old;
            return Err(e.into());
        }
        Ok(())
    }

    /// Add a collider of kind `kind` with the shape's parameters `p`
    /// (`super::geometry::shape`), Coulomb `friction` (None: the settings'), `velocity`
    /// (m/s, world) and `angular_velocity` (rad/s, world, about its centre; it is at `p`
    /// now); returns its index.
    fn add_collider(
        &mut self,
        kind: &str,
        p: Vec<f64>,
        friction: Option<f64>,
        velocity: [f64; 3],
        angular_velocity: [f64; 3],
    ) -> PyResult<usize> {
        let since = self.body.state().time();
        let c = moving_collider((kind, &p), friction, velocity, angular_velocity, since)?;
        let index = self.body.model_mut().add_collider(c.shape, friction)?;
        self.body.model_mut().set_collider(index, c)?;
        Ok(index)
    }

    /// Move collider `index` to the shape `p` of kind `kind` (same kind and size) at the
    /// body's current time, translating at `velocity` (m/s, world) and turning at
    /// `angular_velocity` (rad/s, world, about its centre) from then on.
    fn set_collider(
        &mut self,
        index: Int,
        kind: &str,
        p: Vec<f64>,
        friction: Option<f64>,
        velocity: [f64; 3],
        angular_velocity: [f64; 3],
    ) -> PyResult<()> {
        let index = index.count("index")?;
        let since = self.body.state().time();
        let c = moving_collider((kind, &p), friction, velocity, angular_velocity, since)?;
        Ok(self.body.model_mut().set_collider(index, c)?)
    }

    /// Set (or with `kp` None remove) the PD servo of body `body`'s joint.
    fn set_servo(&mut self, body: Int, kp: Option<f64>, kd: f64, max_torque: f64) -> PyResult<()> {
        let servo = kp.map(|kp| Servo { kp, kd, max_torque });
        Ok(self.body.model_mut().set_servo(body.count("body")?, servo)?)
    }

    /// Advance `steps` steps of `dt` seconds (GIL released).
    fn step(&mut self, py: Python<'_>, dt: f64, steps: Int) -> PyResult<()> {
        let steps = steps.count("steps")?;
        let body = &mut self.body;
        detached(py, || body.step(dt, steps))
    }

    /// Remember the state (a scene's undo point): coordinates, rates, time, targets, torques
    /// and pushes; and the colliders (their poses and count).
    fn _mark(&mut self) {
        let body = &self.body;
        match &mut self.saved {
            Some((state, colliders)) => {
                state.clone_from(body.state());
                colliders.clear();
                colliders.extend_from_slice(body.model().colliders());
            }
            None => self.saved = Some((body.state().clone(), body.model().colliders().to_vec())),
        }
    }

    /// Put the state and the colliders (a scene's, moved and added during the frame) back as
    /// they were at the last [`ArticulatedBody::_mark`], in place (views of `q` and `qd` stay
    /// valid).
    fn _rollback(&mut self) {
        if let Some((state, colliders)) = &self.saved {
            self.body.state_mut().clone_from(state);
            self.body.model_mut().restore_colliders(colliders);
        }
    }

    /// Read-only view of the joint coordinates (nq,), updated in place by `step`.
    #[getter]
    fn q<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let n = slf.borrow().body.model().nq();
        view(slf, &[n], |r| r.body.state().q())
    }

    /// Read-only view of the joint rates (nv,), updated in place by `step`.
    #[getter]
    fn qd<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let n = slf.borrow().body.model().nv();
        view(slf, &[n], |r| r.body.state().qd())
    }

    /// Read-only view of the servo targets (nq,).
    #[getter]
    fn targets<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let n = slf.borrow().body.model().nq();
        view(slf, &[n], |r| r.body.state().targets())
    }

    /// Set the joint coordinates (nq,).
    fn set_q(&mut self, q: Vec<f64>) -> PyResult<()> {
        let (model, state) = self.body.parts_mut();
        Ok(state.set_q(model, &q)?)
    }

    /// Set the joint rates (nv,).
    fn set_qd(&mut self, qd: Vec<f64>) -> PyResult<()> {
        Ok(self.body.state_mut().set_qd(&qd)?)
    }

    /// Set the servo targets (nq,).
    fn set_targets(&mut self, targets: Vec<f64>) -> PyResult<()> {
        let (model, state) = self.body.parts_mut();
        Ok(state.set_targets(model, &targets)?)
    }

    /// Set the applied joint torques (nv,).
    fn set_torques(&mut self, torques: Vec<f64>) -> PyResult<()> {
        Ok(self.body.state_mut().set_torques(&torques)?)
    }

    /// Push body `body` with `force` (N, world) at its centre of mass for `duration` s.
    fn push(&mut self, body: Int, force: [f64; 3], duration: f64) -> PyResult<()> {
        let body = body.count("body")?;
        let (model, state) = self.body.parts_mut();
        Ok(state.push(model, body, DVec3::from_array(force), duration)?)
    }

    /// Centre of mass (m, world).
    #[getter]
    fn com(&mut self) -> [f64; 3] {
        self.body.com().to_array()
    }

    /// Kinetic and gravitational potential energy (J).
    fn energy(&mut self) -> (f64, f64) {
        self.body.energy()
    }

    /// Simulated time (s).
    #[getter]
    fn time(&self) -> f64 {
        self.body.state().time()
    }

    /// Number of position coordinates and of degrees of freedom.
    fn sizes(&self) -> (usize, usize) {
        (self.body.model().nq(), self.body.model().nv())
    }

    /// Number of bodies.
    fn __len__(&self) -> usize {
        self.body.model().bodies().len()
    }

    /// Body names, in order.
    fn names(&self) -> Vec<String> {
        self.body.model().bodies().iter().map(|b| b.name.clone()).collect()
    }

    /// Each body's capsule `(a, b, radius)` (m, body frame), or None.
    fn capsules(&self) -> Vec<Option<CapsuleTuple>> {
        capsules(self.body.model())
    }

    /// The colliders as `(kind, parameters, friction, velocity)` (`super::geometry::params`:
    /// the shape where it is at the body's time, m, world; m/s), in the order added.
    fn colliders(&self) -> Vec<ColliderTuple> {
        colliders(self.body.model(), self.body.state().time())
    }

    /// Body masses (kg), in order.
    fn masses(&self) -> Vec<f64> {
        self.body.model().bodies().iter().map(|b| b.mass).collect()
    }

    /// World positions of the body frames (n, 3) in m (a new array).
    fn positions<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        positions(py, self.body.kinematics())
    }

    /// World orientations of the body frames (n, 4) as (w, x, y, z) (a new array).
    fn orientations<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        orientations(py, self.body.kinematics())
    }

    /// The settings as a dict.
    fn settings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = self.body.model().settings;
        let d = PyDict::new(py);
        d.set_item("gravity", s.gravity.to_array())?;
        d.set_item(
            "integrator",
            if s.integrator == Integrator::Rk4 { "rk4" } else { "symplectic" },
        )?;
        d.set_item(
            "servo_mode",
            if s.servo_mode == ServoMode::Stable { "stable" } else { "explicit" },
        )?;
        d.set_item("ground", s.ground)?;
        d.set_item("self_collision", s.self_collision)?;
        d.set_item("contact_frequency", s.contact_frequency)?;
        d.set_item("contact_damping", s.contact_damping)?;
        d.set_item("friction", s.friction)?;
        d.set_item("slip_speed", s.slip_speed)?;
        d.set_item("limit_frequency", s.limit_frequency)?;
        d.set_item("limit_damping", s.limit_damping)?;
        Ok(d)
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<ArticulatedModel>()?;
    m.add_class::<Walker>()?;
    m.add_class::<ArticulatedBody>()
}

/// A gait from its `lift` and `strike` poses and `[duration, kp, kd, torso_kp, torso_kd,
/// max_torque]`.
pub(super) fn gait(lift: [f64; 8], strike: [f64; 8], control: [f64; 6]) -> Gait {
    let [duration, kp, kd, torso_kp, torso_kd, max_torque] = control;
    Gait {
        lift: pose(lift),
        strike: pose(strike),
        duration,
        kp,
        kd,
        torso_kp,
        torso_kd,
        max_torque,
    }
}

/// The settings of a walker: the default settings with the ground's `contact_frequency`
/// (rad/s) and `friction`, and gravity turned about z by `slope` (rad, positive climbs +x).
pub(super) fn walker_settings(
    contact_frequency: f64,
    friction: f64,
    slope: f64,
) -> PyResult<Settings> {
    if !(slope.is_finite() && slope.abs() < std::f64::consts::FRAC_PI_2) {
        return Err(Error::invalid("slope", "must be finite and within ±π/2").into());
    }
    let g = Settings::default().gravity.length();
    let gravity = DVec3::new(-g * slope.sin(), -g * slope.cos(), 0.0);
    let settings = Settings { contact_frequency, friction, gravity, ..Settings::default() };
    settings_check(&settings)?;
    Ok(settings)
}

/// A pose from its eight values `[cd, cv, torso, swing_hip, swing_knee, swing_ankle,
/// stance_knee, stance_ankle]`.
fn pose(v: [f64; 8]) -> Pose {
    let [cd, cv, torso, swing_hip, swing_knee, swing_ankle, stance_knee, stance_ankle] = v;
    Pose { cd, cv, torso, swing_hip, swing_knee, swing_ankle, stance_knee, stance_ankle }
}

/// A gait as `(lift, strike, [duration, kp, kd, torso_kp, torso_kd, max_torque])`.
pub(super) fn gait_values(g: &Gait) -> ([f64; 8], [f64; 8], [f64; 6]) {
    let control = [g.duration, g.kp, g.kd, g.torso_kp, g.torso_kd, g.max_torque];
    (pose_values(&g.lift), pose_values(&g.strike), control)
}

fn pose_values(p: &Pose) -> [f64; 8] {
    [p.cd, p.cv, p.torso, p.swing_hip, p.swing_knee, p.swing_ankle, p.stance_knee, p.stance_ankle]
}

walker_class! {
    /// The planar SIMBICON walker; see `kinema.character.Biped` for the API.
    Walker(WalkerCore, link_boxes) {
        /// The walker at `speed` (m/s) with the gait's `lift` and `strike` poses (8 values
        /// each, see `pose`), `[duration, kp, kd, torso_kp, torso_kd, max_torque]`, the ground
        /// contact's `contact_frequency` (rad/s) and `friction`, on a `slope` (rad, positive
        /// climbs; the ground stays y = 0 and gravity turns by it).
        #[new]
        fn new(
            lift: [f64; 8],
            strike: [f64; 8],
            control: [f64; 6],
            speed: f64,
            contact_frequency: f64,
            friction: f64,
            slope: f64,
        ) -> PyResult<Self> {
            let (gait, settings) =
                (gait(lift, strike, control), walker_settings(contact_frequency, friction, slope)?);
            Ok(Walker { walker: WalkerCore::new(settings, gait, speed)?, saved: None })
        }
    }
}

fn settings_check(settings: &Settings) -> PyResult<()> {
    Ok(Model::new(*settings).check_settings()?)
}
