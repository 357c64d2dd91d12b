//! Keyframe splines: tracks of keys `(t_i, value_i)` for channels of any width, interpolated
//! by the classic schemes of computer animation, extrapolated, evaluated in parallel.
//!
//! Neutral maths (it imports no system): [`crate::anim`] re-exports it for keyframing,
//! [`crate::constraints`] uses a track as a wire, [`crate::mocap`] as a time warp.
//!
//! Every piecewise scheme is stored the same way: one cubic `c₀ + c₁s + c₂s² + c₃s³` per
//! segment and channel in the local parameter `s = (t - t_k)/(t_{k+1} - t_k)`, so evaluation
//! and the first two derivatives share one code path. The schemes differ only in how they
//! set the cubics (Parent, *Computer Animation: Algorithms and Techniques*, ch. 3; de Boor,
//! *A Practical Guide to Splines*):
//!
//! | scheme | continuity | passes through keys |
//! |---|---|---|
//! | step | C⁻¹ | yes (holds each key) |
//! | linear | C0 | yes |
//! | natural / clamped cubic | C2 | yes (tridiagonal solve for the slopes) |
//! | Hermite | C1 | yes (given tangents) |
//! | Catmull–Rom / cardinal | C1 | yes (tangents from neighbours, scaled by 1 - tension) |
//! | Kochanek–Bartels | C0 (C1 when continuity = 0) | yes (tension, continuity, bias) |
//! | Bézier | C0 (C1 with aligned handles) | yes (given handles) |
//! | uniform cubic B-spline | C2 | no (keys are control points) |
//! | Lagrange polynomial | C∞ | yes (one polynomial; oscillates for many keys, Runge) |

use crate::error::{Error, Result};
use rayon::prelude::*;

/// How a track interpolates between its keys (see the table in the module docs).
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, PartialEq)]
pub enum Interpolation {
    /// Hold each key's value until the next key.
    Step,
    /// Straight lines between keys.
    Linear,
    /// The one polynomial of degree n - 1 through all keys (Newton form).
    Polynomial,
    /// C2 cubic spline with zero second derivative at both ends.
    NaturalCubic,
    /// C2 cubic spline with given first derivatives at the ends (`start`, `end`, each of the
    /// channel width).
    ClampedCubic {
        /// dvalue/dt at the first key.
        start: Vec<f64>,
        /// dvalue/dt at the last key.
        end: Vec<f64>,
    },
    /// Cubic Hermite with the given dvalue/dt at every key (`n x width`, row-major).
    Hermite {
        /// Tangents, one row per key.
        tangents: Vec<f64>,
    },
    /// Cardinal spline: tangents `(1 - tension) (p_{k+1} - p_{k-1}) / (t_{k+1} - t_{k-1})`;
    /// tension 0 is Catmull–Rom (Catmull & Rom 1974).
    Cardinal {
        /// Tension; 0 gives Catmull–Rom, 1 gives zero tangents.
        tension: f64,
    },
    /// Kochanek & Bartels 1984 ("Interpolating splines with local tension, continuity, and
    /// bias control"), with their correction for unequal key spacing (eqs. 8–9).
    KochanekBartels {
        /// Tension t.
        tension: f64,
        /// Continuity c.
        continuity: f64,
        /// Bias b.
        bias: f64,
    },
    /// Cubic Bézier segments; `handles` holds, per segment, the two inner control points
    /// (`(n - 1) x 2 x width`, row-major).
    Bezier {
        /// Inner control points of each segment.
        handles: Vec<f64>,
    },
    /// Uniform cubic B-spline with the keys as control points (end points repeated); it does
    /// not pass through the keys. Each segment spans its key interval, so the curve is C2 in
    /// time when the keys are equally spaced (C0 otherwise).
    BSpline,
}

/// What a track does outside `[t_first, t_last]`.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Extrapolation {
    /// Keep the end values (derivatives 0).
    Hold,
    /// Continue along the end tangents.
    Linear,
    /// Repeat the track with period `t_last - t_first`.
    Cycle,
}

