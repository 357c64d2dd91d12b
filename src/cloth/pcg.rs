//! The iterations of the modified preconditioned conjugate gradient (Baraff & Witkin 1998,
//! §5.3) with the block SSOR preconditioner applied through Eisenstat's trick (see
//! `Cloth::solve_pcg` for the method), on 3-vectors held in four lanes.
//!
//! The kernels are written once, in the four-lane arithmetic of [`Arith`], and compiled for
//! AVX2 registers (taken at run time where the CPU has them, through `pulp`; with AVX-512
//! enabled too where it has that) and for plain arrays. Every build performs the same IEEE
//! operations in the same order (no fused multiply-add), so their results are equal bit for
//! bit (tested).
//!
//! Why four lanes: an iteration is two triangular substitutions whose cost is mostly the 3x3
//! block products. Written on scalars, each product is 9 multiplications and 9 additions and
//! the substitutions ran at the core's instruction throughput (about 6.5 instructions a cycle,
//! 500 a row at 64²); on four-lane registers a product is 3 of each. An iteration became 17–25%
//! faster at 32² and 64² and 12% at 128², where memory traffic bounds it (about 28 MB an
//! iteration from L3; `docs/performance-notes.md`).
//!
//! The backward substitution takes a row's blocks in broadcast form (`Σ column × x_k`), the
//! forward one pulls each row's sum from the finished rows above it through a column index
//! (`Σ_j A_jiᵀ x_j`, three lane-wise accumulators summed once a row), so neither needs a
//! horizontal sum per block nor a second copy of the blocks. The blocks stay compact (9
//! values): a column is read as the four values from its first (the fourth, from the next
//! column, is either multiplied by the zero fourth lane of `x_j` or cleared).

use super::bsr::BlockMatrix;
use crate::error::{Error, Result};
use glam::{DMat3, DVec3};

/// A 3-vector in four lanes, the fourth zero, aligned to 32 bytes (one AVX register).
#[repr(C, align(32))]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Lane(pub [f64; 4]);

impl Lane {
    /// The zero vector.
    pub const ZERO: Lane = Lane([0.0; 4]);

    /// `v` with a zero fourth lane.
    pub fn new(v: DVec3) -> Lane {
        Lane([v.x, v.y, v.z, 0.0])
    }

    /// The first three lanes.
    pub fn vec3(self) -> DVec3 {
        DVec3::new(self.0[0], self.0[1], self.0[2])
    }
}

/// A 3x3 matrix by its columns, each a [`Lane`].
type Columns = [Lane; 3];

fn columns(m: DMat3) -> Columns {
    [Lane::new(m.x_axis), Lane::new(m.y_axis), Lane::new(m.z_axis)]
}

/// The preconditioner's per-row matrices for one solve, in four lanes, and the column index
/// of the matrix's pattern for the forward substitution.
#[derive(Default)]
pub struct Preconditioner {
    /// `D̂ᵢ⁻¹` (the filtered, scaled inverse of the diagonal block).
    inverse: Vec<Columns>,
    /// `D̂ᵢ⁻¹ Aᵢⱼ` for the first strict upper block `(i, j)` of row `i` (zero if none).
    upper: Vec<Columns>,
    /// `D̂ᵢ⁻¹ Aᵢ₋₁,ᵢᵀ` when row `i - 1` is linked to row `i` (zero otherwise).
    lower: Vec<Columns>,
    /// `D/ω` filtered, `Sᵢ Aᵢᵢ / ω`: the norm of the preconditioned residual.
    dhat: Vec<Columns>,
    /// Start of column `i`'s entries in `entries` (length `n + 1`).
    col_ptr: Vec<u32>,
    /// `(row j, block slot)` of the strict upper blocks `(j, i)` of column `i`, rows
    /// ascending, without the block `(i - 1, i)` of a linked row (carried by `lower`).
    entries: Vec<(u32, u32)>,
}

