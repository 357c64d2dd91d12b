//! The flock solver: the neighbour grid and the accelerations of a step. Every boid's
//! steering is computed from the state at the start of the step alone, over its neighbour
//! list in the grid's fixed order, in parallel; so results are bitwise the same on any number
//! of threads. It carries nothing a later step reads.
//!
//! Steering (Reynolds 1999, "Steering behaviors for autonomous characters"): each of
//! Reynolds' (1987) three rules gives a desired direction; its steering is the desired
//! velocity (that direction at the maximum speed) minus the current velocity, at most
//! `max_force` long. The acceleration is the weighted sum, again at most `max_force`; then
//! semi-implicit Euler `v += a dt` (speed capped at `max_speed`), `p += v dt`.

use super::steering::{self, Behaviour, Steering};
use super::{Model, Settings, State};
use crate::error::{Error, Result};
use crate::geometry::grid::Grid;
use glam::DVec3;
use rayon::prelude::*;

/// Boids per parallel task.
const CHUNK: usize = 512;

/// Workspaces of a flock step (see the module docs).
#[derive(Clone, Debug, Default)]
pub struct Solver {
    grid: Grid,
    /// Accelerations of the step (m/s²), `N`.
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
            self.grid.build(&state.positions, n, set.neighbour_radius);
            let (grid, st) = (&self.grid, &*state);
            self.acceleration.par_iter_mut().enumerate().with_min_len(CHUNK).for_each(|(i, a)| {
                *a = flocking(set, st, i, grid.neighbours(i));
                *a = behaviours(set, &model.steering, st, i, *a);
            });
            state
                .velocities
                .par_iter_mut()
                .zip(&mut state.positions)
                .zip(&self.acceleration)
                .for_each(|((v, p), a)| {
                    *v = (*v + *a * dt).clamp_length_max(set.max_speed);
                    *p += *v * dt;
                });
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

/// The acceleration of boid `i` (m/s²) from its `neighbours` (those closer than the
/// neighbour radius) that lie in its field of view: separation away from those closer than
/// the separation distance, each weighted by the inverse distance (`-Σ d / |d|²`), alignment
/// towards their mean velocity, cohesion towards their centre.
fn flocking(set: &Settings, state: &State, i: usize, neighbours: &[u32]) -> DVec3 {
    let (p, v) = (state.positions[i], state.velocities[i]);
    let speed = v.length();
    let sees_all = set.field_of_view >= std::f64::consts::TAU || speed == 0.0;
    let cos_half = (0.5 * set.field_of_view).cos();
    let (mut away, mut velocity, mut offset, mut count) =
        (DVec3::ZERO, DVec3::ZERO, DVec3::ZERO, 0);
    for &j in neighbours {
        let d = state.positions[j as usize] - p;
        let distance = d.length();
        if !sees_all && d.dot(v) < cos_half * distance * speed {
            continue;
        }
        count += 1;
        velocity += state.velocities[j as usize];
        offset += d;
        if distance > 0.0 && distance < set.separation_distance {
            away -= d / (distance * distance);
        }
    }
    if count == 0 {
        return DVec3::ZERO;
    }
    let inv = 1.0 / count as f64;
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
