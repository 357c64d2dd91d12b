//! Arc-length reparameterisation of a track: the point at distance `s` along the curve, so
//! that sampling `s` uniformly moves at constant speed (Parent, *Computer Animation:
//! Algorithms and Techniques*, 3rd ed., §3.2: tabulated arc length, then Newton's method on
//! `S(t) = s`).
//!
//! `S(t) = ∫_{t₀}^{t} |x'(τ)| dτ` is tabulated over the track's key range on subintervals,
//! each integrated by 8-point Gauss–Legendre (exact for polynomials of degree 15); the
//! subintervals are halved until the total changes by at most `tol` times the length.
//! Within one table interval `S` is inverted by Newton's method safeguarded by bisection
//! (`S` is monotone, so the bracket always holds the root) to `1e-12` of the length.
//!
//! The error bounds are a contract: a tolerance that cannot be met (the table still changing
//! after [`MAX_SUBDIVISIONS`] subintervals per key interval, or Newton not converging) is an
//! error, never a silently capped answer.

use super::Track;
use crate::batch;
use crate::error::{filled, Error, Result};
use serde::{Deserialize, Serialize};

/// Most subintervals per key interval the table may use before an unmet `tol` is an error.
pub const MAX_SUBDIVISIONS: usize = 4096;

/// Relative accuracy (of the length) of [`ArcLengthCurve::time_at`].
pub const INVERSE_TOL: f64 = 1e-12;

/// Iterations of safeguarded Newton in [`ArcLengthCurve::time_at`] (bisection alone
/// shrinks the bracket 2^100-fold, below one ulp of any time).
const MAX_NEWTON: usize = 100;

/// Gauss–Legendre nodes on [-1, 1], 8 points (Abramowitz & Stegun, Table 25.4).
const GL_X: [f64; 8] = [
    -0.9602898564975362,
    -0.7966664774136267,
    -0.525532409916329,
    -0.18343464249564978,
    0.18343464249564978,
    0.525532409916329,
    0.7966664774136267,
    0.9602898564975362,
];
/// The matching Gauss–Legendre weights (they sum to 2).
const GL_W: [f64; 8] = [
    0.10122853629037706,
    0.22238103445337443,
    0.3137066458778869,
    0.36268378337836166,
    0.36268378337836166,
    0.3137066458778869,
    0.22238103445337443,
    0.10122853629037706,
];

/// A value track with its arc-length table: `times[i]` (s, increasing, from the first key to
/// the last) and `lengths[i] = S(times[i])` (units of the track's values, non-decreasing,
/// `lengths[0] = 0`).
#[derive(Serialize, Deserialize, Clone, Debug)]
pub struct ArcLengthCurve {
    track: Track,
    times: Vec<f64>,
    lengths: Vec<f64>,
}

/// `|x'(t)|`: the Euclidean norm of the track's first derivative.
fn speed(track: &Track, t: f64, buf: &mut [f64]) -> f64 {
    track.eval(t, 1, buf);
    if let [one] = buf {
        one.abs()
    } else {
        buf.iter().map(|v| v * v).sum::<f64>().sqrt()
    }
}

/// `∫_a^b |x'(t)| dt` by 8-point Gauss–Legendre.
fn partial(track: &Track, a: f64, b: f64, buf: &mut [f64]) -> f64 {
    let (mid, half) = ((a + b) / 2.0, (b - a) / 2.0);
    let sum: f64 = GL_X.iter().zip(GL_W).map(|(&x, w)| speed(track, mid + half * x, buf) * w).sum();
    half * sum
}

impl ArcLengthCurve {
    /// Tabulate the arc length of `track` (a value track of at least two keys, over its key
    /// range) to relative accuracy `tol` (> 0).
    ///
    /// # Errors
    /// [`Error::InvalidInput`] for a track of fewer than two keys, for `tol` not finite and
    /// positive, and (argument `"tol"`) when the total still changes by more than `tol`
    /// relative with [`MAX_SUBDIVISIONS`] subintervals per key interval.
    pub fn new(track: Track, tol: f64) -> Result<Self> {
        let keys = track.times().to_vec();
        if keys.len() < 2 {
            return Err(Error::invalid("track", "needs at least two keys to have a length"));
        }
        if !(tol.is_finite() && tol > 0.0) {
            return Err(Error::invalid("tol", "must be finite and positive"));
        }
        let mut buf = vec![0.0; track.dim()];
        let (mut total, mut per_segment) = (f64::INFINITY, 1);
        loop {
            let n = (keys.len() - 1) * per_segment + 1;
            let mut times = filled("tol", n, 0.0)?;
            for (k, w) in keys.windows(2).enumerate() {
                let step = (w[1] - w[0]) / per_segment as f64;
                for i in 0..per_segment {
                    times[k * per_segment + i] = i as f64 * step + w[0];
                }
            }
            times[n - 1] = keys[keys.len() - 1];
            let mut lengths = filled("tol", n, 0.0)?;
            for i in 1..n {
                lengths[i] = lengths[i - 1] + partial(&track, times[i - 1], times[i], &mut buf);
            }
            let new_total = lengths[n - 1];
            let change = (new_total - total).abs();
            if change <= tol * new_total.max(1e-300) {
                return Ok(Self { track, times, lengths });
            }
            if per_segment >= MAX_SUBDIVISIONS {
                return Err(Error::invalid(
                    "tol",
                    format!(
                        "cannot be met: the length still changes by {:.1e} of itself with \
                         {MAX_SUBDIVISIONS} subintervals per key interval",
                        change / new_total.max(1e-300)
                    ),
                ));
            }
            total = new_total;
            per_segment *= 2;
        }
    }

