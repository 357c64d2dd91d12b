//! A world of free rigid bodies stepped with one clock.

use super::contact::{self, Bodies, Contact, Placed};
use super::joint::{Joint, JointDesc, JointKind, JointMethod, Row, State, SLOTS};
use super::joint_solver::{self as js, Mass, Multipliers};
use crate::error::{Error, Result};
use crate::geometry::{Material, Plane, Shape, Solid};
use glam::{DMat3, DQuat, DVec3};
use nalgebra::{Matrix3, SymmetricEigen};

mod snapshot;

/// How the rotational equations are integrated over a step `h`.
///
/// All methods treat applied torques as impulses `h τ` and gravity as a uniform field (no
/// torque about the centre of mass); the translational part is the exact update for a
/// constant force over the step.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub enum RotationIntegrator {
    /// Forward Euler on `Π̇ = Π × ω` and `q̇ = ½ q ω` (then renormalised). First order; the
    /// kinetic energy and `|L|` grow every step. Shown for comparison only.
    ExplicitEuler,
    /// Semi-implicit Euler as in most game engines: `Π` updated with the explicit gyroscopic
    /// term, then the orientation with the new `ω` through the exponential map. First order;
    /// energy drifts (usually upwards for tumbling bodies).
    SymplecticEuler,
    /// Implicit gyroscopic step (Catto 2015, "Numerical Methods", GDC): solve
    /// `I (ω₂ - ω₁) + h ω₂ × I ω₂ = 0` in the body frame by Newton's method, then rotate by
    /// `exp(h ω₂)`. First order, unconditionally stable, dissipates a little energy.
    ImplicitGyroscopic,
    /// Splitting of the free rigid body into three exactly solvable rotations about the
    /// principal axes, `T = Σ Πₖ²/2Iₖ` (McLachlan 1993, "Explicit Lie–Poisson integration and
    /// the Euler equations", PRL 71; Touma & Wisdom 1994), composed symmetrically
    /// (Strang): `R₁(h/2) R₂(h/2) R₃(h) R₂(h/2) R₁(h/2)`. Second order, symplectic,
    /// time-reversible; each sub-flow preserves the world angular momentum exactly, so it is
    /// conserved to rounding and the energy error stays bounded.
    Splitting,
}

impl RotationIntegrator {
    /// Parse `"explicit_euler" | "symplectic_euler" | "implicit_gyroscopic" | "splitting"`.
    ///
    /// # Errors
    /// Any other name.
    pub fn parse(name: &str) -> Result<Self> {
        Ok(match name {
            "explicit_euler" => Self::ExplicitEuler,
            "symplectic_euler" => Self::SymplecticEuler,
            "implicit_gyroscopic" => Self::ImplicitGyroscopic,
            "splitting" => Self::Splitting,
            _ => {
                return Err(Error::invalid(
                    "integrator",
                    format!("{name:?} is not one of explicit_euler, symplectic_euler, implicit_gyroscopic, splitting"),
                ))
            }
        })
    }
}

/// Everything needed to add one body to a [`World`].
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

/// Sweeps of the XPBD velocity pass over a hinge with limits or a motor.
const XPBD_VELOCITY_SWEEPS: usize = 8;

/// Alternations of a Lagrange velocity projection and a contact sweep when both are present.
const LAGRANGE_CONTACT_ROUNDS: usize = 4;

/// Contact sweeps of an island (in a world without joints) stop early once no contact's
/// speed changes by more than this in a sweep (m/s): at rest, warm-started contacts converge
/// in a few sweeps, and the rest would be paid for nothing. (With joints the sweeps are
/// shared with them and always all run.)
const CONVERGED: f64 = 1e-12;

/// Next-step state, committed only when the whole step succeeded.
type Scratch = (Vec<DVec3>, Vec<DVec3>, Vec<DQuat>, Vec<DVec3>);

/// Rigid bodies in a uniform gravity field, with contacts against static planes, as a struct
/// of arrays (index = body id).
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub struct World {
    /// Gravitational acceleration (m/s²), default `(0, -9.81, 0)`.
    pub gravity: DVec3,
    integrator: RotationIntegrator,
    // Model.
    mass: Vec<f64>,
    inertia_body: Vec<DMat3>,
    com_body: Vec<DVec3>,
    principal: Vec<DQuat>,
    moments: Vec<DVec3>,
    fixed: Vec<bool>,
    /// `1/m` and `1/I_k` (principal), zero for fixed bodies.
    inv_mass: Vec<f64>,
    inv_moments: Vec<DVec3>,
    /// Radius of a sphere about the centre of mass that holds the shape (m).
    bound: Vec<f64>,
    shape: Vec<Solid>,
    restitution: Vec<f64>,
    friction: Vec<f64>,
    /// Linear and angular damping rates per body (1/s), see [`World::set_damping`].
    linear_damping: Vec<f64>,
    angular_damping: Vec<f64>,
    planes: Vec<(Plane, Material)>,
    /// Sequential-impulse sweeps per step when there are contacts.
    pub contact_iterations: usize,
    /// Whether bodies collide with each other (default true); planes always collide.
    pub collisions: bool,
    // State: centre of mass, its velocity, principal frame → world, Π in the principal frame.
    x: Vec<DVec3>,
    v: Vec<DVec3>,
    q: Vec<DQuat>,
    pi: Vec<DVec3>,
    // Forces and torques (world frame, about the centre of mass) applied during the next step.
    force: Vec<DVec3>,
    torque: Vec<DVec3>,
    scratch: Box<Scratch>,
    // Contact workspaces, reused every step.
    contacts: Vec<Contact>,
    previous: Vec<Contact>,
    /// The last good step's contacts (the next step's warm start), put back when a step fails.
    #[serde(skip)]
    contacts_saved: Vec<Contact>,
    islands: contact::Islands,
    points: Vec<DVec3>,
    omega: Vec<DVec3>,
    placed: Vec<Placed>,
    dx: Vec<DVec3>,
    dtheta: Vec<DVec3>,
    order: Vec<usize>,
    touches: Vec<(usize, contact::Touch)>,
    /// Body pairs whose bounds overlap, `(min, max)`.
    pairs: Vec<(usize, usize)>,
    /// Each body's bounding radius grown by its motion over the step (m).
    reach: Vec<f64>,
    // Joints and their workspaces.
    joints: Vec<Joint>,
    /// Pairs `(min, max)` of bodies joined by a joint, sorted: they do not collide.
    jointed: Vec<(usize, usize)>,
    /// Sequential-impulse sweeps (velocity and position) per step for impulse joints.
    pub joint_iterations: usize,
    /// Substeps per step when a joint uses XPBD (each substep projects once; Müller et al.
    /// 2020 prefer substeps to iterations).
    pub xpbd_substeps: usize,
    /// Baumgarte factor `β` of the Lagrange formulation: `k_s = (β/h)²`, `k_d = 2β/h`, the
    /// drift decays critically over about `1/β` steps.
    pub baumgarte: f64,
    rows: Vec<Row>,
    row_mass: Vec<f64>,
    /// Accumulated impulses of impulse joints per row slot, warm-starting the next step.
    joint_impulse: Vec<f64>,
    joint_impulse_next: Vec<f64>,
    multipliers: Multipliers,
    joint_force: Vec<DVec3>,
    joint_torque: Vec<DVec3>,
    acc_free: Vec<DVec3>,
    alpha_free: Vec<DVec3>,
    xpbd_dx: Vec<DVec3>,
    xpbd_dtheta: Vec<DVec3>,
}

