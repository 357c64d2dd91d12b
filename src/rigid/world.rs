//! A world of rigid bodies stepped with one clock: the composition of a [`Model`], one
//! [`State`] of it and a [`Solver`], with the methods of all three in one place (each
//! delegating to the part that holds it).

use super::joint::JointDesc;
use super::{BodyDesc, Model, RotationIntegrator, Solver, State};
use crate::error::Result;
use glam::{DMat3, DQuat, DVec3};

mod snapshot;

/// Rigid bodies in a uniform gravity field, with contacts against static planes and each
/// other, and joints: a [`Model`], its [`State`] and a [`Solver`]. Adding a body or a joint
/// after stepping has begun extends the model and fits the state to it (the new body enters
/// as added, a new joint without warm start).
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub struct World {
    model: Model,
    state: State,
    /// Workspaces only: not stored (a restored world builds them at its first step).
    #[serde(skip)]
    solver: Solver,
}

impl World {
    /// An empty world with the given gravity (m/s²) and rotation integrator.
    pub fn new(gravity: DVec3, integrator: RotationIntegrator) -> Self {
        World::from_model(Model::new(gravity, integrator))
    }

    /// A world of `model` at its initial state ([`Model::state`]).
    pub fn from_model(model: Model) -> Self {
        World { state: model.state(), model, solver: Solver::default() }
    }

    /// The model (bodies, planes, joints, settings).
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The model, to change its settings (gravity, iterations, collisions, Baumgarte factor).
    /// Bodies and joints are added through [`World::add_body`] and [`World::add_joint`],
    /// which keep the state fitted to the model.
    pub fn model_mut(&mut self) -> &mut Model {
        &mut self.model
    }

    /// The current state.
    pub fn state(&self) -> &State {
        &self.state
    }

    /// Copy `state`, a state of this world's model (e.g. one taken from [`World::state`]
    /// earlier, or stepped by another [`Solver`]), into the current state, reusing its
    /// buffers (no allocation once they are large enough).
    ///
    /// # Errors
    /// A `state` whose sizes are not the model's (argument `"state"`).
    pub fn set_state(&mut self, state: &State) -> Result<()> {
        state.check_sizes(&self.model)?;
        self.state.clone_from(state);
        Ok(())
    }

    /// Add a body (see [`Model::add_body`]) and return its index.
    ///
    /// # Errors
    /// As [`Model::add_body`].
    pub fn add_body(&mut self, desc: &BodyDesc) -> Result<usize> {
        let i = self.model.add_body(desc)?;
        self.state.fit(&self.model);
        Ok(i)
    }

    /// Add the static plane `normal · x = offset`, see [`Model::add_plane`].
    ///
    /// # Errors
    /// As [`Model::add_plane`].
    pub fn add_plane(
        &mut self,
        normal: DVec3,
        offset: f64,
        restitution: f64,
        friction: f64,
    ) -> Result<()> {
        self.model.add_plane(normal, offset, restitution, friction)
    }

    /// Add a joint (see [`JointDesc`]) at the current pose and return its index, see
    /// [`Model::add_joint`].
    ///
    /// # Errors
    /// As [`Model::add_joint`].
    pub fn add_joint(&mut self, desc: &JointDesc) -> Result<usize> {
        let j = self.model.add_joint(desc, &self.state)?;
        self.state.fit(&self.model);
        Ok(j)
    }

    /// Set the damping rates of body `i` (1/s), see [`Model::set_damping`].
    ///
    /// # Errors
    /// As [`Model::set_damping`].
    pub fn set_damping(&mut self, i: usize, linear: f64, angular: f64) -> Result<()> {
        self.model.set_damping(i, linear, angular)
    }

    /// Apply `force` (N, world frame) at world `point` (m) of body `i` during the next step.
    ///
    /// # Errors
    /// An index out of range or non-finite input.
    pub fn apply_force(&mut self, i: usize, force: DVec3, point: DVec3) -> Result<()> {
        self.state.apply_force(i, force, point)
    }

