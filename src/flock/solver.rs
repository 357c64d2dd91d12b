//! The flock solver: the boids sorted by cell and the accelerations of a step. Every boid's
//! steering is computed from the state at the start of the step alone, in the cells' sorted
//! order (`cells.rs`), sweeping its neighbours in a fixed order, in parallel; so results are
//! bitwise the same on any number of threads. Within one call the boids stay in the cells'
//! order from step to step (re-sorted each step from the last order) and are written back to
//! the state in index order at the end; nothing is carried from one call to the next.
//!
//! Steering (Reynolds 1999, "Steering behaviors for autonomous characters"): each of
//! Reynolds' (1987) three rules gives a desired direction; its steering is the desired
//! velocity (that direction at the maximum speed) minus the current velocity, at most
//! `max_force` long. The acceleration is the weighted sum, again at most `max_force`; then
//! semi-implicit Euler `v += a dt` (speed capped at `max_speed`), `p += v dt`.

use super::cells::Cells;
use super::steering::{self, Behaviour, Steering, View};
use super::{Model, Settings, State};
use crate::error::{Error, Result};
use glam::{DVec2, DVec3};
use rayon::prelude::*;

/// Boids per parallel task.
const CHUNK: usize = 512;

/// Workspaces of a flock step (see the module docs).
#[derive(Clone, Debug, Default)]
pub struct Solver {
    /// The boids of the call, sorted by cell.
    cells: Cells,
    /// Accelerations of the step (m/s²), `N`, in the cells' sorted order.
    acceleration: Vec<DVec3>,
}

impl Solver {
    /// A solver for `model` (buffers grow on the first step).
    pub fn new(_model: &Model) -> Self {
        Solver::default()
    }

    /// Advance `state` by `steps` steps of `dt` seconds.
    ///
    /// # Errors
    /// `dt` not finite and positive (`dt`); a non-finite position or velocity after a step
    /// ([`Error::Diverged`], naming the step and the lowest such boid). The state is then as
    /// it was (it is written only after the last step).
    pub fn step(&mut self, model: &Model, state: &mut State, dt: f64, steps: usize) -> Result<()> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(Error::invalid("dt", "must be finite and > 0"));
        }
        let n = state.len();
        for s in &model.steering {
            if let Behaviour::Pursue(j) | Behaviour::Evade(j) = s.behaviour {
                if j as usize >= n {
                    return Err(Error::invalid("target", "no boid of that index"));
                }
            }
        }
        let set = &model.settings;
        let cos_half = (0.5 * set.field_of_view).cos();
        self.cells.load(&state.positions, &state.velocities);
        self.acceleration.resize(n, DVec3::ZERO);
        let mut time = state.time;
        for step in 0..steps {
            self.cells.sort(set.neighbour_radius);
            let cells = &self.cells;
            let flock = View {
                positions: &cells.positions,
                velocities: &cells.velocities,
                rank: &cells.rank,
                time,
            };
            self.acceleration.par_iter_mut().enumerate().with_min_len(CHUNK).for_each(|(s, a)| {
                let rules = if cells.flat() {
                    flocking::<DVec2>(set, cos_half, cells, s)
                } else {
                    flocking::<DVec3>(set, cos_half, cells, s)
                };
                *a = behaviours(set, &model.steering, &flock, cells.order[s] as usize, rules);
            });
            let cells = &mut self.cells;
            (&mut cells.velocities, &mut cells.positions, &self.acceleration)
                .into_par_iter()
                .for_each(|(v, p, a)| {
                    *v = (*v + *a * dt).clamp_length_max(set.max_speed);
                    *p += *v * dt;
                });
            time += dt;
            if let Some(index) =
                (cells.positions.par_iter(), cells.velocities.par_iter(), &cells.order)
                    .into_par_iter()
                    .filter(|(p, v, _)| !(p.is_finite() && v.is_finite()))
                    .map(|(_, _, &i)| i as usize)
                    .min()
            {
                return Err(Error::Diverged {
                    step,
                    index,
                    reason: "non-finite boid position or velocity".into(),
                });
            }
        }
        self.cells.store(&mut state.positions, &mut state.velocities);
        state.time = time;
        Ok(())
    }
}

/// Reynolds' steering towards the desired direction `desired` (any length; none if zero):
/// `desired / |desired| · max_speed - v`, at most `max_force` long (m/s²).
fn steer(set: &Settings, desired: DVec3, v: DVec3) -> DVec3 {
    let length = desired.length();
    if length == 0.0 {
        return DVec3::ZERO;
    }
    (desired * (set.max_speed / length) - v).clamp_length_max(set.max_force)
}

