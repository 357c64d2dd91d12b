//! The rigid world's [`State`]: what changes in time and what a later step reads — each
//! body's centre of mass, velocity, principal frame and angular momentum, the forces applied
//! during the next step, and the warm starts (the last step's contacts and the impulse
//! joints' accumulated impulses).

use super::contact::Contact;
use super::joint::SLOTS;
use super::Model;
use crate::error::{Error, Result};
use crate::snapshot::{check, finite, Stamped};
use glam::{DQuat, DVec3};

/// The time-varying part of a rigid world of `N` bodies (index = body id), all in the world
/// frame unless said otherwise. One [`Model`] can have any number of states, each advanced by
/// [`super::Solver::step`]; a state is cheap to clone and serialisable.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, Default)]
pub struct State {
    /// Centres of mass (m), `N`.
    pub x: Vec<DVec3>,
    /// Velocities of the centres of mass (m/s), `N`.
    pub v: Vec<DVec3>,
    /// Principal frames → world, unit quaternions, `N` (the body frame is
    /// `q · principal⁻¹`, see [`State::orientation`]).
    pub q: Vec<DQuat>,
    /// Angular momenta `Π` in the principal frames (kg m²/s), `N`.
    pub pi: Vec<DVec3>,
    /// Forces (N) applied at the centres of mass during the next step, `N`; cleared by
    /// every successful step.
    pub force: Vec<DVec3>,
    /// Torques about the centres of mass (N m, world frame) applied during the next step,
    /// `N`; cleared by every successful step.
    pub torque: Vec<DVec3>,
    /// The last step's contacts with their accumulated impulses: the next step's warm start
    /// (Catto 2005).
    pub(super) contacts: Vec<Contact>,
    /// Accumulated impulses of the impulse joints per row slot (N s or N m s), warm-starting
    /// the next step, `joints · SLOTS`.
    pub(super) joint_impulse: Vec<f64>,
}

impl State {
    /// The initial state of `model`: [`Model::state`].
    pub fn new(model: &Model) -> Self {
        model.state()
    }

    /// Number of bodies.
    pub fn len(&self) -> usize {
        self.x.len()
    }

    /// True when the state holds no body.
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    /// Append one body at rest from forces.
    pub(super) fn push_body(&mut self, x: DVec3, v: DVec3, q: DQuat, pi: DVec3) {
        self.x.push(x);
        self.v.push(v);
        self.q.push(q);
        self.pi.push(pi);
        self.force.push(DVec3::ZERO);
        self.torque.push(DVec3::ZERO);
    }

    /// Size the joints' warm starts for `joints` joints (new ones start from zero).
    pub(super) fn resize_joints(&mut self, joints: usize) {
        self.joint_impulse.resize(joints * SLOTS, 0.0);
    }

    /// Fit the state to `model` after bodies or joints were added to it: the new bodies enter
    /// as the model added them, the new joints with no warm start.
    pub(super) fn fit(&mut self, model: &Model) {
        let init = &model.initial;
        for i in self.len()..model.len() {
            self.push_body(init.x[i], init.v[i], init.q[i], init.pi[i]);
        }
        self.resize_joints(model.joint_count());
    }

    /// `Ok` when every array has the size `model` asks for.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] (argument `"state"`) otherwise.
    pub(super) fn check_sizes(&self, model: &Model) -> Result<()> {
        let n = model.len();
        let sizes =
            [self.v.len(), self.q.len(), self.pi.len(), self.force.len(), self.torque.len()];
        if self.x.len() == n
            && sizes.iter().all(|&l| l == n)
            && self.joint_impulse.len() == model.joint_count() * SLOTS
            && self.contacts.iter().all(|c| c.a < n && c.b.is_none_or(|b| b < n))
        {
            Ok(())
        } else {
            Err(Error::invalid("state", "its sizes are not the model's (another model's state?)"))
        }
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
}

impl Stamped for State {
    const TAG: &'static str = "RigidState";
    type Model = Model;

    /// Check a decoded state against `model`: its sizes, then its values.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] naming the first inconsistent field.
    fn validate(&self, model: &Model) -> Result<()> {
        self.check_sizes(model)?;
        self.validate_values()
    }
}

impl State {
    /// The values of a decoded state: finite, unit orientations, warm-start contacts within
    /// the bodies with finite impulses.
    fn validate_values(&self) -> Result<()> {
        let n = self.x.len();
        let sizes =
            [self.v.len(), self.q.len(), self.pi.len(), self.force.len(), self.torque.len()];
        check(sizes.iter().all(|&l| l == n), "state", || {
            format!("per-body arrays of lengths {sizes:?} for {n} bodies")
        })?;
        let (vec3, unit) = (finite_vectors, unit_quaternions);
        check(
            vec3(&self.x)
                && vec3(&self.v)
                && vec3(&self.pi)
                && vec3(&self.force)
                && vec3(&self.torque)
                && unit(&self.q)
                && finite(self.joint_impulse.iter().copied()),
            "state",
            || "non-finite state or non-unit orientations".into(),
        )?;
        check(
            self.contacts.iter().all(|c| {
                c.a < n
                    && c.b.is_none_or(|b| b < n && b != c.a)
                    && c.ra.is_finite()
                    && finite(c.impulse)
            }),
            "previous",
            || "warm-start contacts out of range or non-finite".into(),
        )
    }
}

/// Whether every vector is finite (for the snapshot checks).
pub(super) fn finite_vectors(v: &[DVec3]) -> bool {
    finite(v.iter().flat_map(|p| p.to_array()))
}

/// Whether every quaternion is finite and of unit length within 1e-6 (for the snapshot
/// checks).
pub(super) fn unit_quaternions(q: &[DQuat]) -> bool {
    q.iter().all(|q| q.is_finite() && (q.length() - 1.0).abs() < 1e-6)
}