    /// Advance every body by `steps` steps of `dt` seconds, see [`Solver::step`]; a failed
    /// step leaves the world at the last good step.
    ///
    /// # Errors
    /// As [`Solver::step`].
    pub fn step(&mut self, dt: f64, steps: usize) -> Result<()> {
        self.solver.step(&self.model, &mut self.state, dt, steps)
    }

    /// Number of bodies.
    pub fn len(&self) -> usize {
        self.model.len()
    }

    /// True when the world holds no body.
    pub fn is_empty(&self) -> bool {
        self.model.is_empty()
    }

    /// Number of joints.
    pub fn joint_count(&self) -> usize {
        self.model.joint_count()
    }

    /// Mass of body `i` (kg).
    pub fn mass(&self, i: usize) -> f64 {
        self.model.mass(i)
    }

    /// Coefficient of Coulomb friction of body `i`'s surface.
    pub fn friction(&self, i: usize) -> f64 {
        self.model.friction(i)
    }

    /// Linear and angular damping rates of body `i` (1/s), see [`Model::set_damping`].
    pub fn damping(&self, i: usize) -> (f64, f64) {
        self.model.damping(i)
    }

    /// Inertia tensor of body `i` about its centre of mass, body-frame axes (kg m²).
    pub fn inertia(&self, i: usize) -> DMat3 {
        self.model.inertia(i)
    }

    /// Centre of mass of body `i` in its body frame (m).
    pub fn center_of_mass(&self, i: usize) -> DVec3 {
        self.model.center_of_mass(i)
    }

    /// Orientation of body `i`, body → world.
    pub fn orientation(&self, i: usize) -> DQuat {
        self.state.orientation(&self.model, i)
    }

    /// World position of the body-frame origin of body `i` (m).
    pub fn position(&self, i: usize) -> DVec3 {
        self.state.position(&self.model, i)
    }

    /// Velocity of the centre of mass of body `i` (m/s).
    pub fn velocity(&self, i: usize) -> DVec3 {
        self.state.velocity(i)
    }

    /// Angular velocity of body `i` in the world frame (rad/s).
    pub fn angular_velocity(&self, i: usize) -> DVec3 {
        self.state.angular_velocity(&self.model, i)
    }

    /// Angular momentum of body `i` about its centre of mass, world frame (kg m²/s).
    pub fn spin_angular_momentum(&self, i: usize) -> DVec3 {
        self.state.spin_angular_momentum(i)
    }

    /// Total kinetic energy, translational plus rotational (J).
    pub fn kinetic_energy(&self) -> f64 {
        self.state.kinetic_energy(&self.model)
    }

    /// Gravitational potential energy `−Σ m g · x` of the free bodies, zero at the origin (J).
    pub fn potential_energy(&self) -> f64 {
        self.state.potential_energy(&self.model)
    }

    /// Total linear momentum (kg m/s).
    pub fn linear_momentum(&self) -> DVec3 {
        self.state.linear_momentum(&self.model)
    }

    /// Total angular momentum about the world origin (kg m²/s): orbital plus spin.
    pub fn angular_momentum(&self) -> DVec3 {
        self.state.angular_momentum(&self.model)
    }

    /// Position error of joint `j` (m, rad), see [`State::joint_violation`].
    ///
    /// # Errors
    /// An index out of range.
    pub fn joint_violation(&self, j: usize) -> Result<(f64, f64)> {
        self.state.joint_violation(&self.model, j)
    }

    /// Coordinate and rate of every joint, see [`State::joint_coordinate`].
    pub fn joint_coordinates(&self) -> Vec<(f64, f64)> {
        self.state.joint_coordinates(&self.model)
    }

    /// Coordinate of joint `j` and its rate, see [`State::joint_coordinate`].
    ///
    /// # Errors
    /// An index out of range.
    pub fn joint_coordinate(&self, j: usize) -> Result<(f64, f64)> {
        self.state.joint_coordinate(&self.model, j)
    }
}