impl Extrapolation {
    /// Parse `"hold" | "linear" | "cycle"`.
    ///
    /// # Errors
    /// Any other name.
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "hold" => Ok(Extrapolation::Hold),
            "linear" => Ok(Extrapolation::Linear),
            "cycle" => Ok(Extrapolation::Cycle),
            _ => Err(Error::invalid(
                "extrapolate",
                format!("{name:?} is not one of hold, linear, cycle"),
            )),
        }
    }
}

/// A keyframed channel of `dim` values per key, ready to evaluate.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub struct Track {
    times: Vec<f64>,
    dim: usize,
    /// Per segment and channel: cubic coefficients in the local parameter s ∈ [0, 1].
    coeffs: Vec<[f64; 4]>,
    /// Newton coefficients (`n x dim`) for the polynomial scheme.
    newton: Option<Vec<f64>>,
    /// The step scheme holds the last key's value from the last key time on.
    last_step_value: Option<Vec<f64>>,
    extrapolate: Extrapolation,
}

fn hermite(p0: f64, p1: f64, d0: f64, d1: f64) -> [f64; 4] {
    // d0, d1 are derivatives with respect to s.
    [p0, d0, 3.0 * (p1 - p0) - 2.0 * d0 - d1, 2.0 * (p0 - p1) + d0 + d1]
}

/// Slopes of the C2 cubic spline by the tridiagonal (Thomas) solve; `ends` fixes the end
/// slopes (clamped) or `None` asks for zero end curvature (natural).
fn spline_slopes(t: &[f64], p: &[f64], ends: Option<(f64, f64)>) -> Vec<f64> {
    let n = t.len();
    let h: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    let d: Vec<f64> = (0..n - 1).map(|k| (p[k + 1] - p[k]) / h[k]).collect();
    let (mut a, mut b, mut c, mut r) = (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    match ends {
        Some((s0, s1)) => {
            b[0] = 1.0;
            r[0] = s0;
            b[n - 1] = 1.0;
            r[n - 1] = s1;
        }
        None => {
            b[0] = 2.0;
            c[0] = 1.0;
            r[0] = 3.0 * d[0];
            a[n - 1] = 1.0;
            b[n - 1] = 2.0;
            r[n - 1] = 3.0 * d[n - 2];
        }
    }
    for k in 1..n - 1 {
        a[k] = h[k];
        b[k] = 2.0 * (h[k - 1] + h[k]);
        c[k] = h[k - 1];
        r[k] = 3.0 * (h[k] * d[k - 1] + h[k - 1] * d[k]);
    }
    for k in 1..n {
        let w = a[k] / b[k - 1];
        b[k] -= w * c[k - 1];
        r[k] -= w * r[k - 1];
    }
    let mut m = vec![0.0; n];
    m[n - 1] = r[n - 1] / b[n - 1];
    for k in (0..n - 1).rev() {
        m[k] = (r[k] - c[k] * m[k + 1]) / b[k];
    }
    m
}

/// Check the keys of a track: at least one key and one channel, `n x dim` finite values,
/// strictly increasing finite times.
fn check_keys(times: &[f64], values: &[f64], dim: usize) -> Result<()> {
    let n = times.len();
    if n == 0 || dim == 0 {
        return Err(Error::invalid("times", "a track needs at least one key and one channel"));
    }
    if values.len() != n * dim {
        return Err(Error::invalid(
            "values",
            format!("expected {n} x {dim} values, got {}", values.len()),
        ));
    }
    check_times(times)?;
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        return Err(Error::InvalidInput {
            arg: "values".into(),
            index: Some(i / dim),
            reason: "contains NaN or infinity".into(),
        });
    }
    Ok(())
}

/// `len` finite numbers in `v`, else an error naming `arg`.
fn check_finite(arg: &str, v: &[f64], len: usize) -> Result<()> {
    if v.len() != len {
        return Err(Error::invalid(arg, format!("expected {len} numbers, got {}", v.len())));
    }
    if v.iter().any(|x| !x.is_finite()) {
        return Err(Error::invalid(arg, "contains NaN or infinity"));
    }
    Ok(())
}

