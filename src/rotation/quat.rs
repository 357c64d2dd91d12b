//! Unit quaternions at the array boundary: checked construction from `(w, x, y, z)`,
//! normalisation that neither overflows nor underflows, the canonical sign, the angle.

use crate::batch::{by_component, lanes, lanes2, map2, LaneKernel, Output, PairKernel, LANES};
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
pub fn normalize_quats(
    quats: &[[f64; 4]],
    canonical: bool,
    out: &mut (impl Output<4> + ?Sized),
) -> Result<()> {
    lanes(quats, out, &Normalize { canonical })?;
    Ok(())
}

/// The lane kernel of [`normalize_quats`].
struct Normalize {
    canonical: bool,
}

impl LaneKernel<4, 4> for Normalize {
    #[inline(always)]
    fn block<S: pulp::Simd>(
        &self,
        _: S,
        first: usize,
        qs: &[[f64; 4]],
        os: &mut [[f64; 4]],
    ) -> Result<usize> {
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

/// The products `a[i] b[i]` (Hamilton) of quaternions `(w, x, y, z)`, a batch of one
/// broadcast against N, into `out`, in parallel.
///
/// Each product is the product of the normalised inputs ([`quat_from_wxyz`]): a pair whose
/// plain product is unit to 32 ulp in its squared norm (every pair of unit quaternions, whose
/// product is then bitwise glam's `DQuat * DQuat`) keeps that product; any other pair is
/// normalised first. Blocks of 8 rows multiply row by row and check the 8 norms lane by lane
/// (SIMD through `pulp`); the result does not depend on how rows fall into blocks.
///
/// # Errors
/// The lowest row that is zero or not finite; lengths that do not broadcast.
pub fn multiply_quats(
    a: &[[f64; 4]],
    b: &[[f64; 4]],
    out: &mut (impl Output<4> + ?Sized),
) -> Result<()> {
    if a.len() == b.len() {
        lanes2(a, b, out, &Multiply)?;
        return Ok(());
    }
    map2(a, b, out, multiply)
}

/// The plain Hamilton product `a b`: glam's `DQuat * DQuat` term by term in its order
/// (bitwise the same), on scalar-first rows.
#[inline(always)]
fn product(a: &[f64; 4], b: &[f64; 4]) -> [f64; 4] {
    let ([w0, x0, y0, z0], [w1, x1, y1, z1]) = (*a, *b);
    [
        w0 * w1 - x0 * x1 - y0 * y1 - z0 * z1,
        w0 * x1 + x0 * w1 + y0 * z1 - z0 * y1,
        w0 * y1 - x0 * z1 + y0 * w1 + z0 * x1,
        w0 * z1 + x0 * y1 - y0 * x1 + z0 * w1,
    ]
}

/// How far a plain product's squared norm may be from 1 (in units of `f64::EPSILON`) for
/// [`multiply_quats`] to keep it: two unit quaternions (to 4 ulp, as [`quat_from_wxyz`]
/// takes them) give at most about 20.
const PRODUCT_UNIT_ULP: f64 = 32.0;

/// One row of [`multiply_quats`].
fn multiply(a: &[f64; 4], b: &[f64; 4]) -> Result<[f64; 4]> {
    let p = product(a, b);
    let n2 = p[0] * p[0] + p[1] * p[1] + p[2] * p[2] + p[3] * p[3];
    if (n2 - 1.0).abs() <= PRODUCT_UNIT_ULP * f64::EPSILON {
        return Ok(p);
    }
    Ok(quat_to_wxyz(quat_from_wxyz(a)? * quat_from_wxyz(b)?))
}

/// The lane kernel of [`multiply_quats`].
struct Multiply;

impl PairKernel<4, 4, 4> for Multiply {
    #[inline(always)]
    fn block<S: pulp::Simd>(
        &self,
        _: S,
        first: usize,
        a: &[[f64; 4]],
        b: &[[f64; 4]],
        os: &mut [[f64; 4]],
    ) -> Result<usize> {
        if a.len() == LANES {
            // Products row by row (this compiles well on interleaved rows), norms lane by lane.
            for ((x, y), o) in a.iter().zip(b).zip(os.iter_mut()) {
                *o = product(x, y);
            }
            let c = by_component(os);
            let off: [f64; LANES] = std::array::from_fn(|k| {
                let n2 =
                    c[0][k] * c[0][k] + c[1][k] * c[1][k] + c[2][k] * c[2][k] + c[3][k] * c[3][k];
                (n2 - 1.0).abs()
            });
            if off.iter().all(|&d| d <= PRODUCT_UNIT_ULP * f64::EPSILON) {
                return Ok(0);
            }
        }
        for (k, ((x, y), o)) in a.iter().zip(b).zip(os.iter_mut()).enumerate() {
            *o = multiply(x, y).map_err(|e| e.at(first + k))?;
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
