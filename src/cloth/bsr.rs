//! A symmetric block-sparse matrix of 3x3 blocks (one block row per vertex) whose pattern is
//! built once from the elements' vertex sets. Only the upper triangle (blocks `(i, j)` with
//! `j >= i`) is stored: a product reads each block once, which halves the memory traffic of
//! the conjugate-gradient iterations (and matters once the matrix leaves the cache, from about
//! 256² vertices), and runs sequentially so results do not depend on the thread count.

use glam::{DMat3, DVec3};

/// Block compressed sparse rows of the upper triangle, 3x3 blocks: the `n` diagonal blocks
/// first (block `i` is `(i, i)`), then the strict upper blocks row by row, so that the
/// triangular substitutions stream the blocks they read without the diagonal ones in between.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub struct BlockMatrix {
    /// Start of each block row's strict upper blocks in `cols` / `blocks` (length `n + 1`,
    /// `row_ptr[0] = n`).
    pub row_ptr: Vec<usize>,
    /// Block column of each block (`i` for the diagonal block `i`, `j > i` for the strict
    /// upper blocks of row `i`, sorted within a row); 32 bits, a third less traffic.
    pub cols: Vec<u32>,
    /// The blocks.
    pub blocks: Vec<DMat3>,
}

/// Marks a pair `(m, n)` of an element whose block is the transpose of a stored one.
pub const LOWER: usize = usize::MAX;