impl Preconditioner {
    /// The per-row matrices from `row(i) = (D̂ᵢ⁻¹, Sᵢ Aᵢᵢ / ω)` and the blocks of `m`; the
    /// column index is built on the first call (the pattern does not change).
    pub fn update(&mut self, m: &BlockMatrix, mut row: impl FnMut(usize) -> (DMat3, DMat3)) {
        let n = m.n();
        if self.col_ptr.len() != n + 1 {
            self.index(m);
        }
        for i in 0..n {
            let (start, end) = (m.row_ptr[i], m.row_ptr[i + 1]);
            let (inverse, dhat) = row(i);
            self.inverse[i] = columns(inverse);
            self.dhat[i] = columns(dhat);
            self.upper[i] =
                columns(if start < end { inverse * m.blocks[start] } else { DMat3::ZERO });
            self.lower[i] = columns(match i.checked_sub(1) {
                Some(h) if m.linked(h) => inverse * m.blocks[m.row_ptr[h]].transpose(),
                _ => DMat3::ZERO,
            });
        }
    }

    fn index(&mut self, m: &BlockMatrix) {
        let n = m.n();
        let mut count = vec![0u32; n + 1];
        let pulled = |i: usize, s: usize| !(s == m.row_ptr[i] && m.linked(i));
        for i in 0..n {
            for s in (m.row_ptr[i]..m.row_ptr[i + 1]).filter(|&s| pulled(i, s)) {
                count[m.cols[s] as usize + 1] += 1;
            }
        }
        for i in 0..n {
            count[i + 1] += count[i];
        }
        let mut next = count.clone();
        self.entries = vec![(0, 0); count[n] as usize];
        for i in 0..n {
            for s in (m.row_ptr[i]..m.row_ptr[i + 1]).filter(|&s| pulled(i, s)) {
                let j = m.cols[s] as usize;
                self.entries[next[j] as usize] = (i as u32, s as u32);
                next[j] += 1;
            }
        }
        self.col_ptr = count;
        for v in [&mut self.inverse, &mut self.upper, &mut self.lower, &mut self.dhat] {
            v.resize(n, [Lane::ZERO; 3]);
        }
    }
}

/// The working vectors of one solve, in four lanes.
#[derive(Default)]
pub struct Work {
    /// The preconditioner.
    pub precond: Preconditioner,
    /// The solution `Δv` (warm start on entry).
    pub dv: Vec<Lane>,
    /// On entry `S (b - A Δv₀)`; then the transformed residual `r̃`.
    pub r: Vec<Lane>,
    /// On entry `S b`; then the input of the forward substitution.
    pub t: Vec<Lane>,
    c: Vec<Lane>,
    q: Vec<Lane>,
    s: Vec<Lane>,
}

impl Work {
    /// Sized for `n` vertices (allocates only when the size changes).
    pub fn resize(&mut self, n: usize) {
        for v in [&mut self.dv, &mut self.r, &mut self.t, &mut self.c, &mut self.q, &mut self.s] {
            v.resize(n, Lane::ZERO);
        }
    }
}

/// The outcome of [`solve`]: iterations, relative residual `sqrt(δ/δ₀)`, converged.
pub type Outcome = (usize, f64, bool);

/// Runs the PCG iterations on `work` (see [`Work`] for what it holds on entry): stops when
/// `δ < max(ε² δ₀, floor)` or after `max_iterations`.
///
/// # Errors
/// [`Error::SolverFailed`] when `pᵀ A p` is not positive (the matrix is not positive definite).
pub fn solve(
    m: &BlockMatrix,
    work: &mut Work,
    tol: f64,
    max_iterations: usize,
    floor: f64,
    kappa: f64,
) -> Result<Outcome> {
    let run = Run { m, work, tol, max_iterations, floor, kappa };
    #[cfg(target_arch = "x86_64")]
    {
        // The same AVX2 kernels, compiled with AVX-512 enabled where the CPU has it (the
        // compiler then folds the broadcasts into the multiplications and has 32 registers).
        if let Some(simd) = pulp::x86::V4::try_new() {
            return simd.vectorize(Dispatch { run, arith: Avx(*simd) });
        }
        if let Some(simd) = pulp::x86::V3::try_new() {
            return simd.vectorize(Dispatch { run, arith: Avx(simd) });
        }
    }
    run.iterate(Portable)
}

struct Run<'a> {
    m: &'a BlockMatrix,
    work: &'a mut Work,
    tol: f64,
    max_iterations: usize,
    floor: f64,
    /// `ω - 1`.
    kappa: f64,
}

#[cfg(target_arch = "x86_64")]
struct Dispatch<'a, L> {
    run: Run<'a>,
    arith: L,
}

