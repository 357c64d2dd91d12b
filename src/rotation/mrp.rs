//! Modified Rodrigues parameters `p = n tan(θ/4)` (Schaub & Junkins, "Analytical Mechanics of
//! Space Systems", 2003, sec. 3.8): finite for every rotation, norm at most 1 on the
//! shorter-angle representation.

use crate::batch::{by_component, by_vector, lanes, on_row, LaneKernel, Output, LANES};
use crate::error::{ensure_finite, Result};
use crate::rotation::{quat_from_wxyz, quat_to_wxyz};
use glam::{DQuat, DVec3};

/// The MRPs of `q` taken with `w >= 0` (angle in `[0, π]`, so `|p| <= 1`): `v / (1 + w)`.
pub fn quat_to_mrp(q: DQuat) -> [f64; 3] {
    on_row([q.w, q.x, q.y, q.z], to_mrp)
}

/// [`quat_to_mrp`] on the components `[w, x, y, z]` of unit quaternions, one vector of
/// `simd`'s lanes each: the arithmetic that the row function (`pulp::Scalar`) and the lanes
/// of [`quats_to_mrps`] share.
#[inline(always)]
fn to_mrp<S: pulp::Simd>(simd: S, [w, x, y, z]: [S::f64s; 4]) -> [S::f64s; 3] {
    let one = simd.splat_f64s(1.0);
    let sign =
        simd.select_f64s(simd.less_than_f64s(w, simd.splat_f64s(0.0)), simd.splat_f64s(-1.0), one);
    let s = simd.div_f64s(one, simd.add_f64s(one, simd.mul_f64s(sign, w)));
    [x, y, z].map(|v| simd.mul_f64s(simd.mul_f64s(sign, v), s))
}

/// The rotation of MRPs `p` (any finite 3-vector; `p` and its shadow `-p/|p|²` give the same
/// rotation): `q = ((1 - |p|²), 2p) / (1 + |p|²)`.
///
/// # Errors
/// [`crate::Error::InvalidInput`] (argument `mrp`) for a non-finite vector.
pub fn quat_from_mrp(p: &[f64; 3]) -> Result<DQuat> {
    ensure_finite("mrp", p)?;
    let n2 = squared_norm(p);
    if !n2.is_finite() {
        // Beyond 1e154: the shadow set -p/|p|² is the same rotation and small.
        let v = DVec3::from_array(*p);
        let u = v / v.length();
        return quat_from_mrp(&(-u / v.length()).to_array());
    }
    let [w, x, y, z] = on_row([p[0], p[1], p[2], n2], from_mrp);
    Ok(DQuat::from_xyzw(x, y, z, w))
}

#[inline(always)]
fn squared_norm(p: &[f64; 3]) -> f64 {
    p[0] * p[0] + p[1] * p[1] + p[2] * p[2]
}

/// [`quat_from_mrp`] of MRPs by component `[x, y, z]` with their finite squared norm `n2`,
/// one vector of `simd`'s lanes each, as `(w, x, y, z)`: the arithmetic that the row function
/// (`pulp::Scalar`) and the lanes of [`mrps_to_quats`] share (the result normalised once more,
/// so that it is unit to rounding; separate multiplies and adds, no fused multiply-add).
#[inline(always)]
fn from_mrp<S: pulp::Simd>(simd: S, [x, y, z, n2]: [S::f64s; 4]) -> [S::f64s; 4] {
    let one = simd.splat_f64s(1.0);
    let s = simd.div_f64s(one, simd.add_f64s(one, n2));
    let two_s = simd.mul_f64s(simd.splat_f64s(2.0), s);
    let q = [
        simd.mul_f64s(simd.sub_f64s(one, n2), s),
        simd.mul_f64s(two_s, x),
        simd.mul_f64s(two_s, y),
        simd.mul_f64s(two_s, z),
    ];
    let sq = |v| simd.mul_f64s(v, v);
    let norm2 = simd.add_f64s(simd.add_f64s(simd.add_f64s(sq(q[0]), sq(q[1])), sq(q[2])), sq(q[3]));
    let inv = simd.div_f64s(one, simd.sqrt_f64s(norm2));
    q.map(|c| simd.mul_f64s(c, inv))
}

