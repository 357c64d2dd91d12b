//! The crowd solver: the neighbour grid, per-chunk scratch and the step of either model. It
//! carries nothing a later step reads: one solver advances any number of states of one
//! model, each as if it had its own.
//!
//! Every agent's new velocity (ORCA) or acceleration (social forces) is computed from the
//! state at the start of the step (substep) alone, in parallel over fixed chunks of agents,
//! so results are bitwise the same on any number of threads.

use super::metrics::{self, Collisions};
use super::navigation::Search;
use super::orca::{self, Scratch};
use super::separation::Separation;
use super::social::{self, Agents};
use super::{Kind, Model, SocialForce, State};
use crate::error::{Error, Result};
use crate::geometry::grid::Grid;
use glam::{DVec2, DVec3};
use rayon::prelude::*;

/// Agents per parallel task.
const CHUNK: usize = 256;

/// What the last call to [`Solver::step`] did.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, Default, PartialEq)]
pub struct Stats {
    /// Steps taken.
    pub steps: usize,
    /// Substeps taken (social forces; equal to `steps` for ORCA).
    pub substeps: usize,
    /// Agent-steps whose linear program was infeasible, so that the 3-D fallback program of
    /// van den Berg et al. 2011, §5.3 chose the velocity (ORCA).
    pub fallbacks: usize,
}

/// Workspaces of a crowd step (see the module docs).
#[derive(Clone, Debug, Default)]
pub struct Solver {
    grid: Grid,
    points: Vec<DVec3>,
    scratch: Vec<Scratch>,
    fallbacks: Vec<usize>,
    /// Per-chunk A* workspaces of the navigation layer.
    routes: Vec<Search>,
    /// New velocities (ORCA) or accelerations (social forces), `N`.
    next: Vec<DVec2>,
    /// Positions at the start of the step (m), `N`.
    start: Vec<DVec2>,
    /// The state at the start of the call, restored if a step fails.
    backup: State,
    /// ORCA's position-level separation.
    separation: Separation,
}

impl Solver {
    /// A solver for `model` (buffers grow on the first step).
    pub fn new(_model: &Model) -> Self {
        Solver::default()
    }