#[cfg(target_arch = "x86_64")]
impl<L: Arith> pulp::NullaryFnOnce for Dispatch<'_, L> {
    type Output = Result<Outcome>;

    #[inline(always)]
    fn call(self) -> Result<Outcome> {
        self.run.iterate(self.arith)
    }
}

impl Run<'_> {
    /// With `Â = L + D + U` (filtered) and `P = (D/ω + L) (D/ω)⁻¹ (D/ω + U)`, Eisenstat's
    /// iteration on `r̃ = (D/ω + L)⁻¹ r` and `p̂ = (D/ω + U) p`:
    /// `(D/ω + L)⁻¹ Â p = p + (D/ω + L)⁻¹ (U p + (ω - 1) (p̂ - U p))`.
    #[inline(always)]
    fn iterate<L: Arith>(self, l: L) -> Result<Outcome> {
        let Run { m, work, tol, max_iterations, floor, kappa } = self;
        let Work { precond: p, dv, r, t, c, q, s } = work;
        let n = m.n();
        // δ₀ = ‖(D/ω + L)⁻¹ S b‖²_{D/ω}.
        let mut norm = Norm { dhat: &p.dhat, sum: l.splat(0.0) };
        forward(l, m, p, t, &mut norm);
        let delta0 = l.sum(norm.sum);
        // r̃ = (D/ω + L)⁻¹ S (b - A Δv₀), z = (D/ω) r̃ (the first p̂, with β = 0).
        forward(l, m, p, r, &mut Skip);
        let mut delta = l.splat(0.0);
        for i in 0..n {
            let ri = l.load(&r[i]);
            let z = mat(l, &p.dhat[i], ri);
            s[i] = l.store(z);
            c[i] = Lane::ZERO;
            delta = l.add(delta, l.mul(ri, z));
        }
        let mut delta = l.sum(delta);
        if !(delta0.is_finite() && delta.is_finite()) {
            // Overflow (a step so large that `h² ∂f/∂x` times the velocities exceeds f64):
            // without this the loop would not start and the step would silently do nothing.
            return Err(Error::SolverFailed {
                reason: "PCG: the residual overflows (the step is too large); reduce dt".into(),
            });
        }
        let target = (tol * tol * delta0).max(floor);
        let mut iterations = 0;
        let mut beta = 0.0;
        while delta > target && iterations < max_iterations {
            // p̂ = z + β p̂ (in `c`, z in `s`), p = (D/ω + U)⁻¹ p̂ (in `s`), t = U p + κ (p̂ - U p);
            // q = p + (D/ω + L)⁻¹ t.
            backward(l, m, p, s, c, beta, t, kappa);
            let mut add = Add { p: s, p_hat: c, q, dot: l.splat(0.0) };
            forward(l, m, p, t, &mut add);
            let pq = l.sum(add.dot);
            if pq <= 0.0 || !pq.is_finite() {
                return Err(Error::SolverFailed {
                    reason: format!(
                        "PCG: the system matrix is not positive definite (pᵀAp = {pq})"
                    ),
                });
            }
            let alpha = l.splat(delta / pq);
            let mut next = l.splat(0.0);
            for i in 0..n {
                dv[i] = l.store(l.add(l.load(&dv[i]), l.mul(alpha, l.load(&s[i]))));
                let ri = l.sub(l.load(&r[i]), l.mul(alpha, l.load(&q[i])));
                let z = mat(l, &p.dhat[i], ri);
                r[i] = l.store(ri);
                s[i] = l.store(z);
                next = l.add(next, l.mul(ri, z));
            }
            let next = l.sum(next);
            beta = next / delta;
            delta = next;
            iterations += 1;
            if delta <= 0.0 {
                break;
            }
        }
        let residual = if delta0 > 0.0 { (delta.max(0.0) / delta0).sqrt() } else { 0.0 };
        Ok((iterations, residual, delta <= target))
    }
}

/// `Σₖ columnₖ xₖ`: a 3x3 matrix given by its columns times `x`, in broadcast form.
#[inline(always)]
fn combine<L: Arith>(l: L, [c0, c1, c2]: [L::V; 3], x: L::V) -> L::V {
    let (x0, x1, x2) = (l.lane::<0>(x), l.lane::<1>(x), l.lane::<2>(x));
    l.add(l.add(l.mul(c0, x0), l.mul(c1, x1)), l.mul(c2, x2))
}

