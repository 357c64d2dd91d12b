//! One-sided Jacobi SVD of a small dense Jacobian, in place and without allocation.
//!
//! Hestenes' method (M. R. Hestenes, "Inversion of matrices by biorthogonalization and
//! related results", J. SIAM 6(1), 1958; analysed by Demmel & Veselić, "Jacobi's method is
//! more accurate than QR", SIAM J. Matrix Anal. Appl. 13(4), 1992): plane rotations applied to
//! the `m` rows of `J` (each of length `n`, the number of joint variables) make them mutually
//! orthogonal. With `Jᵀ V = W` and `W` of orthogonal columns `wᵢ = σᵢ uᵢ`,
//! `J = Σᵢ σᵢ vᵢ uᵢᵀ`: `vᵢ` (the columns of `V`, task space) and `uᵢ` (joint space) are the
//! singular vectors. The solvers only ever need `wᵢ`, `σᵢ² = |wᵢ|²` and `vᵢ`, so nothing else
//! is formed. The task dimension `m` is small (3 or 6 per end effector), which makes the
//! `m²/2` rotations per sweep cheap; each sweep costs `O(m² n)`.
//!
//! nalgebra's SVD (the oracle of the tests) allocates its factors on every call; this one
//! works in the solver's preallocated buffers, so an IK iteration allocates nothing.

/// Orthogonalise the `m` rows of `a` (row-major `m x n`) in place; `v` (row-major `m x m`)
/// receives the rotations (`V`), `sigma2[i]` the squared norm of row `i` (`σᵢ²`).
pub(crate) fn jacobi_rows(a: &mut [f64], m: usize, n: usize, v: &mut [f64], sigma2: &mut [f64]) {
    v[..m * m].fill(0.0);
    for i in 0..m {
        v[i * m + i] = 1.0;
    }
    for _sweep in 0..60 {
        let mut rotated = false;
        for i in 0..m {
            for j in i + 1..m {
                let (mut alpha, mut beta, mut gamma) = (0.0, 0.0, 0.0);
                for k in 0..n {
                    let (x, y) = (a[i * n + k], a[j * n + k]);
                    alpha += x * x;
                    beta += y * y;
                    gamma += x * y;
                }
                if gamma == 0.0 || gamma.abs() <= 1e-15 * (alpha * beta).sqrt() {
                    continue;
                }
                rotated = true;
                let zeta = (beta - alpha) / (2.0 * gamma);
                let t = zeta.signum() / (zeta.abs() + (1.0 + zeta * zeta).sqrt());
                let c = 1.0 / (1.0 + t * t).sqrt();
                let s = c * t;
                for k in 0..n {
                    let (x, y) = (a[i * n + k], a[j * n + k]);
                    a[i * n + k] = c * x - s * y;
                    a[j * n + k] = s * x + c * y;
                }
                for k in 0..m {
                    let (x, y) = (v[k * m + i], v[k * m + j]);
                    v[k * m + i] = c * x - s * y;
                    v[k * m + j] = s * x + c * y;
                }
            }
        }
        if !rotated {
            break;
        }
    }
    for (i, s2) in sigma2[..m].iter_mut().enumerate() {
        *s2 = a[i * n..(i + 1) * n].iter().map(|x| x * x).sum();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;

    #[test]
    fn singular_values_and_reconstruction_match_nalgebra() {
        let (m, n) = (6, 9);
        let j: Vec<f64> = (0..m * n).map(|k| ((k * 7919 % 101) as f64 / 50.0) - 1.0).collect();
        let mut a = j.clone();
        let (mut v, mut s2) = (vec![0.0; m * m], vec![0.0; m]);
        jacobi_rows(&mut a, m, n, &mut v, &mut s2);
        let mut ours: Vec<f64> = s2.iter().map(|x| x.sqrt()).collect();
        ours.sort_by(|x, y| y.total_cmp(x));
        let theirs = DMatrix::from_row_slice(m, n, &j).singular_values();
        for (x, y) in ours.iter().zip(theirs.iter()) {
            assert!((x - y).abs() < 1e-13 * theirs[0], "{ours:?} vs {theirs}");
        }
        // J = V W (rows of W = the orthogonalised rows).
        for r in 0..m {
            for c in 0..n {
                let rec: f64 = (0..m).map(|i| v[r * m + i] * a[i * n + c]).sum();
                assert!((rec - j[r * n + c]).abs() < 1e-13);
            }
        }
    }
}