fn rotate_about(axis: usize, angle: f64) -> DQuat {
    let (s, c) = (0.5 * angle).sin_cos();
    let v = DVec3::AXES[axis] * s;
    DQuat::from_xyzw(v.x, v.y, v.z, c)
}

/// `exp(w)` as a unit quaternion; NaN for a non-finite `w`, so that the step's divergence
/// check reports it instead of a panic.
fn exp_map(w: DVec3) -> DQuat {
    crate::rotation::quat_from_rotvec(&w.to_array()).unwrap_or(DQuat::from_xyzw(
        f64::NAN,
        f64::NAN,
        f64::NAN,
        f64::NAN,
    ))
}

impl World {
    /// An empty world with the given gravity and rotation integrator.
    pub fn new(gravity: DVec3, integrator: RotationIntegrator) -> Self {
        World {
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
            contact_iterations: 40,
            collisions: true,
            x: Vec::new(),
            v: Vec::new(),
            q: Vec::new(),
            pi: Vec::new(),
            force: Vec::new(),
            torque: Vec::new(),
            scratch: Box::default(),
            contacts: Vec::new(),
            previous: Vec::new(),
            contacts_saved: Vec::new(),
            islands: contact::Islands::default(),
            points: Vec::new(),
            omega: Vec::new(),
            placed: Vec::new(),
            dx: Vec::new(),
            dtheta: Vec::new(),
            order: Vec::new(),
            touches: Vec::new(),
            pairs: Vec::new(),
            reach: Vec::new(),
            joints: Vec::new(),
            jointed: Vec::new(),
            joint_iterations: 20,
            xpbd_substeps: 20,
            baumgarte: 0.2,
            rows: Vec::new(),
            row_mass: Vec::new(),
            joint_impulse: Vec::new(),
            joint_impulse_next: Vec::new(),
            multipliers: Multipliers::default(),
            joint_force: Vec::new(),
            joint_torque: Vec::new(),
            acc_free: Vec::new(),
            alpha_free: Vec::new(),
            xpbd_dx: Vec::new(),
            xpbd_dtheta: Vec::new(),
        }
    }

    /// Add a joint (see [`JointDesc`]) and return its index. The anchor and axis are read in
    /// world coordinates at the current pose; bodies joined by a joint no longer collide with
    /// each other.
    ///
    /// # Errors
    /// An index out of range (`a`, `b`), `b == a`, a non-finite anchor or axis, a zero axis
    /// for a hinge or slider, limits that are not finite with `lo ≤ 0 ≤ hi`, a non-finite
    /// motor speed or negative torque bound, non-positive penalty stiffness or negative
    /// damping.
    pub fn add_joint(&mut self, desc: &JointDesc) -> Result<usize> {
        let state = State { x: &self.x, q: &self.q, v: &[], w: &[] };
        let joint = Joint::new(desc, self.len(), &state)?;
        let mut joints = self.joints.clone();
        joints.push(joint);
        if desc.method == JointMethod::Lagrange {
            self.multipliers.build(&joints, self.len())?;
        }
        self.joints = joints;
        if let Some(b) = desc.b {
            let pair = (desc.a.min(b), desc.a.max(b));
            if let Err(k) = self.jointed.binary_search(&pair) {
                self.jointed.insert(k, pair);
            }
        }
        let slots = self.joints.len() * SLOTS;
        self.rows.resize(slots, Row::INACTIVE);
        self.row_mass.resize(slots, 0.0);
        self.joint_impulse.resize(slots, 0.0);
        self.joint_impulse_next.resize(slots, 0.0);
        Ok(self.joints.len() - 1)
    }

    /// Number of joints.
    pub fn joint_count(&self) -> usize {
        self.joints.len()
    }

    fn check_joint(&self, j: usize) -> Result<()> {
        if j < self.joints.len() {
            Ok(())
        } else {
            Err(Error::invalid(
                "joint",
                format!("index {j} out of range ({} joints)", self.joints.len()),
            ))
        }
    }

    /// Position error of joint `j`: the distance between its anchors (m; for a slider, the
    /// distance off its axis) and the angle of the relative rotation it forbids (rad).
    ///
    /// # Errors
    /// An index out of range.
    pub fn joint_violation(&self, j: usize) -> Result<(f64, f64)> {
        self.check_joint(j)?;
        Ok(self.joints[j].violation(&State { x: &self.x, q: &self.q, v: &[], w: &[] }))
    }

