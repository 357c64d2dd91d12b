//! A symmetric banded matrix and its `L D Lᵀ` factorisation in place (Golub & Van Loan 2013,
//! Algorithm 4.3.6, band form): `O(n k²)` work and `O(n k)` storage for half-bandwidth `k`,
//! so a rod's Newton system (half-bandwidth 10 with the degrees of freedom interleaved
//! `x0, θ0, x1, θ1, …`) is solved in time linear in its vertex count. A closed rod's system
//! is cyclic (its last stencils couple its last vertices to its first); stored in the
//! *folded* order of its vertices, `0, V−1, 1, V−2, 2, …` ([`Band::reset_folded`]), every
//! stencil spans at most four consecutive vertex blocks, a band of half-bandwidth 19.

/// A symmetric `n × n` matrix with entries only within `k` of the diagonal, stored by its
/// lower band: row `i`, column `j` (`i - k ≤ j ≤ i`) at `i (k + 1) + (i - j)`. After
/// [`Band::factor`] the same storage holds `L` (unit diagonal, not stored) below and `D` on
/// the diagonal. Rows and columns may be stored permuted ([`Band::reset_folded`]): every
/// method takes and gives them in the caller's order.
#[derive(Debug, Default)]
pub struct Band {
    n: usize,
    k: usize,
    a: Vec<f64>,
    /// The stored position of each row, or empty for the identity.
    order: Vec<usize>,
    /// A permuted right-hand side.
    scratch: Vec<f64>,
}

impl Clone for Band {
    fn clone(&self) -> Self {
        let mut b = Band::default();
        b.clone_from(self);
        b
    }

    /// Reuses the storage (no allocation once the sizes match).
    fn clone_from(&mut self, source: &Self) {
        self.n = source.n;
        self.k = source.k;
        self.a.clone_from(&source.a);
        self.order.clone_from(&source.order);
    }
}

impl Band {
    /// Size for `n` rows of half-bandwidth `k`, stored in their own order, and set every
    /// entry to zero (allocates only when the storage grows).
    pub fn reset(&mut self, n: usize, k: usize) {
        self.n = n;
        self.k = k;
        self.a.clear();
        self.a.resize(n * (k + 1), 0.0);
        self.order.clear();
    }

    /// As [`Band::reset`], with the rows in blocks of `block` (a closed rod's vertices, 4:
    /// position and the next edge's twist) stored in the folded order of the blocks,
    /// `0, m−1, 1, m−2, …`: a cyclic band of `w` blocks becomes a band of `2w` blocks.
    pub fn reset_folded(&mut self, n: usize, k: usize, block: usize) {
        self.reset(n, k);
        let m = n.div_ceil(block);
        let slot = |b: usize| if 2 * b < m { 2 * b } else { 2 * (m - 1 - b) + 1 };
        self.order.extend((0..n).map(|i| block * slot(i / block) + i % block));
    }

    /// The stored position of row `i`.
    #[inline]
    fn at(&self, i: usize) -> usize {
        if self.order.is_empty() {
            i
        } else {
            self.order[i]
        }
    }

    /// Rows (and columns).
    pub fn len(&self) -> usize {
        self.n
    }

    /// Whether the matrix has no rows.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Entry `(i, j)`, within the band (as stored).
    #[inline]
    pub fn get(&self, i: usize, j: usize) -> f64 {
        let (i, j) = (self.at(i), self.at(j));
        let (i, j) = if i >= j { (i, j) } else { (j, i) };
        self.a[i * (self.k + 1) + (i - j)]
    }

    /// Add `v` to entry `(i, j)` (and, by symmetry, `(j, i)`), both within the band (as
    /// stored).
    #[inline]
    pub fn add(&mut self, i: usize, j: usize, v: f64) {
        let (i, j) = (self.at(i), self.at(j));
        let (i, j) = if i >= j { (i, j) } else { (j, i) };
        debug_assert!(i - j <= self.k, "({i}, {j}) outside the band");
        self.a[i * (self.k + 1) + (i - j)] += v;
    }

    /// Replace row and column `i` by those of the identity (a held degree of freedom).
    pub fn hold(&mut self, i: usize) {
        let (p, w) = (self.at(i), self.k + 1);
        for j in p.saturating_sub(self.k)..p {
            self.a[p * w + (p - j)] = 0.0;
        }
        for r in p + 1..(p + w).min(self.n) {
            self.a[r * w + (r - p)] = 0.0;
        }
        self.a[p * w] = 1.0;
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
    pub fn solve(&mut self, b: &mut [f64]) {
        if self.order.is_empty() {
            return self.solve_stored(b);
        }
        let mut x = std::mem::take(&mut self.scratch);
        x.resize(self.n, 0.0);
        for (i, v) in b.iter().enumerate() {
            x[self.order[i]] = *v;
        }
        self.solve_stored(&mut x);
        for (i, v) in b.iter_mut().enumerate() {
            *v = x[self.order[i]];
        }
        self.scratch = x;
    }

    /// [`Band::solve`] of `b` in the stored order.
    fn solve_stored(&self, b: &mut [f64]) {
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
    /// Factor `m` (holding the symmetric `dense`, n x n) and check that it solves `dense x = b`
    /// back to `x`.
    fn solves_back(m: &mut Band, dense: &[f64], x: &[f64]) {
        let n = x.len();
        let mut b: Vec<f64> =
            (0..n).map(|i| dense[i * n..][..n].iter().zip(x).map(|(a, b)| a * b).sum()).collect();
        m.factor().unwrap();
        m.solve(&mut b);
        for (got, want) in b.iter().zip(x) {
            assert!((got - want).abs() < 1e-13, "{got} {want}");
        }
    }

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
        solves_back(&mut m, &dense, &x);
        // A cyclic band (entries within 5 of the diagonal modulo n) in blocks of 4, folded.
        let (n, w) = (36, 5);
        let mut dense = vec![0.0; n * n];
        m.reset_folded(n, 19, 4);
        for i in 0..n {
            for d in 1..=w {
                let (j, v) = ((i + d) % n, rnd());
                m.add(i, j, v);
                dense[i * n + j] += v;
                dense[j * n + i] += v;
            }
            m.add(i, i, 12.0);
            dense[i * n + i] += 12.0;
        }
        let x: Vec<f64> = (0..n).map(|_| rnd()).collect();
        solves_back(&mut m, &dense, &x);
        m.reset(3, 1);
        m.add(0, 0, 1.0);
        m.add(1, 0, 2.0);
        m.add(1, 1, 1.0);
        m.add(2, 2, 1.0);
        assert_eq!(m.factor(), Err(1));
    }
}
