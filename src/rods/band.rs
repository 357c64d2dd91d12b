//! A symmetric banded matrix and its `L D Lᵀ` factorisation in place (Golub & Van Loan 2013,
//! Algorithm 4.3.6, band form): `O(n k²)` work and `O(n k)` storage for half-bandwidth `k`,
//! so a rod's Newton system (half-bandwidth 10 with the degrees of freedom interleaved
//! `x0, θ0, x1, θ1, …`) is solved in time linear in its vertex count.

/// A symmetric `n × n` matrix with entries only within `k` of the diagonal, stored by its
/// lower band: row `i`, column `j` (`i - k ≤ j ≤ i`) at `i (k + 1) + (i - j)`. After
/// [`Band::factor`] the same storage holds `L` (unit diagonal, not stored) below and `D` on
/// the diagonal.
#[derive(Debug, Default)]
pub struct Band {
    n: usize,
    k: usize,
    a: Vec<f64>,
}

impl Clone for Band {
    fn clone(&self) -> Self {
        Band { n: self.n, k: self.k, a: self.a.clone() }
    }

    /// Reuses the storage (no allocation once the sizes match).
    fn clone_from(&mut self, source: &Self) {
        self.n = source.n;
        self.k = source.k;
        self.a.clone_from(&source.a);
    }
}

impl Band {
    /// Size for `n` rows of half-bandwidth `k` and set every entry to zero (allocates only
    /// when the storage grows).
    pub fn reset(&mut self, n: usize, k: usize) {
        self.n = n;
        self.k = k;
        self.a.clear();
        self.a.resize(n * (k + 1), 0.0);
    }

    /// Rows (and columns).
    pub fn len(&self) -> usize {
        self.n
    }

    /// Whether the matrix has no rows.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Entry `(i, j)` of the lower band (`j ≤ i ≤ j + k`).
    #[inline]
    pub fn get(&self, i: usize, j: usize) -> f64 {
        self.a[i * (self.k + 1) + (i - j)]
    }

    /// Add `v` to entry `(i, j)` (and, by symmetry, `(j, i)`); `|i - j| ≤ k`.
    #[inline]
    pub fn add(&mut self, i: usize, j: usize, v: f64) {
        let (i, j) = if i >= j { (i, j) } else { (j, i) };
        debug_assert!(i - j <= self.k, "({i}, {j}) outside the band");
        self.a[i * (self.k + 1) + (i - j)] += v;
    }

    /// Overwrite entry `(i, j)` (`j ≤ i ≤ j + k`).
    #[inline]
    pub fn set(&mut self, i: usize, j: usize, v: f64) {
        self.a[i * (self.k + 1) + (i - j)] = v;
    }

    /// Factor in place as `L D Lᵀ`. Returns the first row whose pivot is not positive and
    /// finite (the matrix is not positive definite), leaving the storage partly factored.
    pub fn factor(&mut self) -> Result<(), usize> {
        let (n, k, w) = (self.n, self.k, self.k + 1);
        for j in 0..n {
            // d_j = a_jj - Σ_p l_jp² d_p, then l_ij = (a_ij - Σ_p l_ip l_jp d_p) / d_j.
            let lo = j.saturating_sub(k);
            let mut d = self.a[j * w];
            for p in lo..j {
                let l = self.a[j * w + (j - p)];
                d -= l * l * self.a[p * w];
            }
            if !(d > 0.0 && d.is_finite()) {
                return Err(j);
            }
            self.a[j * w] = d;
            for i in j + 1..(j + k + 1).min(n) {
                let mut s = self.a[i * w + (i - j)];
                for p in i.saturating_sub(k)..j {
                    s -= self.a[i * w + (i - p)] * self.a[j * w + (j - p)] * self.a[p * w];
                }
                self.a[i * w + (i - j)] = s / d;
            }
        }
        Ok(())
    }

    /// Solve `A x = b` in place (`b` becomes `x`) with the factors of [`Band::factor`].
    pub fn solve(&self, b: &mut [f64]) {
        let (n, k, w) = (self.n, self.k, self.k + 1);
        for i in 0..n {
            let s: f64 = (i.saturating_sub(k)..i).map(|p| self.a[i * w + (i - p)] * b[p]).sum();
            b[i] -= s;
        }
        for (x, row) in b.iter_mut().zip(self.a.chunks_exact(w)) {
            *x /= row[0];
        }
        for i in (0..n).rev() {
            let s: f64 = (i + 1..(i + k + 1).min(n)).map(|r| self.a[r * w + (r - i)] * b[r]).sum();
            b[i] -= s;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A random SPD band matrix (diagonally dominant), solved and checked against its
    /// product; an indefinite one is refused at its first bad pivot.
    #[test]
    fn factor_and_solve_reproduce_the_right_hand_side() {
        let (n, k) = (37, 10);
        let mut seed = 12345u64;
        let mut rnd = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut m = Band::default();
        m.reset(n, k);
        let mut dense = vec![0.0; n * n];
        for i in 0..n {
            for j in i.saturating_sub(k)..i {
                let v = rnd();
                m.add(i, j, v);
                dense[i * n + j] = v;
                dense[j * n + i] = v;
            }
            m.add(i, i, 12.0);
            dense[i * n + i] = 12.0;
        }
        let x: Vec<f64> = (0..n).map(|_| rnd()).collect();
        let mut b: Vec<f64> =
            (0..n).map(|i| dense[i * n..][..n].iter().zip(&x).map(|(a, b)| a * b).sum()).collect();
        m.factor().unwrap();
        m.solve(&mut b);
        for (got, want) in b.iter().zip(&x) {
            assert!((got - want).abs() < 1e-13, "{got} {want}");
        }
        m.reset(3, 1);
        m.add(0, 0, 1.0);
        m.add(1, 0, 2.0);
        m.add(1, 1, 1.0);
        m.add(2, 2, 1.0);
        assert_eq!(m.factor(), Err(1));
    }
}