    /// [`World::joint_coordinate`] of every joint, in order.
    pub fn joint_coordinates(&self) -> Vec<(f64, f64)> {
        let w: Vec<DVec3> = (0..self.len()).map(|i| self.angular_velocity(i)).collect();
        let s = State { x: &self.x, q: &self.q, v: &self.v, w: &w };
        self.joints.iter().map(|j| j.coordinate(&s)).collect()
    }

    /// Coordinate of joint `j` and its rate: a hinge's angle (rad, 0 at creation) and
    /// relative angular velocity about its axis (rad/s); a slider's displacement along its
    /// axis (m, 0 at creation) and velocity (m/s); zeros for ball and fixed joints.
    ///
    /// # Errors
    /// An index out of range.
    pub fn joint_coordinate(&self, j: usize) -> Result<(f64, f64)> {
        self.check_joint(j)?;
        let w: Vec<DVec3> = (0..self.len()).map(|i| self.angular_velocity(i)).collect();
        Ok(self.joints[j].coordinate(&State { x: &self.x, q: &self.q, v: &self.v, w: &w }))
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

    /// Add a body and return its index.
    ///
    /// Without density and mass the body gets the density of water, 1000 kg/m³.
    ///
    /// # Errors
    /// Both density and mass given, a non-positive mass or density, an invalid shape (see
    /// [`Solid::mass_properties`]), a non-finite position, velocity or orientation.
    pub fn add_body(&mut self, desc: &BodyDesc) -> Result<usize> {
        let props = match (desc.density, desc.mass) {
            (Some(_), Some(_)) => {
                return Err(Error::invalid("mass", "give density or mass, not both"))
            }
            (Some(rho), None) => desc.shape.mass_properties(rho)?,
            (None, Some(m)) => {
                if !(m.is_finite() && m > 0.0) {
                    return Err(Error::invalid(
                        "mass",
                        format!("must be positive and finite, got {m}"),
                    ));
                }
                let unit = desc.shape.mass_properties(1.0)?;
                crate::geometry::MassProperties {
                    mass: m,
                    center_of_mass: unit.center_of_mass,
                    inertia: unit.inertia * (m / unit.mass),
                }
            }
            (None, None) => desc.shape.mass_properties(1000.0)?,
        };
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
        // Principal axes: I = P diag(moments) Pᵀ with P a proper rotation.
        let c = props.inertia.to_cols_array();
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
        Material { restitution: desc.restitution, friction: desc.friction }.checked()?;
        let q = (q_body * principal).normalize();
        let omega_principal = q.conjugate() * desc.angular_velocity;
        let energy = kinetic_energy(props.mass, moments, desc.velocity, omega_principal * moments);
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
        self.x.push(desc.position + q_body * props.center_of_mass);
        self.v.push(if desc.fixed { DVec3::ZERO } else { desc.velocity });
        self.q.push(q);
        self.pi.push(if desc.fixed { DVec3::ZERO } else { omega_principal * moments });
        self.force.push(DVec3::ZERO);
        self.torque.push(DVec3::ZERO);
        Ok(self.mass.len() - 1)
    }

    /// Translational and rotational kinetic energy (J) of body `i` at velocity `v` and
    /// principal-frame angular momentum `pi`.
    fn body_energy(&self, i: usize, v: DVec3, pi: DVec3) -> (f64, f64) {
        kinetic_energy(self.mass[i], self.moments[i], v, pi)
    }

    /// Number of bodies.
    pub fn len(&self) -> usize {
        self.mass.len()
    }

    /// True when the world holds no body.
    pub fn is_empty(&self) -> bool {
        self.mass.is_empty()
    }

    /// Mass of body `i` (kg).
    pub fn mass(&self, i: usize) -> f64 {
        self.mass[i]
    }

    /// Coefficient of Coulomb friction of body `i`'s surface.
    pub fn friction(&self, i: usize) -> f64 {
        self.friction[i]
    }

    /// Linear and angular damping rates of body `i` (1/s), see [`World::set_damping`].
    pub fn damping(&self, i: usize) -> (f64, f64) {
        (self.linear_damping[i], self.angular_damping[i])
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
        if i >= self.len() {
            return Err(Error::invalid(
                "body",
                format!("index {i} out of range ({} bodies)", self.len()),
            ));
        }
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

    /// Inertia tensor of body `i` about its centre of mass, body-frame axes (kg m²).
    pub fn inertia(&self, i: usize) -> DMat3 {
        self.inertia_body[i]
    }

    /// Centre of mass of body `i` in its body frame (m).
    pub fn center_of_mass(&self, i: usize) -> DVec3 {
        self.com_body[i]
    }

    /// Orientation of body `i`, body → world.
    pub fn orientation(&self, i: usize) -> DQuat {
        (self.q[i] * self.principal[i].conjugate()).normalize()
    }

    /// World position of the body-frame origin of body `i` (m).
    pub fn position(&self, i: usize) -> DVec3 {
        self.x[i] - self.orientation(i) * self.com_body[i]
    }

    /// Velocity of the centre of mass of body `i` (m/s).
    pub fn velocity(&self, i: usize) -> DVec3 {
        self.v[i]
    }

    /// Angular velocity of body `i` in the world frame (rad/s).
    pub fn angular_velocity(&self, i: usize) -> DVec3 {
        self.q[i] * (self.pi[i] / self.moments[i])
    }

    /// Angular momentum of body `i` about its centre of mass, world frame (kg m²/s).
    pub fn spin_angular_momentum(&self, i: usize) -> DVec3 {
        self.q[i] * self.pi[i]
    }

    /// Total kinetic energy, translational plus rotational (J). Each body's is finite: bodies
    /// are refused ([`World::add_body`]) and steps fail ([`World::step`]) where it would
    /// overflow.
    pub fn kinetic_energy(&self) -> f64 {
        (0..self.len())
            .map(|i| {
                let (linear, angular) = self.body_energy(i, self.v[i], self.pi[i]);
                linear + angular
            })
            .sum()
    }

    /// Gravitational potential energy `−Σ m g · x` of the free bodies, zero at the origin (J).
    pub fn potential_energy(&self) -> f64 {
        (0..self.len())
            .filter(|&i| !self.fixed[i])
            .map(|i| -self.mass[i] * self.gravity.dot(self.x[i]))
            .sum()
    }

    /// Total linear momentum (kg m/s).
    pub fn linear_momentum(&self) -> DVec3 {
        (0..self.len()).map(|i| self.mass[i] * self.v[i]).sum()
    }

    /// Total angular momentum about the world origin (kg m²/s): orbital plus spin.
    pub fn angular_momentum(&self) -> DVec3 {
        (0..self.len())
            .map(|i| self.x[i].cross(self.mass[i] * self.v[i]) + self.spin_angular_momentum(i))
            .sum()
    }

    /// Apply `force` (N, world frame) at world `point` (m) of body `i` during the next step.
    ///
    /// # Errors
    /// An index out of range or non-finite input.
    pub fn apply_force(&mut self, i: usize, force: DVec3, point: DVec3) -> Result<()> {
        if i >= self.len() {
            return Err(Error::invalid(
                "body",
                format!("index {i} out of range ({} bodies)", self.len()),
            ));
        }
        if !force.is_finite() || !point.is_finite() {
            return Err(Error::invalid("force", "force and point must be finite"));
        }
        self.force[i] += force;
        self.torque[i] += (point - self.x[i]).cross(force);
        Ok(())
    }

    /// Advance every body by `steps` steps of `dt` seconds.
    ///
    /// Applied forces act during the first step and are then cleared. Without planes, joints
    /// and two bodies that could collide (or with `collisions` off) the translation is the
    /// exact update for the constant force and the rotation follows the world's integrator.
    /// Otherwise each step (or each of [`World::xpbd_substeps`] substeps when a joint uses
    /// XPBD) is: penalty and Lagrange joint forces at the current state, velocities from all
    /// forces (`v += h a`, `Π += h τ`), contacts found at the current pose, sequential
    /// impulses over the contacts and the impulse joints, positions from the new velocities
    /// (`x += h v`) and the rotation by the world's integrator, a position pass removing
    /// penetration and the impulse joints' drift, and the XPBD projection with its velocity
    /// update. A step that produces a non-finite state, or whose multiplier solve fails,
    /// returns an error and leaves the world at the last good step.
    ///
    /// # Errors
    /// A non-positive or non-finite `dt`; divergence ([`Error::Diverged`]); a failed
    /// factorisation of the joints' multiplier system ([`Error::SolverFailed`]).
    pub fn step(&mut self, dt: f64, steps: usize) -> Result<()> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(Error::invalid("dt", format!("must be positive and finite, got {dt}")));
        }
        let substeps = if self.joints.iter().any(|j| j.method == JointMethod::Xpbd) {
            self.xpbd_substeps.max(1)
        } else {
            1
        };
        for s in 0..steps {
            let (x, v, q, pi) = &mut *self.scratch;
            x.clone_from(&self.x);
            v.clone_from(&self.v);
            q.clone_from(&self.q);
            pi.clone_from(&self.pi);
            let pairs = self.collisions
                && self
                    .shape
                    .iter()
                    .filter(|s| !matches!(s, Solid::Cylinder { .. } | Solid::Mesh { .. }))
                    .count()
                    > 1;
            if self.planes.is_empty() && !pairs && self.joints.is_empty() {
                for i in 0..self.mass.len() {
                    if self.fixed[i] {
                        continue;
                    }
                    let a = self.gravity + self.force[i] / self.mass[i];
                    let c = self.linear_damping[i];
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
                    let tau = q[i].conjugate() * self.torque[i]; // principal frame
                    let c = self.angular_damping[i];
                    let (qi, pii) = if c == 0.0 {
                        rotate(self.integrator, q[i], pi[i], self.moments[i], tau, dt)
                    } else {
                        // The undamped rotation over s, then the decay (see `set_damping`);
                        // a torque's impulse h τ decays with the momentum.
                        let z = -c * dt;
                        let s = -z.exp_m1() / c;
                        let (qi, pii) = rotate(
                            self.integrator,
                            q[i],
                            pi[i],
                            self.moments[i],
                            tau * (dt / s),
                            s,
                        );
                        (qi, z.exp() * pii)
                    };
                    q[i] = qi;
                    pi[i] = pii;
                }
            } else {
                self.joint_impulse_next.clone_from(&self.joint_impulse);
                self.contacts_saved.clone_from(&self.contacts);
                let detect = pairs || !self.planes.is_empty();
                let mut failed = None;
                for _ in 0..substeps {
                    if let Err(e) = self.coupled_step(dt / substeps as f64, detect) {
                        failed = Some(e);
                        break;
                    }
                    if self.first_non_finite().is_some() {
                        break; // reported below, before any contact sees the bad state
                    }
                }
                if failed.is_some() || self.first_non_finite().is_some() {
                    // The next step warm-starts from the last good step's contacts.
                    self.contacts.clone_from(&self.contacts_saved);
                }
                if let Some(e) = failed {
                    return Err(e);
                }
            }
            if let Some(i) = self.first_non_finite() {
                let penalty = self.joints.iter().any(|j| j.method == JointMethod::Penalty);
                let hint = if penalty {
                    "; penalty joints are explicit springs, stable only below a step of about \
                     2/ω of their stiffest coupling: reduce dt, or use another joint method"
                } else {
                    ""
                };
                return Err(Error::Diverged {
                    step: s,
                    index: i,
                    reason: format!("non-finite body state or kinetic energy{hint}"),
                });
            }
            let (x, v, q, pi) = &mut *self.scratch;
            std::mem::swap(&mut self.x, x);
            std::mem::swap(&mut self.v, v);
            std::mem::swap(&mut self.q, q);
            std::mem::swap(&mut self.pi, pi);
            std::mem::swap(&mut self.joint_impulse, &mut self.joint_impulse_next);
            self.force.fill(DVec3::ZERO);
            self.torque.fill(DVec3::ZERO);
        }
        Ok(())
    }

