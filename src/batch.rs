//! Batched element-wise kernels: one function applied to every row of fixed-size arrays.
//!
//! Batches are slices of fixed-size rows (`&[[f64; 4]]` for quaternions, `&[[f64; 9]]` for
//! row-major 3x3 matrices...). Large batches run on the rayon thread pool in fixed chunks; the
//! result is bitwise the same whatever the thread count, because every row is computed by the
//! same scalar code and nothing is reduced across rows. When rows fail, the error of the
//! lowest failing row is returned, also independent of the thread count.
//!
//! Results go to an [`Output`]: rows already initialised (`[[f64; O]]`) or rows of a new
//! buffer that nothing has written yet (`[[MaybeUninit<f64>; O]]`, e.g. a new numpy array),
//! which the kernels write in full (on success) without reading, so that a caller need not
//! zero the buffer first (one pass less over memory).

use crate::error::{Error, Result};
use rayon::prelude::*;
use std::mem::MaybeUninit;

mod sealed {
    use std::mem::MaybeUninit;

    /// The rows of an [`super::Output`], to be written and never read.
    pub trait WriteOnly<const O: usize> {
        fn write_only(&mut self) -> &mut [[MaybeUninit<f64>; O]];
    }
}

/// Where a kernel of this module writes its rows of `O` values: `[[f64; O]]` (a slice, a
/// `Vec` or an array of rows), or
/// `[[MaybeUninit<f64>; O]]` that every row of a successful call initialises (after an error,
/// rows past the failing one may be left unwritten).
pub trait Output<const O: usize>: sealed::WriteOnly<O> {}

impl<const O: usize> sealed::WriteOnly<O> for [[f64; O]] {
    #[allow(unsafe_code)]
    fn write_only(&mut self) -> &mut [[MaybeUninit<f64>; O]] {
        // SAFETY: `MaybeUninit<f64>` has the layout of `f64`, and this module writes only
        // initialised values through the view (the trait is sealed), so the rows stay
        // initialised.
        unsafe { &mut *(self as *mut [[f64; O]] as *mut [[MaybeUninit<f64>; O]]) }
    }
}

impl<const O: usize> sealed::WriteOnly<O> for [[MaybeUninit<f64>; O]] {
    fn write_only(&mut self) -> &mut [[MaybeUninit<f64>; O]] {
        self
    }
}

impl<const O: usize> sealed::WriteOnly<O> for Vec<[f64; O]> {
    fn write_only(&mut self) -> &mut [[MaybeUninit<f64>; O]] {
        self.as_mut_slice().write_only()
    }
}

impl<const O: usize, const K: usize> sealed::WriteOnly<O> for [[f64; O]; K] {
    fn write_only(&mut self) -> &mut [[MaybeUninit<f64>; O]] {
        self.as_mut_slice().write_only()
    }
}

impl<const O: usize> Output<O> for [[f64; O]] {}
impl<const O: usize> Output<O> for [[MaybeUninit<f64>; O]] {}
impl<const O: usize> Output<O> for Vec<[f64; O]> {}
impl<const O: usize, const K: usize> Output<O> for [[f64; O]; K] {}

/// The rows of `out`, to be written (every one, on success) and never read.
pub(crate) fn write_only<const O: usize>(
    out: &mut (impl Output<O> + ?Sized),
) -> &mut [[MaybeUninit<f64>; O]] {
    out.write_only()
}

/// `value` as a row of [`Output`].
#[inline(always)]
fn written<const O: usize>(value: [f64; O]) -> [MaybeUninit<f64>; O] {
    value.map(MaybeUninit::new)
}

/// Rows per parallel chunk; batches shorter than this run on the calling thread.
pub const CHUNK: usize = 8192;

/// The length of a result broadcast from two batches: equal lengths, or one of them 1.
pub fn broadcast_len(a: (&str, usize), b: (&str, usize)) -> Result<usize> {
    match (a.1, b.1) {
        (n, m) if n == m => Ok(n),
        (1, m) => Ok(m),
        (n, 1) => Ok(n),
        (n, m) => Err(Error::invalid(
            a.0,
            format!("holds {n} items but {} holds {m}; lengths must match or one must be 1", b.0),
        )),
    }
}

