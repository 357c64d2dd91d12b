//! The rigid world's [`Model`]: what is built once and read by every step — each body's mass
//! properties (principal frame and moments, Eberly's closed forms through
//! [`Solid::mass_properties`]), shape, surface material and damping; the static planes; the
//! joints; the settings; and the initial state of the bodies as added.

use super::integrate::{kinetic_energy, RotationIntegrator};
use super::joint::{Joint, JointDesc, JointMethod, Kinematics};
use super::lagrange::Multipliers;
use super::state::{finite_vectors, unit_quaternions};
use super::State;
use crate::error::{Error, Result};
use crate::geometry::{MassProperties, Material, Plane, Shape, Solid};
use crate::snapshot::{check, finite, Stamped};
use glam::{DMat3, DQuat, DVec3};
use nalgebra::{Matrix3, SymmetricEigen};

/// Everything needed to add one body to a [`Model`] (or a [`super::World`]).
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub struct BodyDesc {
    /// The body's shape in its own frame.
    pub shape: Solid,
    /// Uniform density (kg/m³); exclusive with `mass`.
    pub density: Option<f64>,
    /// Total mass (kg); the density follows from the shape's volume. Exclusive with `density`.
    pub mass: Option<f64>,
    /// World position of the body-frame origin (m).
    pub position: DVec3,
    /// Orientation, body → world.
    pub orientation: DQuat,
    /// Linear velocity of the centre of mass (m/s).
    pub velocity: DVec3,
    /// Angular velocity in the world frame (rad/s).
    pub angular_velocity: DVec3,
    /// A fixed body never moves (infinite mass).
    pub fixed: bool,
    /// Coefficient of restitution in contacts, in `[0, 1]` (a contact uses the larger of
    /// its two surfaces').
    pub restitution: f64,
    /// Coefficient of Coulomb friction in contacts, `≥ 0` (a contact uses the geometric mean
    /// of its two surfaces').
    pub friction: f64,
}

/// Rigid bodies in a uniform gravity field with static planes and joints, as a struct of
/// arrays (index = body id): built once by [`Model::new`] and the `add_*` methods (which
/// validate everything), then only read by [`super::Solver::step`]. Per-body arrays have one
/// entry per body; the principal frame is the body frame turned by `principal`.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub struct Model {
    /// Gravitational acceleration (m/s²), default `(0, -9.81, 0)`.
    pub gravity: DVec3,
    pub(super) integrator: RotationIntegrator,
    /// Mass (kg).
    pub(super) mass: Vec<f64>,
    /// Inertia tensor about the centre of mass, body axes (kg m²).
    pub(super) inertia_body: Vec<DMat3>,
    /// Centre of mass in the body frame (m).
    pub(super) com_body: Vec<DVec3>,
    /// Principal frame → body frame.
    pub(super) principal: Vec<DQuat>,
    /// Principal moments of inertia (kg m²).
    pub(super) moments: Vec<DVec3>,
    pub(super) fixed: Vec<bool>,
    /// `1/m` and `1/I_k` (principal), zero for fixed bodies.
    pub(super) inv_mass: Vec<f64>,
    pub(super) inv_moments: Vec<DVec3>,
    /// Radius of a sphere about the centre of mass that holds the shape (m).
    pub(super) bound: Vec<f64>,
    pub(super) shape: Vec<Solid>,
    pub(super) restitution: Vec<f64>,
    pub(super) friction: Vec<f64>,
    /// Linear and angular damping rates per body (1/s), see [`Model::set_damping`].
    pub(super) linear_damping: Vec<f64>,
    pub(super) angular_damping: Vec<f64>,
    pub(super) planes: Vec<(Plane, Material)>,
    pub(super) joints: Vec<Joint>,
    /// Pairs `(min, max)` of bodies joined by a joint, sorted: they do not collide.
    pub(super) jointed: Vec<(usize, usize)>,
    /// Sequential-impulse sweeps per step when there are contacts.
    pub contact_iterations: usize,
    /// Whether bodies collide with each other (default true); planes always collide.
    pub collisions: bool,
    /// Sequential-impulse sweeps (velocity and position) per step for impulse joints.
    pub joint_iterations: usize,
    /// Substeps per step when a joint uses XPBD (each substep projects once; Müller et al.
    /// 2020 prefer substeps to iterations).
    pub xpbd_substeps: usize,
    /// Baumgarte factor `β` of the Lagrange formulation: `k_s = (β/h)²`, `k_d = 2β/h`, the
    /// drift decays critically over about `1/β` steps.
    pub baumgarte: f64,
    /// The bodies as added (their [`BodyDesc`] poses and velocities): [`Model::state`].
    pub(super) initial: State,
}