    /// The first body whose scratch state, or kinetic energy, is not finite.
    fn first_non_finite(&self) -> Option<usize> {
        let (x, v, q, pi) = &*self.scratch;
        (0..self.mass.len()).find(|&i| {
            let (linear, angular) = self.body_energy(i, v[i], pi[i]);
            !(x[i].is_finite()
                && v[i].is_finite()
                && q[i].is_finite()
                && pi[i].is_finite()
                && (linear + angular).is_finite())
        })
    }

    /// One step (or substep) of `h` seconds with contacts (when `detect`) and joints, on the
    /// scratch state.
    fn coupled_step(&mut self, h: f64, detect: bool) -> Result<()> {
        let (x, v, q, pi) = &mut *self.scratch;
        let n = self.mass.len();
        let has = |m: JointMethod| self.joints.iter().any(|j| j.method == m);
        let (penalty, lagrange, impulse, xpbd) = (
            has(JointMethod::Penalty),
            has(JointMethod::Lagrange),
            has(JointMethod::Impulse),
            has(JointMethod::Xpbd),
        );
        let mass = Mass { inv_mass: &self.inv_mass, inv_moments: &self.inv_moments };
        self.omega.clear();
        self.omega.extend((0..n).map(|i| q[i] * (pi[i] / self.moments[i])));
        // Joint forces at the start of the step: penalty springs, then the multipliers.
        self.joint_force.clear();
        self.joint_force.resize(n, DVec3::ZERO);
        self.joint_torque.clear();
        self.joint_torque.resize(n, DVec3::ZERO);
        if penalty || lagrange {
            let s = State { x, q, v, w: &self.omega };
            for (ji, j) in self.joints.iter().enumerate() {
                if matches!(j.method, JointMethod::Penalty | JointMethod::Lagrange) {
                    j.rows(&s, &mut self.rows[ji * SLOTS..(ji + 1) * SLOTS]);
                }
                if j.method == JointMethod::Penalty {
                    let rows = &self.rows[ji * SLOTS..ji * SLOTS + j.slots()];
                    js::penalty(
                        j,
                        rows,
                        &mass,
                        &s,
                        h,
                        &mut self.joint_force,
                        &mut self.joint_torque,
                    );
                }
            }
            if lagrange {
                self.acc_free.clear();
                self.alpha_free.clear();
                for i in 0..n {
                    if self.fixed[i] {
                        self.acc_free.push(DVec3::ZERO);
                        self.alpha_free.push(DVec3::ZERO);
                        continue;
                    }
                    let force = self.force[i] + self.joint_force[i];
                    let torque = self.torque[i] + self.joint_torque[i];
                    let l = q[i] * pi[i]; // world angular momentum I ω
                    self.acc_free.push(self.gravity + force / self.mass[i]);
                    self.alpha_free.push(mass.inv_inertia(
                        i,
                        q[i],
                        torque - self.omega[i].cross(l),
                    ));
                }
                self.multipliers.solve(
                    &self.joints,
                    &self.rows,
                    &mass,
                    &s,
                    &self.acc_free,
                    &self.alpha_free,
                    h,
                    self.baumgarte,
                    &mut self.joint_force,
                    &mut self.joint_torque,
                )?;
            }
        }
        self.placed.clear();
        for i in 0..n {
            if !self.fixed[i] {
                v[i] += h * (self.gravity + (self.force[i] + self.joint_force[i]) / self.mass[i]);
                pi[i] += h * (q[i].conjugate() * (self.torque[i] + self.joint_torque[i]));
                // Damping (`set_damping`): e^{−0} = 1 exactly, so none changes nothing.
                v[i] *= (-h * self.linear_damping[i]).exp();
                pi[i] *= (-h * self.angular_damping[i]).exp();
            }
            self.omega[i] = q[i] * (pi[i] / self.moments[i]);
            if detect {
                let orient = q[i] * self.principal[i].conjugate();
                self.placed.push(Placed::new(
                    &self.shape[i],
                    x[i] - orient * self.com_body[i],
                    orient,
                ));
            }
        }
        std::mem::swap(&mut self.contacts, &mut self.previous);
        self.contacts.clear();
        if detect {
            self.detect_contacts(h)?;
        }
        let (x, v, q, pi) = &mut *self.scratch;
        let mass = Mass { inv_mass: &self.inv_mass, inv_moments: &self.inv_moments };
        let bodies = Bodies { inv_mass: &self.inv_mass, inv_moments: &self.inv_moments, q };
        for c in self.contacts.iter_mut() {
            bodies.prepare(c);
        }
        contact::warm_start(&mut self.contacts, &self.previous);
        contact::apply_impulses(&self.contacts, &bodies, v, &mut self.omega);
        let mut sweeps = if self.contacts.is_empty() { 0 } else { self.contact_iterations };
        if impulse {
            sweeps = sweeps.max(self.joint_iterations);
            let s = State { x, q, v, w: &self.omega };
            for (ji, j) in self.joints.iter().enumerate() {
                if j.method != JointMethod::Impulse {
                    continue;
                }
                let slots = ji * SLOTS..ji * SLOTS + j.slots();
                j.rows(&s, &mut self.rows[ji * SLOTS..(ji + 1) * SLOTS]);
                js::effective_masses(
                    j,
                    &self.rows[slots.clone()],
                    &mass,
                    q,
                    &mut self.row_mass[slots.clone()],
                );
            }
            for (ji, j) in self.joints.iter().enumerate() {
                if j.method == JointMethod::Impulse {
                    for k in ji * SLOTS..ji * SLOTS + j.slots() {
                        let l = self.joint_impulse_next[k];
                        js::apply(&mass, j, &self.rows[k], l, q, v, &mut self.omega);
                    }
                }
            }
        }
        if self.joints.is_empty() {
            let fixed = &self.fixed;
            self.islands.build(&self.contacts, |i| !fixed[i], n);
            self.islands.solve(&mut self.contacts, &bodies, sweeps, CONVERGED, v, &mut self.omega);
        }
        // With joints the contacts share the sweeps with the impulse joints, all of them.
        let shared = if self.joints.is_empty() { 0 } else { sweeps };
        for _ in 0..shared {
            for (ji, j) in self.joints.iter().enumerate() {
                if j.method == JointMethod::Impulse {
                    let slots = ji * SLOTS..ji * SLOTS + j.slots();
                    js::sweep(
                        j,
                        &self.rows[slots.clone()],
                        &self.row_mass[slots.clone()],
                        &mut self.joint_impulse_next[slots],
                        &mass,
                        q,
                        h,
                        v,
                        &mut self.omega,
                    );
                }
            }
            contact::sweep(&mut self.contacts, &bodies, v, &mut self.omega);
        }
        if lagrange && !self.contacts.is_empty() {
            // The contacts changed the velocities after the multipliers: alternate a velocity
            // projection onto the Lagrange joints with contact sweeps so both hold.
            for _ in 0..LAGRANGE_CONTACT_ROUNDS {
                self.multipliers.project_velocities(
                    &self.joints,
                    &self.rows,
                    &mass,
                    q,
                    v,
                    &mut self.omega,
                )?;
                contact::sweep(&mut self.contacts, &bodies, v, &mut self.omega);
            }
        }
        // Positions from the new velocities.
        contact::advance_gaps(&mut self.contacts, &bodies, h, v, &self.omega);
        let mass = Mass { inv_mass: &self.inv_mass, inv_moments: &self.inv_moments };
        for i in (0..n).filter(|&i| !self.fixed[i]) {
            pi[i] = (q[i].conjugate() * self.omega[i]) * self.moments[i];
            x[i] += h * v[i];
            let (qi, pii) = rotate(self.integrator, q[i], pi[i], self.moments[i], DVec3::ZERO, h);
            q[i] = qi;
            pi[i] = pii;
        }
        if lagrange {
            // Post-stabilisation of the Lagrange joints at the end-of-step pose.
            self.dx.clear();
            self.dx.resize(n, DVec3::ZERO);
            self.dtheta.clear();
            self.dtheta.resize(n, DVec3::ZERO);
            let s = State { x, q, v: &[], w: &[] };
            for (ji, j) in self.joints.iter().enumerate() {
                if j.method == JointMethod::Lagrange {
                    j.rows(&s, &mut self.rows[ji * SLOTS..(ji + 1) * SLOTS]);
                }
            }
            self.multipliers.project(
                &self.joints,
                &self.rows,
                &mass,
                q,
                &mut self.dx,
                &mut self.dtheta,
            )?;
            for i in (0..n).filter(|&i| !self.fixed[i]) {
                x[i] += self.dx[i];
                q[i] = (exp_map(self.dtheta[i]) * q[i]).normalize();
            }
        }
        // Position pass: penetration and the impulse joints' drift, positions only.
        self.dx.clear();
        self.dx.resize(n, DVec3::ZERO);
        self.dtheta.clear();
        self.dtheta.resize(n, DVec3::ZERO);
        if impulse || !self.contacts.is_empty() {
            let bodies = Bodies { inv_mass: &self.inv_mass, inv_moments: &self.inv_moments, q };
            let s = State { x, q, v: &[], w: &[] };
            for (ji, j) in self.joints.iter().enumerate() {
                if j.method == JointMethod::Impulse {
                    let slots = ji * SLOTS..ji * SLOTS + j.slots();
                    j.rows(&s, &mut self.rows[ji * SLOTS..(ji + 1) * SLOTS]);
                    js::effective_masses(
                        j,
                        &self.rows[slots.clone()],
                        &mass,
                        q,
                        &mut self.row_mass[slots],
                    );
                }
            }
            for _ in 0..sweeps {
                for (ji, j) in self.joints.iter().enumerate() {
                    if j.method == JointMethod::Impulse {
                        let slots = ji * SLOTS..ji * SLOTS + j.slots();
                        js::correct_positions(
                            j,
                            &self.rows[slots.clone()],
                            &self.row_mass[slots],
                            &mass,
                            q,
                            &mut self.dx,
                            &mut self.dtheta,
                        );
                    }
                }
                let pushed = contact::correct_positions(
                    &self.contacts,
                    1,
                    &bodies,
                    &mut self.dx,
                    &mut self.dtheta,
                );
                if self.joints.is_empty() && !pushed {
                    break; // nothing overlaps beyond the slop any more
                }
            }
            for i in (0..n).filter(|&i| !self.fixed[i]) {
                x[i] += self.dx[i];
                q[i] = (exp_map(self.dtheta[i]) * q[i]).normalize();
            }
        }
        if xpbd {
            self.xpbd_step(h);
        }
        Ok(())
    }