/// Item `i` of a batch broadcast to any length: a batch of one repeats its single item.
pub fn item<T>(batch: &[T], i: usize) -> &T {
    &batch[if batch.len() == 1 { 0 } else { i }]
}

/// Fill `out[i]` with `f(i)` for every row, in parallel for large batches.
pub fn fill<const O: usize>(
    out: &mut (impl Output<O> + ?Sized),
    f: impl Fn(usize) -> Result<[f64; O]> + Sync,
) -> Result<()> {
    let out = out.write_only();
    let run_chunk = |start: usize, chunk: &mut [[MaybeUninit<f64>; O]]| -> Option<Error> {
        for (k, row) in chunk.iter_mut().enumerate() {
            match f(start + k) {
                Ok(value) => *row = written(value),
                Err(e) => return Some(e.at(start + k)),
            }
        }
        None
    };
    let first_error = if out.len() <= CHUNK {
        run_chunk(0, out)
    } else {
        out.par_chunks_mut(CHUNK)
            .enumerate()
            .filter_map(|(c, chunk)| run_chunk(c * CHUNK, chunk).map(|e| (c, e)))
            .min_by_key(|(c, _)| *c)
            .map(|(_, e)| e)
    };
    first_error.map_or(Ok(()), Err)
}

/// `Σ` over `0..n` in fixed chunks: `f(range)` sums the terms of one chunk of [`CHUNK`]
/// indices in order (in parallel for more than one chunk) and the chunk sums are added in
/// chunk order, so the result is bitwise the same for any thread count. `f` reports the
/// lowest bad index of its chunk (with [`Error::at`]); the lowest chunk's error is returned.
pub fn sum<const S: usize>(
    n: usize,
    f: impl Fn(std::ops::Range<usize>) -> Result<[f64; S]> + Sync,
) -> Result<[f64; S]> {
    let chunk = |c: usize| f(c * CHUNK..((c + 1) * CHUNK).min(n));
    let chunks = n.div_ceil(CHUNK);
    let sums: Vec<Result<[f64; S]>> =
        if chunks <= 1 { vec![chunk(0)] } else { (0..chunks).into_par_iter().map(chunk).collect() };
    let mut total = [0.0; S];
    for s in sums {
        for (a, t) in total.iter_mut().zip(s?) {
            *a += t;
        }
    }
    Ok(total)
}

/// `out[i] = f(&input[i])` for every row.
pub fn map<const I: usize, const O: usize>(
    input: &[[f64; I]],
    out: &mut (impl Output<O> + ?Sized),
    f: impl Fn(&[f64; I]) -> Result<[f64; O]> + Sync,
) -> Result<()> {
    let out = out.write_only();
    if input.len() != out.len() {
        return Err(Error::invalid("out", "must have as many rows as the input"));
    }
    fill(out, |i| f(&input[i]))
}

/// `out[i] = f(&a[i], &b[i])` with a batch of length 1 broadcast against the other.
pub fn map2<const A: usize, const B: usize, const O: usize>(
    a: &[[f64; A]],
    b: &[[f64; B]],
    out: &mut (impl Output<O> + ?Sized),
    f: impl Fn(&[f64; A], &[f64; B]) -> Result<[f64; O]> + Sync,
) -> Result<()> {
    let out = out.write_only();
    let n = broadcast_len(("a", a.len()), ("b", b.len()))?;
    if out.len() != n {
        return Err(Error::invalid("out", "must have the broadcast length of the inputs"));
    }
    fill(out, |i| f(item(a, i), item(b, i)))
}

/// Rows per block of [`lanes`].
pub const LANES: usize = 8;

