//! Queries on the shapes: the signed distance from a point to the surface (negative inside the
//! solid) with the outward unit normal of the nearest surface point, and that point.
//!
//! For a point exactly on a sphere's centre or a capsule's axis, where every direction is
//! nearest, the normal is `+Y`. Inside a box the nearest face gives the normal.
//!
//! [`Shape::deepest_on_segment`]: the point of a segment of least signed distance, for shapes
//! swept along a segment (capsules) touching a shape.

use super::segment::{closest_point_on_segment, closest_points_of_segments};
use super::shape::{Capsule, Cuboid, Plane, Shape, Sphere};
use glam::DVec3;

impl Plane {
    /// Signed distance from `p` (m) and the normal.
    pub fn distance(&self, p: DVec3) -> (f64, DVec3) {
        ((p - self.point).dot(self.normal), self.normal)
    }
}

impl Sphere {
    /// Signed distance from `p` (m) and the outward normal.
    pub fn distance(&self, p: DVec3) -> (f64, DVec3) {
        let d = p - self.center;
        let len = d.length();
        (len - self.radius, if len > 0.0 { d / len } else { DVec3::Y })
    }
}

impl Capsule {
    /// Signed distance from `p` (m) and the outward normal: those of the ball of the capsule's
    /// radius around the point of the axis nearest to `p`.
    pub fn distance(&self, p: DVec3) -> (f64, DVec3) {
        let center = closest_point_on_segment(self.a, self.b, p);
        Sphere { center, radius: self.radius }.distance(p)
    }
}

impl Cuboid {
    /// Signed distance from `p` (m) and the outward normal: from outside, towards the nearest
    /// point of the surface (face, edge or corner); from inside, the normal of the nearest
    /// face.
    pub fn distance(&self, p: DVec3) -> (f64, DVec3) {
        let q = self.rotation.inverse() * (p - self.center);
        let sign = DVec3::select(q.cmplt(DVec3::ZERO), DVec3::NEG_ONE, DVec3::ONE);
        let excess = q.abs() - self.half;
        let outside = excess.max(DVec3::ZERO);
        let len = outside.length();
        if len > 0.0 {
            return (len, self.rotation * (sign * outside / len));
        }
        let k = if excess.x >= excess.y && excess.x >= excess.z {
            0
        } else if excess.y >= excess.z {
            1
        } else {
            2
        };
        let mut n = DVec3::ZERO;
        n[k] = sign[k];
        (excess[k], self.rotation * n)
    }
}

impl Shape {
    /// Signed distance from `p` (m) to the surface, negative inside, and the outward unit
    /// normal of the nearest surface point.
    pub fn distance(&self, p: DVec3) -> (f64, DVec3) {
        match self {
            Shape::Plane(s) => s.distance(p),
            Shape::Sphere(s) => s.distance(p),
            Shape::Capsule(s) => s.distance(p),
            Shape::Box(s) => s.distance(p),
        }
    }

    /// The point of the surface nearest to `p` (m): `p − d n` with `(d, n)` the signed
    /// distance and normal.
    pub fn closest_point(&self, p: DVec3) -> DVec3 {
        let (d, n) = self.distance(p);
        p - d * n
    }

    /// The parameter `t ∈ [0, 1]` of the point `a + t (b − a)` of the segment `a`–`b` (m) of
    /// least signed distance to the shape (the segment's deepest point inside it, or nearest
    /// outside). A plane's distance is linear along the segment: the lower end (`a` on a tie).
    /// A sphere's and a capsule's: the closest points of the segment to the centre or axis
    /// ([`closest_point_on_segment`], [`closest_points_of_segments`]). A box's signed distance
    /// is convex along any line (the signed distance of a convex set is convex), so its
    /// minimum is found by golden-section search (63 evaluations; the bracket shrinks to
    /// `0.618⁵⁹ ≈ 5e-13`, but near a smooth minimum its values compare equal within rounding
    /// once `t` is within about `√ε ≈ 1e-8` of it; on a plateau, where the segment runs
    /// parallel to a face, any of its points).
    pub fn deepest_on_segment(&self, a: DVec3, b: DVec3) -> f64 {
        let d = b - a;
        let along = |p: DVec3| {
            let l2 = d.length_squared();
            if l2 > 0.0 {
                ((p - a).dot(d) / l2).clamp(0.0, 1.0)
            } else {
                0.0
            }
        };
        match self {
            Shape::Plane(s) => {
                if s.distance(b).0 < s.distance(a).0 {
                    1.0
                } else {
                    0.0
                }
            }
            Shape::Sphere(s) => along(closest_point_on_segment(a, b, s.center)),
            Shape::Capsule(s) => along(closest_points_of_segments(a, b, s.a, s.b).0),
            Shape::Box(s) => {
                const INV_PHI: f64 = 0.618_033_988_749_894_8;
                let f = |t: f64| s.distance(a + t * d).0;
                let (mut lo, mut hi) = (0.0, 1.0);
                let (mut x1, mut x2) = (hi - INV_PHI * (hi - lo), lo + INV_PHI * (hi - lo));
                let (mut f1, mut f2) = (f(x1), f(x2));
                for _ in 0..58 {
                    if f1 <= f2 {
                        hi = x2;
                        (x2, f2) = (x1, f1);
                        x1 = hi - INV_PHI * (hi - lo);
                        f1 = f(x1);
                    } else {
                        lo = x1;
                        (x1, f1) = (x2, f2);
                        x2 = lo + INV_PHI * (hi - lo);
                        f2 = f(x2);
                    }
                }
                let t = 0.5 * (lo + hi);
                // The ends are candidates too (the search never evaluates them).
                [(f(0.0), 0.0), (f(t), t), (f(1.0), 1.0)]
                    .into_iter()
                    .fold((f64::INFINITY, 0.0), |best, c| if c.0 < best.0 { c } else { best })
                    .1
            }
        }
    }
}
