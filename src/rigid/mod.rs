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
//! and advances a state by [`Solver::step`]; [`World`] composes one of each:
//!
//! ```
//! use glam::{DQuat, DVec3};
//! use kinema::geometry::Solid;
//! use kinema::rigid::{BodyDesc, Model, RotationIntegrator, Solver, State};
//! use kinema::snapshot::Stamped;
//!
//! // The model: a ground plane and a box 0.5 m above it (built once, validated).
//! let mut model = Model::new(DVec3::new(0.0, -9.81, 0.0), RotationIntegrator::Splitting);
//! model.add_plane(DVec3::Y, 0.0, 0.2, 0.5)?;
//! model.add_body(&BodyDesc {
//!     shape: Solid::Box { half_extents: DVec3::splat(0.1) },
//!     density: None,
//!     mass: Some(1.0),
//!     position: DVec3::new(0.0, 0.5, 0.0),
//!     orientation: DQuat::IDENTITY,
//!     velocity: DVec3::ZERO,
//!     angular_velocity: DVec3::ZERO,
//!     fixed: false,
//!     restitution: 0.2,
//!     friction: 0.5,
//! })?;
//! // Two states of it: as built, and thrown sideways.
//! let mut dropped = model.state();
//! let mut thrown: State = model.state();
//! thrown.v[0] = DVec3::new(2.0, 1.0, 0.0);
//! // One solver advances both, in any order, each as if it had a solver of its own.
//! let mut solver = Solver::new(&model)?;
//! for _ in 0..120 {
//!     solver.step(&model, &mut dropped, 1.0 / 120.0, 1)?;
//!     solver.step(&model, &mut thrown, 1.0 / 120.0, 1)?;
//! }
//! assert!(thrown.position(&model, 0).x > 0.5 && dropped.position(&model, 0).x.abs() < 1e-6);
//! // A state's snapshot names its model by fingerprint, and is refused on another.
//! let bytes = thrown.to_snapshot(&model)?;
//! assert_eq!(State::from_snapshot(&model, &bytes)?.v, thrown.v);
//! # Ok::<(), kinema::Error>(())
//! ```

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