/// `m x` for a per-row matrix.
#[inline(always)]
fn mat<L: Arith>(l: L, m: &Columns, x: L::V) -> L::V {
    combine(l, [l.load(&m[0]), l.load(&m[1]), l.load(&m[2])], x)
}

/// `w - m x`, with two operations after `x` (the chain of dependent rows runs through it).
#[inline(always)]
fn chain<L: Arith>(l: L, w: L::V, m: &Columns, x: L::V) -> L::V {
    let (x0, x1, x2) = (l.lane::<0>(x), l.lane::<1>(x), l.lane::<2>(x));
    let a = l.sub(w, l.mul(l.load(&m[0]), x0));
    l.sub(a, l.add(l.mul(l.load(&m[1]), x1), l.mul(l.load(&m[2]), x2)))
}

/// The columns of block `slot` of the compact blocks `flat` (9 values a block), each read
/// with the value after it in the fourth lane (the matrix keeps a zero block at the end).
#[inline(always)]
fn block<L: Arith>(l: L, flat: &[f64], slot: usize) -> [L::V; 3] {
    let b = &flat[9 * slot..9 * slot + 10];
    let four = |o: usize| -> [f64; 4] { b[o..o + 4].try_into().expect("four values") };
    [l.array(four(0)), l.array(four(3)), l.array(four(6))]
}

/// Block `slot` of `flat` times `x`; the fourth lane is not cleared.
#[inline(always)]
fn product<L: Arith>(l: L, flat: &[f64], slot: usize, x: L::V) -> L::V {
    combine(l, block(l, flat, slot), x)
}

/// What the forward substitution does with each finished row (a trait rather than a
/// closure: a closure is a function of its own, not compiled for AVX2 with its caller).
trait Row<L: Arith> {
    fn row(&mut self, l: L, i: usize, x: L::V);
}

/// Nothing.
struct Skip;

impl<L: Arith> Row<L> for Skip {
    #[inline(always)]
    fn row(&mut self, _: L, _: usize, _: L::V) {}
}

/// `Σ xᵢᵀ (D/ω) xᵢ`, lane-wise.
struct Norm<'a, L: Arith> {
    dhat: &'a [Columns],
    sum: L::V,
}

impl<L: Arith> Row<L> for Norm<'_, L> {
    #[inline(always)]
    fn row(&mut self, l: L, i: usize, x: L::V) {
        self.sum = l.add(self.sum, l.mul(x, mat(l, &self.dhat[i], x)));
    }
}

/// `qᵢ = pᵢ + xᵢ` and `Σ p̂ᵢᵀ qᵢ`, lane-wise.
struct Add<'a, L: Arith> {
    p: &'a [Lane],
    p_hat: &'a [Lane],
    q: &'a mut [Lane],
    dot: L::V,
}

impl<L: Arith> Row<L> for Add<'_, L> {
    #[inline(always)]
    fn row(&mut self, l: L, i: usize, x: L::V) {
        let qi = l.add(l.load(&self.p[i]), x);
        self.q[i] = l.store(qi);
        self.dot = l.add(self.dot, l.mul(l.load(&self.p_hat[i]), qi));
    }
}

/// Forward substitution `x = (D/ω + L)⁻¹ y` in place (`y` becomes `x`), handing each
/// finished row to `each` ([`Row`]). Row `i` pulls `Σ_j A_jiᵀ x_j` over its column's
/// entries; when row `i - 1` is linked to row `i`, `xᵢ = D̂ᵢ⁻¹ (yᵢ - pulled) - (D̂ᵢ⁻¹
/// Aᵢ₋₁,ᵢᵀ) xᵢ₋₁`, one product on the chain of dependent rows, from a register.
#[inline(always)]
fn forward<L: Arith>(
    l: L,
    m: &BlockMatrix,
    p: &Preconditioner,
    y: &mut [Lane],
    each: &mut impl Row<L>,
) {
    let flat: &[f64] = bytemuck::cast_slice(&m.blocks);
    let mut prev = l.splat(0.0);
    for i in 0..y.len() {
        let (start, end) = (p.col_ptr[i] as usize, p.col_ptr[i + 1] as usize);
        let (mut a0, mut a1, mut a2) = (l.splat(0.0), l.splat(0.0), l.splat(0.0));
        for &(j, slot) in &p.entries[start..end] {
            let xj = l.load(&y[j as usize]);
            let [c0, c1, c2] = block(l, flat, slot as usize);
            a0 = l.add(a0, l.mul(c0, xj));
            a1 = l.add(a1, l.mul(c1, xj));
            a2 = l.add(a2, l.mul(c2, xj));
        }
        let pulled = l.sums(a0, a1, a2);
        let w = mat(l, &p.inverse[i], l.sub(l.load(&y[i]), pulled));
        let xi = chain(l, w, &p.lower[i], prev);
        y[i] = l.store(xi);
        each.row(l, i, xi);
        prev = xi;
    }
}

