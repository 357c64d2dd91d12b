//! Borrowing numpy arrays as slices of fixed-size rows, and returning results as numpy arrays
//! without a copy.
//!
//! Inputs arrive as C-contiguous `float64` arrays (the Python layer converts array-likes once);
//! a batch of `n` items of shape `row_shape` is viewed as `&[[f64; N]]` with
//! `N = product(row_shape)`. Results are written straight into new numpy arrays.

use super::error::detached;
use crate::error::Error;
use numpy::ndarray::IxDyn;
use numpy::{PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;
use rayon::prelude::*;

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

/// Touch every 4 KB page of the fresh, zeroed `values`, in parallel runs of one huge page.
///
/// Measured on the rotations bench (72 MB from `as_matrix` of 10^6 rotations, idle machine,
/// two threads): faulting the pages in as the kernel's chunks reach them took 4–14 ms from
/// call to call, touching them first in whole huge pages 5–6.5 ms every call.
fn touch_pages(values: &mut [f64]) {
    values.par_chunks_mut(HUGE_PAGE).for_each(|run| {
        for v in run.iter_mut().step_by(512) {
            *v = 0.0;
        }
    });
}

/// A new numpy array of shape `(n, *row_shape)` whose rows `fill` computes with the GIL
/// released; errors map to Python exceptions (see [`detached`]).
///
/// The buffer comes from numpy's allocator, which backs large arrays with huge pages: for
/// batches of millions of rows the page faults of a fresh buffer otherwise cost more than the
/// kernel itself. Buffers larger than a huge page have their pages touched first
/// ([`touch_pages`]).
pub fn compute<'py, const N: usize>(
    py: Python<'py>,
    n: usize,
    row_shape: &[usize],
    fill: impl FnOnce(&mut [[f64; N]]) -> Result<(), Error> + Send,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let mut shape = vec![n];
    shape.extend_from_slice(row_shape);
    let array = PyArrayDyn::<f64>::zeros(py, IxDyn(&shape), false);
    {
        let mut guard = array.readwrite();
        let flat = guard.as_slice_mut().expect("a new numpy array is contiguous");
        let (rows, rest) = flat.as_chunks_mut::<N>();
        assert!(rest.is_empty(), "row length equals the product of row_shape");
        detached(py, || {
            if rows.len() * N > HUGE_PAGE {
                touch_pages(rows.as_flattened_mut());
            }
            fill(rows)
        })?;
    }
    Ok(array)
}
