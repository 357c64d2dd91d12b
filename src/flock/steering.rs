//! Steering behaviours of Reynolds (1999, "Steering behaviors for autonomous characters"),
//! composable as weighted forces on top of the flocking rules: seek, flee, arrive, pursue,
//! evade, wander, path following and obstacle avoidance against the shared collision shapes
//! ([`crate::geometry::Shape`]). Each gives a desired velocity `d`; its steering is
//! `d - v`, at most `max_force` long (the velocity relaxes to the desired one in 1 s, as the
//! flocking rules do), weighted and summed with the others, the sum again at most
//! `max_force`.

use super::Settings;
use crate::error::{Error, Result};
use crate::geometry::Shape;
use glam::DVec3;

/// One steering behaviour (Reynolds 1999; positions in m, times in s).
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, PartialEq)]
pub enum Behaviour {
    /// Towards `target` at the maximum speed.
    Seek(DVec3),
    /// Away from `target` at the maximum speed.
    Flee(DVec3),
    /// Towards `target`, the desired speed falling linearly from the maximum at
    /// `slow_radius` (m) to zero at the target.
    Arrive {
        /// The target (m).
        target: DVec3,
        /// Radius in which the boid slows down (m).
        slow_radius: f64,
    },
    /// Seek where boid `.0` will be, predicted straight on for its distance over the maximum
    /// speed.
    Pursue(u32),
    /// Flee from where boid `.0` will be (predicted as for pursue).
    Evade(u32),
    /// Seek a point `radius` (m) from the point `distance` (m) ahead along the velocity, in a
    /// direction drawn afresh each step from `seed`, the time and the boid (splitmix64; in
    /// the `z = 0` plane when `planar`).
    Wander {
        /// Distance of the circle's (sphere's) centre ahead (m).
        distance: f64,
        /// Its radius (m).
        radius: f64,
        /// Seed of the directions.
        seed: u64,
        /// Whether to wander in the `z = 0` plane (a 2-D flock).
        planar: bool,
    },
    /// Steer sideways from `shape` when the boid would come closer than `clearance` (m) to it
    /// within `horizon` (s) going straight on, and straight out of it when already closer.
    Avoid {
        /// The obstacle.
        shape: Shape,
        /// How far ahead (s) the boid looks.
        horizon: f64,
        /// Distance (m) to keep from the surface.
        clearance: f64,
    },
    /// Follow the polyline `path` (Reynolds 1999, "path following"): the boid's position
    /// predicted `lookahead` (s) ahead at its velocity is projected onto the path; while
    /// that projection is within `radius` (m) and the boid moves forwards along the path, no
    /// correction; else seek the path's point `radius` farther along than the projection (its
    /// last point at the end).
    Follow {
        /// The path's points, in order (m; at least two, consecutive ones distinct).
        path: Vec<DVec3>,
        /// Half-width of the path (m).
        radius: f64,
        /// How far ahead (s) the position is predicted.
        lookahead: f64,
    },
}

/// A weighted behaviour acting on the boids `boids[0]..boids[1]`.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, PartialEq)]
pub struct Steering {
    /// The behaviour.
    pub behaviour: Behaviour,
    /// Its weight (≥ 0).
    pub weight: f64,
    /// The first boid it acts on and one past the last.
    pub boids: [u32; 2],
}

impl Steering {
    /// Check the parameters (named in the error).
    pub(super) fn validate(&self) -> Result<()> {
        let finite = |v: DVec3| v.is_finite();
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if !(self.weight.is_finite() && self.weight >= 0.0) {
            return Err(Error::invalid("weight", "must be finite and >= 0"));
        }
        if self.boids[0] > self.boids[1] {
            return Err(Error::invalid("boids", "first must not exceed end"));
        }
        let ok = match &self.behaviour {
            Behaviour::Seek(t) | Behaviour::Flee(t) => finite(*t),
            Behaviour::Arrive { target, slow_radius } => {
                if !positive(*slow_radius) {
                    return Err(Error::invalid("slow_radius", "must be finite and > 0"));
                }
                finite(*target)
            }
            Behaviour::Pursue(_) | Behaviour::Evade(_) => true,
            Behaviour::Wander { distance, radius, .. } => {
                if !(distance.is_finite() && *distance >= 0.0 && positive(*radius)) {
                    return Err(Error::invalid("radius", "distance >= 0 and radius > 0 needed"));
                }
                true
            }
            Behaviour::Avoid { shape, horizon, clearance } => {
                shape.checked()?;
                if !(positive(*horizon) && clearance.is_finite() && *clearance >= 0.0) {
                    return Err(Error::invalid("horizon", "horizon > 0, clearance >= 0 needed"));
                }
                true
            }
            Behaviour::Follow { path, radius, lookahead } => {
                if path.len() < 2
                    || path.windows(2).any(|w| w[0] == w[1])
                    || !path.iter().all(|p| finite(*p))
                {
                    return Err(Error::invalid(
                        "path",
                        "needs at least two finite points, consecutive ones distinct",
                    ));
                }
                if !(positive(*radius) && lookahead.is_finite() && *lookahead >= 0.0) {
                    return Err(Error::invalid("radius", "radius > 0, lookahead >= 0 needed"));
                }
                true
            }
        };
        if ok {
            Ok(())
        } else {
            Err(Error::invalid("target", "contains NaN or infinity"))
        }
    }
}

/// `desired - v`, at most `max_force` long (m/s²).
fn towards(set: &Settings, desired: DVec3, v: DVec3) -> DVec3 {
    (desired - v).clamp_length_max(set.max_force)
}

/// `direction` at the maximum speed (zero if it is zero).
fn full(set: &Settings, direction: DVec3) -> DVec3 {
    direction.normalize_or_zero() * set.max_speed
}

