//! The articulated model: a kinematic tree of rigid bodies joined by revolute, ball, free
//! and fixed joints, with masses, capsule shapes, joint limits, damping, PD servos and the
//! settings of ground contact and integration. Built body by body ([`Model::add_body`],
//! parents first), with colliders ([`Model::add_collider`], static or moving at constant
//! velocities, [`Model::set_collider`]); read-only during a step.

use super::spatial::{rigid_inertia, SMat, Transform};
use crate::error::{Error, Result};
use crate::geometry::Shape;
use glam::{DMat3, DQuat, DVec3};

/// The joint between a body and its parent (or the world).
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub enum Joint {
    /// No motion: the body is welded to its parent (0 coordinates).
    Fixed,
    /// A hinge about `axis` (unit, body and parent frames coincide at angle 0): one angle
    /// (rad) and its rate (rad/s).
    Revolute {
        /// Hinge axis (unit vector, parent = body axes at angle 0).
        axis: DVec3,
    },
    /// A ball joint: the body's orientation relative to its parent as a unit quaternion
    /// `(w, x, y, z)` (4 coordinates) and its angular velocity in body axes (3 rates, rad/s).
    Ball,
    /// A free joint (6 DOF): the body's position (m, parent axes) and orientation `(w, x, y,
    /// z)` relative to the parent frame (7 coordinates), and its rates `[ω; v]`: the angular
    /// velocity in body axes (rad/s) and the velocity of the body frame's origin in the
    /// parent's axes (m/s) (6 rates).
    Free,
    /// A planar joint: translation in the parent's x–y plane and rotation about its z axis
    /// (3 coordinates `[x, y, θ]`: m, m, rad; 3 rates `[vx, vy, ω]`: m/s in parent axes,
    /// rad/s). The root of a planar character (Featherstone 2008, Table 4.1, "planar").
    Planar,
}

impl Joint {
    /// Number of position coordinates.
    pub fn nq(&self) -> usize {
        match self {
            Joint::Fixed => 0,
            Joint::Revolute { .. } => 1,
            Joint::Ball => 4,
            Joint::Free => 7,
            Joint::Planar => 3,
        }
    }

    /// Number of velocity coordinates (degrees of freedom).
    pub fn nv(&self) -> usize {
        match self {
            Joint::Fixed => 0,
            Joint::Revolute { .. } => 1,
            Joint::Ball => 3,
            Joint::Free => 6,
            Joint::Planar => 3,
        }
    }
}

/// A capsule in body coordinates: the points within `radius` (m) of the segment `a`–`b` (m).
/// `a == b` is a sphere.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Capsule {
    /// One end of the axis segment (m, body frame).
    pub a: DVec3,
    /// The other end (m, body frame).
    pub b: DVec3,
    /// Radius (m).
    pub radius: f64,
}

impl Capsule {
    /// Mass (kg), centre of mass (m, body frame) and inertia about it (kg m², body axes) of
    /// the solid capsule of `density` (kg/m³): a cylinder of length `h` plus two hemispheres,
    /// `I_axis = m_c r²/2 + m_s 2r²/5`, `I_⊥ = m_c (r²/4 + h²/12) + m_s (2r²/5 + h²/4 +
    /// 3hr/8)` with `m_c = ρπr²h`, `m_s = ρ 4/3 π r³`.
    pub fn mass_properties(&self, density: f64) -> (f64, DVec3, DMat3) {
        let (r, axis) = (self.radius, self.b - self.a);
        let h = axis.length();
        let mc = density * std::f64::consts::PI * r * r * h;
        let ms = density * 4.0 / 3.0 * std::f64::consts::PI * r * r * r;
        let along = mc * r * r / 2.0 + ms * 2.0 * r * r / 5.0;
        let across = mc * (r * r / 4.0 + h * h / 12.0)
            + ms * (2.0 * r * r / 5.0 + h * h / 4.0 + 3.0 * h * r / 8.0);
        let turn =
            if h > 0.0 { DQuat::from_rotation_arc(DVec3::Z, axis / h) } else { DQuat::IDENTITY };
        let m = DMat3::from_quat(turn);
        let local = DMat3::from_diagonal(DVec3::new(across, across, along));
        (mc + ms, 0.5 * (self.a + self.b), m * local * m.transpose())
    }
}

