//! Signed distances to the solid shapes that cloth and particles collide with: negative
//! inside, with the outward unit normal of the nearest surface point (for a point exactly on
//! a sphere's centre or a capsule's axis, where every direction is nearest, `+Y`).

use glam::{DQuat, DVec3};

/// Distance from `p` to the sphere of `radius` around `center`, and the outward normal.
pub fn sphere(center: DVec3, radius: f64, p: DVec3) -> (f64, DVec3) {
    let d = p - center;
    let len = d.length();
    (len - radius, if len > 0.0 { d / len } else { DVec3::Y })
}

/// Distance from `p` to the capsule of `radius` around the segment `a`–`b`, and the outward
/// normal.
pub fn capsule(a: DVec3, b: DVec3, radius: f64, p: DVec3) -> (f64, DVec3) {
    let ab = b - a;
    let len2 = ab.length_squared();
    let t = if len2 > 0.0 { ((p - a).dot(ab) / len2).clamp(0.0, 1.0) } else { 0.0 };
    sphere(a + t * ab, radius, p)
}

/// Distance from `p` to the box of `half` extents (m, body axes) centred at `center` and
/// turned by `rotation` (body → world), and the outward normal: from outside, towards the
/// nearest point of the surface (face, edge or corner); from inside, the normal of the nearest
/// face.
pub fn oriented_box(center: DVec3, rotation: DQuat, half: DVec3, p: DVec3) -> (f64, DVec3) {
    let q = rotation.inverse() * (p - center);
    let sign = DVec3::select(q.cmplt(DVec3::ZERO), DVec3::NEG_ONE, DVec3::ONE);
    let excess = q.abs() - half;
    let outside = excess.max(DVec3::ZERO);
    let len = outside.length();
    if len > 0.0 {
        return (len, rotation * (sign * outside / len));
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
    (excess[k], rotation * n)
}