/// Newton's divided differences of the points `(times[k], p[k])`, in place: the coefficients
/// of the interpolating polynomial in Newton form.
fn divided_differences(times: &[f64], mut a: Vec<f64>) -> Vec<f64> {
    let n = a.len();
    for j in 1..n {
        for k in (j..n).rev() {
            a[k] = (a[k] - a[k - 1]) / (times[k] - times[k - j]);
        }
    }
    a
}

/// The outgoing and incoming tangents (per unit of each segment's local parameter) of a
/// Kochanek–Bartels spline with tension `t`, continuity `cc` and bias `b` through `p`
/// (Kochanek & Bartels 1984, eqs. 8–9 for unequal key spacing); the end keys take the
/// chord of their segment.
fn kochanek_bartels_tangents(
    times: &[f64],
    p: &[f64],
    (t, cc, b): (f64, f64, f64),
) -> (Vec<f64>, Vec<f64>) {
    let n = p.len();
    let h = |k: usize| times[k + 1] - times[k];
    let mut out = vec![0.0; n];
    let mut inc = vec![0.0; n];
    for k in 0..n {
        if k == 0 || k == n - 1 {
            let d = if k == 0 { p[1] - p[0] } else { p[n - 1] - p[n - 2] };
            out[k] = d;
            inc[k] = d;
            continue;
        }
        let (back, fwd) = (p[k] - p[k - 1], p[k + 1] - p[k]);
        let (h0, h1) = (h(k - 1), h(k));
        let td = 0.5 * (1.0 - t) * ((1.0 + cc) * (1.0 + b) * back + (1.0 - cc) * (1.0 - b) * fwd);
        let ts = 0.5 * (1.0 - t) * ((1.0 - cc) * (1.0 + b) * back + (1.0 + cc) * (1.0 - b) * fwd);
        out[k] = td * 2.0 * h1 / (h0 + h1);
        inc[k] = ts * 2.0 * h0 / (h0 + h1);
    }
    (out, inc)
}

impl Interpolation {
    /// Check the scheme's own parameters for a track of `n` keys and `dim` channels.
    fn check(&self, n: usize, dim: usize) -> Result<()> {
        match self {
            Interpolation::ClampedCubic { start, end } => {
                check_finite("end_tangents", start, dim)?;
                check_finite("end_tangents", end, dim)
            }
            Interpolation::Hermite { tangents } => check_finite("tangents", tangents, n * dim),
            Interpolation::Bezier { handles } => {
                check_finite("handles", handles, (n.saturating_sub(1)) * 2 * dim)
            }
            Interpolation::Cardinal { tension } => check_finite("tension", &[*tension], 1),
            Interpolation::KochanekBartels { tension, continuity, bias } => {
                check_finite("tension", &[*tension, *continuity, *bias], 3)
            }
            _ => Ok(()),
        }
    }

