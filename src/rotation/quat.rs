//! Unit quaternions at the array boundary: checked construction from `(w, x, y, z)`,
//! normalisation that neither overflows nor underflows, the canonical sign, the angle.

use crate::error::{ensure_finite, Error, Result};
use glam::DQuat;

/// A unit quaternion from scalar-first components `(w, x, y, z)`, normalised.
///
/// Any non-zero finite 4-vector is accepted and scaled to unit length (the scale does not
/// change the rotation it denotes); one whose squared norm is within 4 ulp of 1 is returned
/// as is. Tiny or huge components are rescaled by their largest
/// magnitude first so the norm neither underflows nor overflows.
///
/// # Errors
/// [`Error::InvalidInput`] (argument `quat`) for a zero or non-finite quaternion.
pub fn quat_from_wxyz(q: &[f64; 4]) -> Result<DQuat> {
    let n2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
    // Already unit to rounding (the common case inside kinema): dividing would change nothing
    // beyond 2 ulp, and repeated products cannot drift further than this bound.
    if (n2 - 1.0).abs() <= 4.0 * f64::EPSILON {
        return Ok(DQuat::from_xyzw(q[1], q[2], q[3], q[0]));
    }
    // A normal, finite squared norm (NaN and infinity fail `is_normal`).
    if n2.is_normal() && n2 < 1e300 {
        let inv = 1.0 / n2.sqrt();
        return Ok(DQuat::from_xyzw(q[1] * inv, q[2] * inv, q[3] * inv, q[0] * inv));
    }
    ensure_finite("quat", q)?;
    let m = q.iter().fold(0.0_f64, |m, c| m.max(c.abs()));
    if m == 0.0 {
        return Err(Error::invalid("quat", "is zero; a rotation needs a non-zero quaternion"));
    }
    let q = q.map(|c| c / m);
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    Ok(DQuat::from_xyzw(q[1] / n, q[2] / n, q[3] / n, q[0] / n))
}

/// Scalar-first components `(w, x, y, z)` of `q`.
pub fn quat_to_wxyz(q: DQuat) -> [f64; 4] {
    [q.w, q.x, q.y, q.z]
}

/// The representative of `{q, -q}` with `w > 0`; when `w == 0`, the first non-zero of
/// `x, y, z` is made positive (the same rule as scipy's `canonical=True`).
pub fn canonical(q: DQuat) -> DQuat {
    let first_nonzero = [q.w, q.x, q.y, q.z].into_iter().find(|c| *c != 0.0).unwrap_or(1.0);
    if first_nonzero < 0.0 {
        -q
    } else {
        q
    }
}

/// The rotation angle of unit quaternion `q` in radians, in `[0, pi]`:
/// `2 atan2(|v|, |w|)`, accurate for tiny angles (down to subnormal ones: `|v|` is formed
/// with `hypot`, which does not underflow) and near pi alike.
pub fn rotation_angle(q: DQuat) -> f64 {
    2.0 * q.x.hypot(q.y).hypot(q.z).atan2(q.w.abs())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normalises_tiny_and_huge_quaternions() {
        for s in [1e-200, 1e-310, 1e200, 1e307] {
            let q = quat_from_wxyz(&[s, s, 0.0, 0.0]).unwrap();
            assert!((q.w - 0.5_f64.sqrt()).abs() < 1e-15 && (q.x - q.w).abs() < 1e-15, "{s}");
        }
        assert!(quat_from_wxyz(&[0.0; 4]).is_err());
        assert!(quat_from_wxyz(&[f64::NAN, 1.0, 0.0, 0.0]).is_err());
    }

    #[test]
    fn canonical_sign() {
        let q = DQuat::from_xyzw(-1.0, 0.0, 0.0, 0.0);
        assert_eq!(quat_to_wxyz(canonical(q)), [0.0, 1.0, 0.0, 0.0]);
        let q = DQuat::from_xyzw(0.6, 0.0, 0.0, -0.8);
        assert_eq!(quat_to_wxyz(canonical(q)), [0.8, -0.6, -0.0, -0.0]);
    }
}