impl BlockMatrix {
    /// The pattern coupling every pair of vertices that share an element (and each vertex with
    /// itself), zero-filled. Panics from 2³² vertices on (the columns are 32-bit).
    pub fn from_elements<'a>(n: usize, elements: impl Iterator<Item = &'a [usize]>) -> Self {
        let mut neighbours: Vec<Vec<usize>> = vec![Vec::new(); n];
        for element in elements {
            for &a in element {
                for &b in element {
                    if b > a {
                        neighbours[a].push(b);
                    }
                }
            }
        }
        let column = |j: usize| u32::try_from(j).expect("fewer than 2³² vertices");
        let mut row_ptr = Vec::with_capacity(n + 1);
        let mut cols: Vec<u32> = (0..n).map(column).collect();
        row_ptr.push(n);
        for mut row in neighbours {
            row.sort_unstable();
            row.dedup();
            cols.extend(row.into_iter().map(column));
            row_ptr.push(cols.len());
        }
        let blocks = vec![DMat3::ZERO; cols.len()];
        BlockMatrix { row_ptr, cols, blocks }
    }

    /// Number of block rows.
    pub fn n(&self) -> usize {
        self.row_ptr.len() - 1
    }

    /// Index in `blocks` of block `(i, j)` for `i <= j`, or [`LOWER`] for `i > j` (whose block
    /// is the transpose of `(j, i)`). The pair must be in the pattern.
    pub fn slot(&self, i: usize, j: usize) -> usize {
        if i > j {
            return LOWER;
        }
        if i == j {
            return i;
        }
        let row = &self.cols[self.row_ptr[i]..self.row_ptr[i + 1]];
        self.row_ptr[i] + row.binary_search(&(j as u32)).expect("block is in the pattern")
    }

    /// `out = A x` for vectors of `n` 3-vectors.
    pub fn mul(&self, x: &[DVec3], out: &mut [DVec3]) {
        out.fill(DVec3::ZERO);
        for i in 0..self.n() {
            let xi = x[i];
            let mut acc = self.blocks[i] * xi;
            for s in self.row_ptr[i]..self.row_ptr[i + 1] {
                let j = self.cols[s] as usize;
                let b = self.blocks[s];
                acc += b * x[j];
                out[j] += b.transpose() * xi;
            }
            out[i] += acc;
        }
    }

    /// Whether row `h`'s first strict upper block is `(h, h + 1)`: then the substitutions
    /// reach row `h + 1` from row `h` through [`SweepDiagonal`]'s products.
    fn linked(&self, h: usize) -> bool {
        let start = self.row_ptr[h];
        start < self.row_ptr[h + 1] && self.cols[start] as usize == h + 1
    }

    /// Forward substitution `x = (D + L)⁻¹ y` with `D` the diagonal blocks of the matrix given
    /// through `d` and `L` its strict lower triangle (the transposes of the stored blocks). `y`
    /// is overwritten with partial sums.
    ///
    /// A substitution is a chain of dependent rows. When row `i - 1` is linked to row `i` (its
    /// first upper block is `(i - 1, i)`), `xᵢ = Dᵢ⁻¹ yᵢ - (Dᵢ⁻¹ Aᵢ₋₁,ᵢᵀ) xᵢ₋₁` with the
    /// product precomputed in `d`, `yᵢ` having everything else: one matrix-vector product on
    /// the chain, from a register, instead of a scatter into `yᵢ`, its reload and a product.
    /// With that the chain no longer sets the speed (interleaving two or four independent
    /// chains is no faster); the instructions per row do, at about 6.5 a cycle, and the time
    /// per row is the same from 16² to 128² vertices (not the memory traffic either).
    pub fn solve_lower(&self, d: &SweepDiagonal, y: &mut [DVec3], x: &mut [DVec3]) {
        let mut prev = DVec3::ZERO;
        for i in 0..self.n() {
            let xi = d.inverse[i] * y[i] - d.lower[i] * prev;
            x[i] = xi;
            self.scatter(i, xi, y);
            prev = xi;
        }
    }

    /// `q = p + (D + L)⁻¹ y`, the forward substitution of [`Self::solve_lower`] followed by
    /// the sum, returning `p̂ᵀ q`. `y` is overwritten with partial sums.
    pub fn solve_lower_add(
        &self,
        d: &SweepDiagonal,
        y: &mut [DVec3],
        p: &[DVec3],
        p_hat: &[DVec3],
        q: &mut [DVec3],
    ) -> f64 {
        let mut dot = 0.0;
        let mut prev = DVec3::ZERO;
        let rows = d.inverse.iter().zip(&d.lower).zip(p).zip(p_hat).zip(q.iter_mut());
        for (i, ((((inverse, lower), p), p_hat), q)) in rows.enumerate() {
            let xi = *inverse * y[i] - *lower * prev;
            let qi = *p + xi;
            *q = qi;
            dot += p_hat.dot(qi);
            self.scatter(i, xi, y);
            prev = xi;
        }
        dot
    }

    /// `y[j] -= Aᵢⱼᵀ xᵢ` over row `i`'s strict upper blocks, except the block `(i, i + 1)`
    /// of a linked row, which the next row takes through [`SweepDiagonal`].
    #[inline(always)]
    fn scatter(&self, i: usize, xi: DVec3, y: &mut [DVec3]) {
        let (start, end) = (self.row_ptr[i] + usize::from(self.linked(i)), self.row_ptr[i + 1]);
        for (&j, b) in self.cols[start..end].iter().zip(&self.blocks[start..end]) {
            y[j as usize] -= b.transpose() * xi;
        }
    }

    /// Backward substitution `x = (D + U)⁻¹ y` with `D` given through `d` and `U` the stored
    /// strict upper triangle, in place: on entry `x` holds `z` and the right-hand side is
    /// `y = z + β c`, formed row by row and stored into `c` (the conjugate-gradient direction
    /// update in the same pass); `t` receives `U x + κ (y - U x)`. As in the forward
    /// substitution only one product is on the chain of dependent rows: with `j` the first
    /// column of row `i`, `xᵢ = Dᵢ⁻¹ (y - Σₖ₍≠ⱼ₎ Aᵢₖ xₖ) - (Dᵢ⁻¹ Aᵢⱼ) xⱼ`, the sum farthest
    /// column first and `xⱼ` from a register when `j = i + 1`.
    pub fn solve_upper(
        &self,
        d: &SweepDiagonal,
        x: &mut [DVec3],
        c: &mut [DVec3],
        beta: f64,
        t: &mut [DVec3],
        kappa: f64,
    ) {
        let mut next = DVec3::ZERO;
        let rows = self.row_ptr.windows(2).zip(&d.inverse).zip(&d.upper);
        let rows = rows.zip(c.iter_mut()).zip(t.iter_mut());
        for (i, ((((range, inverse), upper), c), t)) in rows.enumerate().rev() {
            let (start, end) = (range[0], range[1]);
            let mut far = DVec3::ZERO;
            let (cols, blocks) = (&self.cols[start..end], &self.blocks[start..end]);
            for (&j, b) in cols.iter().zip(blocks).skip(1).rev() {
                far += *b * x[j as usize];
            }
            let (xj, near) = match (cols.first(), blocks.first()) {
                (Some(&j), Some(b)) => {
                    let xj = if j as usize == i + 1 { next } else { x[j as usize] };
                    (xj, *b * xj)
                }
                _ => (DVec3::ZERO, DVec3::ZERO),
            };
            let y = x[i] + beta * *c;
            *c = y;
            let ux = far + near;
            *t = ux + kappa * (y - ux);
            let xi = *inverse * (y - far) - *upper * xj;
            x[i] = xi;
            next = xi;
        }
    }

    /// The scalar lower-triangle pattern (compressed sparse columns) of this block pattern,
    /// and for each scalar entry the block and the component (row-major `3 r + c` of the block
    /// `(i, j)` with `i >= j`) it is read from.
    pub fn lower_scalar_pattern(&self) -> (Vec<usize>, Vec<usize>, Vec<(usize, usize)>) {
        let n = self.n();
        let mut col_ptr = vec![0];
        let mut row_idx = Vec::new();
        let mut source = Vec::new();
        for j in 0..n {
            for c in 0..3 {
                // Column 3j + c holds rows 3i + r >= 3j + c, i.e. blocks (i, j) with i >= j,
                // which by symmetry are the transposes of the stored blocks (j, i) of row j:
                // the diagonal block, then the strict upper ones.
                for s in std::iter::once(j).chain(self.row_ptr[j]..self.row_ptr[j + 1]) {
                    let i = self.cols[s] as usize;
                    let first = if i == j { c } else { 0 };
                    for r in first..3 {
                        row_idx.push(3 * i + r);
                        // A[3i + r][3j + c] = (block (j, i))[c][r].
                        source.push((s, 3 * c + r));
                    }
                }
                col_ptr.push(row_idx.len());
            }
        }
        (col_ptr, row_idx, source)
    }
}

