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
    if let Some(a) = stability_polynomial(method) {
        return a.iter().rev().fold(C::new(0.0, 0.0), |r, &c| r * z + c);
    }
    match method {
        Method::ImplicitEuler => one / (one - z),
        Method::Trapezoidal => (one + z / 2.0) / (one - z / 2.0),
        Method::Bdf2 => dominant_root(3.0 * one - 2.0 * z, C::new(-4.0, 0.0), one),
        _ => {
            let m = oscillator_step(method, z.norm_sqr(), -2.0 * z.re);
            let (trace, det) = (m[0][0] + m[1][1], m[0][0] * m[1][1] - m[0][1] * m[1][0]);
            dominant_root(one, C::new(-trace, 0.0), C::new(det, 0.0))
        }
    }
}

/// The coefficients `a₀, a₁, …` of `R(z) = Σ a_k z^k` for the explicit Runge–Kutta methods
/// (`Σ_{k≤p} z^k/k!` for these, whose order equals their number of stages; Hairer, Nørsett &
/// Wanner I, §IV.2), `None` for the others.
fn stability_polynomial(method: Method) -> Option<&'static [f64]> {
    match method {
        Method::ExplicitEuler => Some(&[1.0, 1.0]),
        Method::Midpoint | Method::Heun => Some(&[1.0, 1.0, 0.5]),
        Method::Rk4 => Some(&[1.0, 1.0, 0.5, 1.0 / 6.0, 1.0 / 24.0]),
        _ => None,
    }
}

/// The largest `s ≥ 0` with `|R(s u)| ≤ 1` on all of `[0, s]` for the polynomial `R` with
/// coefficients `a` and the direction `u` (`|u| = 1`, `Re u ≤ 0`).
///
/// `g(s) = |R(s u)|² - 1 = Σ_{m≥1} c_m s^m` is a real polynomial whose coefficients are
/// formed exactly from `b_k = a_k u^k` (`c_m = Σ_{j+k=m} Re(b_j conj(b_k))`, with no `1 - 1`
/// cancellation); a coefficient within its rounding error of zero is zero (on the imaginary
/// axis, where the low ones cancel exactly). If the lowest non-zero `c_j` is positive, `|R| > 1`
/// for every small step: 0. Otherwise the stability boundary along the ray is the first root
/// of `q(s) = g(s) / s^j` where `q` turns positive; the real roots of `q` (the eigenvalues of
/// its companion matrix) bracket it, and bisection of `q` itself between the last sample with
/// `q ≤ 0` and the first with `q > 0` places it to rounding. Sampling at the roots and between
/// them, not on a grid, is what finds the stable interval `(0, 2e-4]` of explicit Euler at
/// `u ≈ -1e-4 + i` that a search starting from a fixed `s` steps over.
fn polynomial_limit(a: &[f64], u: C) -> f64 {
    let p = a.len() - 1;
    let b: Vec<C> = (0..=p)
        .scan(C::new(1.0, 0.0), |uk, k| {
            let bk = *uk * a[k];
            *uk *= u;
            Some(bk)
        })
        .collect();
    // c[m] for m = 1..=2p, zeroed when below its rounding error.
    let mut c = vec![0.0; 2 * p + 1];
    for (m, cm) in c.iter_mut().enumerate().skip(1) {
        let (mut sum, mut size) = (0.0, 0.0);
        for j in m.saturating_sub(p)..=m.min(p) {
            let term = (b[j] * b[m - j].conj()).re;
            sum += term;
            size += term.abs();
        }
        *cm = if sum.abs() <= 64.0 * f64::EPSILON * size { 0.0 } else { sum };
    }
    // The lowest non-zero coefficient (c_2p = |a_p|² never vanishes).
    let low = (1..2 * p).find(|&m| c[m] != 0.0).unwrap_or(2 * p);
    if c[low] > 0.0 {
        return 0.0;
    }
    // q(0) = c_low < 0 and q's leading coefficient |a_p|² > 0, so q has a positive root, and
    // all its roots lie within Cauchy's bound.
    let q = &c[low..];
    let top = q.len() - 1;
    let eval = |s: f64| q.iter().rev().fold(0.0, |acc, &cm| acc * s + cm);
    let bound = 1.0 + q[..top].iter().fold(0.0_f64, |m, cm| m.max((cm / q[top]).abs()));
    // The positive real roots of q: the eigenvalues of the companion matrix of q / q_top.
    let companion = nalgebra::DMatrix::from_fn(top, top, |r, col| {
        if r == 0 {
            -q[top - 1 - col] / q[top]
        } else {
            f64::from(u8::from(r == col + 1))
        }
    });
    let mut roots: Vec<f64> = companion
        .complex_eigenvalues()
        .iter()
        .filter(|r| r.re > 0.0 && r.re < bound && r.im.abs() <= 1e-6 * r.re)
        .map(|r| r.re)
        .chain([bound])
        .collect();
    roots.sort_by(f64::total_cmp);
    // Samples at each root and midway before it; q has the sign of its leading coefficient
    // at the bound.
    let samples = roots.iter().scan(0.0, |previous, &r| {
        let mid = 0.5 * (*previous + r);
        *previous = r;
        Some([mid, r])
    });
    let mut stable = 0.0;
    for sample in samples.flatten() {
        if eval(sample) > 0.0 {
            return bisect(stable, sample, |s| eval(s) <= 0.0);
        }
        stable = sample;
    }
    stable // q ≤ 0 at the bound: only rounding can get here
}

/// Bisection of `[lo, hi]` with `stable(lo)` and not `stable(hi)` down to adjacent floats;
/// returns the last stable point.
fn bisect(mut lo: f64, mut hi: f64, stable: impl Fn(f64) -> bool) -> f64 {
    loop {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            return lo;
        }
        if stable(mid) {
            lo = mid;
        } else {
            hi = mid;
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

/// The largest `h` with `stable(h')` for all `h' ≤ h`, for a method that is stable for small
/// steps (implicit methods with `Re λ ≤ 0`, the symplectic ones on a mode with `c ≥ 0`) on a
/// problem whose rates have size `size`: doubled from `h size = 1e-3` until unstable, then
/// bisected to adjacent floats; 0 if unstable from the start, infinite if stable up to
/// `h size = 1e8`.
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
    bisect(lo, hi, stable)
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
/// For the explicit Runge–Kutta methods, whose `R` is a polynomial, the boundary along each
/// eigenvalue's ray is found from the roots of `|R(hλ)|² - 1` (see `polynomial_limit`): exact
/// to rounding however close `λ` is to the imaginary axis, e.g. `2 |Re λ| / |λ|²` for explicit
/// Euler, and 0 where every small step grows (explicit Euler or an RK2 method on an undamped
/// oscillator). For the other methods, stable for small steps, the step is doubled from
/// `|hλ| = 1e-3` until `|R|` exceeds 1 (by more than 1e-14), then the boundary is bisected.
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
            let h = match stability_polynomial(method) {
                Some(a) => polynomial_limit(a, lambda / size) / size,
                None => largest_stable_step(size, |h| {
                    stability_function(method, lambda * h).norm() <= 1.0 + 1e-14
                }),
            };
            best = best.min(h);
        }
    }
    Ok(best)
}
