//! What an adaptive run records: every accepted step, or the dense output at requested times,
//! and the zeros of event functions located on the dense output (as scipy's `solve_ivp`
//! `t_eval` and `events`), by the Illinois variant of regula falsi (Dowell & Jarratt 1971).

use super::adaptive::AdaptiveSolution;
use super::OdeSystem;
use crate::error::{reserve, Result};

/// An event `g(t, y) = 0` to locate during [`super::solve_adaptive`]
/// ([`OdeSystem::events`] gives the values of `g`), as an event of scipy's `solve_ivp`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Event {
    /// Stop the run at the first zero found.
    pub terminal: bool,
    /// Zeros counted: `> 0` where `g` goes from negative to non-negative, `< 0` from positive
    /// to non-positive, `0` both.
    pub direction: f64,
}

/// Where a run's solution goes (the times `t_eval` checked: sorted, within the span).
pub(super) struct Output<'a> {
    t_eval: Option<&'a [f64]>,
    next: usize,
    events: &'a [Event],
    /// The event functions at the last accepted point, and at the new one.
    g_old: Vec<f64>,
    g_new: Vec<f64>,
    buf: Vec<f64>,
    pub(super) sol: AdaptiveSolution,
}

impl<'a> Output<'a> {
    /// An output starting at `(t0, y0)`.
    pub(super) fn new<S: OdeSystem>(
        sys: &mut S,
        t_eval: Option<&'a [f64]>,
        events: &'a [Event],
        t0: f64,
        y0: &[f64],
    ) -> Result<Self> {
        let m = events.len();
        let mut out = Output {
            t_eval,
            next: 0,
            events,
            g_old: vec![0.0; m],
            g_new: vec![0.0; m],
            buf: vec![0.0; y0.len()],
            sol: AdaptiveSolution {
                t_events: vec![Vec::new(); m],
                y_events: vec![Vec::new(); m],
                ..Default::default()
            },
        };
        if m > 0 {
            sys.events(t0, y0, &mut out.g_old)?;
        }
        out.record(t0, y0, &mut |_, _| {})?;
        Ok(out)
    }

    /// Whether event `i` changes sign (in its direction) over the step just taken.
    fn crossed(&self, i: usize) -> bool {
        let (a, b) = (self.g_old[i], self.g_new[i]);
        let up = a < 0.0 && b >= 0.0;
        let down = a > 0.0 && b <= 0.0;
        let d = self.events[i].direction;
        (up && d >= 0.0) || (down && d <= 0.0)
    }

    /// Evaluate the events at the end `(t, y)` of an accepted step and tell whether the step
    /// needs its dense output (a requested time before `t`, or an event in the step). Called
    /// before [`Output::accept`].
    pub(super) fn wants_dense<S: OdeSystem>(
        &mut self,
        sys: &mut S,
        t: f64,
        y: &[f64],
    ) -> Result<bool> {
        if !self.events.is_empty() {
            sys.events(t, y, &mut self.g_new)?;
        }
        let requested = self.t_eval.is_some_and(|te| te.get(self.next).is_some_and(|&s| s < t));
        Ok(requested || (0..self.events.len()).any(|i| self.crossed(i)))
    }

