//! The flock solver: the boids sorted by cell and the accelerations of a step. Every boid's
//! steering is computed from the state at the start of the step alone, in the cells' sorted
//! order (`cells.rs`), sweeping its neighbours in a fixed order, in parallel; so results are
//! bitwise the same on any number of threads. It carries nothing a later step reads.
//!
//! Steering (Reynolds 1999, "Steering behaviors for autonomous characters"): each of
//! Reynolds' (1987) three rules gives a desired direction; its steering is the desired
//! velocity (that direction at the maximum speed) minus the current velocity, at most
//! `max_force` long. The acceleration is the weighted sum, again at most `max_force`; then
//! semi-implicit Euler `v += a dt` (speed capped at `max_speed`), `p += v dt`.

use super::cells::Cells;
use super::steering::{self, Behaviour, Steering};
use super::{Model, Settings, State};
use crate::error::{Error, Result};
use glam::DVec3;
use rayon::prelude::*;

/// Boids per parallel task.
const CHUNK: usize = 512;

/// Workspaces of a flock step (see the module docs).
#[derive(Clone, Debug, Default)]
pub struct Solver {
    cells: Cells,
    /// Accelerations of the step (m/s²), `N`, in the cells' sorted order.
    acceleration: Vec<DVec3>,
    /// The state at the start of the call, restored if a step fails.
    backup: State,
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
    /// ([`Error::Diverged`], naming the step and boid). The state is then as it was.
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
        self.backup.clone_from(state);
        let set = &model.settings;
        for step in 0..steps {
            let n = state.len();
            self.acceleration.resize(n, DVec3::ZERO);
            self.cells.build(&state.positions, &state.velocities, set.neighbour_radius);
            let (cells, st) = (&self.cells, &*state);
            let cos_half = (0.5 * set.field_of_view).cos();
            self.acceleration.par_iter_mut().enumerate().with_min_len(CHUNK).for_each(|(s, a)| {
                let i = cells.order[s] as usize;
                *a = behaviours(set, &model.steering, st, i, flocking(set, cos_half, cells, s));
            });
            let (acceleration, rank) = (&self.acceleration, &self.cells.rank);
            (&mut state.velocities, &mut state.positions, rank).into_par_iter().for_each(
                |(v, p, &s)| {
                    *v = (*v + acceleration[s as usize] * dt).clamp_length_max(set.max_speed);
                    *p += *v * dt;
                },
            );
            state.time += dt;
            if let Some(index) = state
                .positions
                .iter()
                .zip(&state.velocities)
                .position(|(p, v)| !(p.is_finite() && v.is_finite()))
            {
                state.clone_from(&self.backup);
                return Err(Error::Diverged {
                    step,
                    index,
                    reason: "non-finite boid position or velocity".into(),
                });
            }
        }
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

/// The acceleration (m/s²) of the boid in sorted slot `s` from its neighbours (those closer
/// than the neighbour radius) that lie in its field of view, `d · v ≥ cos_half |d| |v|`
/// (`cos_half` the cosine of half the field of view): separation away from those closer than
/// the separation distance, each weighted by the inverse distance (`-Σ d / |d|²`), alignment
/// towards their mean velocity, cohesion towards their centre. The sweep has no branch per
/// candidate (the field of view is tested on squares, so without a square root).
fn flocking(set: &Settings, cos_half: f64, cells: &Cells, s: usize) -> DVec3 {
    let v = cells.velocities[s];
    let speed = v.length();
    let sees_all = set.field_of_view >= std::f64::consts::TAU || speed == 0.0;
    // d · v ≥ c |d| with c = cos_half |v|: for c ≥ 0, d · v ≥ 0 and (d · v)² ≥ c² |d|²; for
    // c < 0, d · v ≥ 0 or (d · v)² ≤ c² |d|².
    let c = cos_half * speed;
    let (ahead, c2) = (c >= 0.0, c * c);
    let separation2 = set.separation_distance * set.separation_distance;
    let (mut away, mut velocity, mut offset, mut count) =
        (DVec3::ZERO, DVec3::ZERO, DVec3::ZERO, 0.0);
    cells.for_each_candidate(s, |t, d, near| {
        let (d2, dot) = (d.length_squared(), d.dot(v));
        let (front, q, r) = (dot >= 0.0, dot * dot, c2 * d2);
        let seen = near & (sees_all | if ahead { front & (q >= r) } else { front | (q <= r) });
        let w = f64::from(u8::from(seen));
        count += w;
        velocity += w * cells.velocities[t];
        offset += w * d;
        let close = f64::from(u8::from(seen & (d2 > 0.0) & (d2 < separation2)));
        away -= (close / d2.max(f64::MIN_POSITIVE)) * d;
    });
    if count == 0.0 {
        return DVec3::ZERO;
    }
    let inv = 1.0 / count;
    let a = set.separation * steer(set, away, v)
        + set.alignment * steer(set, velocity * inv, v)
        + set.cohesion * steer(set, offset * inv, v);
    a.clamp_length_max(set.max_force)
}

/// The flocking acceleration `flocking` of boid `i` plus its weighted steering behaviours,
/// at most `max_force` long (m/s²; `flocking` itself when none acts on it).
fn behaviours(
    set: &Settings,
    list: &[Steering],
    state: &State,
    i: usize,
    flocking: DVec3,
) -> DVec3 {
    let mut a = flocking;
    let mut any = false;
    for s in list.iter().filter(|s| (s.boids[0] as usize..s.boids[1] as usize).contains(&i)) {
        a += s.weight * steering::force(set, &s.behaviour, state, i);
        any = true;
    }
    if any {
        a.clamp_length_max(set.max_force)
    } else {
        flocking
    }
}
