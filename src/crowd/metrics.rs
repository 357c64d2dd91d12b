//! Crowd measurements, as the crowd literature reports them: collisions (overlapping agent
//! pairs and agent–obstacle penetrations, counted per step and summed over time; the
//! measure of van den Berg et al. 2011, §7), time to goal, path length over the straight
//! line from start to goal, and the flow through a line segment (a door) as the number of
//! crossings over the time between the first and the last, `J = (N - 1) / (t_N - t_1)`
//! (Seyfried et al. 2009, "New insights into pedestrian flow through bottlenecks", §3), and
//! the density and velocity fields of Helbing, Johansson & Al-Abideen (2007, "Dynamics of
//! crowd disasters: an empirical study", eqs. 1–2): Gaussian-weighted sums over the agents
//! at the points of a grid ([`fields`]).
//!
//! Two agents collide when their discs overlap by more than [`EPSILON`]; an agent collides
//! with an obstacle when its disc reaches more than [`EPSILON`] over one of the polygon's
//! edges (counted once per agent and polygon).
//!
//! The functions here read positions only; the solver calls them after every step and keeps
//! the sums in the state ([`Tally`]).

use super::orca::segment_distance2;
use super::Model;
use crate::error::{Error, Result};
use crate::geometry::grid::Grid;
use glam::{DVec2, DVec3};
use rayon::prelude::*;

/// Overlaps no deeper than this (m) are not collisions: 1 µm, far below a step's motion and
/// far above the rounding of positions of tens of metres.
pub const EPSILON: f64 = 1e-6;

/// Collisions counted after every step.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, Default, PartialEq)]
pub struct Tally {
    /// Steps counted.
    pub steps: u64,
    /// Overlapping agent pairs, summed over the steps.
    pub agent_collisions: u64,
    /// Agent–obstacle penetrations, summed over the steps.
    pub obstacle_collisions: u64,
    /// Steps with at least one collision of either kind.
    pub steps_with_collisions: u64,
    /// Deepest overlap of two agents seen (m; `2r - distance`, 0 if none).
    pub max_overlap: f64,
    /// Deepest penetration of an obstacle seen (m; `r - distance`, 0 if none).
    pub max_penetration: f64,
}

impl Tally {
    /// Add one step's counts.
    pub fn record(&mut self, agents: Collisions, obstacles: Collisions) {
        self.steps += 1;
        self.agent_collisions += agents.count;
        self.obstacle_collisions += obstacles.count;
        self.steps_with_collisions += u64::from(agents.count + obstacles.count > 0);
        self.max_overlap = self.max_overlap.max(agents.depth);
        self.max_penetration = self.max_penetration.max(obstacles.depth);
    }

    pub(super) fn validate(&self) -> Result<()> {
        crate::snapshot::check(
            self.max_overlap >= 0.0 && self.max_penetration >= 0.0,
            "tally",
            || "NaN or negative depth".into(),
        )
    }
}

/// Collisions at one instant.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Collisions {
    /// How many (pairs of agents, or agent–polygon pairs).
    pub count: u64,
    /// The deepest overlap (m), 0 if none.
    pub depth: f64,
}

/// The overlapping pairs of agents of `radius` (m) at `positions` (m).
pub fn agent_collisions(positions: &[DVec2], radius: f64) -> Collisions {
    let mut grid = Grid::default();
    let mut points = Vec::new();
    agent_collisions_in(&mut grid, &mut points, positions, radius)
}

/// [`agent_collisions`] with the grid and the lifted points as reused buffers.
pub(super) fn agent_collisions_in(
    grid: &mut Grid,
    points: &mut Vec<DVec3>,
    positions: &[DVec2],
    radius: f64,
) -> Collisions {
    lift(positions, points);
    let reach = 2.0 * radius - EPSILON;
    if positions.is_empty() || reach <= 0.0 {
        return Collisions::default();
    }
    grid.build(points, positions.len(), reach);
    let grid = &*grid;
    (0..positions.len())
        .into_par_iter()
        .map(|i| {
            let mut c = Collisions::default();
            for &j in grid.neighbours(i) {
                if (j as usize) > i {
                    c.count += 1;
                    let d = (positions[j as usize] - positions[i]).length();
                    c.depth = c.depth.max(2.0 * radius - d);
                }
            }
            c
        })
        .reduce(Collisions::default, |a, b| Collisions {
            count: a.count + b.count,
            depth: a.depth.max(b.depth),
        })
}