    /// The cubic `[a0, a1, a2, a3]` in the local parameter of each segment of channel `c`
    /// (of `dim`) through the points `p` (at least two) at `times`; zero for
    /// [`Interpolation::Polynomial`], which is stored in Newton form instead.
    fn cubics(&self, times: &[f64], p: &[f64], c: usize, dim: usize) -> Vec<[f64; 4]> {
        let n = p.len();
        let h = |k: usize| times[k + 1] - times[k];
        let hermites = |out: &[f64], inc: &[f64]| -> Vec<[f64; 4]> {
            (0..n - 1).map(|k| hermite(p[k], p[k + 1], out[k] * h(k), inc[k + 1] * h(k))).collect()
        };
        match self {
            Interpolation::Step => (0..n - 1).map(|k| [p[k], 0.0, 0.0, 0.0]).collect(),
            Interpolation::Linear => {
                (0..n - 1).map(|k| [p[k], p[k + 1] - p[k], 0.0, 0.0]).collect()
            }
            // Stored in Newton form instead (`Track::newton`).
            Interpolation::Polynomial => vec![[0.0; 4]; n - 1],
            Interpolation::NaturalCubic => {
                let m = spline_slopes(times, p, None);
                hermites(&m, &m)
            }
            Interpolation::ClampedCubic { start, end } => {
                let m = spline_slopes(times, p, Some((start[c], end[c])));
                hermites(&m, &m)
            }
            Interpolation::Hermite { tangents } => {
                let m: Vec<f64> = (0..n).map(|k| tangents[k * dim + c]).collect();
                hermites(&m, &m)
            }
            Interpolation::Cardinal { tension } => {
                let m: Vec<f64> = (0..n)
                    .map(|k| {
                        let (lo, hi) = (k.saturating_sub(1), (k + 1).min(n - 1));
                        (1.0 - tension) * (p[hi] - p[lo]) / (times[hi] - times[lo])
                    })
                    .collect();
                hermites(&m, &m)
            }
            Interpolation::KochanekBartels { tension, continuity, bias } => {
                let (out, inc) =
                    kochanek_bartels_tangents(times, p, (*tension, *continuity, *bias));
                (0..n - 1).map(|k| hermite(p[k], p[k + 1], out[k], inc[k + 1])).collect()
            }
            Interpolation::Bezier { handles } => (0..n - 1)
                .map(|k| {
                    let (h0, h1) = (handles[(2 * k) * dim + c], handles[(2 * k + 1) * dim + c]);
                    let (p0, p1) = (p[k], p[k + 1]);
                    [
                        p0,
                        3.0 * (h0 - p0),
                        3.0 * (p0 - 2.0 * h0 + h1),
                        -p0 + 3.0 * h0 - 3.0 * h1 + p1,
                    ]
                })
                .collect(),
            Interpolation::BSpline => {
                let q = |i: isize| p[i.clamp(0, n as isize - 1) as usize];
                (0..n - 1)
                    .map(|k| {
                        let i = k as isize;
                        let (a, b, cq, d) = (q(i - 1), q(i), q(i + 1), q(i + 2));
                        [
                            (a + 4.0 * b + cq) / 6.0,
                            (cq - a) / 2.0,
                            (a - 2.0 * b + cq) / 2.0,
                            (-a + 3.0 * b - 3.0 * cq + d) / 6.0,
                        ]
                    })
                    .collect()
            }
        }
    }
}

/// Key times must be finite and strictly increasing; the error names the first bad index
/// (or pair of indices).
pub(crate) fn check_times(times: &[f64]) -> Result<()> {
    if let Some(i) = times.iter().position(|t| !t.is_finite()) {
        return Err(Error::InvalidInput {
            arg: "times".into(),
            index: Some(i),
            reason: "is NaN or infinite".into(),
        });
    }
    if let Some(k) = times.windows(2).position(|w| w[1] <= w[0]) {
        return Err(Error::invalid(
            "times",
            format!(
                "must be strictly increasing: times[{k}] = {} and times[{}] = {}",
                times[k],
                k + 1,
                times[k + 1]
            ),
        ));
    }
    Ok(())
}

impl Track {
    /// A track through `values` (`n x dim`, row-major) at strictly increasing `times` (s).
    ///
    /// # Errors
    /// No keys, times not finite or not strictly increasing (the message names the first
    /// offending pair of indices), non-finite values or parameters, parameter arrays of the
    /// wrong size.
    pub fn new(
        times: &[f64],
        values: &[f64],
        dim: usize,
        interpolation: Interpolation,
        extrapolate: Extrapolation,
    ) -> Result<Self> {
        let n = times.len();
        check_keys(times, values, dim)?;
        interpolation.check(n, dim)?;
        let segments = n.saturating_sub(1);
        let mut coeffs = vec![[0.0; 4]; segments * dim];
        let mut newton = None;
        if n == 1 {
            // A single key: a constant, stored as one flat segment.
            coeffs = (0..dim).map(|c| [values[c], 0.0, 0.0, 0.0]).collect();
        }
        for c in (0..dim).filter(|_| n > 1) {
            let p: Vec<f64> = (0..n).map(|k| values[k * dim + c]).collect();
            for (k, cubic) in interpolation.cubics(times, &p, c, dim).into_iter().enumerate() {
                coeffs[k * dim + c] = cubic;
            }
            if interpolation == Interpolation::Polynomial {
                let a = divided_differences(times, p);
                let store = newton.get_or_insert_with(|| vec![0.0; n * dim]);
                for (k, a) in a.into_iter().enumerate() {
                    store[k * dim + c] = a;
                }
            }
        }
        let last_step_value =
            (interpolation == Interpolation::Step).then(|| values[(n - 1) * dim..].to_vec());
        Ok(Track { times: times.to_vec(), dim, coeffs, newton, last_step_value, extrapolate })
    }

