//! A symmetric block-sparse matrix of 3x3 blocks (one block row per vertex) whose pattern is
//! built once from the elements' vertex sets. Only the upper triangle (blocks `(i, j)` with
//! `j >= i`) is stored: a product reads each block once, which halves the memory traffic of
//! the conjugate-gradient iterations (they are bound by it), and runs sequentially so results
//! do not depend on the thread count.

use glam::{DMat3, DVec3};

/// Block compressed sparse rows of the upper triangle, 3x3 blocks.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub struct BlockMatrix {
    /// Start of each block row in `cols` / `blocks` (length `n + 1`).
    pub row_ptr: Vec<usize>,
    /// Block column `j >= i` of each stored block, sorted within a row.
    pub cols: Vec<usize>,
    /// The blocks.
    pub blocks: Vec<DMat3>,
    /// Position of the diagonal block of each row in `blocks` (the first of the row).
    pub diag: Vec<usize>,
}

/// Marks a pair `(m, n)` of an element whose block is the transpose of a stored one.
pub const LOWER: usize = usize::MAX;

impl BlockMatrix {
    /// The pattern coupling every pair of vertices that share an element (and each vertex with
    /// itself), zero-filled.
    pub fn from_elements<'a>(n: usize, elements: impl Iterator<Item = &'a [usize]>) -> Self {
        let mut neighbours: Vec<Vec<usize>> = (0..n).map(|i| vec![i]).collect();
        for element in elements {
            for &a in element {
                for &b in element {
                    if b > a {
                        neighbours[a].push(b);
                    }
                }
            }
        }
        let mut row_ptr = Vec::with_capacity(n + 1);
        let mut cols = Vec::new();
        let mut diag = Vec::with_capacity(n);
        row_ptr.push(0);
        for mut row in neighbours {
            row.sort_unstable();
            row.dedup();
            diag.push(cols.len());
            cols.extend(row);
            row_ptr.push(cols.len());
        }
        let blocks = vec![DMat3::ZERO; cols.len()];
        BlockMatrix { row_ptr, cols, blocks, diag }
    }

    /// Number of block rows.
    pub fn n(&self) -> usize {
        self.diag.len()
    }

    /// Index in `blocks` of block `(i, j)` for `i <= j`, or [`LOWER`] for `i > j` (whose block
    /// is the transpose of `(j, i)`). The pair must be in the pattern.
    pub fn slot(&self, i: usize, j: usize) -> usize {
        if i > j {
            return LOWER;
        }
        let row = &self.cols[self.row_ptr[i]..self.row_ptr[i + 1]];
        self.row_ptr[i] + row.binary_search(&j).expect("block is in the pattern")
    }

    /// `out = A x` for vectors of `n` 3-vectors.
    pub fn mul(&self, x: &[DVec3], out: &mut [DVec3]) {
        out.fill(DVec3::ZERO);
        for i in 0..self.n() {
            let (start, end) = (self.row_ptr[i], self.row_ptr[i + 1]);
            let xi = x[i];
            let mut acc = self.blocks[start] * xi;
            for s in start + 1..end {
                let j = self.cols[s];
                let b = self.blocks[s];
                acc += b * x[j];
                out[j] += b.transpose() * xi;
            }
            out[i] += acc;
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
                // which by symmetry are the transposes of the stored blocks (j, i) of row j.
                for s in self.diag[j]..self.row_ptr[j + 1] {
                    let i = self.cols[s];
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

/// A 3-vector in four lanes, the fourth zero: the layout of the substitutions' vectors (one
/// 256-bit register, so that AVX2 does a 3-vector operation in one instruction).
pub type Lanes = [f64; 4];

/// A 3x3 matrix as three [`Lanes`]: its rows (the blocks of [`UpperRows`]) or its columns
/// (the diagonal blocks' inverses); the fourth lane of each is zero.
pub type LaneMat = [Lanes; 3];

/// `v` in four lanes.
#[inline(always)]
pub fn lanes(v: DVec3) -> Lanes {
    [v.x, v.y, v.z, 0.0]
}

/// The 3-vector in the first three lanes of `v`.
#[inline(always)]
pub fn from_lanes(v: Lanes) -> DVec3 {
    DVec3::new(v[0], v[1], v[2])
}

/// The columns of `m` as [`Lanes`] (for [`mul_cols`]).
pub fn columns(m: DMat3) -> LaneMat {
    [lanes(m.x_axis), lanes(m.y_axis), lanes(m.z_axis)]
}

/// `m v` for `m` given by its columns: `(m₀ v₀ + m₁ v₁) + m₂ v₂` lane by lane, the order of
/// glam's `DMat3 * DVec3`.
#[inline(always)]
pub fn mul_cols(m: &LaneMat, v: Lanes) -> Lanes {
    std::array::from_fn(|k| m[0][k] * v[0] + m[1][k] * v[1] + m[2][k] * v[2])
}

/// `a + s b` lane by lane.
#[inline(always)]
pub fn add_scaled(a: Lanes, s: f64, b: Lanes) -> Lanes {
    std::array::from_fn(|k| a[k] + s * b[k])
}

/// `a + b` lane by lane.
#[inline(always)]
fn add(a: Lanes, b: Lanes) -> Lanes {
    std::array::from_fn(|k| a[k] + b[k])
}

/// `a - b` lane by lane.
#[inline(always)]
fn sub(a: Lanes, b: Lanes) -> Lanes {
    std::array::from_fn(|k| a[k] - b[k])
}

/// `aᵀ b` over the three components.
#[inline(always)]
pub fn dot(a: Lanes, b: Lanes) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The strict upper triangle of a [`BlockMatrix`] laid out for the triangular substitutions of
/// PCG, which are most of a cloth step: each block `B` as its three rows in [`Lanes`], so that
/// both products a substitution needs are sums of whole rows — `Bᵀ x = Σᵣ Bᵣ xᵣ` (forward)
/// and, for `B x`, the lane-wise products `Bᵣ ∘ x` summed over the row's blocks and then across
/// the lanes once per row (backward) — and 32-bit block columns. The substitutions run through
/// [`pulp::Arch::dispatch`], which compiles them for AVX2 too and picks that build at run time
/// where the CPU has it; no fused multiply-add is introduced, so the results do not depend on
/// the instruction set. They run sequentially (results do not depend on the thread count).
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, Default)]
pub struct UpperRows {
    /// Start of each block row in `cols` / `rows` (length `n + 1`).
    ptr: Vec<usize>,
    /// Block column `j > i` of each block.
    cols: Vec<u32>,
    /// The blocks' rows (read by the forward substitution).
    rows: Vec<LaneMat>,
    /// The blocks' columns (read by the backward substitution).
    cols_of: Vec<LaneMat>,
}

impl UpperRows {
    /// The layout of `m`'s pattern, zero-filled (copy the blocks with [`Self::fill`]).
    pub fn new(m: &BlockMatrix) -> Self {
        let n = m.n();
        let ptr = (0..=n).map(|i| m.row_ptr[i] - i).collect();
        let cols = (0..n)
            .flat_map(|i| &m.cols[m.diag[i] + 1..m.row_ptr[i + 1]])
            .map(|&j| u32::try_from(j).expect("fewer than 2³² vertices"))
            .collect::<Vec<_>>();
        let rows = vec![[[0.0; 4]; 3]; cols.len()];
        UpperRows { ptr, cols, cols_of: rows.clone(), rows }
    }

    /// Copy the strict upper blocks of `m` (of the pattern this was built from).
    pub fn fill(&mut self, m: &BlockMatrix) {
        let upper = (0..m.n()).flat_map(|i| &m.blocks[m.diag[i] + 1..m.row_ptr[i + 1]]);
        for ((rows, cols), b) in self.rows.iter_mut().zip(&mut self.cols_of).zip(upper) {
            *rows = [lanes(b.row(0)), lanes(b.row(1)), lanes(b.row(2))];
            *cols = columns(*b);
        }
    }

    /// Forward substitution `x = (D + L)⁻¹ y` with `D` the diagonal blocks of the matrix given
    /// by the columns of their inverses `dinv` and `L` its strict lower triangle (the
    /// transposes of the stored blocks). `y` is overwritten with partial sums.
    pub fn solve_lower(&self, dinv: &[LaneMat], y: &mut [Lanes], x: &mut [Lanes]) {
        pulp::Arch::new().dispatch(Lower { m: self, dinv, y, x });
    }

    /// `q = p + (D + L)⁻¹ y`, the forward substitution of [`Self::solve_lower`] followed by
    /// the sum, returning `p̂ᵀ q`. `y` is overwritten with partial sums.
    pub fn solve_lower_add(
        &self,
        dinv: &[LaneMat],
        y: &mut [Lanes],
        p: &[Lanes],
        p_hat: &[Lanes],
        q: &mut [Lanes],
    ) -> f64 {
        pulp::Arch::new().dispatch(LowerAdd { m: self, dinv, y, p, p_hat, q })
    }

    /// Backward substitution `x = (D + U)⁻¹ y` with `D` given by the columns of its inverses
    /// `dinv` and `U` the stored strict upper triangle, in place: on entry `x` holds `z` and
    /// the right-hand side is `y = z + β c`, formed row by row and stored into `c` (the
    /// conjugate-gradient direction update in the same pass); `t` receives `U x + κ (y - U x)`.
    pub fn solve_upper(
        &self,
        dinv: &[LaneMat],
        x: &mut [Lanes],
        c: &mut [Lanes],
        beta: f64,
        t: &mut [Lanes],
        kappa: f64,
    ) {
        pulp::Arch::new().dispatch(Upper { m: self, dinv, x, c, beta, t, kappa });
    }

    /// `y[j] -= Bᵀ xᵢ` for the blocks `B` of row `i`: `Bᵀ xᵢ = (B₀ xᵢ₀ + B₁ xᵢ₁) + B₂ xᵢ₂`
    /// over the rows `Bᵣ` (the order of glam's transposed product).
    #[inline(always)]
    fn scatter(&self, i: usize, xi: Lanes, y: &mut [Lanes]) {
        let (start, end) = (self.ptr[i], self.ptr[i + 1]);
        for (&j, b) in self.cols[start..end].iter().zip(&self.rows[start..end]) {
            let yj = &mut y[j as usize];
            *yj = std::array::from_fn(|k| {
                yj[k] - (b[0][k] * xi[0] + b[1][k] * xi[1] + b[2][k] * xi[2])
            });
        }
    }
}

/// The vector update of a conjugate-gradient iteration in the layout of [`UpperRows`]:
/// `x += α s`, `r -= α w`, then `s = D̂ r` (`D̂` by the columns of its blocks); returns
/// `rᵀ D̂ r`. Compiled like the substitutions (AVX2 where the CPU has it).
pub fn cg_update(
    alpha: f64,
    x: &mut [Lanes],
    r: &mut [Lanes],
    s: &mut [Lanes],
    w: &[Lanes],
    dhat: &[LaneMat],
) -> f64 {
    pulp::Arch::new().dispatch(Update { alpha, x, r, s, w, dhat })
}

/// [`cg_update`], compiled for the SIMD instruction set found at run time.
struct Update<'a> {
    alpha: f64,
    x: &'a mut [Lanes],
    r: &'a mut [Lanes],
    s: &'a mut [Lanes],
    w: &'a [Lanes],
    dhat: &'a [LaneMat],
}

