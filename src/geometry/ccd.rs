//! Continuous collision detection of moving points, segments and triangles over one step of
//! linear motion `x(t) = x₀ + t (x₁ − x₀)`, `t ∈ [0, 1]` (Provot 1997, "Collision and
//! self-collision handling in cloth model dedicated to design garments"; Bridson, Fedkiw &
//! Anderson 2002, "Robust treatment of collisions, contact and friction for cloth
//! animation", §6.4).
//!
//! A vertex `p` meets triangle `(a, b, c)`, or edge `(p, q)` meets edge `(r, s)`, only when the
//! four points are coplanar: `((b − a) × (c − a)) · (p − a) = 0`, a cubic in `t`. Its roots in
//! `[0, 1]` are bracketed between the cubic's turning points and refined by bisection; at each
//! root, and at each turning point (a near miss the cubic grazes), the closest points of the
//! two features are computed, and a distance below `tolerance` is a collision. The tolerance
//! makes the test robust to the rounding of the cubic: a true crossing has distance zero at
//! its root, and rounding can only move the root, never hide it.

use super::segment::closest_points_of_segments;
use super::triangle::closest_point_on_triangle;
use glam::DVec3;

/// A collision found by [`vertex_triangle`] or [`edge_edge`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Impact {
    /// Time of impact as a fraction of the step, in `[0, 1]`.
    pub time: f64,
    /// Weights `α` of the four points (vertex–triangle: `[1, −wa, −wb, −wc]` with the
    /// barycentric weights of the closest point; edge–edge: `[1 − s, s, −(1 − u), −u]` with the
    /// segment parameters of the closest points): `Σ αₖ xₖ(t)` is the separation of the
    /// features at the time of impact, and `Σ αₖ = 0`.
    pub weights: [f64; 4],
    /// Distance of the features at the time of impact (m).
    pub distance: f64,
    /// Unit normal at the time of impact: the triangle's normal, or the cross product of the
    /// edges (the separation's direction where that degenerates), pointing as the features'
    /// separation did at `t = 0` (along the motion's reverse when that separation is zero).
    pub normal: DVec3,
}

/// The coefficients `[c₀, c₁, c₂, c₃]` of `f(t) = ((B − A) × (C − A)) · (D − A)` for points moving
/// from `x0` to `x1`.
fn coplanarity_cubic(x0: [DVec3; 4], x1: [DVec3; 4]) -> [f64; 4] {
    let rel = |x: [DVec3; 4]| (x[1] - x[0], x[2] - x[0], x[3] - x[0]);
    let (a, b, c) = rel(x0);
    let (a1, b1, c1) = rel(x1);
    let (da, db, dc) = (a1 - a, b1 - b, c1 - c);
    let (ab, dadb) = (a.cross(b), da.cross(db));
    let mixed = da.cross(b) + a.cross(db);
    [ab.dot(c), mixed.dot(c) + ab.dot(dc), dadb.dot(c) + mixed.dot(dc), dadb.dot(dc)]
}

/// The times worth checking for points moving from `x0` to `x1` ([`candidate_times`]), or
/// `[0, 1]` when the coplanarity cubic vanishes to rounding (the four points stay coplanar,
/// e.g. parallel edges, or a flat sheet moving in its plane: then the features are checked at
/// the start and the end of the step only).
fn times(x0: [DVec3; 4], x1: [DVec3; 4], out: &mut [f64; 6]) -> usize {
    let c = coplanarity_cubic(x0, x1);
    let scale = (1..4)
        .flat_map(|k| [x0[k] - x0[0], x1[k] - x1[0]])
        .fold(0.0f64, |m, v| m.max(v.abs().max_element()));
    if c.iter().all(|ci| ci.abs() <= 1e-12 * scale * scale * scale) {
        (out[0], out[1]) = (0.0, 1.0);
        return 2;
    }
    candidate_times(c, out)
}

/// `f(t)` of cubic coefficients `c`.
fn eval(c: [f64; 4], t: f64) -> f64 {
    ((c[3] * t + c[2]) * t + c[1]) * t + c[0]
}

