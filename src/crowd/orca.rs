//! ORCA's half-planes (van den Berg, Guy, Lin & Manocha 2011, "Reciprocal n-body collision
//! avoidance"): for each neighbour the half-plane `ORCA_A|B^τ` of §5.1 (the relative velocity
//! projected out of the truncated cone `VO_A|B^τ`, eq. 2, onto its nearest boundary — a leg or
//! the cut-off circle — each agent taking half of the change `u`), and for each nearby
//! obstacle edge the half-plane of §6 with the vertex cases of the RVO2 library (convex and
//! concave vertices, edges seen obliquely, legs pointing into the neighbouring edge, edges
//! already covered by earlier half-planes). The new velocity is the linear program of
//! [`super::lp`] over them.

use super::lp::{self, det, Line};
use super::{Model, State};
use glam::DVec2;

/// Per-agent scratch of the velocity computation (reused, so a step allocates nothing once
/// the buffers have grown).
#[derive(Clone, Debug, Default)]
pub(super) struct Scratch {
    /// The nearest agents `(distance², index)`, nearest first.
    agents: Vec<(f64, u32)>,
    /// The obstacle edges in range `(distance², first vertex)`, nearest first.
    edges: Vec<(f64, u32)>,
    /// The half-planes: obstacles' first, then agents'.
    lines: Vec<Line>,
    /// The 3-D program's projected lines.
    projected: Vec<Line>,
}

/// The unit direction from agent `j` to agent `i` used when they coincide: fixed by their
/// indices and opposite for the pair's other agent, so coinciding agents split apart.
pub(super) fn apart(i: usize, j: usize) -> DVec2 {
    let (lo, hi) = (i.min(j) as f64, i.max(j) as f64);
    let angle =
        (lo * 0.618_033_988_749_895 + hi * 0.381_966_011_250_105).fract() * std::f64::consts::TAU;
    let d = DVec2::new(angle.cos(), angle.sin());
    if i < j {
        d
    } else {
        -d
    }
}

/// The unit direction of agent `i`'s preferred-velocity perturbation at step `step` (the
/// steps counted so far), hashed with `seed` (splitmix64, Steele, Lea & Flood 2014), so that
/// it is the same on any number of threads.
pub(super) fn jitter(seed: u64, step: u64, i: usize) -> DVec2 {
    let mut z = seed
        ^ step.wrapping_mul(0x9e37_79b9_7f4a_7c15)
        ^ (i as u64).wrapping_mul(0xd1b5_4a32_d192_ed03);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^= z >> 31;
    let angle = (z >> 11) as f64 / (1u64 << 53) as f64 * std::f64::consts::TAU;
    DVec2::new(angle.cos(), angle.sin())
}

/// Insert `(d2, k)` into `list`, kept sorted by distance (stable: equal distances keep the
/// order of arrival), at most `max` long.
fn insert(list: &mut Vec<(f64, u32)>, max: usize, d2: f64, k: u32) {
    if list.len() < max {
        list.push((d2, k));
    } else if list.last().is_none_or(|last| d2 >= last.0) {
        return;
    }
    let mut at = list.len() - 1;
    while at > 0 && d2 < list[at - 1].0 {
        list[at] = list[at - 1];
        at -= 1;
    }
    list[at] = (d2, k);
}