/// The vectors a sweep works in: 3-D, or 2-D for flat flocks (the `x` and `y` of the same
/// operations in the same order, so the same results without the third component).
trait Vector:
    Copy
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<f64, Output = Self>
    + std::ops::AddAssign
    + std::ops::SubAssign
{
    const ZERO: Self;
    /// The components of `v` it keeps.
    fn of(v: DVec3) -> Self;
    fn dot(self, other: Self) -> f64;
    /// Back to 3-D (`z` zero from 2-D).
    fn widen(self) -> DVec3;
}

impl Vector for DVec3 {
    const ZERO: Self = DVec3::ZERO;
    fn of(v: DVec3) -> Self {
        v
    }
    fn dot(self, other: Self) -> f64 {
        DVec3::dot(self, other)
    }
    fn widen(self) -> DVec3 {
        self
    }
}

impl Vector for DVec2 {
    const ZERO: Self = DVec2::ZERO;
    fn of(v: DVec3) -> Self {
        DVec2::new(v.x, v.y)
    }
    fn dot(self, other: Self) -> f64 {
        DVec2::dot(self, other)
    }
    fn widen(self) -> DVec3 {
        DVec3::new(self.x, self.y, 0.0)
    }
}

/// The acceleration (m/s²) of the boid in sorted slot `s` from its neighbours (those closer
/// than the neighbour radius) that lie in its field of view, `d · v ≥ cos_half |d| |v|`
/// (`cos_half` the cosine of half the field of view): separation away from those closer than
/// the separation distance, each weighted by the inverse distance (`-Σ d / |d|²`), alignment
/// towards their mean velocity, cohesion towards their centre; in the vectors `V` (2-D for a
/// flat flock). The field of view is tested without a square root or a branch: with
/// `c = cos_half |v|`, `d · v ≥ c |d|` is `(d · v) |d · v| ≥ c |c| |d|²` (`x ↦ x |x|` is
/// increasing). Only the separation's division is behind a branch, on the distance alone
/// (few candidates are that close).
fn flocking<V: Vector>(set: &Settings, cos_half: f64, cells: &Cells, s: usize) -> DVec3 {
    let v = V::of(cells.velocities[s]);
    let speed = v.dot(v).sqrt();
    let sees_all = set.field_of_view >= std::f64::consts::TAU || speed == 0.0;
    let c = cos_half * speed;
    let cc = c * c.abs();
    let separation2 = set.separation_distance * set.separation_distance;
    let (mut away, mut velocity, mut offset, mut count) = (V::ZERO, V::ZERO, V::ZERO, 0.0);
    let (p, h2) = (V::of(cells.positions[s]), cells.h2());
    cells.for_each_candidate(s, |t, next| {
        let d = V::of(cells.positions[t]) - p;
        let (d2, dot) = (d.dot(d), d.dot(v));
        let near = next & (d2 < h2) & (t != s);
        let seen = near & (sees_all | (dot * dot.abs() >= cc * d2));
        // Whether a candidate is seen is a coin toss for the branch predictor: no branch.
        let w = std::hint::select_unpredictable(seen, 1.0, 0.0);
        count += w;
        velocity += V::of(cells.velocities[t]) * w;
        offset += d * w;
        // Rare, so well predicted, and on the distance alone (w zero: no change).
        if (d2 < separation2) & (d2 > 0.0) {
            away -= d * (w / d2);
        }
    });
    if count == 0.0 {
        return DVec3::ZERO;
    }
    let inv = 1.0 / count;
    let v = v.widen();
    let a = set.separation * steer(set, away.widen(), v)
        + set.alignment * steer(set, (velocity * inv).widen(), v)
        + set.cohesion * steer(set, (offset * inv).widen(), v);
    a.clamp_length_max(set.max_force)
}

/// The flocking acceleration `flocking` of boid `i` plus its weighted steering behaviours,
/// at most `max_force` long (m/s²; `flocking` itself when none acts on it).
fn behaviours(set: &Settings, list: &[Steering], flock: &View, i: usize, flocking: DVec3) -> DVec3 {
    let mut a = flocking;
    let mut any = false;
    for s in list.iter().filter(|s| (s.boids[0] as usize..s.boids[1] as usize).contains(&i)) {
        a += s.weight * steering::force(set, &s.behaviour, flock, i);
        any = true;
    }
    if any {
        a.clamp_length_max(set.max_force)
    } else {
        flocking
    }
}
