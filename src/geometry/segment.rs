//! Closest points on segments: of a segment to a point, and of two segments (Ericson,
//! *Real-Time Collision Detection*, 2005, §5.1.2 and §5.1.9). Used by capsules (whose axis is
//! a segment) in every system.

use glam::DVec3;

/// The point of segment `[p0, p1]` closest to `x` (m); `p0` for a degenerate segment.
pub fn closest_point_on_segment(p0: DVec3, p1: DVec3, x: DVec3) -> DVec3 {
    let d = p1 - p0;
    let l2 = d.length_squared();
    if l2 == 0.0 {
        return p0;
    }
    p0 + d * ((x - p0).dot(d) / l2).clamp(0.0, 1.0)
}

/// Closest points of segments `[p0, p1]` and `[q0, q1]` (Ericson, *Real-Time Collision
/// Detection*, §5.1.9).
pub fn closest_points_of_segments(p0: DVec3, p1: DVec3, q0: DVec3, q1: DVec3) -> (DVec3, DVec3) {
    let (d1, d2, r) = (p1 - p0, q1 - q0, p0 - q0);
    let (a, e, f) = (d1.length_squared(), d2.length_squared(), d2.dot(r));
    let (s, t);
    if a <= 1e-300 && e <= 1e-300 {
        return (p0, q0);
    }
    if a <= 1e-300 {
        s = 0.0;
        t = (f / e).clamp(0.0, 1.0);
    } else {
        let c = d1.dot(r);
        if e <= 1e-300 {
            t = 0.0;
            s = (-c / a).clamp(0.0, 1.0);
        } else {
            let b = d1.dot(d2);
            let denom = a * e - b * b;
            let mut s0 =
                if denom > 1e-12 * a * e { ((b * f - c * e) / denom).clamp(0.0, 1.0) } else { 0.0 };
            let mut t0 = (b * s0 + f) / e;
            if t0 < 0.0 {
                t0 = 0.0;
                s0 = (-c / a).clamp(0.0, 1.0);
            } else if t0 > 1.0 {
                t0 = 1.0;
                s0 = ((b - c) / a).clamp(0.0, 1.0);
            }
            s = s0;
            t = t0;
        }
    }
    (p0 + d1 * s, q0 + d2 * t)
}