/// A kernel on blocks of [`LANES`] rows for [`lanes`].
pub trait LaneKernel<const I: usize, const O: usize>: Sync {
    /// Fill `out` from `rows` (at most [`LANES`]; `first` is the index of the first row) and
    /// return a count to be summed over the blocks. Implementations are `#[inline(always)]`,
    /// so that they are compiled inside the SIMD context `simd` of [`lanes`], and gather the
    /// rows into one array per component before the arithmetic: loops over the interleaved
    /// rows themselves compiled to scalar code (checked in the disassembly of a release
    /// build). Where LLVM still keeps the lanes scalar (divisions and square roots), the
    /// kernel writes them with `simd`'s vector operations.
    ///
    /// # Errors
    /// A bad row, with its index.
    fn block<S: pulp::Simd>(
        &self,
        simd: S,
        first: usize,
        rows: &[[f64; I]],
        out: &mut [[f64; O]],
    ) -> Result<usize>;
}

/// The rows of a block gathered by component, `c[j][k]` = component `j` of row `k` (rows past
/// `rows.len()` zero), for the arithmetic over contiguous lanes of a [`LaneKernel`].
#[inline(always)]
pub fn by_component<const I: usize>(rows: &[[f64; I]]) -> [[f64; LANES]; I] {
    let mut c = [[0.0; LANES]; I];
    for (k, row) in rows.iter().enumerate() {
        for (lane, &v) in c.iter_mut().zip(row) {
            lane[k] = v;
        }
    }
    c
}

/// `f` on the lanes of a block by component (`c[j]` the lanes of component `j`, as from
/// [`by_component`]), one vector of `simd` at a time: `f` is written with `simd`'s operations,
/// for arithmetic that LLVM leaves scalar when it is written as loops over the lanes
/// (divisions and square roots). Returns the lanes of the `O` output components.
#[inline(always)]
pub fn by_vector<S: pulp::Simd, const I: usize, const O: usize>(
    _: S,
    c: &[[f64; LANES]; I],
    f: impl Fn([S::f64s; I]) -> [S::f64s; O],
) -> [[f64; LANES]; O] {
    let mut out = [[0.0; LANES]; O];
    // LANES is a multiple of every vector width pulp offers (1, 2, 4, 8), so nothing is left.
    for v in 0..LANES / S::F64_LANES {
        let r = f(std::array::from_fn(|j| S::as_simd_f64s(&c[j]).0[v]));
        for (lanes, value) in out.iter_mut().zip(r) {
            S::as_mut_simd_f64s(lanes).0[v] = value;
        }
    }
    out
}

/// `f` of [`by_vector`] on one row, in plain scalar arithmetic (`pulp::Scalar`): the row
/// function that shares its arithmetic, bit for bit, with the lanes.
#[inline(always)]
pub fn on_row<const I: usize, const O: usize>(
    row: [f64; I],
    f: impl Fn(pulp::Scalar, [f64; I]) -> [f64; O],
) -> [f64; O] {
    f(pulp::Scalar::new(), row)
}

/// A kernel on blocks of [`LANES`] pairs of rows (one of `a`, one of `b`) for [`lanes2`]; see
/// [`LaneKernel`] for the rules.
pub trait PairKernel<const A: usize, const B: usize, const O: usize>: Sync {
    /// Fill `out` from the pairs `a[k]`, `b[k]` (at most [`LANES`]; `first` is the index of
    /// the first) and return a count to be summed over the blocks.
    ///
    /// # Errors
    /// A bad row, with its index.
    fn block<S: pulp::Simd>(
        &self,
        simd: S,
        first: usize,
        a: &[[f64; A]],
        b: &[[f64; B]],
        out: &mut [[f64; O]],
    ) -> Result<usize>;
}

/// `kernel.block` on every block of [`LANES`] rows (the last one may be shorter), in parallel
/// chunks of [`CHUNK`] rows, each chunk compiled for the SIMD instruction set found at run
/// time (AVX2 or AVX-512 through `pulp`), so that a block's loops over its lanes vectorise. Returns the
/// sum of the blocks' counts, or the error of the lowest failing block (independent of the
/// thread count).
pub fn lanes<const I: usize, const O: usize>(
    input: &[[f64; I]],
    out: &mut (impl Output<O> + ?Sized),
    kernel: &impl LaneKernel<I, O>,
) -> Result<usize> {
    // Rows of no numbers take no memory: the single-input kernel is a pair kernel whose
    // second rows are empty.
    let none = vec![[0.0; 0]; input.len()];
    lanes2(input, &none, out, &Single(kernel))
}