    /// The XPBD part of a substep: project the positions onto the XPBD joints once, take the
    /// corrections into the velocities (`v += Δx/h`, `ω += Δθ/h`), then run the motors of
    /// those joints as a velocity pass (Müller et al. 2020, Alg. 2).
    fn xpbd_step(&mut self, h: f64) {
        let (x, v, q, pi) = &mut *self.scratch;
        let n = self.mass.len();
        let mass = Mass { inv_mass: &self.inv_mass, inv_moments: &self.inv_moments };
        self.xpbd_dx.clear();
        self.xpbd_dx.resize(n, DVec3::ZERO);
        self.xpbd_dtheta.clear();
        self.xpbd_dtheta.resize(n, DVec3::ZERO);
        for i in 0..n {
            self.omega[i] = q[i] * (pi[i] / self.moments[i]);
        }
        for j in self.joints.iter().filter(|j| j.method == JointMethod::Xpbd) {
            js::project(j, &mass, x, q, &mut self.xpbd_dx, &mut self.xpbd_dtheta);
        }
        for i in (0..n).filter(|&i| !self.fixed[i]) {
            v[i] += self.xpbd_dx[i] / h;
            self.omega[i] += self.xpbd_dtheta[i] / h;
        }
        // Velocity pass of hinges with limits or a motor: a few sweeps over all their rows
        // (equalities, limits as λ ≥ 0, the motor within its torque bound), so that a limit
        // stops the whole body (not only its turning about the centre of mass) and a motor
        // turns it about the hinge.
        let s = State { x, q, v: &[], w: &[] };
        for (ji, j) in self.joints.iter().enumerate() {
            let driven = matches!(j.kind, JointKind::Hinge { limits: Some(_), .. })
                || matches!(j.kind, JointKind::Hinge { motor: Some(_), .. });
            if j.method != JointMethod::Xpbd || !driven {
                continue;
            }
            let slots = ji * SLOTS..(ji + 1) * SLOTS;
            j.rows(&s, &mut self.rows[slots.clone()]);
            js::effective_masses(
                j,
                &self.rows[slots.clone()],
                &mass,
                q,
                &mut self.row_mass[slots.clone()],
            );
            let mut impulse = [0.0; SLOTS];
            for _ in 0..XPBD_VELOCITY_SWEEPS {
                js::sweep(
                    j,
                    &self.rows[slots.clone()],
                    &self.row_mass[slots.clone()],
                    &mut impulse,
                    &mass,
                    q,
                    h,
                    v,
                    &mut self.omega,
                );
            }
        }
        for i in (0..n).filter(|&i| !self.fixed[i]) {
            pi[i] = (q[i].conjugate() * self.omega[i]) * self.moments[i];
        }
    }

