//! PyO3 bindings: the compiled module `kinema._kinema`.
//!
//! Bindings only convert, release the GIL and map errors; all numerics live in the pure-Rust
//! core. Each subject registers its functions and classes from its own file.

use pyo3::prelude::*;

mod anim;
mod array;
mod constraints;
mod error;
mod mocap;
mod ode;
mod particles;
mod rigid;
mod rotation;

/// The compiled core of kinema. Use it through the `kinema` package, which checks and
/// converts arguments and adds the Python-side API.
#[pymodule]
fn _kinema(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    error::register(m)?;
    rotation::register(m)?;
    rigid::register(m)?;
    ode::register(m)?;
    particles::register(m)?;
    constraints::register(m)?;
    anim::register(m)?;
    mocap::register(m)?;
    Ok(())
}