/// Joint limits: for a revolute joint one `(lower, upper)` angle range (rad); for a ball
/// joint three ranges for the components of the rotation vector `log(q)` (rad) about the
/// axes of `frame` (its columns in body axes; ASF limits on `rx ry rz` read this way).
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// `(lower, upper)` per axis (rad); a revolute joint uses the first.
    pub ranges: [(f64, f64); 3],
    /// Axes the ranges refer to (ball joints), as a rotation from limit axes to body axes.
    pub frame: DQuat,
}

/// A PD servo on every degree of freedom of a joint: `τ = k_p (q̄ ⊖ q) − k_d q̇`, clamped to
/// `±max_torque` (N m; infinite for no limit).
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Servo {
    /// Proportional gain (N m/rad).
    pub kp: f64,
    /// Derivative gain (N m s/rad).
    pub kd: f64,
    /// Torque limit per degree of freedom (N m).
    pub max_torque: f64,
}

/// One body of the tree and the joint to its parent.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, PartialEq)]
pub struct Body {
    /// Name (for users; bodies are addressed by index).
    pub name: String,
    /// Parent body index (`None`: the world).
    pub parent: Option<usize>,
    /// The joint to the parent.
    pub joint: Joint,
    /// The joint's position in the parent's frame (m; world frame for a root). The body's
    /// frame has its origin at the joint and the parent's axes at the joint's zero position.
    pub offset: DVec3,
    /// Mass (kg, > 0).
    pub mass: f64,
    /// Centre of mass (m, body frame).
    pub com: DVec3,
    /// Rotational inertia about the centre of mass (kg m², body axes; symmetric positive
    /// definite).
    pub inertia: DMat3,
    /// Collision shape against the ground plane, if any.
    pub shape: Option<Capsule>,
    /// Joint limits, if any (revolute and ball joints).
    pub limits: Option<Limits>,
    /// Viscous joint damping (N m s/rad) on every degree of freedom of a revolute or ball
    /// joint (not on free or planar joints).
    pub damping: f64,
    /// PD servo on the joint, if any (revolute and ball joints).
    pub servo: Option<Servo>,
}

/// A collider of the bodies' capsules: one of the shared shapes ([`crate::geometry::Shape`]:
/// a plane of any normal, a sphere, a capsule or an oriented box), touched by the capsules
/// through the ground's penalty spring-dampers and regularised Coulomb friction along its
/// closest-point normal (`super::forces`), static or kinematic: it translates at `velocity`
/// and turns at `angular_velocity` about its centre, and the contacts' damping and friction
/// act on the capsule's velocity relative to its surface's.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Collider {
    /// The shape (m, world) at time `since`, checked by [`Shape::checked`].
    pub shape: Shape,
    /// Its Coulomb friction coefficient μ (`None`: [`Settings::friction`]).
    pub friction: Option<f64>,
    /// The velocity (m/s, world) the shape's centre ([`Shape::centre`]) translates at: zero
    /// for a static collider.
    pub velocity: DVec3,
    /// The angular velocity (rad/s, world) the shape turns at about its centre.
    pub angular_velocity: DVec3,
    /// The time (s, the bodies' clock, [`super::State::time`]) at which it is at `shape`.
    pub since: f64,
}

impl Collider {
    /// The shape at time `t` (s): `shape` turned about its centre by
    /// `exp(angular_velocity (t − since))`, then translated by `velocity (t − since)`.
    pub fn at(&self, t: f64) -> Shape {
        let h = t - self.since;
        let shape = if self.angular_velocity == DVec3::ZERO {
            self.shape
        } else {
            self.shape.turned(DQuat::from_scaled_axis(self.angular_velocity * h))
        };
        if self.velocity == DVec3::ZERO {
            shape
        } else {
            shape.translated(self.velocity * h)
        }
    }

    /// The velocity (m/s, world) of the collider's surface at the world point `p` of the
    /// shape `at` gives at that time: `velocity + angular_velocity × (p − centre)`.
    pub fn surface_velocity(&self, at: &Shape, p: DVec3) -> DVec3 {
        self.velocity + self.angular_velocity.cross(p - at.centre())
    }
}