impl Model {
    /// An empty model with the given gravity (m/s²) and rotation integrator.
    pub fn new(gravity: DVec3, integrator: RotationIntegrator) -> Self {
        Model {
            gravity,
            integrator,
            mass: Vec::new(),
            inertia_body: Vec::new(),
            com_body: Vec::new(),
            principal: Vec::new(),
            moments: Vec::new(),
            fixed: Vec::new(),
            inv_mass: Vec::new(),
            inv_moments: Vec::new(),
            bound: Vec::new(),
            shape: Vec::new(),
            restitution: Vec::new(),
            friction: Vec::new(),
            linear_damping: Vec::new(),
            angular_damping: Vec::new(),
            planes: Vec::new(),
            joints: Vec::new(),
            jointed: Vec::new(),
            contact_iterations: 40,
            collisions: true,
            joint_iterations: 20,
            xpbd_substeps: 20,
            baumgarte: 0.2,
            initial: State::default(),
        }
    }

    /// The initial state: every body at the pose and velocity it was added with, no applied
    /// force, no warm start.
    pub fn state(&self) -> State {
        self.initial.clone()
    }

    /// The rotation integrator of every step.
    pub fn integrator(&self) -> RotationIntegrator {
        self.integrator
    }

    /// Add a body and return its index.
    ///
    /// Without density and mass the body gets the density of water, 1000 kg/m³.
    ///
    /// # Errors
    /// Both density and mass given, a non-positive mass or density, an invalid shape (see
    /// [`Solid::mass_properties`]), a non-finite position, velocity or orientation.
    pub fn add_body(&mut self, desc: &BodyDesc) -> Result<usize> {
        let props = mass_properties(desc)?;
        for (arg, v) in [
            ("position", desc.position),
            ("velocity", desc.velocity),
            ("angular_velocity", desc.angular_velocity),
        ] {
            if !v.is_finite() {
                return Err(Error::invalid(arg, "contains NaN or infinity"));
            }
        }
        let q_body = crate::rotation::quat_from_wxyz(&[
            desc.orientation.w,
            desc.orientation.x,
            desc.orientation.y,
            desc.orientation.z,
        ])
        .map_err(|_| Error::invalid("orientation", "must be a finite, non-zero quaternion"))?;
        let (principal, moments) = principal_axes(props.inertia)?;
        Material { restitution: desc.restitution, friction: desc.friction }.checked()?;
        let q = (q_body * principal).normalize();
        let pi = (q.conjugate() * desc.angular_velocity) * moments;
        let energy = kinetic_energy(props.mass, moments, desc.velocity, pi);
        for (arg, e) in [("velocity", energy.0), ("angular_velocity", energy.1)] {
            if !e.is_finite() {
                return Err(Error::invalid(
                    arg,
                    "too large: the body's kinetic energy would overflow (exceed 1.8e308 J)",
                ));
            }
        }
        self.mass.push(props.mass);
        self.inertia_body.push(props.inertia);
        self.com_body.push(props.center_of_mass);
        self.principal.push(principal);
        self.moments.push(moments);
        self.fixed.push(desc.fixed);
        let free = if desc.fixed { 0.0 } else { 1.0 };
        self.inv_mass.push(free / props.mass);
        self.inv_moments.push(free / moments);
        self.bound.push(desc.shape.bounding_radius(props.center_of_mass));
        self.shape.push(desc.shape.clone());
        self.restitution.push(desc.restitution);
        self.friction.push(desc.friction);
        self.linear_damping.push(0.0);
        self.angular_damping.push(0.0);
        let (v, pi) = if desc.fixed { (DVec3::ZERO, DVec3::ZERO) } else { (desc.velocity, pi) };
        self.initial.push_body(desc.position + q_body * props.center_of_mass, v, q, pi);
        Ok(self.mass.len() - 1)
    }

