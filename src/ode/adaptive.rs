//! Adaptive explicit Runge–Kutta integration with error control: the driver shared by the
//! embedded pairs ([`Adaptive`]: Dormand–Prince 5(4) in `dopri5.rs`, DOP853 in `dop853.rs`);
//! step-size control as in Hairer, Nørsett & Wanner, *Solving ODEs I*, §II.4.

use super::dop853::Dop853;
use super::dopri5::Dopri5;
use super::OdeSystem;
use crate::error::{reserve, Error, Result};

/// An embedded Runge–Kutta pair of [`solve_adaptive`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Adaptive {
    /// Dormand–Prince 5(4), seven stages of which the last is the next step's first (six
    /// evaluations per step); scipy's `RK45`.
    Dopri5,
    /// Dormand–Prince 8(5,3), twelve evaluations per step; scipy's `DOP853`.
    Dop853,
}

impl Adaptive {
    /// The pairs, in the order of the docs.
    pub const ALL: [Adaptive; 2] = [Adaptive::Dopri5, Adaptive::Dop853];

    /// The name as the Python API spells it (`"dopri5"`, `"dop853"`).
    pub fn name(self) -> &'static str {
        match self {
            Adaptive::Dopri5 => "dopri5",
            Adaptive::Dop853 => "dop853",
        }
    }

    /// Parse a name of [`Adaptive::name`].
    ///
    /// # Errors
    /// An unknown name, listing the known ones.
    pub fn parse(name: &str) -> Result<Self> {
        Adaptive::ALL.into_iter().find(|m| m.name() == name).ok_or_else(|| {
            let known: Vec<&str> = Adaptive::ALL.iter().map(|m| m.name()).collect();
            Error::invalid("method", format!("{name:?} is not one of {}", known.join(", ")))
        })
    }

    /// Order of the propagated solution.
    pub fn order(self) -> u32 {
        match self {
            Adaptive::Dopri5 => 5,
            Adaptive::Dop853 => 8,
        }
    }
}

/// What the driver needs of an embedded pair.
pub(super) trait Pair {
    /// Stage derivatives kept (`k[0]` is `f(t, y)` at the start of a step).
    const STAGES: usize;
    /// Order of the propagated solution: the step changes by `0.9 err^(-1/ORDER)`.
    const ORDER: f64;
    /// Smallest and largest factor of a step change.
    const FACTORS: (f64, f64);
    /// The stages after the first of a step of `h` from `(t, y)` into `k[1..]`, and the
    /// propagated solution into `y_new`; returns the evaluations made.
    fn stages<S: OdeSystem>(
        sys: &mut S,
        t: f64,
        h: f64,
        y: &[f64],
        k: &mut [Vec<f64>],
        y_new: &mut [f64],
    ) -> Result<usize>;
    /// The scaled error of the step just taken (accepted when `<= 1`).
    fn error(tol: &Tolerance, h: f64, k: &[Vec<f64>], y: &[f64], y_new: &[f64]) -> f64;
    /// Put `f(t, y_new)` (with `t` the new time) into `k[0]` after an accepted step; returns
    /// the evaluations made.
    fn advance<S: OdeSystem>(
        sys: &mut S,
        t: f64,
        y_new: &[f64],
        k: &mut [Vec<f64>],
    ) -> Result<usize>;
}

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

/// Integrate from `t0` to `t1 > t0` with the embedded pair `method`, keeping the local error
/// per step below `atol + rtol |y|` (root-mean-square norm), using at most `max_steps`
/// accepted steps.
///
/// The propagated solution is the higher-order one (local extrapolation), so at tight
/// tolerances the observed order is the pair's [`Adaptive::order`].
///
/// # Errors
/// Bad arguments, a system error, a step size underflow, too many steps, or a non-finite
/// state.
#[allow(clippy::too_many_arguments)]
pub fn solve_adaptive<S: OdeSystem>(
    sys: &mut S,
    method: Adaptive,
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
    match method {
        Adaptive::Dopri5 => run::<Dopri5, S>(sys, &tol, y0, t0, t1, max_steps),
        Adaptive::Dop853 => run::<Dop853, S>(sys, &tol, y0, t0, t1, max_steps),
    }
}

/// [`solve_adaptive`] with the pair `P`, the arguments checked.
fn run<P: Pair, S: OdeSystem>(
    sys: &mut S,
    tol: &Tolerance,
    y0: &[f64],
    t0: f64,
    t1: f64,
    max_steps: usize,
) -> Result<AdaptiveSolution> {
    let n = y0.len();
    let mut out = AdaptiveSolution { t: vec![t0], y: y0.to_vec(), ..Default::default() };
    let mut y = y0.to_vec();
    let mut k: Vec<Vec<f64>> = vec![vec![0.0; n]; P::STAGES];
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
        out.nfev += P::stages(sys, t, h, &y, &mut k, &mut stage)?;
        // `stage` is the propagated solution.
        let err = P::error(tol, h, &k, &y, &stage);
        if !err.is_finite() {
            return Err(Error::Diverged {
                step: steps,
                index: stage.iter().position(|v| !v.is_finite()).unwrap_or(0),
                reason: "non-finite state in the Runge-Kutta pair".into(),
            });
        }
        if err <= 1.0 {
            t = if last { t1 } else { t + h };
            y.copy_from_slice(&stage);
            if t < t1 {
                out.nfev += P::advance(sys, t, &y, &mut k)?;
            }
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
        h *= (0.9 * err.powf(-1.0 / P::ORDER)).clamp(P::FACTORS.0, P::FACTORS.1);
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

/// The error control's tolerance per component, `atol + rtol |y|`.
pub(super) struct Tolerance {
    rtol: f64,
    atol: f64,
}

impl Tolerance {
    /// `atol + rtol max(|a|, |b|)`.
    pub(super) fn scale(&self, a: f64, b: f64) -> f64 {
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
}
