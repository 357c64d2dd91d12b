//! Borrowing numpy arrays as slices of fixed-size rows, and returning results as numpy arrays
//! without a copy.
//!
//! Inputs arrive as C-contiguous `float64` arrays (the Python layer converts array-likes once);
//! a batch of `n` items of shape `row_shape` is viewed as `&[[f64; N]]` with
//! `N = product(row_shape)`. Results are written straight into new numpy arrays.

use super::error::detached_on;
use crate::error::Error;
use numpy::ndarray::IxDyn;
use numpy::{PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;
use rayon::prelude::*;
use std::mem::MaybeUninit;

fn shape_text(row_shape: &[usize]) -> String {
    let dims: Vec<String> =
        std::iter::once("N".to_string()).chain(row_shape.iter().map(|d| d.to_string())).collect();
    format!("({})", dims.join(", "))
}

/// View `arr` of shape `(n, *row_shape)` as `n` rows of `N` values.
pub fn rows<'a, const N: usize>(
    arr: &'a PyReadonlyArrayDyn<'_, f64>,
    arg: &str,
    row_shape: &[usize],
) -> PyResult<&'a [[f64; N]]> {
    let shape = arr.shape();
    if shape.len() != row_shape.len() + 1 || shape[1..] != *row_shape {
        return Err(Error::Shape {
            arg: arg.to_string(),
            expected: shape_text(row_shape),
            got: shape.to_vec(),
        }
        .into());
    }
    let flat = arr
        .as_slice()
        .map_err(|_| PyErr::from(Error::invalid(arg, "must be a C-contiguous float64 array")))?;
    Ok(flat.as_chunks::<N>().0)
}

/// Values in a huge page (2 MB).
const HUGE_PAGE: usize = 1 << 18;

/// Rows of a new output array that nothing has written yet.
pub type Unwritten<const N: usize> = [[MaybeUninit<f64>; N]];

/// `out` with every value set to 0, as initialised rows, for results that are not written
/// row by row through [`crate::batch::Output`] (the zeros are written in parallel runs of one
/// huge page for large arrays, on the kernels' pool).
#[allow(unsafe_code)]
pub fn zeroed<const N: usize>(out: &mut Unwritten<N>) -> &mut [[f64; N]] {
    let zero = [MaybeUninit::new(0.0); N];
    let run = HUGE_PAGE / N.max(1);
    if out.len() > run {
        out.par_chunks_mut(run).for_each(|rows| rows.fill(zero));
    } else {
        out.fill(zero);
    }
    // SAFETY: every value has just been initialised; `MaybeUninit<f64>` has `f64`'s layout.
    unsafe { &mut *(out as *mut Unwritten<N> as *mut [[f64; N]]) }
}

/// A new numpy array of shape `(n, *row_shape)` whose rows `fill` writes with the GIL
/// released; errors map to Python exceptions (see [`detached_on`]). Fewer rows than one
/// parallel chunk ([`crate::batch::CHUNK`]) are written on the calling thread: handing them
/// to the pool chosen by `set_num_threads` cost about 22 µs a call (a getter of 8 masses),
/// 100 times the work. `fill` must initialise every
/// row when it succeeds: through the kernels of [`crate::batch`] (which write every row of an
/// [`crate::batch::Output`]) or after [`zeroed`]. The array is not zeroed first, so results
/// cost one pass over memory, not two.
#[allow(unsafe_code)]
pub fn compute<'py, const N: usize>(
    py: Python<'py>,
    n: usize,
    row_shape: &[usize],
    fill: impl FnOnce(&mut Unwritten<N>) -> Result<(), Error> + Send,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let mut shape = vec![n];
    shape.extend_from_slice(row_shape);
    assert_eq!(
        shape.iter().product::<usize>(),
        n * N,
        "row length equals the product of row_shape"
    );
    // SAFETY: `f64` is `Copy`, so the array may be dropped with its values uninitialised (as it
    // is when `fill` fails); it is returned only after `fill` succeeded, having written every row.
    let array = unsafe { PyArrayDyn::<f64>::new(py, IxDyn(&shape), false) };
    // SAFETY: a new C-contiguous array owns `n * N` values from `data()`, aligned for `f64`
    // and referenced by nothing else while this slice lives; they are only written through it.
    let rows =
        unsafe { std::slice::from_raw_parts_mut(array.data().cast::<[MaybeUninit<f64>; N]>(), n) };
    detached_on(py, n >= crate::batch::CHUNK, || fill(rows))?;
    Ok(array)
}
