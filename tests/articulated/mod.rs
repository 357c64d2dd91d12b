//! Shared by the articulated-character integration tests: a free capsule body.

use glam::DVec3;
use kinema::character::{Body, Capsule, Joint};

/// A free capsule of radius `r` (m, water density) from `a` to `b` (body frame, the frame at
/// `at`, world axes); a ball where `a == b`.
pub fn capsule(a: DVec3, b: DVec3, r: f64, at: DVec3) -> Body {
    let shape = Capsule { a, b, radius: r };
    let (mass, com, inertia) = shape.mass_properties(1000.0);
    Body {
        name: String::new(),
        parent: None,
        joint: Joint::Free,
        offset: at,
        mass,
        com,
        inertia,
        shape: Some(shape),
        limits: None,
        damping: 0.0,
        servo: None,
    }
}
