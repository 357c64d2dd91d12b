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

/// A new C-contiguous numpy array of `shape`, every value 0.
///
/// Like `PyArray::zeros`, but the zeros are written here, in parallel runs of one huge page
/// on the pool of the kernels for large arrays, into a buffer from numpy's allocator (which
/// backs large arrays with huge pages), instead of by `calloc` on one thread.
#[allow(unsafe_code)]
fn zeros<'py>(py: Python<'py>, shape: &[usize]) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    // SAFETY: `f64` is `Copy` (the array may be dropped uninitialised); its values are only
    // written, through `MaybeUninit`, until every one is initialised below.
    let array = unsafe { PyArrayDyn::<f64>::new(py, IxDyn(shape), false) };
    let len = array.len();
    // SAFETY: a new C-contiguous array owns `len` values from `data()`, aligned for `f64`
    // and referenced by nothing else while this slice lives.
    let values =
        unsafe { std::slice::from_raw_parts_mut(array.data().cast::<MaybeUninit<f64>>(), len) };
    let zero = MaybeUninit::new(0.0);
    if len > HUGE_PAGE {
        detached(py, || {
            values.par_chunks_mut(HUGE_PAGE).for_each(|run| run.fill(zero));
            Ok(())
        })?;
    } else {
        values.fill(zero);
    }
    Ok(array)
}

/// A new numpy array of shape `(n, *row_shape)` whose rows `fill` computes with the GIL
/// released; errors map to Python exceptions (see [`detached`]).
pub fn compute<'py, const N: usize>(
    py: Python<'py>,
    n: usize,
    row_shape: &[usize],
    fill: impl FnOnce(&mut [[f64; N]]) -> Result<(), Error> + Send,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let mut shape = vec![n];
    shape.extend_from_slice(row_shape);
    let array = zeros(py, &shape)?;
    {
        let mut guard = array.readwrite();
        let flat = guard.as_slice_mut().expect("a new numpy array is contiguous");
        let (rows, rest) = flat.as_chunks_mut::<N>();
        assert!(rest.is_empty(), "row length equals the product of row_shape");
        detached(py, || fill(rows))?;
    }
    Ok(array)
}
