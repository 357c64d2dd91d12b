//! Queries on the shapes: the signed distance from a point to the surface (negative inside the
//! solid) with the outward unit normal of the nearest surface point, and that point.
//!
//! For a point exactly on a sphere's centre or a capsule's axis, where every direction is
//! nearest, the normal is `+Y`. Inside a box the nearest face gives the normal.

use super::segment::closest_point_on_segment;
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
}
