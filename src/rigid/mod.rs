//! Rigid bodies: mass properties from shapes, and the Newton–Euler equations of free bodies
//! under gravity and applied forces, with a choice of rotation integrators.
//!
//! State per body: centre-of-mass position `x` and velocity `v` (world frame), orientation `q`
//! (unit quaternion, body → world) and angular momentum. The rotational equations are Euler's,
//! written for the angular momentum `Π` in the principal frame of the body,
//! `Π̇ = Π × I⁻¹Π + τ_body`, `q̇ = ½ q ⊗ (0, I⁻¹Π)`, whose gyroscopic term `Π × I⁻¹Π` makes the
//! intermediate-axis (Dzhanibekov) flip happen. See [`RotationIntegrator`] for the methods.
//!
//! Contacts with static planes (ground) use sequential impulses with restitution and Coulomb
//! friction ([`contact`]), between bodies as well. Joints (ball, hinge with limits and a motor,
//! slider, fixed) are enforced by one of four formulations, [`JointMethod`]: penalty forces,
//! Lagrange multipliers, sequential impulses or XPBD.
//!
//! The code has the shape of MuJoCo's `mjModel`/`mjData` and Newton's `Model`/`State`/solver:
//! a [`Model`] built once (bodies, planes, joints, settings), any number of [`State`]s of it
//! (poses, velocities, applied forces, warm starts), and a [`Solver`] that owns the workspaces
//! and advances a state by [`Solver::step`]; [`World`] composes one of each.

pub mod contact;
mod integrate;
mod joint;
mod joint_solver;
mod lagrange;
mod model;
mod narrow;
mod query;
mod solver;
mod state;
mod world;

pub use integrate::RotationIntegrator;
pub use joint::{JointDesc, JointKind, JointMethod, Motor, PENALTY_DAMPING, PENALTY_STIFFNESS};
pub use model::{BodyDesc, Model};
pub use solver::Solver;
pub use state::State;
pub use world::World;