    /// A track whose segment `k` (from key `k` to key `k + 1`) follows `schemes[k]`: per-key
    /// interpolation modes, each key choosing how the curve leaves it. The cubics of each
    /// segment are those its scheme makes over the whole track (a Catmull–Rom segment takes
    /// its tangents from the neighbouring keys whatever their own modes), so the curve is C0
    /// at keys where the mode changes and as smooth as the scheme elsewhere.
    ///
    /// # Errors
    /// As [`Track::new`]; `schemes` of a length other than the number of segments, or the
    /// polynomial scheme (it is one curve through every key, not a per-segment scheme).
    pub fn per_segment(
        times: &[f64],
        values: &[f64],
        dim: usize,
        schemes: &[Interpolation],
        extrapolate: Extrapolation,
    ) -> Result<Self> {
        let segments = times.len().saturating_sub(1);
        if schemes.len() != segments {
            return Err(Error::invalid(
                "interpolation",
                format!("expected one scheme per segment ({segments}), got {}", schemes.len()),
            ));
        }
        if schemes.contains(&Interpolation::Polynomial) {
            return Err(Error::invalid(
                "interpolation",
                "polynomial is one curve through all keys and cannot be mixed per key",
            ));
        }
        let Some(first) = schemes.first() else {
            return Track::new(times, values, dim, Interpolation::Linear, extrapolate);
        };
        let mut track = Track::new(times, values, dim, first.clone(), extrapolate)?;
        let mut done = vec![first.clone()];
        for scheme in schemes {
            if done.contains(scheme) {
                continue;
            }
            let other = Track::new(times, values, dim, scheme.clone(), extrapolate)?;
            for (k, _) in schemes.iter().enumerate().filter(|(_, s)| *s == scheme) {
                track.coeffs[k * dim..(k + 1) * dim]
                    .copy_from_slice(&other.coeffs[k * dim..(k + 1) * dim]);
            }
            done.push(scheme.clone());
        }
        track.last_step_value = (schemes[segments - 1] == Interpolation::Step)
            .then(|| values[segments * dim..].to_vec());
        Ok(track)
    }

    /// Key times (s).
    pub fn times(&self) -> &[f64] {
        &self.times
    }

    /// Channel width.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Write the value (`order` 0), first or second time derivative (`order` 1, 2) at time `t`
    /// into `out` (length `dim`).
    pub fn eval(&self, t: f64, order: usize, out: &mut [f64]) {
        let (t0, t1) = (self.times[0], self.times[self.times.len() - 1]);
        let span = t1 - t0;
        if self.times.len() == 1 {
            for (c, o) in out.iter_mut().enumerate() {
                *o = if order == 0 { self.coeffs[c][0] } else { 0.0 };
            }
            return;
        }
        if t < t0 || t > t1 {
            match self.extrapolate {
                Extrapolation::Cycle => {
                    return self.inside((t - t0).rem_euclid(span) + t0, order, out)
                }
                Extrapolation::Hold => {
                    if order == 0 {
                        self.inside(t.clamp(t0, t1), 0, out);
                    } else {
                        out.fill(0.0);
                    }
                    return;
                }
                Extrapolation::Linear => {
                    let end = t.clamp(t0, t1);
                    match order {
                        0 => {
                            let mut slope = vec![0.0; self.dim];
                            self.inside(end, 1, &mut slope);
                            self.inside(end, 0, out);
                            out.iter_mut().zip(&slope).for_each(|(o, s)| *o += s * (t - end));
                        }
                        1 => self.inside(end, 1, out),
                        _ => out.fill(0.0),
                    }
                    return;
                }
            }
        }
        self.inside(t, order, out);
    }