impl pulp::WithSimd for Update<'_> {
    type Output = f64;

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) -> f64 {
        let Update { alpha, x, r, s, w, dhat } = self;
        let mut sum = 0.0;
        let rows = x.iter_mut().zip(r.iter_mut()).zip(s.iter_mut()).zip(w).zip(dhat);
        for ((((x, r), s), w), dhat) in rows {
            *x = add_scaled(*x, alpha, *s);
            *r = add_scaled(*r, -alpha, *w);
            *s = mul_cols(dhat, *r);
            sum += dot(*r, *s);
        }
        sum
    }
}

/// [`UpperRows::solve_lower`], compiled for the SIMD instruction set found at run time.
struct Lower<'a> {
    m: &'a UpperRows,
    dinv: &'a [LaneMat],
    y: &'a mut [Lanes],
    x: &'a mut [Lanes],
}

impl pulp::WithSimd for Lower<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) {
        let Lower { m, dinv, y, x } = self;
        for (i, (dinv, x)) in dinv.iter().zip(x.iter_mut()).enumerate() {
            let xi = mul_cols(dinv, y[i]);
            *x = xi;
            m.scatter(i, xi, y);
        }
    }
}

/// [`UpperRows::solve_lower_add`], compiled for the SIMD instruction set found at run time.
struct LowerAdd<'a> {
    m: &'a UpperRows,
    dinv: &'a [LaneMat],
    y: &'a mut [Lanes],
    p: &'a [Lanes],
    p_hat: &'a [Lanes],
    q: &'a mut [Lanes],
}

