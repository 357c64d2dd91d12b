//! Linear stability: the growth factor `R(z)` per step on `y' = λy` (`z = hλ`) and the largest
//! stable step for given eigenvalues.

use super::Method;
use crate::error::{Error, Result};
use nalgebra::Complex;

type C = Complex<f64>;

/// The root of largest modulus of `a μ² + b μ + c = 0`.
fn dominant_root(a: C, b: C, c: C) -> C {
    let disc = (b * b - 4.0 * a * c).sqrt();
    let (r1, r2) = ((-b + disc) / (2.0 * a), (-b - disc) / (2.0 * a));
    if r1.norm() >= r2.norm() {
        r1
    } else {
        r2
    }
}

/// The stability function `R(z)` of `method`: the factor by which one step multiplies the
/// solution of `y' = λy` with `z = hλ`; the method is stable where `|R(z)| ≤ 1`.
///
/// One-step methods have the rational functions of their docs. For BDF2, a two-step method,
/// `R(z)` is the root of largest modulus of its characteristic polynomial
/// `(3 - 2z) ζ² - 4ζ + 1 = 0`. The second-order methods (symplectic Euler, velocity Verlet)
/// are applied to the oscillator `x'' = (z/h)² x` (eigenvalues `±z/h` of its first-order form)
/// and `R(z)` is the eigenvalue of largest modulus of their amplification matrix, a root of
/// `μ² - (2 + z²) μ + 1 = 0` for both.
pub fn stability_function(method: Method, z: C) -> C {
    let one = C::new(1.0, 0.0);
    match method {
        Method::ExplicitEuler => one + z,
        Method::Midpoint | Method::Heun => one + z + z * z / 2.0,
        Method::Rk4 => one + z + z * z / 2.0 + z * z * z / 6.0 + z * z * z * z / 24.0,
        Method::ImplicitEuler => one / (one - z),
        Method::Trapezoidal => (one + z / 2.0) / (one - z / 2.0),
        Method::Bdf2 => dominant_root(3.0 * one - 2.0 * z, C::new(-4.0, 0.0), one),
        Method::SymplecticEuler | Method::VelocityVerlet => {
            dominant_root(one, -(2.0 * one + z * z), one)
        }
    }
}

/// The largest step `h` such that `|R(hλ)| ≤ 1` for every eigenvalue `λ` and every step in
/// `(0, h]`, or `f64::INFINITY` when no step up to `|hλ| = 1e8` leaves the stability region
/// (A-stable methods, or no non-zero eigenvalue).
///
/// Along each eigenvalue's ray the step is doubled from `|hλ| = 1e-3` until `|R|` exceeds 1 (by
/// more than 1e-14), then the boundary is bisected to a relative precision of 1e-13. A method
/// already unstable at `|hλ| = 1e-3` (e.g. explicit Euler on an undamped oscillator) gets 0.
///
/// # Errors
/// An eigenvalue with positive real part (a growing solution has no stability limit to speak
/// of) or a non-finite one.
pub fn max_stable_dt(method: Method, eigenvalues: &[C]) -> Result<f64> {
    let mut best = f64::INFINITY;
    for (i, &lambda) in eigenvalues.iter().enumerate() {
        if !(lambda.re.is_finite() && lambda.im.is_finite()) {
            return Err(Error::InvalidInput {
                arg: "eigenvalues".into(),
                index: Some(i),
                reason: "is NaN or infinite".into(),
            });
        }
        if lambda.re > 0.0 {
            return Err(Error::InvalidInput {
                arg: "eigenvalues".into(),
                index: Some(i),
                reason: format!("has positive real part {}; only decaying or oscillating modes have a stability limit", lambda.re),
            });
        }
        let size = lambda.norm();
        if size == 0.0 {
            continue;
        }
        let stable = |h: f64| stability_function(method, lambda * h).norm() <= 1.0 + 1e-14;
        let mut lo = 1e-3 / size;
        if !stable(lo) {
            return Ok(0.0);
        }
        let mut hi = lo;
        while stable(hi) {
            lo = hi;
            hi *= 2.0;
            if hi * size > 1e8 {
                hi = f64::INFINITY;
                break;
            }
        }
        if hi.is_finite() {
            while hi - lo > 1e-13 * lo {
                let mid = 0.5 * (lo + hi);
                if stable(mid) {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            best = best.min(lo);
        }
    }
    Ok(best)
}
