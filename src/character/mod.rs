//! Articulated characters in reduced coordinates: a kinematic tree of rigid bodies joined by
//! revolute, ball, free and fixed joints, its dynamics by Featherstone's recursive
//! algorithms ("Rigid Body Dynamics Algorithms", 2008: RNEA, CRBA, ABA), contact with the
//! ground and with static or moving colliders (planes, spheres, capsules, boxes: a
//! staircase), joint limits, PD and stable PD servos (Tan, Liu & Turk 2011), and ragdolls
//! built from motion-capture skeletons.
//!
//! Conventions, stated once: spatial vectors are **angular first** (`[ω; v]`, `[n; f]`) in
//! body coordinates ([`spatial`]); quaternion coordinates are `(w, x, y, z)`; a ball joint's
//! rates are its angular velocity in body axes; a free joint's rates are `[ω (body axes);
//! v (parent axes)]`, its coordinates `[position; quaternion]`.
//!
//! - `spatial.rs`: spatial vectors, cross products, Plücker transforms, rigid inertias
//!   (Featherstone ch. 2).
//! - `model.rs`: the [`Model`] (bodies, joints, shapes, limits, servos, settings, static
//!   colliders).
//! - `state.rs`: the [`State`] (`q`, `q̇`, time, servo targets, torques, pushes).
//! - `joints.rs`: joint transforms and motion subspaces (Table 4.1), `⊕`/`⊖` on coordinates.
//! - `dynamics.rs`: kinematics, RNEA (Table 5.1), CRBA (Table 6.2), ABA (Table 7.1).
//! - `forces.rs`: damping, joint limits, pushes, penalty contact with friction against the
//!   ground and static or moving colliders (planes, spheres, capsules, boxes).
//! - `servo.rs`: PD and stable PD (Tan et al. 2011, eq. 5–8).
//! - `solver.rs`: the [`Solver`] (forward dynamics of a step, symplectic Euler, RK4).
//! - `ragdoll.rs`: a model from an ASF or a BVH skeleton.
//! - `biped.rs`: the planar 7-link biped of SIMBICON (Yin et al. 2007, Table 1).
//! - `simbicon.rs`: the SIMBICON controller and the [`Walker`] (Yin et al. 2007, §3).
//! - `biped3d.rs`: the 3-D biped of SIMBICON (torso, ball hips, hinge knees, ball ankles).
//! - `simbicon3d.rs`: SIMBICON in 3-D and the [`Walker3d`] (Yin et al. 2007, §5).
//! - `snapshot.rs`: snapshots of states and of [`ArticulatedBody`].
//! - `tracking.rs`: a ragdoll tracking a mocap clip (ASF or BVH) with PD servos and a
//!   measured root assistance ([`Tracker`]).

mod biped;
mod biped3d;
mod dynamics;
mod forces;
mod joints;
mod model;
mod ragdoll;
mod servo;
mod simbicon;
mod simbicon3d;
mod snapshot;
mod solver;
pub mod spatial;
mod state;
mod tracking;

pub use biped::{hip_height, link_boxes, planar_biped, LEFT, RIGHT, TORSO};
pub use biped3d::{biped3d, link_boxes_3d, FOOT_WIDTH, HIP_WIDTH, LEFT_3D, RIGHT_3D, TORSO_3D};
pub use dynamics::Tree;
pub use joints::{difference, integrate};
pub use model::{
    Body, Capsule, Collider, Integrator, Joint, Limits, Model, Servo, ServoMode, Settings,
};
pub use ragdoll::{ragdoll, ragdoll_bvh, RagdollOptions};
pub use simbicon::{Gait, Phase, Pose, Walker};
pub use simbicon3d::{Coronal, Walker3d};
pub use solver::Solver;
pub use state::{Push, State};
pub use tracking::{FrameReport, TrackedSkeleton, Tracker, TrackingOptions};

use crate::error::Result;
use glam::DVec3;

/// An articulated body: a [`Model`] with one [`State`] and a [`Solver`], its methods
/// delegating to them. A snapshot holds the model and the state.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub struct ArticulatedBody {
    model: Model,
    state: State,
    #[serde(skip)]
    solver: Solver,
}

impl ArticulatedBody {
    /// The body of `model` in its zero pose ([`State::new`]).
    pub fn new(model: Model) -> Self {
        let state = State::new(&model);
        let solver = Solver::new(&model);
        ArticulatedBody { model, state, solver }
    }

    /// The model.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The model, to change its settings or servos between steps.
    pub fn model_mut(&mut self) -> &mut Model {
        &mut self.model
    }

    /// The state.
    pub fn state(&self) -> &State {
        &self.state
    }

    /// The state, to change it (coordinates, rates, targets, torques, pushes).
    pub fn state_mut(&mut self) -> &mut State {
        &mut self.state
    }

    /// The model and the state, both mutable (to set what needs the model).
    pub fn parts_mut(&mut self) -> (&Model, &mut State) {
        (&self.model, &mut self.state)
    }

    /// Advance `steps` steps of `dt` seconds ([`Solver::step`]).
    ///
    /// # Errors
    /// Those of [`Solver::step`]; the state is then as it was.
    pub fn step(&mut self, dt: f64, steps: usize) -> Result<()> {
        self.solver.step(&self.model, &mut self.state, dt, steps)
    }

    /// The kinematics of the current state (body poses, velocities).
    pub fn kinematics(&mut self) -> &mut Tree {
        self.solver.kinematics(&self.model, &self.state)
    }

    /// Centre of mass (m, world).
    pub fn com(&mut self) -> DVec3 {
        let model = &self.model;
        self.solver.kinematics(model, &self.state).com(model)
    }

    /// Kinetic and gravitational potential energy (J); contact and limit springs excluded.
    pub fn energy(&mut self) -> (f64, f64) {
        let model = &self.model;
        let tree = self.solver.kinematics(model, &self.state);
        (tree.kinetic_energy(model), tree.potential_energy(model))
    }
}