/// The block diagonal `D` of the triangular substitutions of a [`BlockMatrix`], by the inverses
/// of its blocks, with the products that leave one matrix-vector product on the chain of
/// dependent rows ([`BlockMatrix::solve_lower`], [`BlockMatrix::solve_upper`]).
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, Default)]
pub struct SweepDiagonal {
    /// `Dᵢ⁻¹`, set by the caller before [`Self::update`].
    pub inverse: Vec<DMat3>,
    /// `Dᵢ⁻¹ Aᵢⱼ` for the first strict upper block `(i, j)` of row `i` (zero if it has none).
    upper: Vec<DMat3>,
    /// `Dᵢ⁻¹ Aᵢ₋₁,ᵢᵀ` when row `i - 1` is linked to row `i` (zero otherwise).
    lower: Vec<DMat3>,
}

impl SweepDiagonal {
    /// For `n` rows: identity inverses, zero products.
    pub fn new(n: usize) -> Self {
        SweepDiagonal {
            inverse: vec![DMat3::IDENTITY; n],
            upper: vec![DMat3::ZERO; n],
            lower: vec![DMat3::ZERO; n],
        }
    }

    /// The products from `inverse` and the blocks of `m`.
    pub fn update(&mut self, m: &BlockMatrix) {
        for i in 0..m.n() {
            let (start, end) = (m.row_ptr[i], m.row_ptr[i + 1]);
            let inverse = self.inverse[i];
            self.upper[i] = if start < end { inverse * m.blocks[start] } else { DMat3::ZERO };
            self.lower[i] = match i.checked_sub(1) {
                Some(h) if m.linked(h) => inverse * m.blocks[m.row_ptr[h]].transpose(),
                _ => DMat3::ZERO,
            };
        }
    }
}