    /// Add the static plane `normal · x = offset` (the solid side below it) with its surface
    /// material; bodies then collide with it.
    ///
    /// # Errors
    /// A zero or non-finite normal, a non-finite offset, restitution outside `[0, 1]`, a
    /// negative or non-finite friction.
    pub fn add_plane(
        &mut self,
        normal: DVec3,
        offset: f64,
        restitution: f64,
        friction: f64,
    ) -> Result<()> {
        if !offset.is_finite() {
            return Err(Error::invalid("height", "must be finite"));
        }
        let shape = Shape::Plane(Plane { point: DVec3::ZERO, normal }).checked()?;
        let Shape::Plane(Plane { normal, .. }) = shape else { unreachable!("a plane stays one") };
        let material = Material { restitution, friction }.checked()?;
        self.planes.push((Plane { point: offset * normal, normal }, material));
        Ok(())
    }

    /// Add a joint (see [`JointDesc`]) and return its index. The anchor and axis are read in
    /// world coordinates at the pose of the bodies in `pose` (the model's own [`Model::state`]
    /// for a model being built; a [`super::World`] gives its current state); bodies joined by
    /// a joint no longer collide with each other.
    ///
    /// # Errors
    /// A `pose` of another number of bodies, an index out of range (`a`, `b`), `b == a`, a
    /// non-finite anchor or axis, a zero axis for a hinge or slider, limits that are not
    /// finite with `lo ≤ 0 ≤ hi`, a non-finite motor speed or negative torque bound,
    /// non-positive penalty stiffness or negative damping.
    pub fn add_joint(&mut self, desc: &JointDesc, pose: &State) -> Result<usize> {
        if pose.x.len() != self.len() {
            return Err(Error::invalid("pose", "not a state of this model's bodies"));
        }
        let kinematics = Kinematics { x: &pose.x, q: &pose.q, v: &[], w: &[] };
        let joint = Joint::new(desc, self.len(), &kinematics)?;
        let mut joints = self.joints.clone();
        joints.push(joint);
        if desc.method == JointMethod::Lagrange {
            // The pattern of the multiplier system must factorise (the solver builds its own).
            Multipliers::default().build(&joints, self.len())?;
        }
        self.joints = joints;
        if let Some(b) = desc.b {
            let pair = (desc.a.min(b), desc.a.max(b));
            if let Err(k) = self.jointed.binary_search(&pair) {
                self.jointed.insert(k, pair);
            }
        }
        self.initial.resize_joints(self.joints.len());
        Ok(self.joints.len() - 1)
    }

    /// Set the damping rates of body `i` (1/s, both 0 when added): its velocity and its
    /// angular momentum decay as `v̇ = … − c v`, `Π̇ = … − c_ω Π`, exactly over each step
    /// (`v ← e^{−c h} v`; Box2D and Bullet damp the same way, with the factors `1/(1 + c h)`
    /// and `(1 − c)^h`). Without contacts and joints the free update stays exact: the
    /// translation solves `v̇ = a − c v` in closed form, and the rotation is the undamped one
    /// over the shortened time `(1 − e^{−c_ω h})/c_ω` followed by `Π ← e^{−c_ω h} Π` (with
    /// `Π = e^{−c_ω t} P`, Euler's equations for `P` are the undamped ones in that time), so
    /// a torque-free body keeps its path and only slows down. Zero damping leaves every
    /// update bit for bit as without it.
    ///
    /// # Errors
    /// An index out of range; a negative or non-finite rate.
    pub fn set_damping(&mut self, i: usize, linear: f64, angular: f64) -> Result<()> {
        self.check_body(i)?;
        for (arg, c) in [("linear_damping", linear), ("angular_damping", angular)] {
            if !(c.is_finite() && c >= 0.0) {
                return Err(Error::invalid(
                    arg,
                    format!("must be non-negative and finite (1/s), got {c}"),
                ));
            }
        }
        self.linear_damping[i] = linear;
        self.angular_damping[i] = angular;
        Ok(())
    }

