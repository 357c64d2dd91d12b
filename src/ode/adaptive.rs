//! Dormand–Prince 5(4) with error control (Dormand & Prince 1980, "A family of embedded
//! Runge–Kutta formulae", J. Comp. Appl. Math. 6; step-size control as in Hairer, Nørsett &
//! Wanner, *Solving ODEs I*, §II.4).

// Numeric kernels index several arrays in step; index loops read closest to the formulas.
#![allow(clippy::needless_range_loop)]

use super::OdeSystem;
use crate::error::{reserve, Error, Result};

const C: [f64; 7] = [0.0, 1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0, 1.0, 1.0];
const A: [[f64; 6]; 7] = [
    [0.0; 6],
    [1.0 / 5.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [3.0 / 40.0, 9.0 / 40.0, 0.0, 0.0, 0.0, 0.0],
    [44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0, 0.0, 0.0, 0.0],
    [19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0, 0.0, 0.0],
    [9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0, 0.0],
    [35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0],
];
/// Fifth-order weights minus the embedded fourth-order ones.
const E: [f64; 7] = [
    35.0 / 384.0 - 5179.0 / 57600.0,
    0.0,
    500.0 / 1113.0 - 7571.0 / 16695.0,
    125.0 / 192.0 - 393.0 / 640.0,
    -2187.0 / 6784.0 + 92097.0 / 339200.0,
    11.0 / 84.0 - 187.0 / 2100.0,
    -1.0 / 40.0,
];

/// The accepted steps of an adaptive run.
#[derive(Clone, Debug, Default)]
pub struct AdaptiveSolution {
    /// Times of the accepted steps, starting with `t0` and ending with `t1`.
    pub t: Vec<f64>,
    /// States at those times, row after row (`t.len() x dim`).
    pub y: Vec<f64>,
    /// Right-hand-side evaluations.
    pub nfev: usize,
    /// Rejected step attempts.
    pub rejected: usize,
}

/// Integrate from `t0` to `t1 > t0` with local error per step below
/// `atol + rtol |y|` (root-mean-square norm), using at most `max_steps` accepted steps.
///
/// The propagated solution is the fifth-order one (local extrapolation), so at tight
/// tolerances the observed order is 5.
///
/// # Errors
/// Bad arguments, a system error, a step size underflow, too many steps, or a non-finite
/// state.
pub fn solve_adaptive<S: OdeSystem>(
    sys: &mut S,
    y0: &[f64],
    t0: f64,
    t1: f64,
    rtol: f64,
    atol: f64,
    max_steps: usize,
) -> Result<AdaptiveSolution> {
    let n = sys.dim();
    check_arguments(n, y0, t0, t1, rtol, atol)?;
    let tol = Tolerance { rtol, atol };
    let mut out = AdaptiveSolution { t: vec![t0], y: y0.to_vec(), ..Default::default() };
    let mut y = y0.to_vec();
    let mut k: Vec<Vec<f64>> = vec![vec![0.0; n]; 7];
    let mut stage = vec![0.0; n];
    sys.rhs(t0, &y, &mut k[0])?;
    out.nfev += 1;
    let mut h = tol.initial_step(&y, &k[0]).min(t1 - t0);
    let mut t = t0;
    let mut steps = 0;
    while t < t1 {
        if steps >= max_steps {
            return Err(Error::SolverFailed {
                reason: format!(
                    "more than {max_steps} steps needed; loosen rtol/atol or raise max_steps"
                ),
            });
        }
        if h < 1e-14 * t.abs().max(1.0) {
            return Err(Error::SolverFailed { reason: format!("step size underflow at t = {t}") });
        }
        let last = t + h >= t1;
        if last {
            h = t1 - t;
        }
        stages(sys, t, h, &y, &mut k, &mut stage)?;
        out.nfev += 6;
        // `stage` is the fifth-order solution (the stage of row 7).
        let err = tol.error_norm(h, &k, &y, &stage);
        if !err.is_finite() {
            return Err(Error::Diverged {
                step: steps,
                index: stage.iter().position(|v| !v.is_finite()).unwrap_or(0),
                reason: "non-finite state in Dormand-Prince".into(),
            });
        }
        if err <= 1.0 {
            t = if last { t1 } else { t + h };
            y.copy_from_slice(&stage);
            k.swap(0, 6); // first same as last
                          // The output grows by a step's state: refused (naming the step bound) when it no
                          // longer fits in memory, instead of the process being killed.
            reserve("max_steps", &mut out.t, 1)?;
            reserve("max_steps", &mut out.y, n)?;
            out.t.push(t);
            out.y.extend_from_slice(&y);
            steps += 1;
        } else {
            out.rejected += 1;
        }
        h *= (0.9 * err.powf(-0.2)).clamp(0.2, 5.0);
    }
    Ok(out)
}

/// The arguments of [`solve_adaptive`] for a system of dimension `n`, checked.
fn check_arguments(n: usize, y0: &[f64], t0: f64, t1: f64, rtol: f64, atol: f64) -> Result<()> {
    if y0.len() != n {
        return Err(Error::invalid(
            "y0",
            format!("has length {}, the system has dimension {n}", y0.len()),
        ));
    }
    if !(t0.is_finite() && t1.is_finite() && t1 > t0) {
        return Err(Error::invalid(
            "t_span",
            format!("must be finite with t1 > t0, got ({t0}, {t1})"),
        ));
    }
    if !(rtol > 0.0 && atol >= 0.0 && rtol.is_finite() && atol.is_finite()) {
        return Err(Error::invalid("rtol", "rtol must be positive and atol non-negative"));
    }
    Ok(())
}

/// Stages 2 to 7 of one Dormand–Prince step of size `h` from `(t, y)` into `k[1..7]`
/// (`k[0]` holds `f(t, y)`); `stage` ends as the fifth-order solution.
fn stages<S: OdeSystem>(
    sys: &mut S,
    t: f64,
    h: f64,
    y: &[f64],
    k: &mut [Vec<f64>],
    stage: &mut [f64],
) -> Result<()> {
    for s in 1..7 {
        for i in 0..y.len() {
            stage[i] = y[i] + h * (0..s).map(|j| A[s][j] * k[j][i]).sum::<f64>();
        }
        sys.rhs(t + C[s] * h, stage, &mut k[s])?;
    }
    Ok(())
}

/// The error control's tolerance per component, `atol + rtol |y|`.
struct Tolerance {
    rtol: f64,
    atol: f64,
}

impl Tolerance {
    fn scale(&self, a: f64, b: f64) -> f64 {
        self.atol + self.rtol * a.abs().max(b.abs())
    }

    /// The first step (Hairer, Nørsett & Wanner, II.4): `h ~ 0.01 |y| / |f|` in the scaled
    /// root-mean-square norms.
    fn initial_step(&self, y: &[f64], f: &[f64]) -> f64 {
        let n = y.len().max(1) as f64;
        let d0 = (y.iter().map(|v| (v / self.scale(*v, *v)).powi(2)).sum::<f64>() / n).sqrt();
        let d1 = (f.iter().zip(y).map(|(f, v)| (f / self.scale(*v, *v)).powi(2)).sum::<f64>() / n)
            .sqrt();
        if d0 < 1e-5 || d1 < 1e-5 {
            1e-6
        } else {
            0.01 * d0 / d1
        }
    }

    /// The root-mean-square of the local error estimate `h Σ E_j k_j` of a step from `y`
    /// to `y_new`, scaled per component.
    fn error_norm(&self, h: f64, k: &[Vec<f64>], y: &[f64], y_new: &[f64]) -> f64 {
        let sum = (0..y.len())
            .map(|i| {
                let e = h * (0..7).map(|j| E[j] * k[j][i]).sum::<f64>();
                (e / self.scale(y[i], y_new[i])).powi(2)
            })
            .sum::<f64>();
        (sum / y.len().max(1) as f64).sqrt()
    }
}
