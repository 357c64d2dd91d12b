//! Adaptive integration with error control: the driver shared by the explicit embedded pairs
//! (Dormand–Prince 5(4) in `dopri5.rs`, DOP853 in `dop853.rs`; step-size control as in
//! Hairer, Nørsett & Wanner, *Solving ODEs I*, §II.4), the implicit Radau IIA of order 5
//! (`radau.rs`), and the output both write: every accepted step, or the dense output at
//! requested times.

use super::dop853::Dop853;
use super::dopri5::Dopri5;
use super::output::{Event, Output};
use super::{radau, OdeSystem};
use crate::error::{Error, Result};

/// An adaptive method of [`solve_adaptive`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Adaptive {
    /// Dormand–Prince 5(4), seven stages of which the last is the next step's first (six
    /// evaluations per step); scipy's `RK45`. Dense output of order 4.
    Dopri5,
    /// Dormand–Prince 8(5,3), twelve evaluations per step; scipy's `DOP853`. Dense output of
    /// order 7 (Hairer's `contd8`, three more evaluations on a step that needs it).
    Dop853,
    /// Radau IIA of order 5 (Hairer's RADAU5), implicit and L-stable, for stiff problems;
    /// scipy's `Radau`. Uses the system's dense Jacobian or forward differences; the dense
    /// output is the collocation polynomial (order 3).
    Radau,
}

impl Adaptive {
    /// The methods, in the order of the docs.
    pub const ALL: [Adaptive; 3] = [Adaptive::Dopri5, Adaptive::Dop853, Adaptive::Radau];

    /// The name as the Python API spells it (`"dopri5"`, `"dop853"`, `"radau"`).
    pub fn name(self) -> &'static str {
        match self {
            Adaptive::Dopri5 => "dopri5",
            Adaptive::Dop853 => "dop853",
            Adaptive::Radau => "radau",
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
            Adaptive::Dopri5 | Adaptive::Radau => 5,
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
    /// Vectors of the dense output.
    const DENSE: usize;
    /// After [`Pair::advance`] of the step of `h` from `(t, y)` to `y_new`, the dense output's
    /// vectors into `d`; returns the evaluations made.
    #[allow(clippy::too_many_arguments)]
    fn dense<S: OdeSystem>(
        sys: &mut S,
        t: f64,
        h: f64,
        y: &[f64],
        y_new: &[f64],
        k: &mut [Vec<f64>],
        d: &mut [Vec<f64>],
    ) -> Result<usize>;
    /// The dense output at `θ = (t - t_old)/h` in `[0, 1]` from the vectors of [`Pair::dense`].
    fn interpolate(theta: f64, y: &[f64], d: &[Vec<f64>], out: &mut [f64]);
}

/// The solution of an adaptive run.
#[derive(Clone, Debug, Default)]
pub struct AdaptiveSolution {
    /// Times of the accepted steps, starting with `t0` and ending with `t1`, or the requested
    /// times `t_eval`.
    pub t: Vec<f64>,
    /// States at those times, row after row (`t.len() x dim`).
    pub y: Vec<f64>,
    /// Accepted steps.
    pub steps: usize,
    /// Right-hand-side evaluations (including those of differenced Jacobians).
    pub nfev: usize,
    /// Rejected step attempts (for Radau including those whose Newton iteration failed).
    pub rejected: usize,
    /// Jacobian evaluations (Radau; 0 for the explicit pairs).
    pub njev: usize,
    /// LU factorisations of the pair of Newton matrices (Radau; 0 for the explicit pairs).
    pub nlu: usize,
    /// Per event given, the times of its zeros found (in order).
    pub t_events: Vec<Vec<f64>>,
    /// Per event given, the states at those zeros, row after row.
    pub y_events: Vec<Vec<f64>>,
    /// Whether a terminal event stopped the run before `t1` (the last time is the event's).
    pub terminated: bool,
}

/// Integrate from `t0` to `t1 > t0` with the adaptive `method`, keeping the local error per
/// step below `atol + rtol |y|` (root-mean-square norm), using at most `max_steps` accepted
/// steps; the solution at every accepted step, or at the times `t_eval` (non-decreasing,
/// within `[t0, t1]`) from the method's dense output. The zeros of the system's event
/// functions ([`OdeSystem::events`], one per entry of `events`) are located on the dense output
/// to 1e-12 relative in `t` (Illinois), and a terminal one ends the run there.
///
/// The explicit pairs propagate the higher-order solution (local extrapolation), so at tight
/// tolerances the observed order is the pair's [`Adaptive::order`].
///
/// # Errors
/// Bad arguments, a system error, a step size underflow (for Radau also when its Newton
/// iteration keeps failing), too many steps, or a non-finite state.
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
    t_eval: Option<&[f64]>,
    events: &[Event],
) -> Result<AdaptiveSolution> {
    let n = sys.dim();
    check_arguments(n, y0, t0, t1, rtol, atol, t_eval)?;
    let tol = Tolerance { rtol, atol };
    let mut out = Output::new(sys, t_eval, events, t0, y0)?;
    match method {
        Adaptive::Dopri5 => run::<Dopri5, S>(sys, &tol, y0, t0, t1, max_steps, &mut out)?,
        Adaptive::Dop853 => run::<Dop853, S>(sys, &tol, y0, t0, t1, max_steps, &mut out)?,
        Adaptive::Radau => {
            let c = radau::run(sys, &tol, y0, t0, t1, max_steps, &mut out)?;
            (out.sol.steps, out.sol.nfev, out.sol.rejected) = (c.steps, c.nfev, c.rejected);
            (out.sol.njev, out.sol.nlu) = (c.njev, c.nlu);
        }
    }
    Ok(out.sol)
}