    /// Find the contacts of the scratch state (planes, then body pairs by sweep and prune)
    /// into `self.contacts`, in the order of [`contact::warm_start`]; velocities already
    /// include this step's forces.
    ///
    /// # Errors
    /// A step too large for a speculative contact ([`resolvable`]).
    fn detect_contacts(&mut self, h: f64) -> Result<()> {
        let (x, v, q, _) = &*self.scratch;
        let n = self.mass.len();
        let resting_speed = 2.0 * self.gravity.length() * h;
        // The new contact: its target normal velocity from the approach speed and the gap.
        let make = |key, a: usize, b: Option<usize>, p: DVec3, nrm: DVec3, gap: f64, e: f64, mu| {
            let (ra, rb) = (p - x[a], b.map_or(DVec3::ZERO, |b| p - x[b]));
            let vel = v[a] + self.omega[a].cross(ra)
                - b.map_or(DVec3::ZERO, |b| v[b] + self.omega[b].cross(rb));
            let vn = vel.dot(nrm);
            // Bounce when approaching fast (landing within this step or touching); otherwise
            // close any gap exactly and stop (overlaps are undone by the position pass).
            let target = if vn < -resting_speed && e > 0.0 { -e * vn } else { -gap.max(0.0) / h };
            let t1 = nrm.any_orthonormal_vector();
            (
                vn,
                Contact {
                    key,
                    a,
                    b,
                    ra,
                    rb,
                    n: nrm,
                    t1,
                    t2: nrm.cross(t1),
                    mass: [0.0; 3],
                    compliance: [0.0; 3],
                    spin: [[DVec3::ZERO; 3]; 2],
                    coupling: [0.0; 2],
                    target,
                    gap,
                    mu,
                    impulse: [0.0; 3],
                },
            )
        };
        let np = self.planes.len();
        for i in (0..n).filter(|&i| !self.fixed[i]) {
            let orient = q[i] * self.principal[i].conjugate();
            let origin = x[i] - orient * self.com_body[i];
            for (k, (plane, material)) in self.planes.iter().enumerate() {
                self.points.clear();
                contact::candidate_points(
                    &self.shape[i],
                    origin,
                    orient,
                    plane.normal,
                    &mut self.points,
                );
                for (j, &p) in self.points.iter().enumerate() {
                    let (gap, _) = plane.distance(p);
                    let e = self.restitution[i].max(material.restitution);
                    let mu = (self.friction[i] * material.friction).sqrt();
                    let (vn, c) = make((i, k, j), i, None, p, plane.normal, gap, e, mu);
                    if gap <= (-vn * h).max(0.0) + 1e-9 {
                        resolvable(vn, gap, h, resting_speed, i)?;
                        self.contacts.push(c);
                    }
                }
            }
        }
        // Broad phase: sweep and prune along x over bounding spheres grown by the motion.
        self.reach.clear();
        self.reach.extend(
            (0..n).map(|i| {
                self.bound[i] + h * (v[i].length() + self.omega[i].length() * self.bound[i])
            }),
        );
        let reach = &self.reach;
        self.order.clear();
        if self.collisions {
            self.order.extend((0..n).filter(|&i| !matches!(self.placed[i], Placed::Other)));
        }
        self.order.sort_unstable_by(|&i, &j| {
            (x[i].x - reach[i]).total_cmp(&(x[j].x - reach[j])).then(i.cmp(&j))
        });
        self.pairs.clear();
        for (k, &i) in self.order.iter().enumerate() {
            for &j in &self.order[k + 1..] {
                if x[j].x - reach[j] > x[i].x + reach[i] {
                    break;
                }
                let (a, b) = (i.min(j), i.max(j));
                if (self.fixed[i] && self.fixed[j])
                    || (x[i] - x[j]).length() > reach[i] + reach[j]
                    || self.jointed.binary_search(&(a, b)).is_ok()
                {
                    continue;
                }
                self.pairs.push((a, b));
            }
        }
        // Pairs in order, so the contacts come out sorted for warm starting (planes first).
        self.pairs.sort_unstable();
        for &(a, b) in &self.pairs {
            let margin = h * (v[a] - v[b]).length().max(resting_speed) + contact::SLOP;
            self.touches.clear();
            contact::touches(&self.placed[a], &self.placed[b], margin, &mut self.touches);
            let e = self.restitution[a].max(self.restitution[b]);
            let mu = (self.friction[a] * self.friction[b]).sqrt();
            for &(f, (p, nrm, gap)) in &self.touches {
                let (vn, c) = make((a, np + b, f), a, Some(b), p, nrm, gap, e, mu);
                if gap <= (-vn * h).max(0.0) + contact::SLOP {
                    resolvable(vn, gap, h, resting_speed, a)?;
                    self.contacts.push(c);
                }
            }
        }
        Ok(())
    }
}

