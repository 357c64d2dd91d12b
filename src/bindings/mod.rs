//! PyO3 bindings: the compiled module `kinema._kinema`.
//!
//! Bindings only convert, release the GIL and map errors; all numerics live in the pure-Rust
//! core. Each subject registers its functions and classes from its own file.

use pyo3::prelude::*;

mod anim;
mod array;
mod cloth;
mod constraints;
mod error;
mod ik;
mod mocap;
mod ode;
mod particles;
mod rigid;
mod rotation;

/// Use `n` threads in every parallel kernel from now on (any time, as often as wanted;
/// results are bitwise the same for any thread count).
#[pyfunction]
fn set_num_threads(n: usize) -> PyResult<()> {
    if n == 0 {
        return Err(crate::Error::invalid("n", "the thread count must be at least 1").into());
    }
    error::set_pool(n)
}

/// Threads used by the parallel kernels.
#[pyfunction]
fn num_threads() -> usize {
    error::num_threads()
}

/// The compiled core of kinema. Use it through the `kinema` package, which checks and
/// converts arguments and adds the Python-side API.
#[pymodule]
fn _kinema(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(set_num_threads, m)?)?;
    m.add_function(wrap_pyfunction!(num_threads, m)?)?;
    error::register(m)?;
    rotation::register(m)?;
    rigid::register(m)?;
    ode::register(m)?;
    particles::register(m)?;
    constraints::register(m)?;
    cloth::register(m)?;
    anim::register(m)?;
    mocap::register(m)?;
    ik::register(m)?;
    Ok(())
}