    /// Advance `state` by `steps` steps of `dt` seconds: set each agent's preferred velocity
    /// (towards its goal at the preferred speed, or the speed that reaches it in one step
    /// when nearer — in one relaxation time for social forces), move the agents, and record
    /// collisions, path lengths and arrivals.
    ///
    /// # Errors
    /// `dt` not finite and positive (`dt`); a non-finite position or velocity after a step
    /// ([`Error::Diverged`], naming the step and agent). The state is then as it was.
    pub fn step(
        &mut self,
        model: &Model,
        state: &mut State,
        dt: f64,
        steps: usize,
    ) -> Result<Stats> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(Error::invalid("dt", "must be finite and > 0"));
        }
        self.backup.clone_from(state);
        let mut stats = Stats { steps, ..Stats::default() };
        for step in 0..steps {
            let before = state.time;
            self.start.clone_from(&state.positions);
            match model.settings.kind {
                Kind::Orca => {
                    stats.substeps += 1;
                    stats.fallbacks += self.orca(model, state, dt);
                }
                Kind::SocialForce(sf) => {
                    let n = (dt / sf.max_substep).ceil().max(1.0);
                    for _ in 0..n as usize {
                        self.social(model, &sf, state, dt / n);
                    }
                    stats.substeps += n as usize;
                }
            }
            state.time = before + dt;
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
                    reason: "non-finite agent position or velocity".into(),
                });
            }
            self.measure(model, state);
        }
        Ok(stats)
    }

    /// Preferred velocities: towards the goal at the preferred speed, or `(goal - p) /
    /// horizon` when that is slower; with navigation on, at the preferred speed towards the
    /// next waypoint while the goal is out of sight; plus `jitter` (m/s) times
    /// [`orca::jitter`] if positive.
    fn prefer(&mut self, model: &Model, state: &mut State, horizon: f64, jitter: f64) {
        let (speed, seed, step) =
            (model.settings.preferred_speed, model.settings.seed, state.tally.steps);
        let (positions, goals) = (&state.positions, &state.goals);
        self.routes.resize_with(state.len().div_ceil(CHUNK), Search::default);
        state.preferred.par_chunks_mut(CHUNK).zip(self.routes.par_iter_mut()).enumerate().for_each(
            |(c, (out, route))| {
                for (k, pref) in out.iter_mut().enumerate() {
                    let i = c * CHUNK + k;
                    let (p, g) = (positions[i], goals[i]);
                    let target = match &model.navigation {
                        Some(map) => map.waypoint(model, p, g, route),
                        None => g,
                    };
                    *pref = if target == g {
                        let to = (g - p) / horizon;
                        let l = to.length();
                        if l > speed {
                            to * (speed / l)
                        } else {
                            to
                        }
                    } else {
                        (target - p).normalize_or_zero() * speed
                    };
                    if jitter > 0.0 {
                        *pref += jitter * orca::jitter(seed, step, i);
                    }
                }
            },
        );
    }

    /// Size the per-agent buffers for `n` agents.
    fn fit(&mut self, n: usize) {
        self.next.resize(n, DVec2::ZERO);
        let chunks = n.div_ceil(CHUNK);
        self.scratch.resize_with(chunks, Scratch::default);
        self.fallbacks.resize(chunks, 0);
    }

    /// One ORCA step (§5 of van den Berg et al. 2011, and RVO2's update): new velocities from
    /// the half-planes of the nearest agents and obstacles, then `p += v dt`. Returns the
    /// number of agents that needed the fallback program.
    fn orca(&mut self, model: &Model, state: &mut State, dt: f64) -> usize {
        let n = state.len();
        self.prefer(model, state, dt, model.settings.perturbation);
        if n == 0 {
            return 0;
        }
        self.fit(n);
        metrics::lift(&state.positions, &mut self.points);
        self.grid.build(&self.points, n, model.settings.neighbour_distance);
        let (grid, st) = (&self.grid, &*state);
        self.next
            .par_chunks_mut(CHUNK)
            .zip(self.scratch.par_iter_mut())
            .zip(self.fallbacks.par_iter_mut())
            .enumerate()
            .for_each(|(c, ((out, scratch), fell))| {
                *fell = 0;
                for (k, o) in out.iter_mut().enumerate() {
                    let i = c * CHUNK + k;
                    let (v, fallback) =
                        orca::velocity(model, st, i, grid.neighbours(i), dt, scratch);
                    *o = v;
                    *fell += usize::from(fallback);
                }
            });
        state.velocities.copy_from_slice(&self.next);
        state.positions.par_iter_mut().zip(&state.velocities).for_each(|(p, v)| *p += *v * dt);
        if self.separation.separate(model, &mut state.positions) > 0 {
            // Position-based dynamics' velocity update (Müller et al. 2007, §3.1, step 12)
            // for the agents the separation moved.
            let (start, next) = (&self.start, &self.next);
            state.velocities.par_iter_mut().zip(&state.positions).enumerate().for_each(
                |(i, (v, p))| {
                    let moved = *p - (start[i] + next[i] * dt);
                    if moved != DVec2::ZERO {
                        *v = next[i] + moved / dt;
                    }
                },
            );
        }
        self.fallbacks.iter().sum()
    }

    /// One substep `h` of social forces: accelerations from the state, then semi-implicit
    /// Euler `v += a h` (speed capped at the maximum), `p += v h`.
    fn social(&mut self, model: &Model, sf: &SocialForce, state: &mut State, h: f64) {
        let n = state.len();
        self.prefer(model, state, sf.relaxation_time, 0.0);
        if n == 0 {
            return;
        }
        self.fit(n);
        metrics::lift(&state.positions, &mut self.points);
        self.grid.build(&self.points, n, model.settings.neighbour_distance);
        let grid = &self.grid;
        let agents = Agents {
            positions: &state.positions,
            velocities: &state.velocities,
            preferred: &state.preferred,
        };
        self.next.par_iter_mut().enumerate().with_min_len(CHUNK).for_each(|(i, a)| {
            *a = social::acceleration(model, sf, &agents, i, grid.neighbours(i));
        });
        let max = model.settings.max_speed;
        state.velocities.par_iter_mut().zip(&mut state.positions).zip(&self.next).for_each(
            |((v, p), a)| {
                *v += *a * h;
                let speed = v.length();
                if speed > max {
                    *v *= max / speed;
                }
                *p += *v * h;
            },
        );
    }

    /// After a step: path lengths, arrivals and the collision tallies.
    fn measure(&mut self, model: &Model, state: &mut State) {
        let tolerance = model.settings.goal_tolerance;
        let time = state.time;
        state
            .path_length
            .par_iter_mut()
            .zip(&mut state.arrival)
            .zip(&state.positions)
            .zip(&self.start)
            .zip(&state.goals)
            .for_each(|((((len, arrival), p), q), g)| {
                *len += (*p - *q).length();
                if arrival.is_infinite() && (*p - *g).length() <= tolerance {
                    *arrival = time;
                }
            });
        let agents = metrics::agent_collisions_in(
            &mut self.grid,
            &mut self.points,
            &state.positions,
            model.settings.radius,
        );
        let obstacles: Collisions = metrics::obstacle_collisions(model, &state.positions);
        state.tally.record(agents, obstacles);
    }
}