/// [`lanes`] for a kernel on pairs of rows `a[i]`, `b[i]` (all three of one length).
///
/// # Errors
/// Lengths that differ, or the lowest failing block's error.
pub fn lanes2<const A: usize, const B: usize, const O: usize>(
    a: &[[f64; A]],
    b: &[[f64; B]],
    out: &mut (impl Output<O> + ?Sized),
    kernel: &impl PairKernel<A, B, O>,
) -> Result<usize> {
    let out = out.write_only();
    if a.len() != out.len() || b.len() != out.len() {
        return Err(Error::invalid("out", "must have as many rows as the inputs"));
    }
    let chunks: Vec<Result<usize>> = out
        .par_chunks_mut(CHUNK)
        .zip(a.par_chunks(CHUNK))
        .zip(b.par_chunks(CHUNK))
        .enumerate()
        .map(|(c, ((out, a), b))| vectorize(LaneChunk { start: c * CHUNK, a, b, out, kernel }))
        .collect();
    chunks.into_iter().sum()
}

/// `op` compiled for AVX2 where the CPU has it, else for the best instruction set `pulp`
/// finds. Not AVX-512: there LLVM turns the lane kernels' gathering of interleaved rows into
/// gather and scatter instructions, which made the quaternion product 2.5x slower than with
/// AVX2 on an AVX-512 machine (AMD EPYC, docs/performance-notes.md).
#[inline(always)]
pub(crate) fn vectorize<Op: pulp::WithSimd>(op: Op) -> Op::Output {
    #[cfg(target_arch = "x86_64")]
    if let Some(simd) = pulp::x86::V3::try_new() {
        return pulp::Simd::vectorize(simd, op);
    }
    pulp::Arch::new().dispatch(op)
}

/// A [`LaneKernel`] as a [`PairKernel`] whose second rows are empty.
struct Single<'a, K>(&'a K);

impl<const I: usize, const O: usize, K: LaneKernel<I, O>> PairKernel<I, 0, O> for Single<'_, K> {
    #[inline(always)]
    fn block<S: pulp::Simd>(
        &self,
        simd: S,
        first: usize,
        a: &[[f64; I]],
        _: &[[f64; 0]],
        out: &mut [[f64; O]],
    ) -> Result<usize> {
        self.0.block(simd, first, a, out)
    }
}

/// One parallel chunk of [`lanes2`].
struct LaneChunk<'a, const A: usize, const B: usize, const O: usize, K> {
    start: usize,
    a: &'a [[f64; A]],
    b: &'a [[f64; B]],
    out: &'a mut [[MaybeUninit<f64>; O]],
    kernel: &'a K,
}

