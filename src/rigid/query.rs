//! Queries of a rigid [`State`] under its [`Model`]: body poses and velocities in the body
//! frame's terms, energies, momenta and the joints' errors and coordinates.

use super::integrate::kinetic_energy;
use super::joint::Kinematics;
use super::{Model, State};
use crate::error::Result;
use glam::{DQuat, DVec3};

impl State {
    /// Orientation of body `i`, body → world.
    pub fn orientation(&self, model: &Model, i: usize) -> DQuat {
        (self.q[i] * model.principal[i].conjugate()).normalize()
    }

    /// World position of the body-frame origin of body `i` (m).
    pub fn position(&self, model: &Model, i: usize) -> DVec3 {
        self.x[i] - self.orientation(model, i) * model.com_body[i]
    }

    /// Velocity of the centre of mass of body `i` (m/s).
    pub fn velocity(&self, i: usize) -> DVec3 {
        self.v[i]
    }

    /// Angular velocity of body `i` in the world frame (rad/s).
    pub fn angular_velocity(&self, model: &Model, i: usize) -> DVec3 {
        self.q[i] * (self.pi[i] / model.moments[i])
    }

    /// Angular momentum of body `i` about its centre of mass, world frame (kg m²/s).
    pub fn spin_angular_momentum(&self, i: usize) -> DVec3 {
        self.q[i] * self.pi[i]
    }

    /// Total kinetic energy, translational plus rotational (J). Each body's is finite: bodies
    /// are refused ([`Model::add_body`]) and steps fail ([`super::Solver::step`]) where it
    /// would overflow.
    pub fn kinetic_energy(&self, model: &Model) -> f64 {
        (0..self.len())
            .map(|i| {
                let (linear, angular) =
                    kinetic_energy(model.mass[i], model.moments[i], self.v[i], self.pi[i]);
                linear + angular
            })
            .sum()
    }

    /// Gravitational potential energy `−Σ m g · x` of the free bodies, zero at the origin (J).
    pub fn potential_energy(&self, model: &Model) -> f64 {
        (0..self.len())
            .filter(|&i| !model.fixed[i])
            .map(|i| -model.mass[i] * model.gravity.dot(self.x[i]))
            .sum()
    }

    /// Total linear momentum (kg m/s).
    pub fn linear_momentum(&self, model: &Model) -> DVec3 {
        (0..self.len()).map(|i| model.mass[i] * self.v[i]).sum()
    }

    /// Total angular momentum about the world origin (kg m²/s): orbital plus spin.
    pub fn angular_momentum(&self, model: &Model) -> DVec3 {
        (0..self.len())
            .map(|i| self.x[i].cross(model.mass[i] * self.v[i]) + self.spin_angular_momentum(i))
            .sum()
    }

    /// Position error of joint `j`: the distance between its anchors (m; for a slider, the
    /// distance off its axis) and the angle of the relative rotation it forbids (rad).
    ///
    /// # Errors
    /// An index out of range.
    pub fn joint_violation(&self, model: &Model, j: usize) -> Result<(f64, f64)> {
        model.check_joint(j)?;
        Ok(model.joints[j].violation(&Kinematics { x: &self.x, q: &self.q, v: &[], w: &[] }))
    }

    /// [`State::joint_coordinate`] of every joint, in order.
    pub fn joint_coordinates(&self, model: &Model) -> Vec<(f64, f64)> {
        let w: Vec<DVec3> = (0..self.len()).map(|i| self.angular_velocity(model, i)).collect();
        let s = Kinematics { x: &self.x, q: &self.q, v: &self.v, w: &w };
        model.joints.iter().map(|j| j.coordinate(&s)).collect()
    }

    /// Coordinate of joint `j` and its rate: a hinge's angle (rad, 0 at creation) and
    /// relative angular velocity about its axis (rad/s); a slider's displacement along its
    /// axis (m, 0 at creation) and velocity (m/s); zeros for ball and fixed joints.
    ///
    /// # Errors
    /// An index out of range.
    pub fn joint_coordinate(&self, model: &Model, j: usize) -> Result<(f64, f64)> {
        model.check_joint(j)?;
        let w: Vec<DVec3> = (0..self.len()).map(|i| self.angular_velocity(model, i)).collect();
        Ok(model.joints[j].coordinate(&Kinematics { x: &self.x, q: &self.q, v: &self.v, w: &w }))
    }
}