    /// Record the accepted step from `t_old` to `(t, y)`, `interp(time, out)` its dense
    /// output: the events' zeros in it, then the step's end or the requested times up to it;
    /// a terminal event ends the record at its zero. Returns whether to stop.
    pub(super) fn accept<S: OdeSystem>(
        &mut self,
        sys: &mut S,
        t_old: f64,
        t: f64,
        y: &[f64],
        mut interp: impl FnMut(f64, &mut [f64]),
    ) -> Result<bool> {
        let mut stop: Option<f64> = None;
        let crossed: Vec<usize> = (0..self.events.len()).filter(|&i| self.crossed(i)).collect();
        if !crossed.is_empty() {
            let mut g = vec![0.0; self.events.len()];
            let mut roots = Vec::with_capacity(crossed.len());
            for &i in &crossed {
                let mut value = |s: f64| -> Result<f64> {
                    interp(s, &mut self.buf);
                    sys.events(s, &self.buf, &mut g)?;
                    Ok(g[i])
                };
                roots.push((illinois(&mut value, t_old, t, self.g_old[i], self.g_new[i])?, i));
            }
            roots.sort_by(|a, b| a.0.total_cmp(&b.0));
            for (s, i) in roots {
                if stop.is_some_and(|ts| s > ts) {
                    break;
                }
                interp(s, &mut self.buf);
                reserve("events", &mut self.sol.y_events[i], y.len())?;
                self.sol.t_events[i].push(s);
                self.sol.y_events[i].extend_from_slice(&self.buf);
                if self.events[i].terminal && stop.is_none() {
                    stop = Some(s);
                }
            }
        }
        match stop {
            Some(ts) => {
                interp(ts, &mut self.buf);
                let end = std::mem::take(&mut self.buf);
                let r = self.record(ts, &end, &mut interp);
                self.buf = end;
                r?;
                self.sol.terminated = true;
            }
            None => self.record(t, y, &mut interp)?,
        }
        std::mem::swap(&mut self.g_old, &mut self.g_new);
        Ok(stop.is_some())
    }

    /// The output up to `(t, y)`: the point itself, or the requested times up to `t`, those
    /// before `t` from `interp`.
    fn record(
        &mut self,
        t: f64,
        y: &[f64],
        interp: &mut impl FnMut(f64, &mut [f64]),
    ) -> Result<()> {
        let Some(te) = self.t_eval else { return self.push(t, y) };
        while let Some(&s) = te.get(self.next).filter(|&&s| s <= t) {
            self.next += 1;
            if s == t {
                self.push(t, y)?;
            } else {
                let mut buf = std::mem::take(&mut self.buf);
                interp(s, &mut buf);
                let r = self.push(s, &buf);
                self.buf = buf;
                r?;
            }
        }
        Ok(())
    }

    /// Append `(t, y)`: refused (naming the step bound) when it no longer fits in memory,
    /// instead of the process being killed.
    fn push(&mut self, t: f64, y: &[f64]) -> Result<()> {
        reserve("max_steps", &mut self.sol.t, 1)?;
        reserve("max_steps", &mut self.sol.y, y.len())?;
        self.sol.t.push(t);
        self.sol.y.extend_from_slice(y);
        Ok(())
    }
}

/// The zero of `g` in `(a, b]` where `g(a) = ga` and `g(b) = gb` differ in sign (or `gb = 0`),
/// to `1e-12 max(|a|, |b|)` in `t`: regula falsi with the Illinois modification (the value kept
/// at an end that stays twice in a row is halved), which converges superlinearly.
fn illinois(
    g: &mut impl FnMut(f64) -> Result<f64>,
    mut a: f64,
    mut b: f64,
    mut ga: f64,
    mut gb: f64,
) -> Result<f64> {
    let tol = 1e-12 * a.abs().max(b.abs()).max(f64::MIN_POSITIVE);
    let mut side = 0;
    let mut c = b;
    for _ in 0..200 {
        if gb == 0.0 || (b - a).abs() <= tol {
            return Ok(if gb == 0.0 { b } else { c });
        }
        c = (a * gb - b * ga) / (gb - ga);
        if !(c > a.min(b) && c < a.max(b)) {
            c = 0.5 * (a + b);
        }
        let gc = g(c)?;
        if gc == 0.0 {
            return Ok(c);
        }
        if (gc > 0.0) == (gb > 0.0) {
            (b, gb) = (c, gc);
            if side == -1 {
                ga *= 0.5;
            }
            side = -1;
        } else {
            (a, ga) = (c, gc);
            if side == 1 {
                gb *= 0.5;
            }
            side = 1;
        }
    }
    Ok(c)
}