/// The new velocity of agent `i` (m/s) from the state at the start of the step, and whether
/// the fallback program was needed. `candidates` are the agents within the neighbour
/// distance, `dt` the step (s; the cut-off of already overlapping pairs).
pub(super) fn velocity(
    model: &Model,
    state: &State,
    i: usize,
    candidates: &[u32],
    dt: f64,
    s: &mut Scratch,
) -> (DVec2, bool) {
    let set = &model.settings;
    let (p, v) = (state.positions[i], state.velocities[i]);
    s.lines.clear();
    nearby_edges(model, p, &mut s.edges);
    let inv_tau = 1.0 / set.obstacle_time_horizon;
    for &(_, k) in &s.edges {
        if let Some(line) = obstacle_line(model, k as usize, p, v, set.radius, inv_tau, &s.lines) {
            s.lines.push(line);
        }
    }
    let hard = s.lines.len();
    s.agents.clear();
    let mut range2 = set.neighbour_distance * set.neighbour_distance;
    if set.max_neighbours > 0 {
        for &j in candidates {
            let d2 = (state.positions[j as usize] - p).length_squared();
            if d2 < range2 {
                insert(&mut s.agents, set.max_neighbours, d2, j);
                if s.agents.len() == set.max_neighbours {
                    range2 = s.agents[set.max_neighbours - 1].0;
                }
            }
        }
    }
    // The combined radius the agents plan with (the planning margin's, not the true one).
    let planning = 2.0 * set.radius * (1.0 + set.planning_margin);
    for &(_, j) in &s.agents {
        let j = j as usize;
        let relative = Relative {
            position: state.positions[j] - p,
            velocity: v - state.velocities[j],
            apart: apart(i, j),
        };
        s.lines.push(agent_line(relative, v, planning, set.time_horizon, dt));
    }
    lp::solve(&s.lines, hard, set.max_speed, state.preferred[i], &mut s.projected)
}

/// A neighbour as seen from the agent.
#[derive(Clone, Copy, Debug)]
pub(super) struct Relative {
    /// Its position minus the agent's (m).
    pub position: DVec2,
    /// The agent's velocity minus its (m/s).
    pub velocity: DVec2,
    /// The unit direction from it to the agent if they coincide ([`apart`]).
    pub apart: DVec2,
}

/// The half-plane `ORCA_A|B^τ` of an agent of velocity `v` against one neighbour (§5.1):
/// `u` is the smallest change of the relative velocity that takes it out of `VO^τ` (the cone
/// of apex 0 through the disc of radius `combined` about `position`, cut off by the disc
/// scaled by `1/τ`); the agent takes half of it. Pairs already overlapping use the cut-off
/// of one step `dt` instead of `τ`, so they separate within it.
pub(super) fn agent_line(rel: Relative, v: DVec2, combined: f64, tau: f64, dt: f64) -> Line {
    let d2 = rel.position.length_squared();
    let r2 = combined * combined;
    let (direction, u);
    if d2 > r2 {
        let w = rel.velocity - rel.position / tau; // from the cut-off centre
        let w2 = w.length_squared();
        let dot = w.dot(rel.position);
        if dot < 0.0 && dot * dot > r2 * w2 {
            // Nearest boundary point on the cut-off circle.
            let wl = w2.sqrt();
            let unit = w / wl;
            direction = DVec2::new(unit.y, -unit.x);
            u = (combined / tau - wl) * unit;
        } else {
            // Nearest boundary point on a leg: the tangent from 0 to the disc.
            let leg = (d2 - r2).sqrt();
            let (x, y) = (rel.position.x, rel.position.y);
            direction = if det(rel.position, w) > 0.0 {
                DVec2::new(x * leg - y * combined, x * combined + y * leg) / d2
            } else {
                -DVec2::new(x * leg + y * combined, -x * combined + y * leg) / d2
            };
            u = rel.velocity.dot(direction) * direction - rel.velocity;
        }
    } else {
        // Overlapping: leave the cut-off circle of time dt.
        let w = rel.velocity - rel.position / dt;
        let wl = w.length();
        let unit = if wl > 1e-12 * combined / dt { w / wl } else { rel.apart };
        direction = DVec2::new(unit.y, -unit.x);
        u = (combined / dt - wl) * unit;
    }
    Line { point: v + 0.5 * u, direction }
}

/// The obstacle edges near `p`: those within `τ_obst · max_speed + radius` that face it
/// (the agent on their right, i.e. outside a counterclockwise polygon), nearest first.
fn nearby_edges(model: &Model, p: DVec2, out: &mut Vec<(f64, u32)>) {
    out.clear();
    let set = &model.settings;
    let range = set.obstacle_time_horizon * set.max_speed + set.radius;
    for (k, a) in model.vertices.iter().enumerate() {
        let b = model.vertices[a.next as usize].point;
        if det(a.point - p, b - a.point) >= 0.0 {
            continue; // the agent is on the edge's left (inside) or on its line
        }
        let d2 = segment_distance2(p, a.point, b);
        if d2 < range * range {
            insert(out, usize::MAX, d2, k as u32);
        }
    }
}

