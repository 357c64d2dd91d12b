//! Keyframing: tracks of keys `(t_i, value_i)` for channels of any width, interpolated by the
//! classic schemes of computer animation, subdivision curves, arc-length reparameterisation,
//! easing curves and clips of named channels.
//!
//! Value tracks ([`Track`]) are keyframe splines, shared maths that constraints (a bead on a
//! keyframed wire) and mocap (time warps) use too; they live in the neutral [`crate::spline`]
//! and are re-exported here.

mod arc_length;
mod clip;
mod easing;
mod rotation_spline;
mod rotation_track;
mod subdivide;

pub use crate::spline::{Extrapolation, Interpolation, Track};
pub use arc_length::{ArcLengthCurve, INVERSE_TOL, MAX_SUBDIVISIONS};
pub use clip::{frame_times, Channel, Clip, Samples};
pub use easing::Easing;
pub use rotation_track::{RotationInterpolation, RotationTrack};
pub use subdivide::{subdivide, Scheme};