/// Backward substitution `x = (D/ω + U)⁻¹ y` in place: on entry `x` holds `z` and the
/// right-hand side is `y = z + β c`, formed row by row and stored into `c` (the
/// conjugate-gradient direction update in the same pass); `t` receives `U x + κ (y - U x)`.
/// With `j` the first column of row `i`, `xᵢ = D̂ᵢ⁻¹ (yᵢ - Σₖ₍≠ⱼ₎ Aᵢₖ xₖ) - (D̂ᵢ⁻¹ Aᵢⱼ) xⱼ`,
/// the sum farthest column first and `xⱼ` from a register when `j = i + 1`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn backward<L: Arith>(
    l: L,
    m: &BlockMatrix,
    p: &Preconditioner,
    x: &mut [Lane],
    c: &mut [Lane],
    beta: f64,
    t: &mut [Lane],
    kappa: f64,
) {
    let flat: &[f64] = bytemuck::cast_slice(&m.blocks);
    let (beta, kappa) = (l.splat(beta), l.splat(kappa));
    let mut next = l.splat(0.0);
    for i in (0..x.len()).rev() {
        let (start, end) = (m.row_ptr[i], m.row_ptr[i + 1]);
        let mut far = l.splat(0.0);
        for s in (start + 1..end).rev() {
            far = l.add(far, product(l, flat, s, l.load(&x[m.cols[s] as usize])));
        }
        let far = l.clean(far);
        let (xj, near) = if start < end {
            let j = m.cols[start] as usize;
            let xj = if j == i + 1 { next } else { l.load(&x[j]) };
            (xj, l.clean(product(l, flat, start, xj)))
        } else {
            (l.splat(0.0), l.splat(0.0))
        };
        let y = l.add(l.load(&x[i]), l.mul(beta, l.load(&c[i])));
        c[i] = l.store(y);
        let ux = l.add(far, near);
        t[i] = l.store(l.add(ux, l.mul(kappa, l.sub(y, ux))));
        let xi = chain(l, mat(l, &p.inverse[i], l.sub(y, far)), &p.upper[i], xj);
        x[i] = l.store(xi);
        next = xi;
    }
}

/// Four-lane arithmetic: lane-wise IEEE operations, and sums in a fixed order.
trait Arith: Copy {
    type V: Copy;
    fn load(self, a: &Lane) -> Self::V;
    fn store(self, v: Self::V) -> Lane;
    fn array(self, a: [f64; 4]) -> Self::V;
    fn splat(self, x: f64) -> Self::V;
    fn add(self, a: Self::V, b: Self::V) -> Self::V;
    fn sub(self, a: Self::V, b: Self::V) -> Self::V;
    fn mul(self, a: Self::V, b: Self::V) -> Self::V;
    /// Lane `K` in every lane.
    fn lane<const K: usize>(self, v: Self::V) -> Self::V;
    /// The fourth lane set to zero.
    fn clean(self, v: Self::V) -> Self::V;
    /// `(Σa, Σb, Σc, 0)`, each sum `(v₀ + v₁) + (v₂ + v₃)`.
    fn sums(self, a: Self::V, b: Self::V, c: Self::V) -> Self::V;
    /// `(v₀ + v₁) + (v₂ + v₃)`.
    fn sum(self, v: Self::V) -> f64;
}

/// Arrays, for any CPU.
#[derive(Clone, Copy)]
struct Portable;

impl Arith for Portable {
    type V = [f64; 4];