/// Time integrator of [`super::Solver::step`].
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Integrator {
    /// Semi-implicit (symplectic) Euler: `q̇ += dt q̈(q, q̇)`, then `q ← q ⊕ dt q̇` (order 1,
    /// symplectic for conservative forces).
    SymplecticEuler,
    /// Classical Runge–Kutta 4 on `(q, q̇)`, positions moved by `⊕` (quaternions by the
    /// exponential map) from the step's start with the stages' weighted velocity (order 4).
    Rk4,
}

/// How the PD servos are applied.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ServoMode {
    /// `τ = k_p (q̄ ⊖ q) − k_d q̇` from the current state (stable only for small gains).
    Explicit,
    /// Stable PD (Tan, Liu & Turk 2011, eq. 5–8): the next step's position and velocity,
    /// `τ = −k_p (q + dt q̇ ⊖ q̄) − k_d (q̇ + dt q̈)`, with `q̈` solved together with `τ`.
    Stable,
}

/// Settings read by every step.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Gravity (m/s²), default `(0, −9.81, 0)`.
    pub gravity: DVec3,
    /// Time integrator (default symplectic Euler).
    pub integrator: Integrator,
    /// Servo mode (default stable PD).
    pub servo_mode: ServoMode,
    /// Whether the capsules collide with the ground plane `y = 0` (default true).
    pub ground: bool,
    /// Whether the capsules of [`Model::collision_pairs`] collide with each other (default
    /// false): penalty spring-dampers of the ground's frequency and damping ratio on the
    /// pair's reduced mass, with the ground's friction (`super::forces`).
    pub self_collision: bool,
    /// Natural frequency (rad/s) of a body resting on a ground contact: the penalty stiffness
    /// of a contact point is `m ω²` for a body of mass `m` (resting penetration `g/ω²`).
    pub contact_frequency: f64,
    /// Damping ratio ζ of the contact: damping `2 ζ m ω`.
    pub contact_damping: f64,
    /// Coulomb friction coefficient μ of the ground.
    pub friction: f64,
    /// Slip speed (m/s) below which friction is viscous (regularised Coulomb).
    pub slip_speed: f64,
    /// Natural frequency (rad/s) of a joint pressed against its limit: stiffness `m ω²` with
    /// `m = 1 / (M⁻¹)_jj` the effective inertia of the degree of freedom at the current pose.
    pub limit_frequency: f64,
    /// Damping ratio ζ of the limit springs: damping `2 ζ m ω`.
    pub limit_damping: f64,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            gravity: DVec3::new(0.0, -9.81, 0.0),
            integrator: Integrator::SymplecticEuler,
            servo_mode: ServoMode::Stable,
            ground: true,
            self_collision: false,
            contact_frequency: 60.0,
            contact_damping: 1.0,
            friction: 1.0,
            slip_speed: 0.05,
            limit_frequency: 40.0,
            limit_damping: 1.0,
        }
    }
}

/// The articulated model: bodies in parent-first order, the settings and the layout of the
/// coordinates (`q`: `nq` numbers, `q̇`: `nv` numbers, each body's joint in order).
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, PartialEq, Default)]
pub struct Model {
    pub(super) bodies: Vec<Body>,
    /// Settings read by every step (free to change between steps).
    pub settings: Settings,
    /// Start of each body's joint in `q`.
    pub(super) q_start: Vec<usize>,
    /// Start of each body's joint in `q̇`.
    pub(super) v_start: Vec<usize>,
    /// Spatial inertia of each body at its frame's origin.
    pub(super) inertias: Vec<SMat>,
    /// The fixed part of each body's transform from its parent, `xlt(offset)`.
    pub(super) tree: Vec<Transform>,
    /// The pairs `(i, j)`, `i < j`, of bodies whose capsules may collide with each other.
    pub(super) collision_pairs: Vec<(usize, usize)>,
    /// The colliders of the capsules, in the order added.
    pub(super) colliders: Vec<Collider>,
}

impl Model {
    /// An empty model with `settings`.
    pub fn new(settings: Settings) -> Self {
        Model { settings, ..Model::default() }
    }