/// Whether a speculative contact of `body` apart by `gap` (m), approaching at normal speed
/// `-vn` (m/s), can be honoured in a step of `h` (s): its target speed `gap / h` must stand
/// above the rounding of the speeds the impulse cancels (16 ulp of `|vn|`). Otherwise (e.g. a
/// body 2.5 m above the ground at dt = 1e9 s, which gravity moves at 1e10 m/s) the target is
/// lost in the cancellation and the body would stop in mid-air. Only an approach the step's
/// gravity accounts for (`|vn| <= resting_speed = 2 |g| h`) is blamed on `dt`; a faster one is
/// a diverging state, reported as divergence after the step.
///
/// # Errors
/// [`Error::InvalidInput`] (argument `"dt"`) naming the body.
fn resolvable(vn: f64, gap: f64, h: f64, resting_speed: f64, body: usize) -> Result<()> {
    if gap > contact::SLOP && vn.abs() <= resting_speed && gap / h < 16.0 * f64::EPSILON * vn.abs()
    {
        return Err(Error::invalid(
            "dt",
            format!(
                "{h} s is too large for the contacts of body {body}: closing its gap of {gap:.3e} \
                 m within the step needs {:.3e} m/s, below the rounding of its approach speed \
                 {:.3e} m/s; take smaller steps",
                gap / h,
                vn.abs()
            ),
        ));
    }
    Ok(())
}

