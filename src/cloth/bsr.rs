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
    /// The blocks, then one zero block that is not part of the matrix: every block's last
    /// column can then be read with four-lane loads (the PCG's substitutions).
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
        let blocks = vec![DMat3::ZERO; cols.len() + 1];
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

    /// Whether row `h`'s first strict upper block is `(h, h + 1)`: then the PCG's
    /// substitutions reach row `h + 1` from row `h` through a product kept per row.
    pub fn linked(&self, h: usize) -> bool {
        let start = self.row_ptr[h];
        start < self.row_ptr[h + 1] && self.cols[start] as usize == h + 1
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

/// Entry `(r, c)` of a block, `k = 3 r + c`.
pub fn entry(m: &DMat3, k: usize) -> f64 {
    m.col(k % 3)[k / 3]
}
