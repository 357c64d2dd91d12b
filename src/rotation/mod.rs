//! 3D rotations: unit quaternions, matrices, Euler and fixed angles, rotation vectors,
//! axis-angle, modified Rodrigues parameters, spherical interpolation, weighted means, the
//! finite rotation groups and homogeneous transforms.
//!
//! Conventions (see `ARCHITECTURE.md`):
//! - Quaternions are scalar-first `(w, x, y, z)` at every array boundary, with the Hamilton
//!   product; inside Rust they are [`glam::DQuat`]. A vector is rotated actively,
//!   `v' = q v q*`, the same as `v' = R v` with column vectors.
//! - `q` and `-q` are the same rotation; [`canonical`] picks `w >= 0`.
//! - Matrices cross the boundary row-major as `[f64; 9]` (3x3) or `[f64; 16]` (4x4).
//! - Euler sequences are 3-letter strings: upper case intrinsic, lower case extrinsic
//!   ([`EulerSequence`]).
//!
//! Every function that accepts user data checks it and returns [`crate::Error`] instead of
//! producing NaN: zero or non-finite quaternions, matrices that are not rotations, zero axes.

mod align;
mod davenport;
mod euler;
mod group;
mod matrix;
mod mean;
mod mrp;
mod quat;
mod rotvec;
mod screw;
mod slerp;
mod transform;
mod trig;

pub use align::{align_vectors, Alignment};
pub use davenport::{davenport_from_quat, davenport_from_quats};
pub use euler::{EulerSequence, GIMBAL_LOCK_TOL};
pub use group::{create_group, reduce};
pub use matrix::{
    is_rotation_matrix, orthonormalize, quat_from_matrix, quat_to_matrix, quats_to_matrices,
    ROTATION_MATRIX_TOL,
};
pub use mean::mean;
pub use mrp::{mrps_to_quats, quat_from_mrp, quat_to_mrp, quats_to_mrps};
pub use quat::{
    canonical, multiply_quats, normalize_quats, quat_from_wxyz, quat_to_wxyz, rotation_angle,
};
pub use rotvec::{
    quat_from_axis_angle, quat_from_rotvec, quat_to_axis_angle, quat_to_rotvec, quats_from_rotvecs,
};
pub use screw::{
    rigid_parts, transform_from_dual_quat, transform_from_exp_coords, transform_to_dual_quat,
    transform_to_exp_coords,
};
pub use slerp::slerp;
pub use transform::{
    transform_apply_direction, transform_apply_point, transform_compose, transform_from_parts,
    transform_invert, validate_transform,
};
