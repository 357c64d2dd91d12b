//! PyO3 bindings: the compiled module `kinema._kinema`.
//!
//! Bindings only convert, release the GIL and map errors; all numerics live in the pure-Rust
//! core. Each subject registers its functions and classes from its own file.

use pyo3::prelude::*;

mod anim;
mod args;
mod array;
mod biped3d;
mod character;
mod character_tracking;
mod cloth;
mod constraints;
mod crowd;
mod error;
mod flock;
mod fluid;
mod geometry;
mod ik;
mod mocap;
mod ode;
mod particles;
mod pickle;
mod rigid;
mod rods;
mod rotation;
mod skin;
mod view;
mod walker;

/// Use `n` threads (1 to `MAX_THREADS` = 1024) in every parallel kernel from now on (any
/// time, as often as wanted; results are bitwise the same for any thread count).
#[pyfunction]
fn set_num_threads(n: args::Int) -> PyResult<()> {
    error::set_pool(n.range("n", 1, args::MAX_THREADS)?)
}

/// Threads used by the parallel kernels.
#[pyfunction]
fn num_threads() -> usize {
    error::num_threads()
}

/// How the compiled module was built: `profile` ("release" or "debug"), `target` (arch-os),
/// `features` of the crate, `simd` (vector instruction sets enabled at compile time).
#[pyfunction]
fn build_info() -> Vec<(&'static str, String)> {
    let profile = if cfg!(debug_assertions) { "debug" } else { "release" };
    let simd: Vec<&str> = [
        ("sse2", cfg!(target_feature = "sse2")),
        ("avx", cfg!(target_feature = "avx")),
        ("avx2", cfg!(target_feature = "avx2")),
        ("fma", cfg!(target_feature = "fma")),
        ("neon", cfg!(target_feature = "neon")),
    ]
    .iter()
    .filter(|(_, on)| *on)
    .map(|(name, _)| *name)
    .collect();
    vec![
        ("profile", profile.to_string()),
        ("target", format!("{}-{}", std::env::consts::ARCH, std::env::consts::OS)),
        ("features", "python".to_string()),
        ("simd", simd.join(" ")),
    ]
}

/// The compiled core of kinema. Use it through the `kinema` package, which checks and
/// converts arguments and adds the Python-side API.
#[pymodule]
fn _kinema(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(set_num_threads, m)?)?;
    m.add_function(wrap_pyfunction!(num_threads, m)?)?;
    m.add_function(wrap_pyfunction!(build_info, m)?)?;
    error::register(m)?;
    rotation::register(m)?;
    rigid::register(m)?;
    ode::register(m)?;
    particles::register(m)?;
    constraints::register(m)?;
    cloth::register(m)?;
    fluid::register(m)?;
    crowd::register(m)?;
    flock::register(m)?;
    rods::register(m)?;
    character::register(m)?;
    biped3d::register(m)?;
    character_tracking::register(m)?;
    anim::register(m)?;
    mocap::register(m)?;
    ik::register(m)?;
    skin::register(m)?;
    Ok(())
}
