//! One exception tree for Python, one conversion from [`kinema::Error`], and the one helper
//! that leaves Python, runs a kernel and maps its error.

use crate::error::Error;
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyTuple, PyType};
use std::sync::{Arc, RwLock};

create_exception!(
    kinema,
    KinemaError,
    PyException,
    "The root of kinema's own exceptions: `except kinema.KinemaError` catches a failed \
     simulation, an unreadable file and a bad checkpoint alike."
);

/// `SimulationError(KinemaError, RuntimeError)`, made once.
static SIMULATION_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();
/// `ParseError(KinemaError, ValueError)`, made once.
static PARSE_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();

/// The class `name(KinemaError, base)` of module `kinema`. Python's exceptions take one base
/// in `create_exception!`; these need two (the root and the builtin they always derived
/// from, so `except ValueError` keeps catching a `ParseError`), so they are made by calling
/// `type(name, bases, namespace)` as a `class` statement would.
fn subclass<'py>(
    py: Python<'py>,
    cell: &'static PyOnceLock<Py<PyType>>,
    name: &str,
    base: Bound<'py, PyType>,
    doc: &str,
) -> Bound<'py, PyType> {
    cell.get_or_init(py, || {
        let make = || -> PyResult<Py<PyType>> {
            let namespace = PyDict::new(py);
            namespace.set_item("__module__", "kinema")?;
            namespace.set_item("__doc__", doc)?;
            let bases = PyTuple::new(py, [py.get_type::<KinemaError>(), base])?;
            let class = py.get_type::<PyType>().call1((name, bases, namespace))?;
            Ok(class.cast_into::<PyType>()?.unbind())
        };
        make().expect("creating an exception class cannot fail")
    })
    .bind(py)
    .clone()
}

/// `kinema.SimulationError`: a simulation diverged or a solver failed.
pub fn simulation_error(py: Python<'_>) -> Bound<'_, PyType> {
    subclass(
        py,
        &SIMULATION_ERROR,
        "SimulationError",
        py.get_type::<PyRuntimeError>(),
        "A simulation diverged or a solver failed; the state is left at the last good step.",
    )
}

/// `kinema.ParseError`: a file could not be parsed.
pub fn parse_error(py: Python<'_>) -> Bound<'_, PyType> {
    subclass(
        py,
        &PARSE_ERROR,
        "ParseError",
        py.get_type::<PyValueError>(),
        "A file could not be parsed; the message gives the file, the line and what was expected.",
    )
}

impl From<Error> for PyErr {
    fn from(e: Error) -> PyErr {
        let msg = e.to_string();
        match e {
            Error::InvalidInput { .. } | Error::Shape { .. } => PyValueError::new_err(msg),
            Error::Parse { .. } => Python::attach(|py| PyErr::from_type(parse_error(py), msg)),
            Error::Diverged { .. } | Error::SolverFailed { .. } => {
                Python::attach(|py| PyErr::from_type(simulation_error(py), msg))
            }
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
    detached_on(py, true, f)
}

/// [`detached`], on the chosen thread pool only when `parallel`: work too small to be shared
/// out runs on the calling thread, since handing it to a pool wakes a pool thread and waits
/// for it on every call.
pub fn detached_on<T, F>(py: Python<'_>, parallel: bool, f: F) -> PyResult<T>
where
    T: Send,
    F: FnOnce() -> Result<T, Error> + Send,
{
    let pool = if parallel { POOL.read().unwrap_or_else(|e| e.into_inner()).clone() } else { None };
    py.detach(move || match pool {
        Some(pool) => pool.install(f),
        None => f(),
    })
    .map_err(PyErr::from)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("KinemaError", py.get_type::<KinemaError>())?;
    m.add("SimulationError", simulation_error(py))?;
    m.add("ParseError", parse_error(py))?;
    Ok(())
}