/// Squared distance from `p` to the segment `ab`.
pub(super) fn segment_distance2(p: DVec2, a: DVec2, b: DVec2) -> f64 {
    let ab = b - a;
    let t = ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
    (p - (a + t * ab)).length_squared()
}

/// The left (`sign = 1`) or right (`sign = -1`) tangent direction from the agent to the
/// disc of `radius` about `rel` (a vertex relative to the agent, farther than `radius`).
fn tangent(rel: DVec2, radius: f64, sign: f64) -> DVec2 {
    let d2 = rel.length_squared();
    let leg = (d2 - radius * radius).max(0.0).sqrt();
    DVec2::new(rel.x * leg - sign * rel.y * radius, sign * rel.x * radius + rel.y * leg) / d2
}

/// The half-plane of the edge from vertex `k` for an agent at `p` with velocity `v`, or
/// `None` when no constraint is needed (already covered, a concave vertex, a foreign leg).
fn obstacle_line(
    model: &Model,
    k: usize,
    p: DVec2,
    v: DVec2,
    radius: f64,
    inv_tau: f64,
    lines: &[Line],
) -> Option<Line> {
    let verts = &model.vertices;
    let (mut o1, mut o2) = (k, verts[k].next as usize);
    let rel1 = verts[o1].point - p;
    let rel2 = verts[o2].point - p;
    // Already covered: both ends' cut-off discs lie on the forbidden side of an earlier line.
    let r_tau = inv_tau * radius;
    if lines.iter().any(|l| {
        det(inv_tau * rel1 - l.point, l.direction) - r_tau >= -1e-9
            && det(inv_tau * rel2 - l.point, l.direction) - r_tau >= -1e-9
    }) {
        return None;
    }
    let (d2a, d2b, r2) = (rel1.length_squared(), rel2.length_squared(), radius * radius);
    let edge = verts[o2].point - verts[o1].point;
    let s = (-rel1).dot(edge) / edge.length_squared();
    let d2line = (-rel1 - s * edge).length_squared();
    let through =
        |rel: DVec2| Line { point: DVec2::ZERO, direction: DVec2::new(-rel.y, rel.x).normalize() };
    // Already touching a vertex or the edge: forbid any velocity towards it.
    if s < 0.0 && d2a <= r2 {
        return verts[o1].convex.then(|| through(rel1));
    }
    if s > 1.0 && d2b <= r2 {
        let own = verts[o2].convex && det(rel2, verts[o2].direction) >= 0.0;
        return own.then(|| through(rel2));
    }
    if (0.0..=1.0).contains(&s) && d2line <= r2 {
        return Some(Line { point: DVec2::ZERO, direction: -verts[o1].direction });
    }
    // The legs of the velocity obstacle; seen obliquely, both come from one vertex.
    let (mut left, mut right);
    if s < 0.0 && d2line <= r2 {
        if !verts[o1].convex {
            return None;
        }
        o2 = o1;
        (left, right) = (tangent(rel1, radius, 1.0), tangent(rel1, radius, -1.0));
    } else if s > 1.0 && d2line <= r2 {
        if !verts[o2].convex {
            return None;
        }
        o1 = o2;
        (left, right) = (tangent(rel2, radius, 1.0), tangent(rel2, radius, -1.0));
    } else {
        left = if verts[o1].convex { tangent(rel1, radius, 1.0) } else { -verts[o1].direction };
        right = if verts[o2].convex { tangent(rel2, radius, -1.0) } else { verts[o1].direction };
    }
    // A leg pointing into the neighbouring edge is replaced by that edge (a "foreign" leg:
    // projecting onto it adds no constraint).
    let before = verts[verts[o1].previous as usize].direction;
    let left_foreign = verts[o1].convex && det(left, -before) >= 0.0;
    if left_foreign {
        left = -before;
    }
    let right_foreign = verts[o2].convex && det(right, verts[o2].direction) <= 0.0;
    if right_foreign {
        right = verts[o2].direction;
    }
    let legs = Legs {
        left_cutoff: inv_tau * (verts[o1].point - p),
        right_cutoff: inv_tau * (verts[o2].point - p),
        left,
        right,
        left_foreign,
        right_foreign,
        single: o1 == o2,
        edge_direction: verts[o1].direction,
    };
    legs.project(v, r_tau)
}