    #[inline(always)]
    fn load(self, a: &Lane) -> [f64; 4] {
        a.0
    }
    #[inline(always)]
    fn store(self, v: [f64; 4]) -> Lane {
        Lane(v)
    }
    #[inline(always)]
    fn array(self, a: [f64; 4]) -> [f64; 4] {
        a
    }
    #[inline(always)]
    fn splat(self, x: f64) -> [f64; 4] {
        [x; 4]
    }
    #[inline(always)]
    fn add(self, a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
        std::array::from_fn(|k| a[k] + b[k])
    }
    #[inline(always)]
    fn sub(self, a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
        std::array::from_fn(|k| a[k] - b[k])
    }
    #[inline(always)]
    fn mul(self, a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
        std::array::from_fn(|k| a[k] * b[k])
    }
    #[inline(always)]
    fn lane<const K: usize>(self, v: [f64; 4]) -> [f64; 4] {
        [v[K]; 4]
    }
    #[inline(always)]
    fn clean(self, v: [f64; 4]) -> [f64; 4] {
        [v[0], v[1], v[2], 0.0]
    }
    #[inline(always)]
    fn sums(self, a: [f64; 4], b: [f64; 4], c: [f64; 4]) -> [f64; 4] {
        [self.sum(a), self.sum(b), self.sum(c), 0.0]
    }
    #[inline(always)]
    fn sum(self, v: [f64; 4]) -> f64 {
        (v[0] + v[1]) + (v[2] + v[3])
    }
}

/// AVX2 registers (`pulp`'s safe intrinsics).
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
struct Avx(pulp::x86::V3);

#[cfg(target_arch = "x86_64")]
impl Arith for Avx {
    type V = std::arch::x86_64::__m256d;

    #[inline(always)]
    fn load(self, a: &Lane) -> Self::V {
        pulp::cast(a.0)
    }
    #[inline(always)]
    fn store(self, v: Self::V) -> Lane {
        Lane(pulp::cast(v))
    }
    #[inline(always)]
    fn array(self, a: [f64; 4]) -> Self::V {
        pulp::cast(a)
    }
    #[inline(always)]
    fn splat(self, x: f64) -> Self::V {
        self.0.avx._mm256_set1_pd(x)
    }
    #[inline(always)]
    fn add(self, a: Self::V, b: Self::V) -> Self::V {
        self.0.avx._mm256_add_pd(a, b)
    }
    #[inline(always)]
    fn sub(self, a: Self::V, b: Self::V) -> Self::V {
        self.0.avx._mm256_sub_pd(a, b)
    }
    #[inline(always)]
    fn mul(self, a: Self::V, b: Self::V) -> Self::V {
        self.0.avx._mm256_mul_pd(a, b)
    }
    #[inline(always)]
    fn lane<const K: usize>(self, v: Self::V) -> Self::V {
        let avx2 = self.0.avx2;
        match K {
            0 => avx2._mm256_broadcastsd_pd(self.0.avx._mm256_castpd256_pd128(v)),
            1 => avx2._mm256_permute4x64_pd::<0x55>(v),
            2 => avx2._mm256_permute4x64_pd::<0xAA>(v),
            _ => avx2._mm256_permute4x64_pd::<0xFF>(v),
        }
    }
    #[inline(always)]
    fn clean(self, v: Self::V) -> Self::V {
        self.0.avx._mm256_blend_pd::<0b1000>(v, self.0.avx._mm256_setzero_pd())
    }
    #[inline(always)]
    fn sums(self, a: Self::V, b: Self::V, c: Self::V) -> Self::V {
        let avx = self.0.avx;
        // (a₀+a₁, b₀+b₁, a₂+a₃, b₂+b₃) and (c₀+c₁, 0, c₂+c₃, 0).
        let ab = avx._mm256_hadd_pd(a, b);
        let c0 = avx._mm256_hadd_pd(c, avx._mm256_setzero_pd());
        let low = avx._mm256_permute2f128_pd::<0x20>(ab, c0);
        let high = avx._mm256_permute2f128_pd::<0x31>(ab, c0);
        avx._mm256_add_pd(low, high)
    }
    #[inline(always)]
    fn sum(self, v: Self::V) -> f64 {
        Portable.sum(pulp::cast(v))
    }
}

#[cfg(test)]
#[path = "pcg_tests.rs"]
mod tests;