/// A unit direction hashed (splitmix64) from `seed`, `time` and the boid `i`, uniform on the
/// sphere (on the circle in the `z = 0` plane when `planar`).
fn random_direction(seed: u64, time: f64, i: usize, planar: bool) -> DVec3 {
    let mut z = seed ^ time.to_bits().wrapping_mul(0x9e37_79b9_7f4a_7c15);
    z ^= (i as u64).wrapping_mul(0xd1b5_4a32_d192_ed03);
    let mut next = || {
        z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut x = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        (x ^ (x >> 31)) as f64 / u64::MAX as f64
    };
    let angle = next() * std::f64::consts::TAU;
    if planar {
        return DVec3::new(angle.cos(), angle.sin(), 0.0);
    }
    let cz = 2.0 * next() - 1.0;
    let s = (1.0 - cz * cz).sqrt();
    DVec3::new(s * angle.cos(), s * angle.sin(), cz)
}

/// The flock as the behaviours read it: positions (m) and velocities (m/s) in some order,
/// the slot in it of each boid, and the time (s).
pub(super) struct View<'a> {
    /// Positions (m).
    pub positions: &'a [DVec3],
    /// Velocities (m/s).
    pub velocities: &'a [DVec3],
    /// The slot in `positions` of each boid.
    pub rank: &'a [u32],
    /// The time (s).
    pub time: f64,
}

impl View<'_> {
    /// Position and velocity of boid `i`.
    fn boid(&self, i: usize) -> (DVec3, DVec3) {
        let s = self.rank[i] as usize;
        (self.positions[s], self.velocities[s])
    }
}

/// The steering (m/s², not yet weighted) of `behaviour` on boid `i` of `flock`.
pub(super) fn force(set: &Settings, behaviour: &Behaviour, flock: &View, i: usize) -> DVec3 {
    let (p, v) = flock.boid(i);
    let predicted = |j: u32| {
        let (q, u) = flock.boid(j as usize);
        q + u * ((q - p).length() / set.max_speed)
    };
    match *behaviour {
        Behaviour::Follow { ref path, radius, lookahead } => {
            follow(set, path, radius, lookahead, p, v)
        }
        Behaviour::Seek(t) => towards(set, full(set, t - p), v),
        Behaviour::Flee(t) => towards(set, full(set, p - t), v),
        Behaviour::Arrive { target, slow_radius } => {
            let offset = target - p;
            let speed = set.max_speed * (offset.length() / slow_radius).min(1.0);
            towards(set, offset.normalize_or_zero() * speed, v)
        }
        Behaviour::Pursue(j) if j as usize != i => towards(set, full(set, predicted(j) - p), v),
        Behaviour::Evade(j) if j as usize != i => towards(set, full(set, p - predicted(j)), v),
        Behaviour::Pursue(_) | Behaviour::Evade(_) => DVec3::ZERO,
        Behaviour::Wander { distance, radius, seed, planar } => {
            let ahead = v.normalize_or_zero() * distance;
            let aim = ahead + radius * random_direction(seed, flock.time, i, planar);
            towards(set, full(set, aim), v)
        }
        Behaviour::Avoid { shape, horizon, clearance } => {
            avoid(set, &shape, horizon, clearance, p, v)
        }
    }
}

/// Path following (Reynolds 1999; see [`Behaviour::Follow`]).
fn follow(
    set: &Settings,
    path: &[DVec3],
    radius: f64,
    lookahead: f64,
    p: DVec3,
    v: DVec3,
) -> DVec3 {
    let ahead = p + v * lookahead;
    // The nearest point of the path to the predicted position: segment k, parameter t.
    let (mut best, mut k, mut t) = (f64::INFINITY, 0, 0.0);
    for (j, w) in path.windows(2).enumerate() {
        let ab = w[1] - w[0];
        let s = ((ahead - w[0]).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
        let d2 = (ahead - (w[0] + s * ab)).length_squared();
        if d2 < best {
            (best, k, t) = (d2, j, s);
        }
    }
    let tangent = (path[k + 1] - path[k]).normalize();
    if best <= radius * radius && v.dot(tangent) > 0.0 {
        return DVec3::ZERO;
    }
    // `radius` farther along the path from the projection.
    let mut left = radius + t * (path[k + 1] - path[k]).length();
    let mut target = path[path.len() - 1];
    for w in path[k..].windows(2) {
        let l = (w[1] - w[0]).length();
        if left <= l {
            target = w[0] + (w[1] - w[0]) * (left / l);
            break;
        }
        left -= l;
    }
    towards(set, full(set, target - p), v)
}

/// Obstacle avoidance (Reynolds 1999): if the boid is within `clearance` of `shape`, straight
/// out along the normal; else, if a point of its straight path within `horizon` comes within
/// `clearance`, sideways at the maximum force: along the normal there without its component
/// along the velocity (a fixed perpendicular when head-on).
fn avoid(set: &Settings, shape: &Shape, horizon: f64, clearance: f64, p: DVec3, v: DVec3) -> DVec3 {
    let (d, n) = shape.distance(p);
    if d < clearance {
        return towards(set, full(set, n), v);
    }
    const SAMPLES: usize = 8;
    for k in 1..=SAMPLES {
        let (d, n) = shape.distance(p + v * (horizon * k as f64 / SAMPLES as f64));
        if d < clearance {
            let heading = v.normalize_or_zero();
            let mut side = n - n.dot(heading) * heading;
            if side.length_squared() < 1e-24 {
                side = DVec3::Z.cross(heading);
                if side.length_squared() < 1e-24 {
                    side = DVec3::X.cross(heading);
                }
            }
            return side.normalize() * set.max_force;
        }
    }
    DVec3::ZERO
}