/// `φ₂(z) = (e^z − 1 − z)/z²` for `z ≤ 0`, by its series near 0 where the closed form
/// cancels: `(h − s)/c = h² φ₂(−c h)` is the distance a damped body falls short of the
/// undamped drift `a h²/2` (Hochbruck & Ostermann 2010, "Exponential integrators", §2).
fn phi2(z: f64) -> f64 {
    if z.abs() < 0.1 {
        // Σ z^k/(k+2)!, k = 0..11: the first omitted term is below 1e-17 relative.
        let mut term = 0.5;
        let mut sum = 0.5;
        for k in 1..12 {
            term *= z / (k + 2) as f64;
            sum += term;
        }
        sum
    } else {
        (z.exp_m1() / z - 1.0) / z // → 0, not NaN, as z → −∞
    }
}

/// One rotational step of a body with principal moments `m`: orientation `q` (principal →
/// world), principal-frame angular momentum `pi`, principal-frame torque `tau`.
fn rotate(
    method: RotationIntegrator,
    q: DQuat,
    pi: DVec3,
    m: DVec3,
    tau: DVec3,
    h: f64,
) -> (DQuat, DVec3) {
    match method {
        RotationIntegrator::ExplicitEuler => {
            let w = pi / m;
            let pi2 = pi + h * (pi.cross(w) + tau);
            let q2 = q + q * DQuat::from_xyzw(w.x, w.y, w.z, 0.0) * (0.5 * h);
            (q2.normalize(), pi2)
        }
        RotationIntegrator::SymplecticEuler => {
            let w = pi / m;
            let pi2 = pi + h * (pi.cross(w) + tau);
            (q * exp_map(h * (pi2 / m)), pi2)
        }
        RotationIntegrator::ImplicitGyroscopic => {
            // Newton on f(ω) = I(ω - ω₁) + h ω × Iω - h τ = 0; J = I + h (ω̂ I - (Iω)^).
            let w1 = pi / m;
            let mut w = w1;
            let skew = |a: DVec3| {
                DMat3::from_cols(
                    DVec3::new(0.0, a.z, -a.y),
                    DVec3::new(-a.z, 0.0, a.x),
                    DVec3::new(a.y, -a.x, 0.0),
                )
            };
            let inertia = DMat3::from_diagonal(m);
            for _ in 0..8 {
                let iw = m * w;
                let f = m * (w - w1) + h * w.cross(iw) - h * tau;
                let jac = inertia + (skew(w) * inertia - skew(iw)) * h;
                let dw = jac.inverse() * f;
                w -= dw;
                if dw.length() <= 1e-15 * w.length().max(1e-300) {
                    break;
                }
            }
            // Π is carried in the rotating principal frame: Π₂ = I ω₂.
            (q * exp_map(h * w), m * w)
        }
        RotationIntegrator::Splitting => {
            let pi = pi + 0.5 * h * tau;
            let (mut q, mut pi) = (q, pi);
            for (axis, frac) in [(0, 0.5), (1, 0.5), (2, 1.0), (1, 0.5), (0, 0.5)] {
                // Exact flow of Πₖ²/2Iₖ: the body turns by +θ about its axis k, Π by -θ.
                let theta = frac * h * pi[axis] / m[axis];
                let r = rotate_about(axis, theta);
                q *= r;
                pi = r.conjugate() * pi;
            }
            (q.normalize(), pi + 0.5 * h * tau)
        }
    }
}

/// Translational and rotational kinetic energy (J) of a body of `mass` (kg) and principal
/// `moments` (kg m²) at velocity `v` (m/s) and principal-frame angular momentum `pi`
/// (kg m²/s): `|√m v|² / 2` and `|π / √I|² / 2`, squared after scaling so that they overflow
/// only when the energy itself exceeds the largest `f64`.
fn kinetic_energy(mass: f64, moments: DVec3, v: DVec3, pi: DVec3) -> (f64, f64) {
    (0.5 * (mass.sqrt() * v).length_squared(), 0.5 * (pi / moments.sqrt()).length_squared())
}