/// Positions on the plane as 3-D points `(x, y, 0)` for the neighbour grid.
pub(super) fn lift(positions: &[DVec2], points: &mut Vec<DVec3>) {
    points.clear();
    points.extend(positions.iter().map(|p| p.extend(0.0)));
}

/// The agents of `model` at `positions` (m) penetrating an obstacle's edges (once per agent
/// and polygon).
pub fn obstacle_collisions(model: &Model, positions: &[DVec2]) -> Collisions {
    let r = model.settings.radius;
    if model.vertices.is_empty() {
        return Collisions::default();
    }
    positions
        .par_iter()
        .map(|&p| {
            let mut c = Collisions::default();
            for w in model.polygons.windows(2) {
                let nearest = (w[0] as usize..w[1] as usize)
                    .map(|k| {
                        let a = &model.vertices[k];
                        segment_distance2(p, a.point, model.vertices[a.next as usize].point)
                    })
                    .fold(f64::INFINITY, f64::min)
                    .sqrt();
                if nearest < r - EPSILON {
                    c.count += 1;
                    c.depth = c.depth.max(r - nearest);
                }
            }
            c
        })
        .reduce(Collisions::default, |a, b| Collisions {
            count: a.count + b.count,
            depth: a.depth.max(b.depth),
        })
}

/// A trajectory: `frames[f][i]` the position (m) of agent `i` at `times[f]` (s).
fn check_trajectory(frames: &[&[DVec2]], times: &[f64]) -> Result<usize> {
    if frames.len() != times.len() || frames.is_empty() {
        return Err(Error::invalid("times", "expected one time per frame, at least one frame"));
    }
    if times.windows(2).any(|t| t[1] <= t[0] || t[1].is_nan())
        || !times.iter().all(|t| t.is_finite())
    {
        return Err(Error::invalid("times", "must be finite and increasing"));
    }
    let n = frames[0].len();
    if let Some(f) = frames.iter().position(|fr| fr.len() != n) {
        return Err(Error::invalid("frames", "every frame must hold the same agents").at(f));
    }
    Ok(n)
}

/// For each agent of the trajectory (`frames[f][i]` at `times[f]`), the first time (s) it
/// comes within `tolerance` (m) of its goal, by linear interpolation between frames; `None`
/// if it never does.
///
/// # Errors
/// Frames and times of different lengths or no frame, times not increasing (`times`);
/// frames of different sizes or goals not one per agent (`frames`, `goals`).
pub fn time_to_goal(
    frames: &[&[DVec2]],
    times: &[f64],
    goals: &[DVec2],
    tolerance: f64,
) -> Result<Vec<Option<f64>>> {
    let n = check_trajectory(frames, times)?;
    if goals.len() != n {
        return Err(Error::invalid("goals", "expected one goal per agent"));
    }
    Ok((0..n)
        .map(|i| {
            let gap = |f: usize| (frames[f][i] - goals[i]).length() - tolerance;
            if gap(0) <= 0.0 {
                return Some(times[0]);
            }
            (1..frames.len()).find(|&f| gap(f) <= 0.0).map(|f| {
                let (g0, g1) = (gap(f - 1), gap(f));
                times[f - 1] + (times[f] - times[f - 1]) * g0 / (g0 - g1)
            })
        })
        .collect())
}

/// For each agent, the length of its path through the frames over the straight-line
/// distance from its first position to its goal (1 for a straight walk to the goal; infinite
/// when it starts on its goal and moves).
///
/// # Errors
/// As [`time_to_goal`].
pub fn path_ratio(frames: &[&[DVec2]], times: &[f64], goals: &[DVec2]) -> Result<Vec<f64>> {
    let n = check_trajectory(frames, times)?;
    if goals.len() != n {
        return Err(Error::invalid("goals", "expected one goal per agent"));
    }
    Ok((0..n)
        .map(|i| {
            let walked: f64 = frames.windows(2).map(|w| (w[1][i] - w[0][i]).length()).sum();
            ratio(walked, (goals[i] - frames[0][i]).length())
        })
        .collect())
}

