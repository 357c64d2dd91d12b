//! Rotation vectors (the exponential map) and axis-angle pairs.
//!
//! `exp(v) = (cos(θ/2), sin(θ/2) v/θ)` with `θ = |v|`, and its inverse
//! `log(q) = 2 atan2(|u|, w) u/|u|` for `q = (w, u)` taken with `w >= 0` (Grassia 1998,
//! "Practical parameterization of rotations using the exponential map", JGT 3(3)). Both are
//! evaluated so that they stay accurate for `θ` down to 0 and up to pi: the small-angle
//! factor `sin(θ/2)/θ` uses its Taylor series below `θ = 1e-3`, and `atan2` needs no series.

use crate::error::{ensure_finite, Error, Result};
use glam::{DQuat, DVec3};

/// Unit quaternion of rotation vector `v` (axis times angle in radians).
///
/// # Errors
/// Non-finite components.
pub fn quat_from_rotvec(v: &[f64; 3]) -> Result<DQuat> {
    ensure_finite("rotvec", v)?;
    let v = DVec3::from_array(*v);
    let theta = v.length();
    // Components beyond ~1e154 overflow the squares; scaling by the largest is exact enough.
    let theta = if theta.is_finite() {
        theta
    } else {
        let m = v.abs().max_element();
        m * (v / m).length()
    };
    let half = 0.5 * theta;
    let (sin, cos) = half.sin_cos();
    // sin(θ/2)/θ; the series error at θ = 1e-3 is below θ⁶/322560 ≈ 3e-24.
    let k = if theta < 1e-3 {
        let t2 = theta * theta;
        0.5 - t2 / 48.0 + t2 * t2 / 3840.0
    } else {
        sin / theta
    };
    Ok(DQuat::from_xyzw(k * v.x, k * v.y, k * v.z, cos))
}

/// Rotation vector of unit quaternion `q`, with angle in `[0, pi]`.
pub fn quat_to_rotvec(q: DQuat) -> [f64; 3] {
    let q = if q.w < 0.0 { -q } else { q };
    let u = q.xyz();
    let s = u.length();
    // θ/|u| = 2 atan2(s, w)/s is well conditioned for every s > 0; at s = 0 its limit is 2/w.
    let k = if s > 0.0 { 2.0 * s.atan2(q.w) / s } else { 2.0 / q.w };
    (u * k).to_array()
}

/// Unit quaternion of a rotation by `angle` radians about `axis` (normalised here).
///
/// # Errors
/// Non-finite input, or a zero axis.
pub fn quat_from_axis_angle(axis: &[f64; 3], angle: f64) -> Result<DQuat> {
    ensure_finite("axis", axis)?;
    if !angle.is_finite() {
        return Err(Error::invalid("angle", "is NaN or infinite"));
    }
    let a = DVec3::from_array(*axis);
    let m = a.abs().max_element();
    if m == 0.0 {
        return Err(Error::invalid("axis", "is the zero vector"));
    }
    let a = (a / m).normalize();
    let (s, c) = (0.5 * angle).sin_cos();
    Ok(DQuat::from_xyzw(a.x * s, a.y * s, a.z * s, c))
}

/// Unit axis and angle in `[0, pi]` of unit quaternion `q`; the identity gets axis `+x`.
pub fn quat_to_axis_angle(q: DQuat) -> ([f64; 3], f64) {
    let q = if q.w < 0.0 { -q } else { q };
    let u = q.xyz();
    let s = u.length();
    if s == 0.0 {
        ([1.0, 0.0, 0.0], 0.0)
    } else {
        ((u / s).to_array(), 2.0 * s.atan2(q.w))
    }
}