    /// The track this curve follows.
    pub fn track(&self) -> &Track {
        &self.track
    }

    /// Total arc length (units of the track's values).
    pub fn length(&self) -> f64 {
        self.lengths[self.lengths.len() - 1]
    }

    /// The table: times (s) and the arc length at each.
    pub fn table(&self) -> (&[f64], &[f64]) {
        (&self.times, &self.lengths)
    }

    /// The track time at arc length `s` (clamped to `[0, length]`), to [`INVERSE_TOL`] of
    /// the length.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] (argument `"s"`) for a non-finite `s`;
    /// [`Error::SolverFailed`] if the accuracy cannot be reached in floating point.
    pub fn time_at(&self, s: f64) -> Result<f64> {
        if !s.is_finite() {
            return Err(Error::invalid("s", "contains NaN or infinity"));
        }
        let s = s.clamp(0.0, self.length());
        let last = self.times.len() - 2;
        let j = self.lengths.partition_point(|&x| x <= s).saturating_sub(1).min(last);
        let (t0, t1) = (self.times[j], self.times[j + 1]);
        let (s0, s1) = (self.lengths[j], self.lengths[j + 1]);
        let mut t = if s1 > s0 { t0 + (t1 - t0) * ((s - s0) / (s1 - s0)) } else { t0 };
        let (mut lo, mut hi) = (t0, t1);
        let tol = INVERSE_TOL * self.length().max(1e-300);
        let mut buf = vec![0.0; self.track.dim()];
        for _ in 0..MAX_NEWTON {
            let f = s0 + partial(&self.track, t0, t, &mut buf) - s;
            if f.abs() <= tol {
                return Ok(t);
            }
            if f < 0.0 {
                lo = t;
            } else {
                hi = t;
            }
            let v = speed(&self.track, t, &mut buf);
            let newton = t - f / v;
            t = if v > 0.0 && newton > lo && newton < hi { newton } else { 0.5 * (lo + hi) };
        }
        Err(Error::SolverFailed {
            reason: format!(
                "arc length: no time within {INVERSE_TOL:e} of the length found in \
                 {MAX_NEWTON} iterations"
            ),
        })
    }

    /// [`ArcLengthCurve::time_at`] for every row of `s` into `out`, in parallel.
    ///
    /// # Errors
    /// As [`ArcLengthCurve::time_at`], for the lowest failing row (named by its index).
    pub fn times_at(
        &self,
        s: &[[f64; 1]],
        out: &mut (impl batch::Output<1> + ?Sized),
    ) -> Result<()> {
        batch::map(s, out, |&[s]| Ok([self.time_at(s)?]))
    }
}

impl crate::snapshot::Snapshot for ArcLengthCurve {
    const TAG: &'static str = "ArcLengthCurve";

    fn validate(&self) -> Result<()> {
        use crate::snapshot::{check, finite};
        crate::snapshot::Snapshot::validate(&self.track)?;
        let (t, s) = (&self.times, &self.lengths);
        let keys = self.track.times();
        check(t.len() == s.len() && t.len() >= 2, "lengths", || {
            format!("{} times and {} lengths", t.len(), s.len())
        })?;
        check(finite(t.iter().chain(s).copied()), "times", || "must be finite".into())?;
        check(t.windows(2).all(|w| w[0] < w[1]), "times", || "must increase".into())?;
        check(s[0] == 0.0 && s.windows(2).all(|w| w[0] <= w[1]), "lengths", || {
            "must start at 0 and never decrease".into()
        })?;
        check(t[0] == keys[0] && t[t.len() - 1] == keys[keys.len() - 1], "times", || {
            "must span the track's keys".into()
        })
    }
}
