//! One exception tree for Python, one conversion from [`kinema::Error`], and the one helper
//! that leaves Python, runs a kernel and maps its error.

use crate::error::Error;
use pyo3::create_exception;
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;

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

/// Run `f` with the GIL released and turn its error into the matching Python exception.
pub fn detached<T, F>(py: Python<'_>, f: F) -> PyResult<T>
where
    T: Send,
    F: FnOnce() -> Result<T, Error> + Send,
{
    py.detach(f).map_err(PyErr::from)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("SimulationError", py.get_type::<SimulationError>())?;
    m.add("ParseError", py.get_type::<ParseError>())?;
    Ok(())
}