/// The boundary of an obstacle's truncated velocity obstacle: two cut-off discs (radius
/// `r/τ`) joined by the cut-off line, and the two legs.
struct Legs {
    left_cutoff: DVec2,
    right_cutoff: DVec2,
    left: DVec2,
    right: DVec2,
    left_foreign: bool,
    right_foreign: bool,
    /// Both legs come from one vertex.
    single: bool,
    edge_direction: DVec2,
}

impl Legs {
    /// The half-plane through the boundary point nearest `v` (`r_tau` = radius / τ).
    fn project(&self, v: DVec2, r_tau: f64) -> Option<Line> {
        let span = self.right_cutoff - self.left_cutoff;
        let t = if self.single {
            0.5
        } else {
            (v - self.left_cutoff).dot(span) / span.length_squared()
        };
        let t_left = (v - self.left_cutoff).dot(self.left);
        let t_right = (v - self.right_cutoff).dot(self.right);
        let on_circle = |centre: DVec2| {
            let unit = (v - centre).normalize_or(DVec2::X);
            Line { direction: DVec2::new(unit.y, -unit.x), point: centre + r_tau * unit }
        };
        if (t < 0.0 && t_left < 0.0) || (self.single && t_left < 0.0 && t_right < 0.0) {
            return Some(on_circle(self.left_cutoff));
        }
        if t > 1.0 && t_right < 0.0 {
            return Some(on_circle(self.right_cutoff));
        }
        let d2_cutoff = if !(0.0..=1.0).contains(&t) || self.single {
            f64::INFINITY
        } else {
            (v - (self.left_cutoff + t * span)).length_squared()
        };
        let d2_left = if t_left < 0.0 {
            f64::INFINITY
        } else {
            (v - (self.left_cutoff + t_left * self.left)).length_squared()
        };
        let d2_right = if t_right < 0.0 {
            f64::INFINITY
        } else {
            (v - (self.right_cutoff + t_right * self.right)).length_squared()
        };
        let offset = |d: DVec2| r_tau * DVec2::new(-d.y, d.x);
        if d2_cutoff <= d2_left && d2_cutoff <= d2_right {
            let d = -self.edge_direction;
            return Some(Line { point: self.left_cutoff + offset(d), direction: d });
        }
        if d2_left <= d2_right {
            return (!self.left_foreign).then(|| Line {
                point: self.left_cutoff + offset(self.left),
                direction: self.left,
            });
        }
        let d = -self.right;
        (!self.right_foreign).then(|| Line { point: self.right_cutoff + offset(d), direction: d })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn insert_keeps_the_nearest_in_order() {
        let mut list = Vec::new();
        for (k, d2) in [5.0, 1.0, 3.0, 1.0, 0.5, 9.0].into_iter().enumerate() {
            insert(&mut list, 3, d2, k as u32);
        }
        assert_eq!(list, vec![(0.5, 4), (1.0, 1), (1.0, 3)]);
    }

    #[test]
    fn apart_is_antisymmetric_and_unit() {
        for (i, j) in [(0, 1), (3, 17), (100, 2)] {
            let (a, b) = (apart(i, j), apart(j, i));
            assert!((a + b).length() < 1e-15 && (a.length() - 1.0).abs() < 1e-15);
        }
    }

    #[test]
    fn head_on_pair_gets_symmetric_half_planes() {
        // Two agents 10 m apart closing at 2 m/s each: each half-plane permits the other's
        // mirror image, and the current velocity is forbidden by half the needed change.
        let (va, vb) = (DVec2::new(1.0, 0.0), DVec2::new(-1.0, 0.0));
        let pa = DVec2::ZERO;
        let pb = DVec2::new(10.0, 0.0);
        let a = agent_line(
            Relative { position: pb - pa, velocity: va - vb, apart: apart(0, 1) },
            va,
            1.0,
            10.0,
            0.1,
        );
        let b = agent_line(
            Relative { position: pa - pb, velocity: vb - va, apart: apart(1, 0) },
            vb,
            1.0,
            10.0,
            0.1,
        );
        assert!(a.violation(va) > 0.0 && b.violation(vb) > 0.0);
        assert!((a.violation(va) - b.violation(vb)).abs() < 1e-12);
        // The two changes sum to u: the relative velocity at the two boundary points lies on
        // the velocity obstacle's boundary, i.e. (va' - vb') passes the disc tangentially.
        let va2 = va + a.violation(va) * DVec2::new(-a.direction.y, a.direction.x);
        let vb2 = vb + b.violation(vb) * DVec2::new(-b.direction.y, b.direction.x);
        let rel = va2 - vb2;
        let closest = ((pb - pa) - (pb - pa).dot(rel) / rel.length_squared() * rel).length();
        assert!((closest - 1.0).abs() < 1e-9, "{closest}");
    }

    #[test]
    fn coinciding_agents_are_pushed_apart_along_apart() {
        let line = agent_line(
            Relative { position: DVec2::ZERO, velocity: DVec2::ZERO, apart: DVec2::Y },
            DVec2::ZERO,
            1.0,
            10.0,
            0.5,
        );
        // Permitted: moving along +y at least half of combined / dt = 1 m/s.
        assert!(line.violation(DVec2::new(0.0, 1.0)) <= 1e-12);
        assert!(line.violation(DVec2::new(0.0, 0.9)) > 0.0);
        assert!(line.violation(DVec2::ZERO) > 0.0);
    }

    #[test]
    fn velocities_permitted_to_both_agents_do_not_collide_within_the_horizon() {
        let mut rnd = super::super::lp::uniform(99);
        let (combined, tau) = (3.0, 10.0);
        let mut checked = 0;
        for _ in 0..2000 {
            let pa = DVec2::ZERO;
            let pb = DVec2::new(rnd() * 30.0 - 15.0, rnd() * 30.0 - 15.0);
            if (pb - pa).length() <= combined {
                continue;
            }
            let va = DVec2::new(rnd() * 4.0 - 2.0, rnd() * 4.0 - 2.0);
            let vb = DVec2::new(rnd() * 4.0 - 2.0, rnd() * 4.0 - 2.0);
            let la = agent_line(
                Relative { position: pb - pa, velocity: va - vb, apart: DVec2::X },
                va,
                combined,
                tau,
                0.25,
            );
            let lb = agent_line(
                Relative { position: pa - pb, velocity: vb - va, apart: -DVec2::X },
                vb,
                combined,
                tau,
                0.25,
            );
            for _ in 0..20 {
                let a2 = DVec2::new(rnd() * 8.0 - 4.0, rnd() * 8.0 - 4.0);
                let b2 = DVec2::new(rnd() * 8.0 - 4.0, rnd() * 8.0 - 4.0);
                if la.violation(a2) > 0.0 || lb.violation(b2) > 0.0 {
                    continue;
                }
                checked += 1;
                let rel = a2 - b2;
                let d = pb - pa;
                let t = (d.dot(rel) / rel.length_squared()).clamp(0.0, tau);
                let closest = (d - rel * t).length();
                assert!(
                    closest >= combined - 1e-9,
                    "{closest} pa {pa} pb {pb} va {va} vb {vb} a2 {a2} b2 {b2}"
                );
            }
        }
        assert!(checked > 1000, "{checked}");
    }
}
