//! ORCA's position-level separation: after `p += v dt`, overlapping agents are pushed apart
//! and agents reaching into an obstacle pushed out, as the non-penetration constraints
//! `|p_i - p_j| ≥ 2r` and `dist(p_i, polygon) ≥ r` of position-based dynamics (Müller,
//! Heidelberger, Hennix & Ratcliff 2007, "Position based dynamics", §3.3 and the
//! Gauss–Seidel projection of §3.5; applied to crowds by Weiss, Litteneker, Jiang &
//! Terzopoulos 2017, "Position-based multi-agent dynamics for real-time crowd simulation",
//! whose short-range collision constraint this is).
//!
//! ORCA guarantees no collision only when every agent's linear program is feasible (van den
//! Berg et al. 2011, §5.3): in dense crowds the fallback program relaxes the agents'
//! half-planes and, with at most `max_neighbours` neighbours avoided, agents overlap (RVO2
//! as well). The projection removes those overlaps and leaves every collision-free
//! configuration untouched: a pair of equal agents moves apart symmetrically by half the
//! overlap each along the line of their centres (equal masses), an obstacle (infinite mass)
//! pushes the agent alone, away from the nearest point of its edges. The constraints are
//! swept in a fixed order (pairs by first then second index, obstacles after the pairs), so
//! the result does not depend on the thread count. The solver then adds each moved agent's
//! correction over the step to its velocity (position-based dynamics' velocity update).

use super::lp::det;
use super::metrics::{self, EPSILON};
use super::orca::{apart, segment_distance2};
use super::Model;
use crate::geometry::grid::Grid;
use glam::{DVec2, DVec3};

/// Gauss–Seidel sweeps over the pairs found by one neighbour search.
const SWEEPS: usize = 4;
/// Neighbour searches at most; each finds the pairs closer than `SLACK · 2r`, so a pair
/// pushed together by a sweep is caught by the same search.
const ROUNDS: usize = 64;
/// How much farther than contact pairs are collected.
const SLACK: f64 = 1.25;
/// Overlaps below this fraction of the collision threshold [`EPSILON`] are left alone.
const TOLERANCE: f64 = 0.01 * EPSILON;

/// Buffers of the separation (grown once, then reused).
#[derive(Clone, Debug, Default)]
pub(super) struct Separation {
    grid: Grid,
    points: Vec<DVec3>,
    /// Close pairs `(i, j)`, `i < j`.
    pairs: Vec<(u32, u32)>,
    /// Agents near an obstacle edge.
    walled: Vec<u32>,
}

impl Separation {
    /// Separate the agents of `model` at `positions` (m). Returns the number of neighbour
    /// searches that found something to correct (0 when no agent overlapped).
    pub(super) fn separate(&mut self, model: &Model, positions: &mut [DVec2]) -> usize {
        let r = model.settings.radius;
        let contact = 2.0 * r;
        for round in 0..ROUNDS {
            metrics::lift(positions, &mut self.points);
            self.grid.build(&self.points, positions.len(), SLACK * contact);
            self.pairs.clear();
            let mut overlapping = false;
            for (i, &p) in positions.iter().enumerate() {
                for &j in self.grid.neighbours(i) {
                    if j as usize > i {
                        self.pairs.push((i as u32, j));
                        overlapping |= (positions[j as usize] - p).length() < contact - TOLERANCE;
                    }
                }
            }
            self.walled.clear();
            if !model.vertices.is_empty() {
                for (i, &p) in positions.iter().enumerate() {
                    let d = wall_distance(model, p);
                    if d < SLACK * r {
                        self.walled.push(i as u32);
                        overlapping |= d < r - TOLERANCE;
                    }
                }
            }
            if !overlapping {
                return round;
            }
            for _ in 0..SWEEPS {
                for &(i, j) in &self.pairs {
                    let (i, j) = (i as usize, j as usize);
                    let d = positions[j] - positions[i];
                    let l = d.length();
                    if l < contact {
                        let n = if l > 1e-12 * contact { d / l } else { -apart(i, j) };
                        let push = 0.5 * (contact - l) * n;
                        positions[i] -= push;
                        positions[j] += push;
                    }
                }
                for &i in &self.walled {
                    push_out(model, &mut positions[i as usize], r);
                }
            }
        }
        ROUNDS
    }
}

/// Distance (m) from `p` to the nearest obstacle edge facing it.
fn wall_distance(model: &Model, p: DVec2) -> f64 {
    edges(model, p).map(|(a, b)| segment_distance2(p, a, b)).fold(f64::INFINITY, f64::min).sqrt()
}

/// The obstacle edges `(a, b)` facing `p`: `p` on their right (outside a counterclockwise
/// polygon) or on their line. An agent whose centre is inside a solid polygon is not moved
/// (it started there: no edge faces it); a two-point wall faces both sides.
fn edges(model: &Model, p: DVec2) -> impl Iterator<Item = (DVec2, DVec2)> + '_ {
    model
        .vertices
        .iter()
        .map(|a| (a.point, model.vertices[a.next as usize].point))
        .filter(move |&(a, b)| det(a - p, b - a) <= 0.0)
}

/// Move `p` out to distance `r` (m) from every obstacle edge facing it and closer than that,
/// one edge after the other, away from the edge's nearest point (along the edge's outward
/// normal when `p` lies on it).
fn push_out(model: &Model, p: &mut DVec2, r: f64) {
    for (a, b) in edges(model, *p) {
        let ab = b - a;
        let t = ((*p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
        let d = *p - (a + t * ab);
        let l = d.length();
        if l < r {
            let n = if l > 1e-12 * r { d / l } else { DVec2::new(ab.y, -ab.x).normalize() };
            *p += (r - l) * n;
        }
    }
}