impl<const A: usize, const B: usize, const O: usize, K: PairKernel<A, B, O>> pulp::WithSimd
    for LaneChunk<'_, A, B, O, K>
{
    type Output = Result<usize>;

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, simd: S) -> Result<usize> {
        let LaneChunk { start, a, b, out, kernel } = self;
        let mut count = 0;
        let blocks = a.chunks(LANES).zip(b.chunks(LANES)).zip(out.chunks_mut(LANES));
        for (k, ((a, b), out)) in blocks.enumerate() {
            let mut block = [[0.0; O]; LANES];
            count += kernel.block(simd, start + k * LANES, a, b, &mut block[..out.len()])?;
            for (row, &value) in out.iter_mut().zip(block.iter()) {
                *row = written(value);
            }
        }
        Ok(count)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lowest_failing_row_is_reported_for_large_batches() {
        let input: Vec<[f64; 1]> = (0..100_000).map(|i| [i as f64]).collect();
        let mut out = vec![[0.0; 1]; input.len()];
        let err = map(&input, &mut out, |x| {
            if x[0] >= 30_000.0 && (x[0] as usize).is_multiple_of(7) {
                Err(Error::invalid("x", "bad"))
            } else {
                Ok([x[0] * 2.0])
            }
        })
        .unwrap_err();
        assert_eq!(
            err,
            Error::InvalidInput { arg: "x".into(), index: Some(30_002), reason: "bad".into() }
        );
    }

    #[test]
    fn sums_are_bitwise_the_same_for_any_thread_count_and_report_the_lowest_bad_term() {
        let n = 5 * CHUNK + 123;
        let term = |i: usize| {
            let x = (i as f64 * 0.618_033_988_7).sin() * 1e3;
            [x, x * x]
        };
        let terms = |r: std::ops::Range<usize>| -> Result<[f64; 2]> {
            let mut acc = [0.0; 2];
            for i in r {
                let t = term(i);
                acc[0] += t[0];
                acc[1] += t[1];
            }
            Ok(acc)
        };
        let on = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| sum(n, terms).unwrap())
        };
        let one = on(1);
        assert_eq!(one.map(f64::to_bits), on(4).map(f64::to_bits));
        let exact: f64 = (0..n).map(|i| term(i)[0]).sum();
        assert!((one[0] - exact).abs() < 1e-9 * n as f64);
        let failing = |r: std::ops::Range<usize>| -> Result<[f64; 1]> {
            match r.clone().find(|i| i % 7000 == 6999) {
                Some(i) => Err(Error::invalid("x", "bad").at(i)),
                None => Ok([r.len() as f64]),
            }
        };
        let err = sum(n, failing).unwrap_err();
        assert_eq!(
            err,
            Error::InvalidInput { arg: "x".into(), index: Some(6999), reason: "bad".into() }
        );
    }

    #[test]
    fn broadcasting_repeats_a_single_row() {
        let a = [[2.0]];
        let b = [[1.0], [2.0], [3.0]];
        let mut out = [[0.0]; 3];
        map2(&a, &b, &mut out, |x, y| Ok([x[0] * y[0]])).unwrap();
        assert_eq!(out, [[2.0], [4.0], [6.0]]);
        assert!(broadcast_len(("a", 2), ("b", 3)).is_err());
    }

    /// Doubles each row lane by lane, counting the rows it saw.
    struct Double;

    impl LaneKernel<2, 2> for Double {
        fn block<S: pulp::Simd>(
            &self,
            _: S,
            _: usize,
            rows: &[[f64; 2]],
            out: &mut [[f64; 2]],
        ) -> Result<usize> {
            for (o, r) in out.iter_mut().zip(rows) {
                *o = [2.0 * r[0], 2.0 * r[1]];
            }
            Ok(rows.len())
        }
    }

    #[test]
    fn unwritten_rows_are_written_in_full_as_initialised_ones_are() {
        let n = 3 * CHUNK + 5; // parallel chunks and a ragged last block
        let input: Vec<[f64; 2]> = (0..n).map(|i| [i as f64, -(i as f64)]).collect();
        let mut expected = vec![[f64::NAN; 2]; n];
        assert_eq!(lanes(&input, &mut expected, &Double).unwrap(), n);
        let mut unwritten = vec![[MaybeUninit::<f64>::uninit(); 2]; n];
        assert_eq!(lanes(&input, unwritten.as_mut_slice(), &Double).unwrap(), n);
        let written: Vec<[f64; 2]> = unwritten.iter().map(|r| r.map(|v| read(&v))).collect();
        assert_eq!(written, expected);
        assert!(expected.iter().enumerate().all(|(i, r)| *r == [2.0 * i as f64, -2.0 * i as f64]));

        let mut unwritten = vec![[MaybeUninit::<f64>::uninit(); 1]; n];
        map(&input, unwritten.as_mut_slice(), |r| Ok([r[0] + r[1]])).unwrap();
        assert!(unwritten.iter().all(|r| read(&r[0]) == 0.0));
    }

    /// A value the kernels wrote (the test reads only those).
    #[allow(unsafe_code)]
    fn read(v: &MaybeUninit<f64>) -> f64 {
        // SAFETY: called only on rows the kernel under test wrote.
        unsafe { v.assume_init() }
    }
}
