//! Shared by the articulated-character integration tests: a free capsule body and the CMU
//! ragdoll.

use glam::DVec3;
use kinema::character::{ragdoll, Body, Capsule, Joint, Model, RagdollOptions, Settings};

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

/// The ragdoll of the CMU skeleton of `tests/data/mocap/07-walk.asf` (in metres), lifted so that
/// its lowest point at rest is `clearance` (m) above the ground.
pub fn cmu_ragdoll(clearance: f64, settings: Settings) -> Model {
    let text = std::fs::read_to_string("tests/data/mocap/07-walk.asf").unwrap();
    let skeleton = kinema::mocap::parse_asf(&text, "07-walk.asf").unwrap();
    let options = RagdollOptions {
        scale: skeleton.metres_per_unit(),
        clearance,
        ..RagdollOptions::default()
    };
    ragdoll(&skeleton, &options, settings).unwrap()
}
