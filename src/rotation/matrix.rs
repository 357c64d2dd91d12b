//! Rotation matrices (row-major `[f64; 9]`) to and from unit quaternions, and the nearest
//! rotation to an arbitrary matrix.

use super::quat::quat_from_wxyz;
use crate::batch::{by_component, lanes, LaneKernel, Output, LANES};
use crate::error::{ensure_finite, Error, Result};
use glam::DQuat;
use nalgebra::Matrix3;

/// Largest entry of `|RᵀR - I|` (and `|det R - 1|`) accepted for a rotation matrix.
///
/// Matrices further from orthonormal are refused unless orthonormalisation is asked for,
/// because silently projecting them would hide a bug in the caller's data.
pub const ROTATION_MATRIX_TOL: f64 = 1e-6;

/// Row-major rotation matrix of unit quaternion `q` (the standard formula, e.g.
/// Shoemake 1985, "Animating rotation with quaternion curves", eq. in section 3).
#[inline(always)]
pub fn quat_to_matrix(q: DQuat) -> [f64; 9] {
    let (w, x, y, z) = (q.w, q.x, q.y, q.z);
    let (ww, xx, yy, zz) = (w * w, x * x, y * y, z * z);
    let (xy, xz, yz) = (x * y, x * z, y * z);
    let (wx, wy, wz) = (w * x, w * y, w * z);
    // The diagonal as `w² + x² - y² - z²` (not `1 - 2(y² + z²)`): where the exact entry is 0
    // (a quarter turn, `w² = y²`, `x = z = 0`) the terms cancel exactly instead of leaving
    // the rounding of `1 - 2·0.5…` (2.2e-16).
    [
        (ww + xx) - (yy + zz),
        2.0 * (xy - wz),
        2.0 * (xz + wy),
        2.0 * (xy + wz),
        (ww + yy) - (xx + zz),
        2.0 * (yz - wx),
        2.0 * (xz - wy),
        2.0 * (yz + wx),
        (ww + zz) - (xx + yy),
    ]
}

/// [`quat_to_matrix`] of every quaternion `(w, x, y, z)` of `quats` (normalised as
/// [`quat_from_wxyz`] does) into `out`, in parallel; bitwise the same as row by row (blocks
/// of 8 unit quaternions run lane by lane, which vectorises: AVX2 or AVX-512 through `pulp` where the
/// CPU has it; other blocks row by row).
///
/// # Errors
/// The lowest row that is zero or not finite, or `out` of another length.
pub fn quats_to_matrices(quats: &[[f64; 4]], out: &mut (impl Output<9> + ?Sized)) -> Result<()> {
    lanes(quats, out, &ToMatrices)?;
    Ok(())
}

/// The lane kernel of [`quats_to_matrices`].
struct ToMatrices;

impl LaneKernel<4, 9> for ToMatrices {
    #[inline(always)]
    fn block<S: pulp::Simd>(
        &self,
        _: S,
        first: usize,
        qs: &[[f64; 4]],
        os: &mut [[f64; 9]],
    ) -> Result<usize> {
        if qs.len() == LANES {
            let c = by_component(qs);
            let mut off = [0.0; LANES];
            for k in 0..LANES {
                let n2 =
                    c[0][k] * c[0][k] + c[1][k] * c[1][k] + c[2][k] * c[2][k] + c[3][k] * c[3][k];
                off[k] = (n2 - 1.0).abs();
            }
            // Unit to rounding: quat_from_wxyz would take them unchanged.
            if off.iter().all(|&d| d <= 4.0 * f64::EPSILON) {
                let mut m = [[0.0; LANES]; 9];
                for k in 0..LANES {
                    let q = DQuat::from_xyzw(c[1][k], c[2][k], c[3][k], c[0][k]);
                    for (lane, v) in m.iter_mut().zip(quat_to_matrix(q)) {
                        lane[k] = v;
                    }
                }
                for (k, o) in os.iter_mut().enumerate() {
                    *o = std::array::from_fn(|e| m[e][k]);
                }
                return Ok(0);
            }
        }
        for (k, (q, o)) in qs.iter().zip(os.iter_mut()).enumerate() {
            *o = quat_to_matrix(quat_from_wxyz(q).map_err(|e| e.at(first + k))?);
        }
        Ok(0)
    }
}

/// Whether row-major `m` is a rotation: `|RᵀR - I| <= tol` entry-wise and `det R > 0`.
pub fn is_rotation_matrix(m: &[f64; 9], tol: f64) -> bool {
    let r = Matrix3::from_row_slice(m);
    let e = r.transpose() * r - Matrix3::identity();
    e.amax() <= tol && (r.determinant() - 1.0).abs() <= tol
}

