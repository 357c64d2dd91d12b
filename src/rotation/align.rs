//! The rotation that best aligns two sets of vectors: Wahba's problem, `min_C Σ wᵢ |aᵢ - C bᵢ|²`
//! over rotations `C`, solved by the SVD of the attitude profile matrix `B = Σ wᵢ aᵢ bᵢᵀ`
//! (Markley 1988, "Attitude determination using vector observations and the singular value
//! decomposition", J. Astronautical Sciences 36(3): `C = U diag(1, 1, det U det V) Vᵀ`, and the
//! covariance of the rotation-vector error, eq. 38 there, as the sensitivity matrix), or, with
//! one primary pair of infinite weight, the rotation that maps the primary `b` exactly onto the
//! primary `a` and then turns about it to best align the rest.

use crate::batch::sum;
use crate::error::{ensure_finite, Error, Result};
use crate::math::svd::jacobi_rows;
use glam::{DQuat, DVec3};
use nalgebra::Matrix3;

/// The solution of [`align_vectors`].
#[derive(Debug, Clone, Copy)]
pub struct Alignment {
    /// `C` as a unit quaternion, `a ≈ C b`.
    pub rotation: DQuat,
    /// `sqrt(Σ wᵢ |aᵢ - C bᵢ|²)` over the pairs of finite weight.
    pub rssd: f64,
    /// The 3x3 sensitivity (row-major): the covariance of the rotation vector of `C`'s error
    /// per unit variance of the vectors, scaled by the mean weight; `None` with a primary pair.
    pub sensitivity: Option<[f64; 9]>,
    /// Whether `C` is not unique (the vectors span at most a line: the second and third
    /// singular values vanish against the first).
    pub degenerate: bool,
}

/// The rotation `C` minimising `Σ wᵢ |aᵢ - C bᵢ|²` (Markley 1988). One pair may have infinite
/// weight (the primary pair, aligned exactly: shortest arc from `b` to `a`, then the turn about
/// `a` that best aligns the projections of the others); a single pair is always primary.
///
/// # Errors
/// [`Error::InvalidInput`] naming `a`, `b` or `weights`: non-finite vectors, lengths that
/// differ, no vectors, a negative or NaN weight, more than one infinite weight, or a primary
/// vector of length zero.
pub fn align_vectors(a: &[[f64; 3]], b: &[[f64; 3]], weights: &[f64]) -> Result<Alignment> {
    if a.is_empty() || a.len() != b.len() || weights.len() != a.len() {
        return Err(Error::invalid(
            "b",
            "must hold as many vectors as a (at least one), and weights one per vector",
        ));
    }
    // Σ w a bᵀ (row-major), Σ w (|a|² + |b|²), Σ w over the finite weights, and the number
    // of infinite ones, in one pass that checks every input.
    let s = sum(a.len(), |range| {
        let (mut acc, mut fine) = ([0.0; 12], true);
        for k in range.clone() {
            let (x, y, w) = (a[k], b[k], weights[k]);
            fine &= x.iter().chain(&y).all(|c| c.is_finite()) && w >= 0.0 && w.is_finite();
            add_pair(&mut acc, x, y, w);
        }
        if !fine {
            acc = [0.0; 12];
            for k in range {
                let (x, y, w) = (a[k], b[k], weights[k]);
                ensure_finite("a", &x).map_err(|e| e.at(k))?;
                ensure_finite("b", &y).map_err(|e| e.at(k))?;
                if w.is_nan() || w < 0.0 {
                    return Err(Error::invalid("weights", "must be non-negative").at(k));
                }
                if w == f64::INFINITY {
                    acc[11] += 1.0;
                } else {
                    add_pair(&mut acc, x, y, w);
                }
            }
        }
        Ok(acc)
    })?;
    let infinite = weights.iter().position(|w| *w == f64::INFINITY);
    match (s[11], a.len()) {
        (0.0, 1) => primary(a, b, weights, 0),
        (0.0, _) => Ok(kabsch(&s, a.len())),
        (1.0, _) => primary(a, b, weights, infinite.unwrap_or(0)),
        _ => Err(Error::invalid("weights", "may hold at most one infinite weight")),
    }
}

/// Add `w x yᵀ` (row-major), `w (|x|² + |y|²)` and `w` to `acc[..11]`.
#[inline(always)]
fn add_pair(acc: &mut [f64; 12], x: [f64; 3], y: [f64; 3], w: f64) {
    for (i, &xi) in x.iter().enumerate() {
        for (j, &yj) in y.iter().enumerate() {
            acc[3 * i + j] += w * xi * yj;
        }
    }
    let norms = x[0] * x[0] + x[1] * x[1] + x[2] * x[2] + y[0] * y[0] + y[1] * y[1] + y[2] * y[2];
    acc[9] += w * norms;
    acc[10] += w;
}