/// The times in `[0, 1]` worth checking for the cubic `c`, ascending, into `out`: the cubic's
/// roots (bracketed between its turning points and the ends, refined by bisection to
/// `2⁻⁴⁸`) and its turning points. Returns how many.
pub fn candidate_times(c: [f64; 4], out: &mut [f64; 6]) -> usize {
    // Turning points: roots of 3c₃t² + 2c₂t + c₁ inside (0, 1).
    let mut knots = [0.0, 1.0, 1.0, 1.0];
    let mut k = 1;
    let (qa, qb, qc) = (3.0 * c[3], 2.0 * c[2], c[1]);
    let mut turn = |t: f64| {
        if t > 0.0 && t < 1.0 {
            knots[k] = t;
            k += 1;
        }
    };
    if qa != 0.0 {
        let disc = qb * qb - 4.0 * qa * qc;
        if disc >= 0.0 {
            // The numerically stable pair of roots.
            let q = -0.5 * (qb + qb.signum() * disc.sqrt());
            let (r1, r2) = (q / qa, if q != 0.0 { qc / q } else { 0.0 });
            turn(r1.min(r2));
            if r2 != r1 {
                turn(r1.max(r2));
            }
        }
    } else if qb != 0.0 {
        turn(-qc / qb);
    }
    knots[k] = 1.0;
    knots[..=k].sort_by(f64::total_cmp);
    let mut n = 0;
    for w in 0..k {
        let (mut lo, mut hi) = (knots[w], knots[w + 1]);
        let (flo, fhi) = (eval(c, lo), eval(c, hi));
        if w > 0 {
            out[n] = lo;
            n += 1;
        }
        if flo == 0.0 && w == 0 {
            out[n] = lo;
            n += 1;
            continue;
        }
        if (flo < 0.0) == (fhi < 0.0) && fhi != 0.0 {
            continue;
        }
        let below = flo < 0.0;
        for _ in 0..48 {
            let mid = 0.5 * (lo + hi);
            if (eval(c, mid) < 0.0) == below {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        out[n] = hi;
        n += 1;
    }
    out[..n].sort_by(f64::total_cmp);
    n
}

/// Positions at time `t` of points moving from `x0` to `x1`.
fn at(x0: [DVec3; 4], x1: [DVec3; 4], t: f64) -> [DVec3; 4] {
    std::array::from_fn(|i| x0[i] + (x1[i] - x0[i]) * t)
}

/// The unit normal `n` oriented as the separation `Σ αₖ xₖ` was at the start (or against the
/// relative motion when it was zero); where `n` is zero, `fallback`, else the start separation,
/// else the reverse of the relative motion.
fn oriented(n: DVec3, weights: [f64; 4], x0: [DVec3; 4], x1: [DVec3; 4], fallback: DVec3) -> DVec3 {
    let sep = |x: [DVec3; 4]| (0..4).fold(DVec3::ZERO, |s, k| s + x[k] * weights[k]);
    let (s0, s1) = (sep(x0), sep(x1));
    let n = [n, fallback, s0, s0 - s1].iter().find_map(|v| v.try_normalize()).unwrap_or(DVec3::Y);
    let side = n.dot(s0);
    let side = if side != 0.0 { side } else { -n.dot(s1 - s0) };
    if side < 0.0 {
        -n
    } else {
        n
    }
}

/// The first time the vertex `x[0]` comes within `tolerance` (m) of the triangle
/// `(x[1], x[2], x[3])` while coplanar with it (or at a turning point of the coplanarity
/// cubic), for linear motion from `x0` to `x1`; `None` when it does not.
pub fn vertex_triangle(x0: [DVec3; 4], x1: [DVec3; 4], tolerance: f64) -> Option<Impact> {
    let mut times = [0.0; 6];
    let n = self::times(x0, x1, &mut times);
    for &t in &times[..n] {
        let [p, a, b, c] = at(x0, x1, t);
        let (q, w) = closest_point_on_triangle(p, a, b, c);
        let distance = (p - q).length();
        if distance <= tolerance {
            let weights = [1.0, -w[0], -w[1], -w[2]];
            let normal = oriented((b - a).cross(c - a), weights, x0, x1, p - q);
            return Some(Impact { time: t, weights, distance, normal });
        }
    }
    None
}

/// The first time the edge `(x[0], x[1])` comes within `tolerance` (m) of the edge
/// `(x[2], x[3])` while the four points are coplanar (or at a turning point of the coplanarity
/// cubic), for linear motion from `x0` to `x1`; `None` when it does not.
pub fn edge_edge(x0: [DVec3; 4], x1: [DVec3; 4], tolerance: f64) -> Option<Impact> {
    let mut times = [0.0; 6];
    // The cubic of (p, q, r, s): ((q − p) × (r − p)) · (s − p) vanishes when the edges are
    // coplanar.
    let n = self::times(x0, x1, &mut times);
    for &t in &times[..n] {
        let [p, q, r, s] = at(x0, x1, t);
        let (c1, c2) = closest_points_of_segments(p, q, r, s);
        let distance = (c1 - c2).length();
        if distance <= tolerance {
            let weights = segment_weights(p, q, c1, r, s, c2);
            let normal = oriented((q - p).cross(s - r), weights, x0, x1, c1 - c2);
            return Some(Impact { time: t, weights, distance, normal });
        }
    }
    None
}

/// The weights `[1 − s, s, −(1 − u), −u]` of closest points `c1 = p + s (q − p)` and
/// `c2 = r + u (s − r)`.
pub fn segment_weights(p: DVec3, q: DVec3, c1: DVec3, r: DVec3, s: DVec3, c2: DVec3) -> [f64; 4] {
    let param = |a: DVec3, b: DVec3, c: DVec3| {
        let d = b - a;
        let l2 = d.length_squared();
        if l2 > 0.0 {
            ((c - a).dot(d) / l2).clamp(0.0, 1.0)
        } else {
            0.0
        }
    };
    let (sp, up) = (param(p, q, c1), param(r, s, c2));
    [1.0 - sp, sp, -(1.0 - up), -up]
}
