//! The one pickling recipe of the compiled classes: `__reduce__` returns
//! `(cls._from_snapshot, (snapshot bytes, *extra))`, the snapshot taken with the GIL released
//! (see `kinema::snapshot` for what it stores); `_from_snapshot` rebuilds the object from it.

use super::error::detached;
use crate::snapshot::Snapshot;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyTuple};
use pyo3::PyClass;

/// What `__reduce__` returns: the class's `_from_snapshot` and its arguments.
pub type Reduced<'py> = (Bound<'py, PyAny>, Bound<'py, PyTuple>);

/// The pickle recipe of `slf`, whose Rust state `inner(slf)` is stored as a snapshot;
/// `extra` are further arguments of `_from_snapshot` (the Python objects it is tied to).
pub fn reduce<'py, C, T>(
    slf: &Bound<'py, C>,
    inner: impl FnOnce(&C) -> &T,
    extra: Vec<Bound<'py, PyAny>>,
) -> PyResult<Reduced<'py>>
where
    C: PyClass,
    T: Snapshot + Sync,
{
    let this = slf.borrow();
    let state = inner(&this);
    let bytes = detached(slf.py(), || state.to_snapshot())?;
    recipe(slf.as_any(), &bytes, extra)
}

/// The pickle recipe `(cls._from_snapshot, (snapshot, *extra))` from a snapshot already
/// taken: for a class whose state cannot leave the GIL (it holds Python callables).
pub fn recipe<'py>(
    slf: &Bound<'py, PyAny>,
    snapshot: &[u8],
    extra: Vec<Bound<'py, PyAny>>,
) -> PyResult<Reduced<'py>> {
    let py = slf.py();
    let mut args = vec![PyBytes::new(py, snapshot).into_any()];
    args.extend(extra);
    Ok((slf.get_type().getattr("_from_snapshot")?, PyTuple::new(py, args)?))
}