/// Entry `(r, c)` of a block, `k = 3 r + c`.
pub fn entry(m: &DMat3, k: usize) -> f64 {
    m.col(k % 3)[k / 3]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The substitutions against their definitions on the pattern of `elements` (5 vertices).
    fn check_triangular_solves(elements: &[[usize; 3]]) {
        let mut m = BlockMatrix::from_elements(5, elements.iter().map(|e| &e[..]));
        for (k, b) in m.blocks.iter_mut().enumerate() {
            let f = k as f64;
            *b = DMat3::from_cols_array(&[4.0, 0.3, f, 0.1, 5.0 + f, 0.2, -f, 0.4, 6.0]) * 0.5;
        }
        let mut dinv = SweepDiagonal::new(5);
        dinv.inverse = (0..5).map(|i| m.blocks[i].inverse()).collect();
        dinv.update(&m);
        let z: Vec<DVec3> = (0..5).map(|i| DVec3::new(1.0, -2.0, 0.5) * (i as f64 + 1.0)).collect();
        let y = z.clone();
        // (D + U) x = y with y = z + β c: check each row, c = y and t = U x + κ D x.
        let c0: Vec<DVec3> = (0..5).map(|i| DVec3::new(0.5, -1.0, i as f64)).collect();
        let (beta, kappa) = (0.7, 0.4);
        let y: Vec<DVec3> = (0..5).map(|i| y[i] + beta * c0[i]).collect();
        let (mut x, mut c, mut t) = (z, c0.clone(), vec![DVec3::ZERO; 5]);
        m.solve_upper(&dinv, &mut x, &mut c, beta, &mut t, kappa);
        assert!(c.iter().zip(&y).all(|(a, b)| (*a - *b).length() < 1e-15));
        for i in 0..5 {
            let mut ux = DVec3::ZERO;
            for s in m.row_ptr[i]..m.row_ptr[i + 1] {
                ux += m.blocks[s] * x[m.cols[s] as usize];
            }
            let dx = m.blocks[i] * x[i];
            assert!((dx + ux - y[i]).length() < 1e-12);
            assert!((ux + kappa * dx - t[i]).length() < 1e-12);
        }
        // (D + L) x = y with L = Uᵀ.
        let mut w = y.clone();
        m.solve_lower(&dinv, &mut w, &mut x);
        let mut row: Vec<DVec3> = (0..5).map(|i| m.blocks[i] * x[i]).collect();
        for (i, &xi) in x.iter().enumerate() {
            for s in m.row_ptr[i]..m.row_ptr[i + 1] {
                row[m.cols[s] as usize] += m.blocks[s].transpose() * xi;
            }
        }
        assert!(row.iter().zip(&y).all(|(a, b)| (*a - *b).length() < 1e-12));
        // q = p + (D + L)⁻¹ y and p̂ᵀ q.
        let p: Vec<DVec3> = (0..5).map(|i| DVec3::new(0.5, i as f64, -1.0)).collect();
        let p_hat: Vec<DVec3> = (0..5).map(|i| DVec3::new(i as f64, 2.0, 0.25)).collect();
        let (mut w, mut q) = (y.clone(), vec![DVec3::ZERO; 5]);
        let dot = m.solve_lower_add(&dinv, &mut w, &p, &p_hat, &mut q);
        let expected: f64 = (0..5).map(|i| p_hat[i].dot(p[i] + x[i])).sum();
        assert!((0..5).all(|i| (q[i] - p[i] - x[i]).length() < 1e-12));
        assert!((dot - expected).abs() < 1e-12 * expected.abs());
    }

    #[test]
    fn triangular_solves_invert_their_halves() {
        // Every row linked to the next (the products of `SweepDiagonal` carry the chain).
        check_triangular_solves(&[[0, 1, 2], [1, 2, 3], [2, 3, 4]]);
        // Rows 0-2 not linked, row 3 linked, row 4 without upper blocks.
        let m = BlockMatrix::from_elements(5, [[0, 2, 4], [1, 3, 4]].iter().map(|e| &e[..]));
        assert_eq!((0..4).map(|h| m.linked(h)).collect::<Vec<_>>(), [false, false, false, true]);
        check_triangular_solves(&[[0, 2, 4], [1, 3, 4]]);
    }
}
