//! One exception tree for Python, one conversion from [`kinema::Error`], and the one helper
//! that leaves Python, runs a kernel and maps its error.

use crate::error::Error;
use pyo3::create_exception;
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyTuple};
use std::sync::{Arc, RwLock};

create_exception!(
    _kinema,
    SimulationError,
    PyRuntimeError,
    "A simulation diverged or a solver failed; the state is left at the last good step."
);
create_exception!(
    _kinema,
    ParseError,
    PyValueError,
    "A file could not be parsed; the message gives the file, the line and what was expected."
);

impl From<Error> for PyErr {
    fn from(e: Error) -> PyErr {
        let msg = e.to_string();
        match e {
            Error::InvalidInput { .. } | Error::Shape { .. } => PyValueError::new_err(msg),
            Error::Parse { .. } => ParseError::new_err(msg),
            Error::Diverged { .. } | Error::SolverFailed { .. } => SimulationError::new_err(msg),
        }
    }
}

/// The pool chosen by `set_num_threads`, or `None` for rayon's global pool.
static POOL: RwLock<Option<Arc<rayon::ThreadPool>>> = RwLock::new(None);

/// Run the parallel kernels of every later call on a pool of `n` threads.
pub fn set_pool(n: usize) -> PyResult<()> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .build()
        .map_err(|e| PyRuntimeError::new_err(format!("cannot start {n} threads: {e}")))?;
    *POOL.write().unwrap_or_else(|e| e.into_inner()) = Some(Arc::new(pool));
    Ok(())
}

/// Threads of the pool the kernels run on.
pub fn num_threads() -> usize {
    match &*POOL.read().unwrap_or_else(|e| e.into_inner()) {
        Some(pool) => pool.current_num_threads(),
        None => rayon::current_num_threads(),
    }
}

/// Run `f` with the GIL released, on the chosen thread pool, and turn its error into the
/// matching Python exception.
pub fn detached<T, F>(py: Python<'_>, f: F) -> PyResult<T>
where
    T: Send,
    F: FnOnce() -> Result<T, Error> + Send,
{
    let pool = POOL.read().unwrap_or_else(|e| e.into_inner()).clone();
    py.detach(move || match pool {
        Some(pool) => pool.install(f),
        None => f(),
    })
    .map_err(PyErr::from)
}

/// What `__reduce__` returns: the class's `_from_snapshot` and its arguments.
pub type Reduced<'py> = (Bound<'py, PyAny>, Bound<'py, PyTuple>);

/// The pickle recipe `(cls._from_snapshot, (snapshot bytes, *extra))` of a compiled object.
pub fn reduce<'py>(
    slf: &Bound<'py, PyAny>,
    snapshot: Vec<u8>,
    extra: Vec<Bound<'py, PyAny>>,
) -> PyResult<Reduced<'py>> {
    let py = slf.py();
    let mut args = vec![PyBytes::new(py, &snapshot).into_any()];
    args.extend(extra);
    Ok((slf.get_type().getattr("_from_snapshot")?, PyTuple::new(py, args)?))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("SimulationError", py.get_type::<SimulationError>())?;
    m.add("ParseError", py.get_type::<ParseError>())?;
    Ok(())
}
