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
/// are applied to the damped oscillator `x'' + c x' + ω² x = 0` whose first-order eigenvalues
/// are `λ = z/h` and its conjugate (`ω = |λ|`, `c = -2 Re λ`: an undamped spring for imaginary
/// `λ`), exactly as their steps compute it, and `R(z)` is the eigenvalue of largest modulus of
/// the resulting 2x2 amplification matrix; undamped, it is a root of `μ² - (2 + z²) μ + 1 = 0`
/// for both.
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
            let m = oscillator_step(method, z.norm_sqr(), -2.0 * z.re);
            let (trace, det) = (m[0][0] + m[1][1], m[0][0] * m[1][1] - m[0][1] * m[1][0]);
            dominant_root(one, C::new(-trace, 0.0), C::new(det, 0.0))
        }
    }
}

/// The largest step `h` such that `method` is stable on the mode `x'' + c x' + ω² x = 0`
/// (`omega` in rad/s, `damping` = `c` in 1/s) for every step in `(0, h]`: a spring of a
/// particle system, the fastest vibration of a cloth. One-step first-order methods are judged
/// on the mode's two eigenvalues `(-c ± √(c² - 4ω²)) / 2` by [`max_stable_dt`]; the
/// second-order methods (symplectic Euler, velocity Verlet) by the spectral radius of their
/// amplification matrix on the mode, which for an overdamped mode is not a function of either
/// eigenvalue alone. `f64::INFINITY` for A-stable methods or a mode at rest.
///
/// # Errors
/// A negative or non-finite `omega` or `damping`.
pub fn max_stable_dt_oscillator(method: Method, omega: f64, damping: f64) -> Result<f64> {
    for (arg, value) in [("omega", omega), ("damping", damping)] {
        if !(value.is_finite() && value >= 0.0) {
            return Err(Error::invalid(arg, format!("must be finite and >= 0, got {value}")));
        }
    }
    if !method.is_second_order() {
        let root = C::new(damping * damping - 4.0 * omega * omega, 0.0).sqrt();
        let pair = [(root - damping) / 2.0, (-root - damping) / 2.0];
        return max_stable_dt(method, &pair);
    }
    let size = omega.max(damping);
    if size == 0.0 {
        return Ok(f64::INFINITY);
    }
    Ok(largest_stable_step(size, |h| {
        let m = oscillator_step(method, (omega * h).powi(2), damping * h);
        let (trace, det) = (m[0][0] + m[1][1], m[0][0] * m[1][1] - m[0][1] * m[1][0]);
        let one = C::new(1.0, 0.0);
        dominant_root(one, C::new(-trace, 0.0), C::new(det, 0.0)).norm() <= 1.0 + 1e-14
    }))
}

/// The largest `h` with `stable(h')` for all `h' ≤ h`, for a problem whose rates have size
/// `size`: doubled from `h size = 1e-3` until unstable, then bisected to 1e-13 relative; 0 if
/// unstable from the start, infinite if stable up to `h size = 1e8`.
fn largest_stable_step(size: f64, stable: impl Fn(f64) -> bool) -> f64 {
    let mut lo = 1e-3 / size;
    if !stable(lo) {
        return 0.0;
    }
    let mut hi = lo;
    while stable(hi) {
        lo = hi;
        hi *= 2.0;
        if hi * size > 1e8 {
            return f64::INFINITY;
        }
    }
    while hi - lo > 1e-13 * lo {
        let mid = 0.5 * (lo + hi);
        if stable(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// The amplification matrix of one step of a second-order method on `x'' = -ω² x - c x'`, in
/// the scaled state `(x, h x')`, given `p = (ωh)²` and `q = c h`; it repeats the stepper's
/// arithmetic (`Stepper::step`) on the two unit states.
fn oscillator_step(method: Method, p: f64, q: f64) -> [[f64; 2]; 2] {
    let accel = |x: f64, v: f64| -p * x - q * v; // h² x''
    let step = |x: f64, v: f64| match method {
        Method::SymplecticEuler => {
            let v1 = v + accel(x, v);
            (x + v1, v1)
        }
        _ => {
            // Velocity Verlet with the predicted velocity of the closing kick.
            let a0 = accel(x, v);
            let half = v + 0.5 * a0;
            let x1 = x + half;
            (x1, half + 0.5 * accel(x1, v + a0))
        }
    };
    let (a, b) = (step(1.0, 0.0), step(0.0, 1.0));
    [[a.0, b.0], [a.1, b.1]]
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
        if size > 0.0 {
            let h = largest_stable_step(size, |h| {
                stability_function(method, lambda * h).norm() <= 1.0 + 1e-14
            });
            best = best.min(h);
        }
    }
    Ok(best)
}