    /// Append `body` (its parent must already be in the model) and return its index.
    ///
    /// # Errors
    /// A parent not yet added (`parent`), a non-finite or non-positive mass (`mass`), an
    /// inertia that is not symmetric positive definite or non-finite values (`inertia`,
    /// `com`, `offset`), a zero hinge axis (`axis`), limits on a joint without angles or
    /// with lower > upper (`limits`), a negative damping (`damping`), a shape of negative
    /// radius (`shape`), a servo on a free, planar or fixed joint or with negative gains (`servo`).
    pub fn add_body(&mut self, mut body: Body) -> Result<usize> {
        check_body(&body, self.bodies.len())?;
        if let Joint::Revolute { axis } = &mut body.joint {
            *axis = axis.normalize();
        }
        self.q_start.push(self.nq());
        self.v_start.push(self.nv());
        self.inertias.push(rigid_inertia(body.mass, body.com, body.inertia));
        self.tree.push(Transform { rot: DMat3::IDENTITY, pos: body.offset });
        self.bodies.push(body);
        let new = self.bodies.len() - 1;
        for j in 0..new {
            if self.may_collide(j, new) {
                self.collision_pairs.push((j, new));
            }
        }
        Ok(new)
    }

    /// The pairs `(i, j)`, `i < j`, of bodies with capsules that collide with each other when
    /// [`Settings::self_collision`] is on: all pairs but a body and its parent, two children
    /// of one parent (they meet at the joint), and capsules that overlap in the zero pose
    /// (where the skeleton puts them together, e.g. hips and spine at the pelvis).
    pub fn collision_pairs(&self) -> &[(usize, usize)] {
        &self.collision_pairs
    }

    /// Whether bodies `i < j` form a pair of [`Model::collision_pairs`].
    fn may_collide(&self, i: usize, j: usize) -> bool {
        let (a, b) = (&self.bodies[i], &self.bodies[j]);
        let (Some(ca), Some(cb)) = (a.shape, b.shape) else { return false };
        if b.parent == Some(i) || (a.parent.is_some() && a.parent == b.parent) {
            return false;
        }
        let (oa, ob) = (self.zero_pose_origin(i), self.zero_pose_origin(j));
        let (pa, pb) = crate::geometry::segment::closest_points_of_segments(
            oa + ca.a,
            oa + ca.b,
            ob + cb.a,
            ob + cb.b,
        );
        pa.distance(pb) >= ca.radius + cb.radius
    }

    /// Where body `i`'s frame is in the zero pose (m, world): the sum of the offsets from
    /// the root (every joint's zero keeps the parent's axes).
    fn zero_pose_origin(&self, mut i: usize) -> DVec3 {
        let mut origin = self.bodies[i].offset;
        while let Some(p) = self.bodies[i].parent {
            origin += self.bodies[p].offset;
            i = p;
        }
        origin
    }

    /// Add a static collider touched by every body's capsule ([`Collider`]) and return its
    /// index. A model without colliders pays nothing for them.
    ///
    /// # Errors
    /// A shape that [`Shape::checked`] refuses (its argument named: `point`, `normal`,
    /// `center`, `radius`, `a`, `b`, `half_extents`, `orientation`); a negative or non-finite
    /// `friction`.
    pub fn add_collider(&mut self, shape: Shape, friction: Option<f64>) -> Result<usize> {
        let collider = Collider {
            shape: shape.checked()?,
            friction,
            velocity: DVec3::ZERO,
            angular_velocity: DVec3::ZERO,
            since: 0.0,
        };
        check_collider(&collider)?;
        self.colliders.push(collider);
        Ok(self.colliders.len() - 1)
    }

    /// Move collider `index` (a kinematic collider): `collider` replaces it, its shape of the
    /// same kind and size (radius, half extents, a capsule's length to 1e-9 relative; only
    /// the pose changes), at `collider.shape` at time `collider.since` and translating at
    /// `collider.velocity` and turning at `collider.angular_velocity` from then on. Set it between steps, e.g. every frame with the
    /// pose at the body's time and the velocity to the next frame's pose.
    ///
    /// # Errors
    /// `index` beyond the colliders; a shape of another kind or size (`shape`), or one that
    /// [`Shape::checked`] refuses; `friction` as [`Model::add_collider`]; a non-finite
    /// `velocity` or `since`.
    pub fn set_collider(&mut self, index: usize, collider: Collider) -> Result<()> {
        let Some(old) = self.colliders.get(index) else {
            return Err(Error::invalid("index", "no collider of that index"));
        };
        let collider = Collider { shape: collider.shape.checked()?, ..collider };
        check_collider(&collider)?;
        if !same_size(&old.shape, &collider.shape) {
            return Err(Error::invalid("shape", "must be of the collider's kind and size"));
        }
        self.colliders[index] = collider;
        Ok(())
    }