impl pulp::WithSimd for LowerAdd<'_> {
    type Output = f64;

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) -> f64 {
        let LowerAdd { m, dinv, y, p, p_hat, q } = self;
        let mut sum = 0.0;
        let rows = dinv.iter().zip(p).zip(p_hat).zip(q.iter_mut());
        for (i, (((dinv, p), p_hat), q)) in rows.enumerate() {
            let xi = mul_cols(dinv, y[i]);
            let qi = add(*p, xi);
            *q = qi;
            sum += dot(*p_hat, qi);
            m.scatter(i, xi, y);
        }
        sum
    }
}

/// [`UpperRows::solve_upper`], compiled for the SIMD instruction set found at run time.
struct Upper<'a> {
    m: &'a UpperRows,
    dinv: &'a [LaneMat],
    x: &'a mut [Lanes],
    c: &'a mut [Lanes],
    beta: f64,
    t: &'a mut [Lanes],
    kappa: f64,
}

impl pulp::WithSimd for Upper<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) {
        let Upper { m, dinv, x, c, beta, t, kappa } = self;
        let rows = m.ptr.windows(2).zip(dinv).zip(c.iter_mut()).zip(t.iter_mut());
        for (i, (((range, dinv), c), t)) in rows.enumerate().rev() {
            // U x over the row's blocks, each `(B₀ x₀ + B₁ x₁) + B₂ x₂` over its columns `Bₖ`
            // (the order of glam's product).
            let mut ux = [0.0; 4];
            let (start, end) = (range[0], range[1]);
            for (&j, b) in m.cols[start..end].iter().zip(&m.cols_of[start..end]) {
                ux = add(ux, mul_cols(b, x[j as usize]));
            }
            let y = add_scaled(x[i], beta, *c);
            *c = y;
            let rest = sub(y, ux);
            *t = add_scaled(ux, kappa, rest);
            x[i] = mul_cols(dinv, rest);
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

    #[test]
    fn triangular_solves_invert_their_halves() {
        let elements = [[0, 1, 2], [1, 2, 3], [2, 3, 4]];
        let mut m = BlockMatrix::from_elements(5, elements.iter().map(|e| &e[..]));
        for (k, b) in m.blocks.iter_mut().enumerate() {
            let f = k as f64;
            *b = DMat3::from_cols_array(&[4.0, 0.3, f, 0.1, 5.0 + f, 0.2, -f, 0.4, 6.0]) * 0.5;
        }
        let mut u = UpperRows::new(&m);
        u.fill(&m);
        let dinv: Vec<LaneMat> = m.diag.iter().map(|&d| columns(m.blocks[d].inverse())).collect();
        let v = |f: &dyn Fn(f64) -> DVec3| (0..5).map(|i| f(i as f64)).collect::<Vec<DVec3>>();
        let l = |v: &[DVec3]| v.iter().map(|&x| lanes(x)).collect::<Vec<Lanes>>();
        let d = |v: &[Lanes]| v.iter().map(|&x| from_lanes(x)).collect::<Vec<DVec3>>();
        let z = v(&|i| DVec3::new(1.0, -2.0, 0.5) * (i + 1.0));
        // (D + U) x = y with y = z + β c: check each row, c = y and t = U x + κ D x.
        let c0 = v(&|i| DVec3::new(0.5, -1.0, i));
        let (beta, kappa) = (0.7, 0.4);
        let y: Vec<DVec3> = (0..5).map(|i| z[i] + beta * c0[i]).collect();
        let (mut x, mut c, mut t) = (l(&z), l(&c0), vec![[0.0; 4]; 5]);
        u.solve_upper(&dinv, &mut x, &mut c, beta, &mut t, kappa);
        let (x, c, t) = (d(&x), d(&c), d(&t));
        assert!(c.iter().zip(&y).all(|(a, b)| (*a - *b).length() < 1e-15));
        for i in 0..5 {
            let mut ux = DVec3::ZERO;
            for s in m.diag[i] + 1..m.row_ptr[i + 1] {
                ux += m.blocks[s] * x[m.cols[s]];
            }
            let dx = m.blocks[m.diag[i]] * x[i];
            assert!((dx + ux - y[i]).length() < 1e-12);
            assert!((ux + kappa * dx - t[i]).length() < 1e-12);
        }
        // (D + L) x = y with L = Uᵀ.
        let (mut w, mut xl) = (l(&y), vec![[0.0; 4]; 5]);
        u.solve_lower(&dinv, &mut w, &mut xl);
        let x = d(&xl);
        let mut row: Vec<DVec3> = (0..5).map(|i| m.blocks[m.diag[i]] * x[i]).collect();
        for (i, &xi) in x.iter().enumerate() {
            for s in m.diag[i] + 1..m.row_ptr[i + 1] {
                row[m.cols[s]] += m.blocks[s].transpose() * xi;
            }
        }
        assert!(row.iter().zip(&y).all(|(a, b)| (*a - *b).length() < 1e-12));
        // q = p + (D + L)⁻¹ y and p̂ᵀ q.
        let p = v(&|i| DVec3::new(0.5, i, -1.0));
        let p_hat = v(&|i| DVec3::new(i, 2.0, 0.25));
        let (mut w, mut q) = (l(&y), vec![[0.0; 4]; 5]);
        let dot = u.solve_lower_add(&dinv, &mut w, &l(&p), &l(&p_hat), &mut q);
        let (q_lanes, q) = (q.clone(), d(&q));
        let expected: f64 = (0..5).map(|i| p_hat[i].dot(p[i] + x[i])).sum();
        assert!((0..5).all(|i| (q[i] - p[i] - x[i]).length() < 1e-12));
        assert!((dot - expected).abs() < 1e-12 * expected.abs());
        // The fourth lanes stay zero.
        assert!(xl.iter().chain(&q_lanes).all(|x| x[3] == 0.0));
    }
}
