//! The one zero-copy view of a compiled object's state: a read-only numpy array over a Rust
//! buffer, whose base is the Python object that owns the buffer, so the view keeps it alive
//! (`del` of the parent leaves the view valid) and no copy is made per step.

use crate::error::Error;
use numpy::ndarray::{ArrayViewD, IxDyn};
use numpy::{PyArray, PyArrayDyn, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::PyClass;

/// A read-only view of shape `shape` over the buffer `data(slf)` picks from `slf`.
///
/// The caller's buffer must never be reallocated while `slf` lives (a fixed-capacity or
/// fixed-size state written in place only); every system that offers views guarantees that.
#[allow(unsafe_code)]
pub fn view<'py, C: PyClass>(
    slf: &Bound<'py, C>,
    shape: &[usize],
    data: impl FnOnce(&C) -> &[f64],
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let this = slf.borrow();
    let view = ArrayViewD::from_shape(IxDyn(shape), data(&this))
        .map_err(|e| Error::invalid("state", e.to_string()))?;
    // SAFETY: the buffer belongs to `slf`, which the array keeps alive as its base, and (as
    // documented above) it is never reallocated, only overwritten in place, so the pointer
    // stays valid for the array's lifetime.
    let array = unsafe { PyArray::borrow_from_array(&view, slf.clone().into_any()) };
    drop(this);
    array.readwrite().make_nonwriteable();
    Ok(array)
}