    fn inside(&self, t: f64, order: usize, out: &mut [f64]) {
        if let Some(a) = &self.newton {
            let n = self.times.len();
            for (c, o) in out.iter_mut().enumerate() {
                let (mut p, mut dp, mut d2p) = (a[(n - 1) * self.dim + c], 0.0, 0.0);
                for k in (0..n - 1).rev() {
                    let x = t - self.times[k];
                    d2p = d2p * x + 2.0 * dp;
                    dp = dp * x + p;
                    p = p * x + a[k * self.dim + c];
                }
                *o = [p, dp, d2p][order.min(2)];
            }
            return;
        }
        if let Some(last) = &self.last_step_value {
            if t >= self.times[self.times.len() - 1] {
                for (o, v) in out.iter_mut().zip(last) {
                    *o = if order == 0 { *v } else { 0.0 };
                }
                return;
            }
        }
        let segments = self.times.len() - 1;
        let k = self.times.partition_point(|&x| x <= t).saturating_sub(1).min(segments - 1);
        let h = self.times[k + 1] - self.times[k];
        let s = (t - self.times[k]) / h;
        for (c, o) in out.iter_mut().enumerate() {
            let [c0, c1, c2, c3] = self.coeffs[k * self.dim + c];
            *o = match order {
                0 => c0 + s * (c1 + s * (c2 + s * c3)),
                1 => (c1 + s * (2.0 * c2 + 3.0 * s * c3)) / h,
                _ => (2.0 * c2 + 6.0 * s * c3) / (h * h),
            };
        }
    }

    /// Evaluate at every time of `ts` into `out` (`ts.len() x dim`), in parallel.
    ///
    /// # Errors
    /// A non-finite time (named by its index), an order above 2, or a wrong `out` length.
    pub fn eval_many(&self, ts: &[f64], order: usize, out: &mut [f64]) -> Result<()> {
        if order > 2 {
            return Err(Error::invalid("order", format!("derivatives up to order 2, got {order}")));
        }
        if out.len() != ts.len() * self.dim {
            return Err(Error::invalid("out", "must hold len(times) x dim values"));
        }
        if let Some(i) = ts.iter().position(|t| !t.is_finite()) {
            return Err(Error::InvalidInput {
                arg: "t".into(),
                index: Some(i),
                reason: "is NaN or infinite".into(),
            });
        }
        const CHUNK: usize = 4096;
        out.par_chunks_mut(CHUNK * self.dim).zip(ts.par_chunks(CHUNK)).for_each(|(o, t)| {
            for (row, &ti) in o.chunks_mut(self.dim).zip(t) {
                self.eval(ti, order, row);
            }
        });
        Ok(())
    }
}

impl crate::snapshot::Snapshot for Track {
    const TAG: &'static str = "Track";

    /// Key times finite and strictly increasing, one cubic per segment and channel (one flat
    /// segment for a single key), Newton coefficients and the held last value of their
    /// lengths, every coefficient finite.
    fn validate(&self) -> Result<()> {
        use crate::snapshot::{check, finite};
        let (n, dim) = (self.times.len(), self.dim);
        check(n > 0 && dim > 0, "times", || "a track needs a key and a channel".into())?;
        check(
            finite(self.times.iter().copied()) && self.times.windows(2).all(|w| w[0] < w[1]),
            "times",
            || "must be finite and strictly increasing".into(),
        )?;
        check(
            self.coeffs.len() == (n - 1).max(1).saturating_mul(dim)
                && finite(self.coeffs.iter().flatten().copied()),
            "coeffs",
            || "not one finite cubic per segment and channel".into(),
        )?;
        check(
            self.newton.as_ref().is_none_or(|a| a.len() == n * dim && finite(a.iter().copied()))
                && self
                    .last_step_value
                    .as_ref()
                    .is_none_or(|v| v.len() == dim && finite(v.iter().copied())),
            "newton",
            || "Newton coefficients or last value of the wrong length".into(),
        )
    }
}