    /// `Ok` for a body index in range, else an error naming `body`.
    pub(super) fn check_body(&self, i: usize) -> Result<()> {
        if i < self.len() {
            Ok(())
        } else {
            Err(Error::invalid("body", format!("index {i} out of range ({} bodies)", self.len())))
        }
    }

    /// `Ok` for a joint index in range, else an error naming `joint`.
    pub(super) fn check_joint(&self, j: usize) -> Result<()> {
        if j < self.joints.len() {
            Ok(())
        } else {
            Err(Error::invalid(
                "joint",
                format!("index {j} out of range ({} joints)", self.joints.len()),
            ))
        }
    }

    /// Number of bodies.
    pub fn len(&self) -> usize {
        self.mass.len()
    }

    /// True when the model holds no body.
    pub fn is_empty(&self) -> bool {
        self.mass.is_empty()
    }

    /// Number of joints.
    pub fn joint_count(&self) -> usize {
        self.joints.len()
    }

    /// Mass of body `i` (kg).
    pub fn mass(&self, i: usize) -> f64 {
        self.mass[i]
    }

    /// Coefficient of Coulomb friction of body `i`'s surface.
    pub fn friction(&self, i: usize) -> f64 {
        self.friction[i]
    }

    /// Linear and angular damping rates of body `i` (1/s), see [`Model::set_damping`].
    pub fn damping(&self, i: usize) -> (f64, f64) {
        (self.linear_damping[i], self.angular_damping[i])
    }

    /// Inertia tensor of body `i` about its centre of mass, body-frame axes (kg m²).
    pub fn inertia(&self, i: usize) -> DMat3 {
        self.inertia_body[i]
    }

    /// Centre of mass of body `i` in its body frame (m).
    pub fn center_of_mass(&self, i: usize) -> DVec3 {
        self.com_body[i]
    }

    /// A deterministic 64-bit hash of the model (FNV-1a over its snapshot encoding): equal
    /// for equal models, so a [`State`] snapshot can tell the model it belongs to.
    pub fn fingerprint(&self) -> u64 {
        crate::snapshot::fingerprint(self)
    }
}

/// The body's mass, centre of mass and inertia from its density, its mass or (neither given)
/// the density of water.
fn mass_properties(desc: &BodyDesc) -> Result<MassProperties> {
    match (desc.density, desc.mass) {
        (Some(_), Some(_)) => Err(Error::invalid("mass", "give density or mass, not both")),
        (Some(rho), None) => desc.shape.mass_properties(rho),
        (None, Some(m)) => {
            if !(m.is_finite() && m > 0.0) {
                return Err(Error::invalid(
                    "mass",
                    format!("must be positive and finite, got {m}"),
                ));
            }
            let unit = desc.shape.mass_properties(1.0)?;
            Ok(MassProperties {
                mass: m,
                center_of_mass: unit.center_of_mass,
                inertia: unit.inertia * (m / unit.mass),
            })
        }
        (None, None) => desc.shape.mass_properties(1000.0),
    }
}