/// The rotation nearest to `m` in the Frobenius norm: `U diag(1, 1, det(U Vᵀ)) Vᵀ` from the
/// SVD `m = U Σ Vᵀ` (the orthogonal Procrustes solution, Higham 1989).
///
/// The nearest rotation does not depend on a positive scale of `m`, so `m` is first scaled
/// by a power of two (exactly) to a largest entry in `[1, 2)`: any finite matrix, with
/// entries as large as `1e300` or as small as subnormals, is orthonormalised without
/// overflow or underflow in the SVD.
///
/// # Errors
/// Non-finite entries, or a matrix of rank below 2 (no unique nearest rotation).
pub fn orthonormalize(m: &[f64; 9]) -> Result<[f64; 9]> {
    ensure_finite("matrix", m)?;
    let largest = m.iter().fold(0.0_f64, |a, x| a.max(x.abs()));
    if largest == 0.0 {
        return Err(Error::invalid("matrix", "has rank 0 (is zero); no nearest rotation"));
    }
    // 2^-e with e = floor(log2 largest), applied in two factors that are each representable
    // (e ranges over -1074..=1023).
    let e = largest.log2().floor() as i32;
    let (a, b) = (-e / 2, -e - (-e / 2));
    let scaled = m.map(|x| x * 2f64.powi(a) * 2f64.powi(b));
    let svd = Matrix3::from_row_slice(&scaled).svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Err(Error::invalid("matrix", "singular value decomposition failed"));
    };
    let mut s = svd.singular_values;
    s.as_mut_slice().sort_by(|a, b| b.total_cmp(a));
    if s[1] <= f64::EPSILON * s[0].max(f64::MIN_POSITIVE) {
        return Err(Error::invalid("matrix", "has rank below 2; no unique nearest rotation"));
    }
    let d = (u * v_t).determinant().signum();
    let r = u * Matrix3::from_diagonal(&nalgebra::Vector3::new(1.0, 1.0, d)) * v_t;
    let mut out = [0.0; 9];
    for (k, o) in out.iter_mut().enumerate() {
        *o = r[(k / 3, k % 3)];
    }
    Ok(out)
}

/// Unit quaternion of rotation matrix `m` (row-major).
///
/// Shepperd's method (Shepperd 1978, "Quaternion from rotation matrix", J. Guidance and
/// Control 1(3)): the largest of `4w², 4x², 4y², 4z²` is found from the trace and the diagonal
/// and the other components are taken from sums and differences of off-diagonal pairs, so no
/// square root of a small number is ever divided by.
///
/// With `orthonormalize`, `m` is first replaced by its nearest rotation ([`orthonormalize`]).
///
/// # Errors
/// Non-finite entries; a matrix further than [`ROTATION_MATRIX_TOL`] from a rotation when
/// `orthonormalize` is false.
pub fn quat_from_matrix(m: &[f64; 9], orthonormalize: bool) -> Result<DQuat> {
    ensure_finite("matrix", m)?;
    let m = if orthonormalize {
        self::orthonormalize(m)?
    } else if is_rotation_matrix(m, ROTATION_MATRIX_TOL) {
        *m
    } else {
        return Err(Error::invalid(
            "matrix",
            "is not a rotation (RᵀR != I or det <= 0); pass orthonormalize=True to project it",
        ));
    };
    let [r00, r01, r02, r10, r11, r12, r20, r21, r22] = m;
    let trace = r00 + r11 + r22;
    let (w, x, y, z) = if trace >= r00 && trace >= r11 && trace >= r22 {
        let w = 0.5 * (1.0 + trace).sqrt();
        let s = 0.25 / w;
        (w, (r21 - r12) * s, (r02 - r20) * s, (r10 - r01) * s)
    } else if r00 >= r11 && r00 >= r22 {
        let x = 0.5 * (1.0 + r00 - r11 - r22).sqrt();
        let s = 0.25 / x;
        ((r21 - r12) * s, x, (r01 + r10) * s, (r02 + r20) * s)
    } else if r11 >= r22 {
        let y = 0.5 * (1.0 - r00 + r11 - r22).sqrt();
        let s = 0.25 / y;
        ((r02 - r20) * s, (r01 + r10) * s, y, (r12 + r21) * s)
    } else {
        let z = 0.5 * (1.0 - r00 - r11 + r22).sqrt();
        let s = 0.25 / z;
        ((r10 - r01) * s, (r02 + r20) * s, (r12 + r21) * s, z)
    };
    Ok(DQuat::from_xyzw(x, y, z, w).normalize())
}