/// [`solve_adaptive`] with the pair `P`, the arguments checked.
fn run<P: Pair, S: OdeSystem>(
    sys: &mut S,
    tol: &Tolerance,
    y0: &[f64],
    t0: f64,
    t1: f64,
    max_steps: usize,
    out: &mut Output<'_>,
) -> Result<()> {
    let n = y0.len();
    let mut y = y0.to_vec();
    let mut k: Vec<Vec<f64>> = vec![vec![0.0; n]; P::STAGES];
    let mut d: Vec<Vec<f64>> = vec![vec![0.0; n]; P::DENSE];
    let mut stage = vec![0.0; n];
    sys.rhs(t0, &y, &mut k[0])?;
    let mut nfev = 1;
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
        nfev += P::stages(sys, t, h, &y, &mut k, &mut stage)?;
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
            let t_old = t;
            t = if last { t1 } else { t + h };
            let dense = out.wants_dense(sys, t, &stage)?;
            if t < t1 || dense {
                nfev += P::advance(sys, t, &stage, &mut k)?;
            }
            if dense {
                nfev += P::dense(sys, t_old, h, &y, &stage, &mut k, &mut d)?;
            }
            let stop = out.accept(sys, t_old, t, &stage, |s, buf| {
                P::interpolate((s - t_old) / h, &y, &d, buf);
            })?;
            y.copy_from_slice(&stage);
            steps += 1;
            if stop {
                break;
            }
        } else {
            out.sol.rejected += 1;
        }
        h *= (0.9 * err.powf(-1.0 / P::ORDER)).clamp(P::FACTORS.0, P::FACTORS.1);
    }
    (out.sol.steps, out.sol.nfev) = (steps, nfev);
    Ok(())
}

/// The arguments of [`solve_adaptive`] for a system of dimension `n`, checked.
fn check_arguments(
    n: usize,
    y0: &[f64],
    t0: f64,
    t1: f64,
    rtol: f64,
    atol: f64,
    t_eval: Option<&[f64]>,
) -> Result<()> {
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
    if let Some(te) = t_eval {
        if !te.iter().all(|s| (t0..=t1).contains(s)) || te.windows(2).any(|w| w[1] < w[0]) {
            return Err(Error::invalid(
                "t_eval",
                format!("must be non-decreasing times within t_span ({t0}, {t1})"),
            ));
        }
    }
    Ok(())
}

/// The error control's tolerance per component, `atol + rtol |y|`.
pub(super) struct Tolerance {
    pub(super) rtol: f64,
    pub(super) atol: f64,
}

impl Tolerance {
    /// `atol + rtol max(|a|, |b|)`.
    pub(super) fn scale(&self, a: f64, b: f64) -> f64 {
        self.atol + self.rtol * a.abs().max(b.abs())
    }

    /// The first step (Hairer, Nørsett & Wanner, II.4): `h ~ 0.01 |y| / |f|` in the scaled
    /// root-mean-square norms.
    pub(super) fn initial_step(&self, y: &[f64], f: &[f64]) -> f64 {
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