/// Principal axes `I = P diag(moments) Pᵀ` of an inertia tensor, `P` a proper rotation given
/// as a quaternion (principal → body frame).
///
/// # Errors
/// A non-positive (or NaN) principal moment, naming `shape`.
fn principal_axes(inertia: DMat3) -> Result<(DQuat, DVec3)> {
    let c = inertia.to_cols_array();
    let eig = SymmetricEigen::new(Matrix3::from_column_slice(&c));
    let mut p = eig.eigenvectors;
    if p.determinant() < 0.0 {
        p.set_column(2, &(-p.column(2)));
    }
    let p_mat = DMat3::from_cols_slice(p.as_slice());
    let principal = DQuat::from_mat3(&p_mat).normalize();
    let moments = DVec3::new(eig.eigenvalues[0], eig.eigenvalues[1], eig.eigenvalues[2]);
    if moments.is_nan() || moments.min_element() <= 0.0 {
        return Err(Error::invalid("shape", "has a non-positive principal moment of inertia"));
    }
    Ok((principal, moments))
}

/// Largest iteration or substep count a model read from a snapshot may carry, so that a
/// damaged count cannot hang a step.
const MAX_ITERATIONS: usize = 100_000;

impl Model {
    /// Check a model decoded from a snapshot: every per-body array of one length, masses and
    /// inertias finite and positive, shapes, materials, planes, damping and settings in their
    /// domains, joints and jointed pairs within the bodies, and its initial state valid.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] naming the first inconsistent field.
    pub(super) fn validate(&self) -> Result<()> {
        let n = self.mass.len();
        let lengths = [
            self.inertia_body.len(),
            self.com_body.len(),
            self.principal.len(),
            self.moments.len(),
            self.fixed.len(),
            self.inv_mass.len(),
            self.inv_moments.len(),
            self.bound.len(),
            self.shape.len(),
            self.restitution.len(),
            self.friction.len(),
            self.linear_damping.len(),
            self.angular_damping.len(),
        ];
        check(lengths.iter().all(|&l| l == n), "bodies", || {
            format!("per-body arrays of lengths {lengths:?} for {n} bodies")
        })?;
        let (vec3, unit) = (finite_vectors, unit_quaternions);
        check(
            vec3(&self.com_body)
                && vec3(&self.moments)
                && vec3(&self.inv_moments)
                && unit(&self.principal),
            "state",
            || "non-finite mass properties or non-unit principal frames".into(),
        )?;
        check(
            finite(self.mass.iter().chain(&self.inv_mass).chain(&self.bound).copied())
                && self.mass.iter().all(|&m| m > 0.0)
                && finite(self.inertia_body.iter().flat_map(|m| m.to_cols_array())),
            "mass",
            || "masses must be finite and positive".into(),
        )?;
        check(
            self.linear_damping
                .iter()
                .chain(&self.angular_damping)
                .all(|c| c.is_finite() && *c >= 0.0),
            "damping",
            || "damping rates must be finite and >= 0".into(),
        )?;
        for (i, s) in self.shape.iter().enumerate() {
            s.mass_properties(1.0).map_err(|e| e.at(i))?;
            Material { restitution: self.restitution[i], friction: self.friction[i] }
                .checked()
                .map_err(|e| e.at(i))?;
        }
        self.validate_planes_and_settings()?;
        for j in &self.joints {
            j.validate(n)?;
        }
        check(self.jointed.iter().all(|&(a, b)| a < b && b < n), "jointed", || {
            "body index out of range".into()
        })?;
        self.initial.validate(self)
    }

    /// The planes' part of [`Model::validate`], with gravity and the iteration counts.
    fn validate_planes_and_settings(&self) -> Result<()> {
        for (plane, material) in &self.planes {
            Shape::Plane(*plane).checked()?;
            check((plane.normal.length() - 1.0).abs() < 1e-6, "planes", || {
                "a plane's normal is not unit".into()
            })?;
            material.checked()?;
        }
        check(self.gravity.is_finite() && self.baumgarte.is_finite(), "gravity", || {
            "non-finite gravity or Baumgarte factor".into()
        })?;
        check(
            [self.contact_iterations, self.joint_iterations, self.xpbd_substeps]
                .iter()
                .all(|&k| k <= MAX_ITERATIONS),
            "contact_iterations",
            || format!("iteration counts above {MAX_ITERATIONS}"),
        )
    }
}