/// `walked / straight`, 1 for `0 / 0`.
pub(super) fn ratio(walked: f64, straight: f64) -> f64 {
    if walked == 0.0 {
        1.0
    } else {
        walked / straight
    }
}

/// The times (s) at which agents cross the segment `a`–`b` (m) from its right to its left
/// (the side `det(b - a, p - a) > 0`), interpolated linearly between frames, in the order of
/// time.
///
/// # Errors
/// As [`time_to_goal`]; `a` and `b` equal or not finite (`door`).
pub fn crossings(frames: &[&[DVec2]], times: &[f64], a: DVec2, b: DVec2) -> Result<Vec<f64>> {
    let n = check_trajectory(frames, times)?;
    if !a.is_finite() || !b.is_finite() || a == b {
        return Err(Error::invalid("door", "must be two distinct finite points"));
    }
    let mut found = Vec::new();
    for f in 1..frames.len() {
        for (&p, &q) in frames[f - 1].iter().zip(frames[f]).take(n) {
            if let Some(s) = crossing(p, q, a, b) {
                found.push(times[f - 1] + s * (times[f] - times[f - 1]));
            }
        }
    }
    found.sort_by(f64::total_cmp);
    Ok(found)
}

/// Goals (m) that lead agents at `positions` (m) out through the door `a`–`b` (m) from its
/// right to its left (as [`crossings`] counts them): `reach` m along the direction to the
/// nearest point of the door narrowed by `radius` (m, at most half the door) at each end for
/// agents on its right, along its left normal for those on its left or in it. Set every step,
/// the desired direction points to the exit, as in Helbing, Farkas & Vicsek (2000).
///
/// # Errors
/// `positions` not finite; `a` and `b` equal or not finite (`door`); `radius` negative or not
/// finite; `reach` not positive and finite; `goals` not one per position. Nothing is written then.
pub fn door_goals(
    positions: &[DVec2],
    a: DVec2,
    b: DVec2,
    radius: f64,
    reach: f64,
    goals: &mut [DVec2],
) -> Result<()> {
    if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
        return Err(Error::invalid("positions", "contains NaN or infinity").at(i));
    }
    if !a.is_finite() || !b.is_finite() || a == b {
        return Err(Error::invalid("door", "must be two distinct finite points"));
    }
    if !(radius.is_finite() && radius >= 0.0) {
        return Err(Error::invalid("radius", "must be finite and >= 0"));
    }
    if !(reach.is_finite() && reach > 0.0) {
        return Err(Error::invalid("reach", "must be finite and > 0"));
    }
    if goals.len() != positions.len() {
        return Err(Error::invalid("goals", "expected one goal per position"));
    }
    let length = (b - a).length();
    let (u, r) = ((b - a) / length, radius.min(length / 2.0));
    let left = u.perp();
    for (g, &p) in goals.iter_mut().zip(positions) {
        let to = a + (p - a).dot(u).clamp(r, length - r) * u - p;
        let dist = to.length();
        let e = if (p - a).dot(left) < 0.0 && dist > 1e-9 { to / dist } else { left };
        *g = p + reach * e;
    }
    Ok(())
}

/// Cut-off of the fields' Gaussian weight, in units of `radius`: a weight is left out when
/// the agent is farther than this along `x` or `y`, where it is below `e⁻¹⁶ ≈ 1.1·10⁻⁷` of the
/// peak.
pub const FIELD_CUTOFF: f64 = 4.0;

