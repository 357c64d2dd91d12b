//! Borrowing numpy arrays as slices of fixed-size rows, and returning results as numpy arrays
//! without a copy.
//!
//! Inputs arrive as C-contiguous `float64` arrays (the Python layer converts array-likes once);
//! a batch of `n` items of shape `row_shape` is viewed as `&[[f64; N]]` with
//! `N = product(row_shape)`.

use crate::error::Error;
use numpy::ndarray::{ArrayD, IxDyn};
use numpy::{IntoPyArray, PyArrayDyn, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;

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

/// A numpy array of shape `(rows.len(), *row_shape)` that takes ownership of `rows`.
pub fn to_numpy<'py, const N: usize>(
    py: Python<'py>,
    rows: Vec<[f64; N]>,
    row_shape: &[usize],
) -> Bound<'py, PyArrayDyn<f64>> {
    let mut shape = vec![rows.len()];
    shape.extend_from_slice(row_shape);
    ArrayD::from_shape_vec(IxDyn(&shape), rows.into_flattened())
        .expect("row length equals the product of row_shape")
        .into_pyarray(py)
}