/// [`quat_to_mrp`] of every row of `quats` (`(w, x, y, z)`, taken by [`quat_from_wxyz`]) into
/// `out`, in parallel. Blocks of 8 rows that are unit to rounding run lane by lane (SIMD
/// through `pulp`), bitwise the row-by-row function.
///
/// # Errors
/// The lowest row that is zero or not finite, or `out` of another length.
pub fn quats_to_mrps(quats: &[[f64; 4]], out: &mut (impl Output<3> + ?Sized)) -> Result<()> {
    lanes(quats, out, &ToMrps)?;
    Ok(())
}

/// The lane kernel of [`quats_to_mrps`].
struct ToMrps;

impl LaneKernel<4, 3> for ToMrps {
    #[inline(always)]
    fn block<S: pulp::Simd>(
        &self,
        simd: S,
        first: usize,
        qs: &[[f64; 4]],
        os: &mut [[f64; 3]],
    ) -> Result<usize> {
        if qs.len() == LANES {
            let c = by_component(qs);
            let mut unit = [false; LANES];
            for k in 0..LANES {
                let n2 =
                    c[0][k] * c[0][k] + c[1][k] * c[1][k] + c[2][k] * c[2][k] + c[3][k] * c[3][k];
                // quat_from_wxyz takes such a row as it is.
                unit[k] = (n2 - 1.0).abs() <= 4.0 * f64::EPSILON;
            }
            if unit.iter().all(|&u| u) {
                let p = by_vector(simd, &c, |q| to_mrp(simd, q));
                for (k, o) in os.iter_mut().enumerate() {
                    *o = [p[0][k], p[1][k], p[2][k]];
                }
                return Ok(0);
            }
        }
        for (k, (q, o)) in qs.iter().zip(os.iter_mut()).enumerate() {
            *o = quat_to_mrp(quat_from_wxyz(q).map_err(|e| e.at(first + k))?);
        }
        Ok(0)
    }
}

/// [`quat_from_mrp`] of every row of `mrps` into `out` as `(w, x, y, z)`, in parallel. Blocks
/// of 8 rows with finite squared norms run lane by lane (SIMD through `pulp`), bitwise the
/// row-by-row function.
///
/// # Errors
/// The lowest row that is not finite, or `out` of another length.
pub fn mrps_to_quats(mrps: &[[f64; 3]], out: &mut (impl Output<4> + ?Sized)) -> Result<()> {
    lanes(mrps, out, &FromMrps)?;
    Ok(())
}

/// The lane kernel of [`mrps_to_quats`].
struct FromMrps;

impl LaneKernel<3, 4> for FromMrps {
    #[inline(always)]
    fn block<S: pulp::Simd>(
        &self,
        simd: S,
        first: usize,
        ps: &[[f64; 3]],
        os: &mut [[f64; 4]],
    ) -> Result<usize> {
        if ps.len() == LANES {
            let c = by_component(ps);
            let mut n2 = [0.0; LANES];
            for k in 0..LANES {
                n2[k] = squared_norm(&[c[0][k], c[1][k], c[2][k]]);
            }
            // A finite squared norm has finite components: the row function's first branch.
            if n2.iter().all(|n| n.is_finite()) {
                let [x, y, z] = c;
                let q = by_vector(simd, &[x, y, z, n2], |p| from_mrp(simd, p));
                for (k, o) in os.iter_mut().enumerate() {
                    *o = [q[0][k], q[1][k], q[2][k], q[3][k]];
                }
                return Ok(0);
            }
        }
        for (k, (p, o)) in ps.iter().zip(os.iter_mut()).enumerate() {
            *o = quat_to_wxyz(quat_from_mrp(p).map_err(|e| e.at(first + k))?);
        }
        Ok(0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_quarter_angle_tangent() {
        let q = DQuat::from_axis_angle(DVec3::new(0.0, 0.6, 0.8), 2.0);
        let p = quat_to_mrp(q);
        assert!((DVec3::from_array(p).length() - 0.5_f64.tan()).abs() < 1e-15);
        assert!(quat_from_mrp(&p).unwrap().dot(q).abs() > 1.0 - 1e-15);
        // The half turn has |p| = 1; a huge p is its shadow.
        assert!((quat_to_mrp(DQuat::from_rotation_x(std::f64::consts::PI))[0] - 1.0).abs() < 1e-15);
        assert!(
            quat_from_mrp(&[1e200, 0.0, 0.0]).unwrap().dot(DQuat::IDENTITY).abs() > 1.0 - 1e-15
        );
        assert!(quat_from_mrp(&[f64::NAN, 0.0, 0.0]).is_err());
    }
}