    /// The colliders, in the order added.
    pub fn colliders(&self) -> &[Collider] {
        &self.colliders
    }

    /// Put back colliders saved from this model's [`Model::colliders`] (a scene's undo: the
    /// poses, and the count, of colliders added since), reusing the storage.
    pub fn restore_colliders(&mut self, saved: &[Collider]) {
        self.colliders.truncate(saved.len());
        let kept = self.colliders.len();
        self.colliders.clone_from_slice(&saved[..kept]);
        self.colliders.extend_from_slice(&saved[kept..]);
    }

    /// The bodies, parents first.
    pub fn bodies(&self) -> &[Body] {
        &self.bodies
    }

    /// Number of position coordinates.
    pub fn nq(&self) -> usize {
        self.bodies.iter().map(|b| b.joint.nq()).sum()
    }

    /// Number of degrees of freedom.
    pub fn nv(&self) -> usize {
        self.bodies.iter().map(|b| b.joint.nv()).sum()
    }

    /// Total mass (kg).
    pub fn mass(&self) -> f64 {
        self.bodies.iter().map(|b| b.mass).sum()
    }

    /// The start of body `i`'s joint in `q` and in `q̇`.
    pub fn starts(&self, i: usize) -> (usize, usize) {
        (self.q_start[i], self.v_start[i])
    }

    /// The coordinates of the zero pose: angles 0, identity quaternions, free joints at the
    /// origin of their parent frame.
    pub fn neutral(&self) -> Vec<f64> {
        let mut q = Vec::with_capacity(self.nq());
        for b in &self.bodies {
            match b.joint {
                Joint::Fixed => {}
                Joint::Revolute { .. } => q.push(0.0),
                Joint::Ball => q.extend([1.0, 0.0, 0.0, 0.0]),
                Joint::Free => q.extend([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]),
                Joint::Planar => q.extend([0.0, 0.0, 0.0]),
            }
        }
        q
    }

    /// Set a PD servo on body `body`'s joint (or remove it with `None`).
    ///
    /// # Errors
    /// `body` out of range (`body`); a servo that [`Model::add_body`] would refuse.
    pub fn set_servo(&mut self, body: usize, servo: Option<Servo>) -> Result<()> {
        let Some(b) = self.bodies.get(body) else {
            return Err(Error::invalid("body", "beyond the last body"));
        };
        check_servo(b.joint, servo.as_ref())?;
        self.bodies[body].servo = servo;
        Ok(())
    }

    /// Check the settings (called by every step).
    ///
    /// # Errors
    /// A non-finite gravity or a negative or non-finite contact or limit parameter (named).
    pub fn check_settings(&self) -> Result<()> {
        let s = &self.settings;
        if !s.gravity.is_finite() {
            return Err(Error::invalid("gravity", "must be finite"));
        }
        for (name, v) in [
            ("contact_frequency", s.contact_frequency),
            ("contact_damping", s.contact_damping),
            ("friction", s.friction),
            ("limit_frequency", s.limit_frequency),
            ("limit_damping", s.limit_damping),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::invalid(name, "must be finite and >= 0"));
            }
        }
        if !(s.slip_speed.is_finite() && s.slip_speed > 0.0) {
            return Err(Error::invalid("slip_speed", "must be finite and > 0"));
        }
        Ok(())
    }
}

