//! # kinema: physically based animation
//!
//! A pure-Rust core (this crate) with Python bindings in [`bindings`] behind the `python` cargo
//! feature. Every subject lives in its own module; all share the conventions of
//! `ARCHITECTURE.md`: SI units, +Y up, scalar-first `(w, x, y, z)` quaternions, `f64` everywhere,
//! batches as slices of fixed-size rows, and one [`Error`] type.

pub mod anim;
pub mod batch;
pub mod character;
pub mod cloth;
pub mod constraints;
pub mod crowd;
pub mod error;
pub mod flock;
pub mod fluid;
pub mod geometry;
pub mod ik;
pub mod linalg;
pub mod math;
pub mod mocap;
pub mod ode;
pub mod particles;
pub mod rigid;
pub mod rods;
pub mod rotation;
pub mod skin;
pub mod snapshot;
pub mod spline;

#[cfg(feature = "python")]
mod bindings;

pub use error::{Error, Result};
