//! Unit quaternions at the array boundary: checked construction from `(w, x, y, z)`,
//! normalisation that neither overflows nor underflows, the canonical sign, the angle.

use crate::batch::{by_component, lanes, lanes2, map2, LaneKernel, PairKernel, LANES};
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

/// [`quat_from_wxyz`] of every row of `quats` (`(w, x, y, z)`), made [`canonical`] if asked,
/// into `out`, in parallel. Blocks of 8 rows whose squared norms are normal numbers below
/// `1e300` run lane by lane (SIMD through `pulp`), bitwise the row-by-row function.
///
/// # Errors
/// The lowest row that is zero or not finite, or `out` of another length.
pub fn normalize_quats(quats: &[[f64; 4]], canonical: bool, out: &mut [[f64; 4]]) -> Result<()> {
    lanes(quats, out, &Normalize { canonical })?;
    Ok(())
}

/// The lane kernel of [`normalize_quats`].
struct Normalize {
    canonical: bool,
}

impl LaneKernel<4, 4> for Normalize {
    #[inline(always)]
    fn block(&self, first: usize, qs: &[[f64; 4]], os: &mut [[f64; 4]]) -> Result<usize> {
        if qs.len() == LANES && !self.canonical {
            let c = by_component(qs);
            let mut n2 = [0.0; LANES];
            for k in 0..LANES {
                n2[k] =
                    c[0][k] * c[0][k] + c[1][k] * c[1][k] + c[2][k] * c[2][k] + c[3][k] * c[3][k];
            }
            // The two first branches of quat_from_wxyz, as selects.
            if n2.iter().all(|&n| n.is_normal() && n < 1e300) {
                let mut q = [[0.0; LANES]; 4];
                for k in 0..LANES {
                    let unit = (n2[k] - 1.0).abs() <= 4.0 * f64::EPSILON;
                    let inv = 1.0 / n2[k].sqrt();
                    for (lane, comp) in q.iter_mut().zip(&c) {
                        lane[k] = if unit { comp[k] } else { comp[k] * inv };
                    }
                }
                for (k, o) in os.iter_mut().enumerate() {
                    *o = std::array::from_fn(|e| q[e][k]);
                }
                return Ok(0);
            }
        }
        for (k, (q, o)) in qs.iter().zip(os.iter_mut()).enumerate() {
            let q = quat_from_wxyz(q).map_err(|e| e.at(first + k))?;
            *o = quat_to_wxyz(if self.canonical { canonical(q) } else { q });
        }
        Ok(0)
    }
}

/// The products `a[i] b[i]` (Hamilton) of quaternions `(w, x, y, z)` (normalised as
/// [`quat_from_wxyz`] does), a batch of one broadcast against N, into `out`, in parallel.
/// Blocks of 8 unit pairs run lane by lane (SIMD through `pulp`), bitwise the row-by-row
/// product.
///
/// # Errors
/// The lowest row that is zero or not finite; lengths that do not broadcast.
pub fn multiply_quats(a: &[[f64; 4]], b: &[[f64; 4]], out: &mut [[f64; 4]]) -> Result<()> {
    if a.len() == b.len() {
        lanes2(a, b, out, &Multiply)?;
        return Ok(());
    }
    map2(a, b, out, |x, y| Ok(quat_to_wxyz(quat_from_wxyz(x)? * quat_from_wxyz(y)?)))
}

/// The lane kernel of [`multiply_quats`].
struct Multiply;

impl PairKernel<4, 4, 4> for Multiply {
    #[inline(always)]
    fn block(
        &self,
        first: usize,
        a: &[[f64; 4]],
        b: &[[f64; 4]],
        os: &mut [[f64; 4]],
    ) -> Result<usize> {
        if a.len() == LANES {
            let (ca, cb) = (by_component(a), by_component(b));
            let mut off = [0.0; LANES];
            for k in 0..LANES {
                let na = ca[0][k] * ca[0][k]
                    + ca[1][k] * ca[1][k]
                    + ca[2][k] * ca[2][k]
                    + ca[3][k] * ca[3][k];
                let nb = cb[0][k] * cb[0][k]
                    + cb[1][k] * cb[1][k]
                    + cb[2][k] * cb[2][k]
                    + cb[3][k] * cb[3][k];
                off[k] = (na - 1.0).abs().max((nb - 1.0).abs());
            }
            // Unit to rounding: quat_from_wxyz would take them unchanged.
            if off.iter().all(|&d| d <= 4.0 * f64::EPSILON) {
                let mut p = [[0.0; LANES]; 4];
                for k in 0..LANES {
                    let qa = DQuat::from_xyzw(ca[1][k], ca[2][k], ca[3][k], ca[0][k]);
                    let qb = DQuat::from_xyzw(cb[1][k], cb[2][k], cb[3][k], cb[0][k]);
                    for (lane, v) in p.iter_mut().zip(quat_to_wxyz(qa * qb)) {
                        lane[k] = v;
                    }
                }
                for (k, o) in os.iter_mut().enumerate() {
                    *o = std::array::from_fn(|e| p[e][k]);
                }
                return Ok(0);
            }
        }
        for (k, ((x, y), o)) in a.iter().zip(b).zip(os.iter_mut()).enumerate() {
            let product = quat_from_wxyz(x).and_then(|x| Ok(x * quat_from_wxyz(y)?));
            *o = quat_to_wxyz(product.map_err(|e| e.at(first + k))?);
        }
        Ok(0)
    }
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
