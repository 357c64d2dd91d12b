//! Rotation vectors (the exponential map) and axis-angle pairs.
//!
//! `exp(v) = (cos(θ/2), sin(θ/2) v/θ)` with `θ = |v|`, and its inverse
//! `log(q) = 2 atan2(|u|, w) u/|u|` for `q = (w, u)` taken with `w >= 0` (Grassia 1998,
//! "Practical parameterization of rotations using the exponential map", JGT 3(3)). Both are
//! evaluated so that they stay accurate for `θ` down to 0 and up to pi: the small-angle
//! factor `sin(θ/2)/θ` uses its Taylor series below `θ = 1e-3`, and `atan2` needs no series.

use super::trig::{sin_cos_reduced, SIN_COS_LIMIT};
use crate::batch::{by_component, lanes, LaneKernel, Output, LANES};
use crate::error::{ensure_finite, Error, Result};
use glam::{DQuat, DVec3};

/// Unit quaternion of rotation vector `v` (axis times angle in radians).
///
/// # Errors
/// Non-finite components.
pub fn quat_from_rotvec(v: &[f64; 3]) -> Result<DQuat> {
    ensure_finite("rotvec", v)?;
    let theta = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if theta <= 2.0 * SIN_COS_LIMIT {
        let (w, k) = exp_factors(theta);
        return Ok(DQuat::from_xyzw(k * v[0], k * v[1], k * v[2], w));
    }
    // Many turns, or components beyond ~1e154 whose squares overflow (then scaled by the
    // largest): libm's sin_cos with its exact reduction.
    let v = DVec3::from_array(*v);
    let theta = if theta.is_finite() {
        theta
    } else {
        let m = v.abs().max_element();
        m * (v / m).length()
    };
    let (sin, cos) = (0.5 * theta).sin_cos();
    let k = sin / theta;
    Ok(DQuat::from_xyzw(k * v.x, k * v.y, k * v.z, cos))
}

/// `(cos(θ/2), sin(θ/2)/θ)` for `θ = |v| <= 2·10^6`, so that `exp(v) = (w, k v)`; without
/// branches so that loops over lanes vectorise; `sin(θ/2)/θ` by its series below `θ = 1e-3`
/// (error below `θ⁶/322560 ≈ 3e-24`).
#[inline(always)]
fn exp_factors(theta: f64) -> (f64, f64) {
    let (sin, cos) = sin_cos_reduced(0.5 * theta);
    let t2 = theta * theta;
    let series = 0.5 - t2 / 48.0 + t2 * t2 / 3840.0;
    let ratio = sin / theta; // 0/0 at θ = 0: the series is taken there
    (cos, if theta < 1e-3 { series } else { ratio })
}

/// [`quat_from_rotvec`] of every row of `rotvecs` into `out` as `(w, x, y, z)`, in parallel;
/// bitwise the same as row by row (blocks of 8 rows of finite vectors up to `2·10^6` rad run
/// lane by lane, which vectorises: AVX2 or AVX-512 through `pulp` where the CPU has it).
///
/// # Errors
/// The lowest row with a non-finite component, or `out` of another length.
pub fn quats_from_rotvecs(rotvecs: &[[f64; 3]], out: &mut (impl Output<4> + ?Sized)) -> Result<()> {
    lanes(rotvecs, out, &FromRotvecs)?;
    Ok(())
}

/// The lane kernel of [`quats_from_rotvecs`].
struct FromRotvecs;

impl LaneKernel<3, 4> for FromRotvecs {
    #[inline(always)]
    fn block<S: pulp::Simd>(
        &self,
        _: S,
        first: usize,
        vs: &[[f64; 3]],
        os: &mut [[f64; 4]],
    ) -> Result<usize> {
        if vs.len() == LANES {
            let c = by_component(vs);
            let mut theta = [0.0; LANES];
            for k in 0..LANES {
                theta[k] = (c[0][k] * c[0][k] + c[1][k] * c[1][k] + c[2][k] * c[2][k]).sqrt();
            }
            // NaN fails the comparison, so non-finite rows go row by row (and fail there).
            if theta.iter().all(|&t| t <= 2.0 * SIN_COS_LIMIT) {
                let (mut w, mut f) = ([0.0; LANES], [0.0; LANES]);
                for k in 0..LANES {
                    (w[k], f[k]) = exp_factors(theta[k]);
                }
                for (k, o) in os.iter_mut().enumerate() {
                    *o = [w[k], f[k] * c[0][k], f[k] * c[1][k], f[k] * c[2][k]];
                }
                return Ok(0);
            }
        }
        for (k, (v, o)) in vs.iter().zip(os.iter_mut()).enumerate() {
            let q = quat_from_rotvec(v).map_err(|e| e.at(first + k))?;
            *o = [q.w, q.x, q.y, q.z];
        }
        Ok(0)
    }
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