/// The least-squares rotation from the sums of [`align_vectors`]'s pass over `n` pairs:
/// `B = Σ w a bᵀ` (`sums[..9]`), `Σ w (|a|² + |b|²)` (`sums[9]`) and `Σ w` (`sums[10]`).
fn kabsch(sums: &[f64; 12], n: usize) -> Alignment {
    let m = Matrix3::from_row_slice(&sums[..9]);
    let sq = sums[9];
    // The SVD by one-sided Jacobi rotations (accurate for the small singular values even when
    // the weights span many orders of magnitude, where nalgebra's bidiagonal SVD loses them):
    // with the rows of B orthogonalised, B = Σ σᵢ vᵢ uᵢᵀ, vᵢ the columns of V.
    let mut rows = [0.0; 9];
    for (k, r) in rows.iter_mut().enumerate() {
        *r = m[(k / 3, k % 3)];
    }
    let (mut v, mut s2) = ([0.0; 9], [0.0; 3]);
    jacobi_rows(&mut rows, 3, 3, &mut v, &mut s2);
    let mut order = [0, 1, 2];
    order.sort_by(|&i, &j| s2[j].total_cmp(&s2[i]));
    let left = order.map(|i| DVec3::new(v[i], v[3 + i], v[6 + i]));
    let w = order.map(|i| DVec3::new(rows[3 * i], rows[3 * i + 1], rows[3 * i + 2]));
    let sigma = order.map(|i| s2[i].sqrt());
    // Right singular vectors: u1, u2 made orthonormal, u3 = u1 x u2 (defined even when the
    // vectors span less than 3 dimensions).
    let u1 = if sigma[0] > 0.0 { w[0] / w[0].length() } else { DVec3::X };
    let u2 = w[1] - w[1].dot(u1) * u1;
    let u2 = if u2.length() > 0.0 { u2 / u2.length() } else { u1.any_orthonormal_vector() };
    let u3 = u1.cross(u2);
    let d = left[0].cross(left[1]).dot(left[2]).signum();
    // σ3 signed as in the factorisation with proper U and the flip that makes C a rotation.
    let s = [sigma[0], sigma[1], d * w[2].dot(u3)];
    let outer = |x: DVec3, y: DVec3| glam::DMat3::from_cols(x * y.x, x * y.y, x * y.z);
    let c = outer(left[0], u1) + outer(left[1], u2) + outer(d * left[2], u3);
    let rotation = DQuat::from_mat3(&c).normalize();
    let rssd = (sq - 2.0 * (s[0] + s[1] + s[2])).max(0.0).sqrt();
    let zeta = (s[0] + s[1]) * (s[1] + s[2]) * (s[2] + s[0]);
    let kappa = s[0] * s[1] + s[1] * s[2] + s[2] * s[0];
    let mean_w = sums[10] / n as f64;
    let cov = (Matrix3::identity() * kappa + m * m.transpose()) * (mean_w / zeta);
    let sensitivity = std::array::from_fn(|k| cov[(k / 3, k % 3)]);
    Alignment {
        rotation,
        rssd,
        sensitivity: Some(sensitivity),
        degenerate: s[1] + s[2] < 1e-16 * s[0],
    }
}

fn primary(a: &[[f64; 3]], b: &[[f64; 3]], weights: &[f64], p: usize) -> Result<Alignment> {
    let (a0, b0) = (DVec3::from_array(a[p]), DVec3::from_array(b[p]));
    if a0.length() == 0.0 || b0.length() == 0.0 {
        return Err(Error::invalid("a", "primary vectors must be non-zero").at(p));
    }
    let (a0, b0) = (a0 / a0.length(), b0 / b0.length());
    // Shortest arc b0 -> a0 (any half turn when they are opposite).
    let first = DQuat::from_rotation_arc(b0, a0);
    let (mut num, mut den) = (0.0, 0.0);
    for k in (0..a.len()).filter(|&k| k != p) {
        let (x, y) = (DVec3::from_array(a[k]), first * DVec3::from_array(b[k]));
        let (px, py) = (x - x.dot(a0) * a0, y - y.dot(a0) * a0);
        num += weights[k] * py.cross(px).dot(a0);
        den += weights[k] * py.dot(px);
    }
    let rotation = (DQuat::from_axis_angle(a0, num.atan2(den)) * first).normalize();
    let rssd = (0..a.len())
        .filter(|&k| k != p)
        .map(|k| {
            weights[k]
                * (DVec3::from_array(a[k]) - rotation * DVec3::from_array(b[k])).length_squared()
        })
        .sum::<f64>()
        .sqrt();
    Ok(Alignment { rotation, rssd, sensitivity: None, degenerate: false })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_a_rotation_from_exact_and_noisy_pairs() {
        let c = DQuat::from_axis_angle(DVec3::new(0.3, -0.4, 0.5).normalize(), 2.5);
        let b = [[1.0, 0.2, -0.3], [0.0, 1.0, 0.5], [-0.7, 0.1, 2.0], [0.3, 0.3, 0.3]];
        let a = b.map(|y| (c * DVec3::from_array(y)).to_array());
        let got = align_vectors(&a, &b, &[1.0; 4]).unwrap();
        assert!(got.rotation.dot(c).abs() > 1.0 - 1e-15 && got.rssd < 1e-7);
        // A reflection is not a rotation: its best rotation leaves a residual.
        let mirrored = b.map(|y| [-y[0], y[1], y[2]]);
        assert!(align_vectors(&mirrored, &b, &[1.0; 4]).unwrap().rssd > 0.1);
        // The primary pair is aligned exactly whatever the other weights.
        let mut bent = a;
        bent[1] = [5.0, 5.0, 5.0];
        let got = align_vectors(&bent, &b, &[f64::INFINITY, 1.0, 1.0, 1.0]).unwrap();
        let b0 = got.rotation * DVec3::from_array(b[0]).normalize();
        assert!((b0 - DVec3::from_array(a[0]).normalize()).length() < 1e-15);
        assert!(align_vectors(&a, &b, &[f64::INFINITY, f64::INFINITY, 1.0, 1.0]).is_err());
        assert!(align_vectors(&a, &b, &[-1.0, 1.0, 1.0, 1.0]).is_err());
        // Antiparallel single pair: a half turn.
        let flip = align_vectors(&[[-1.0, 0.0, 0.0]], &[[1.0, 0.0, 0.0]], &[1.0]).unwrap();
        assert!((flip.rotation * DVec3::X + DVec3::X).length() < 1e-15);
    }
}