/// The local density (agents/m²) and velocity (m/s) fields of agents at `positions` (m)
/// moving at `velocities` (m/s), at the points `(xs[i], ys[j])` (m) of a grid, as Helbing,
/// Johansson & Al-Abideen (2007, eqs. 1–2) measure crowds:
/// `ρ(r) = Σ_j f(r_j - r)` with `f(d) = exp(-|d|²/R²) / (π R²)` (each agent spread over a
/// Gaussian of integral 1; `R` = `radius`, m), and `V(r) = Σ_j v_j f(r_j - r) / Σ_j f(r_j - r)`
/// (zero where no agent is within [`FIELD_CUTOFF`] `R`). Written row by row (`y` outer):
/// `density[j · xs.len() + i]`, `velocity[j · xs.len() + i]`. Each point sums its agents in
/// index order: the same bits on any thread count.
///
/// # Errors
/// `positions` or `velocities` not finite, or not one velocity per position; `xs` or `ys`
/// not finite and strictly increasing; `radius` not finite and positive; `density` or
/// `velocity` not one per grid point. Nothing is written then.
pub fn fields(
    positions: &[DVec2],
    velocities: &[DVec2],
    xs: &[f64],
    ys: &[f64],
    radius: f64,
    density: &mut [f64],
    velocity: &mut [DVec2],
) -> Result<()> {
    for (arg, points) in [("positions", positions), ("velocities", velocities)] {
        if let Some(i) = points.iter().position(|p| !p.is_finite()) {
            return Err(Error::invalid(arg, "contains NaN or infinity").at(i));
        }
    }
    if velocities.len() != positions.len() {
        return Err(Error::invalid("velocities", "expected one velocity per position"));
    }
    for (arg, axis) in [("xs", xs), ("ys", ys)] {
        if let Some(i) = axis.iter().position(|x| !x.is_finite()) {
            return Err(Error::invalid(arg, "contains NaN or infinity").at(i));
        }
        if let Some(i) = axis.windows(2).position(|w| w[1] <= w[0]) {
            return Err(Error::invalid(arg, "must be strictly increasing").at(i + 1));
        }
    }
    if !(radius.is_finite() && radius > 0.0) {
        return Err(Error::invalid("radius", "must be finite and > 0"));
    }
    let points = xs.len() * ys.len();
    if density.len() != points || velocity.len() != points {
        return Err(Error::invalid("density", "expected one value per grid point"));
    }
    if xs.is_empty() {
        return Ok(());
    }
    let (inv_r2, cutoff) = (1.0 / (radius * radius), FIELD_CUTOFF * radius);
    let norm = inv_r2 / std::f64::consts::PI;
    let rows = density.par_chunks_mut(xs.len()).zip(velocity.par_chunks_mut(xs.len()));
    rows.zip(ys).for_each(|((density, velocity), &y)| {
        // The weights' sums first, then scaled in place.
        density.fill(0.0);
        velocity.fill(DVec2::ZERO);
        for (p, v) in positions.iter().zip(velocities) {
            let dy = p.y - y;
            if dy.abs() >= cutoff {
                continue;
            }
            let wy = (-dy * dy * inv_r2).exp();
            let first = xs.partition_point(|&x| x <= p.x - cutoff);
            let end = xs.partition_point(|&x| x < p.x + cutoff);
            for i in first..end {
                let dx = p.x - xs[i];
                let w = wy * (-dx * dx * inv_r2).exp();
                density[i] += w;
                velocity[i] += *v * w;
            }
        }
        for (d, u) in density.iter_mut().zip(velocity) {
            *u = if *d > 0.0 { *u / *d } else { DVec2::ZERO };
            *d *= norm;
        }
    });
    Ok(())
}

/// Where along the move `p → q` (a fraction in `[0, 1)`) it crosses the segment `a`–`b`
/// from right to left, if it does.
pub fn crossing(p: DVec2, q: DVec2, a: DVec2, b: DVec2) -> Option<f64> {
    let ab = b - a;
    let (sp, sq) = (ab.perp_dot(p - a), ab.perp_dot(q - a));
    if !(sp <= 0.0 && sq > 0.0) {
        return None;
    }
    let s = -sp / (sq - sp);
    let x = p + s * (q - p);
    let along = (x - a).dot(ab) / ab.length_squared();
    (0.0..=1.0).contains(&along).then_some(s)
}

/// The flow (agents per second) of crossings at `times` (s, sorted): `(N - 1) / (t_N -
/// t_1)`; `None` for fewer than two crossings or all at one instant.
pub fn flow_rate(times: &[f64]) -> Option<f64> {
    let (first, last) = (times.first()?, times.last()?);
    (times.len() >= 2 && last > first).then(|| (times.len() - 1) as f64 / (last - first))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flow_rate_of_regular_crossings() {
        assert_eq!(flow_rate(&[1.0, 2.0, 3.0, 4.0]), Some(1.0));
        assert_eq!(flow_rate(&[0.5, 0.75, 1.0]), Some(4.0));
        assert_eq!(flow_rate(&[2.0]), None);
        assert_eq!(flow_rate(&[]), None);
    }
}