/// The checks of [`Model::add_body`] for a body that would get index `index`.
fn check_body(body: &Body, index: usize) -> Result<()> {
    if body.parent.is_some_and(|p| p >= index) {
        return Err(Error::invalid("parent", "must be a body added before"));
    }
    if !(body.mass.is_finite() && body.mass > 0.0) {
        return Err(Error::invalid("mass", "must be finite and > 0"));
    }
    if !body.com.is_finite() {
        return Err(Error::invalid("com", "must be finite"));
    }
    if !body.offset.is_finite() {
        return Err(Error::invalid("offset", "must be finite"));
    }
    let i = body.inertia;
    let size = i.to_cols_array().iter().fold(0.0_f64, |a, b| a.max(b.abs()));
    let asymmetry = (i - i.transpose()).to_cols_array().iter().fold(0.0_f64, |a, b| a.max(b.abs()));
    let symmetric = asymmetry <= 1e-12 * size;
    let minors = [i.x_axis.x, i.x_axis.x * i.y_axis.y - i.x_axis.y * i.y_axis.x, i.determinant()];
    if !(i.is_finite() && symmetric && minors.iter().all(|&m| m > 0.0)) {
        return Err(Error::invalid("inertia", "must be finite, symmetric and positive definite"));
    }
    if let Joint::Revolute { axis } = body.joint {
        if !(axis.is_finite() && axis.length() > 1e-12) {
            return Err(Error::invalid("axis", "must be a finite non-zero vector"));
        }
    }
    if let Some(l) = &body.limits {
        let angular = matches!(body.joint, Joint::Revolute { .. } | Joint::Ball);
        let ordered = l.ranges.iter().all(|(lo, hi)| !lo.is_nan() && !hi.is_nan() && lo <= hi);
        if !(angular && ordered && l.frame.is_finite() && l.frame.length() > 1e-12) {
            return Err(Error::invalid(
                "limits",
                "need a revolute or ball joint and lower <= upper",
            ));
        }
    }
    if !(body.damping.is_finite() && body.damping >= 0.0) {
        return Err(Error::invalid("damping", "must be finite and >= 0"));
    }
    if let Some(c) = &body.shape {
        if !(c.a.is_finite() && c.b.is_finite() && c.radius.is_finite() && c.radius >= 0.0) {
            return Err(Error::invalid("shape", "needs finite ends and a radius >= 0"));
        }
    }
    check_servo(body.joint, body.servo.as_ref())
}

/// The checks of [`Model::add_collider`] and [`Model::set_collider`] on a collider whose
/// shape is already checked.
pub(super) fn check_collider(c: &Collider) -> Result<()> {
    if c.friction.is_some_and(|mu| !(mu.is_finite() && mu >= 0.0)) {
        return Err(Error::invalid("friction", "must be finite and >= 0"));
    }
    if !c.velocity.is_finite() {
        return Err(Error::invalid("velocity", "must be finite"));
    }
    if !c.angular_velocity.is_finite() {
        return Err(Error::invalid("angular_velocity", "must be finite"));
    }
    if !c.since.is_finite() {
        return Err(Error::invalid("since", "must be finite"));
    }
    Ok(())
}

/// Whether two shapes are of one kind and size (radius, half extents, a capsule's length to
/// 1e-9 relative), whatever their poses.
fn same_size(a: &Shape, b: &Shape) -> bool {
    match (a, b) {
        (Shape::Plane(_), Shape::Plane(_)) => true,
        (Shape::Sphere(a), Shape::Sphere(b)) => a.radius == b.radius,
        (Shape::Capsule(a), Shape::Capsule(b)) => {
            let (la, lb) = (a.a.distance(a.b), b.a.distance(b.b));
            a.radius == b.radius && (la - lb).abs() <= 1e-9 * la.max(lb)
        }
        (Shape::Box(a), Shape::Box(b)) => a.half == b.half,
        _ => false,
    }
}

fn check_servo(joint: Joint, servo: Option<&Servo>) -> Result<()> {
    let Some(s) = servo else { return Ok(()) };
    if !matches!(joint, Joint::Revolute { .. } | Joint::Ball) {
        return Err(Error::invalid("servo", "only revolute and ball joints have servos"));
    }
    let ok = [s.kp, s.kd].iter().all(|v| v.is_finite() && *v >= 0.0) && s.max_torque >= 0.0;
    if !ok {
        return Err(Error::invalid("servo", "gains must be finite and >= 0, max_torque >= 0"));
    }
    Ok(())
}
