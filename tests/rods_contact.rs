//! Rods against the shared collision shapes (`kinema::rods`, `contact.rs`): a rod dropped on
//! a plane comes to rest on it, sunk by its weight over the contact stiffness; a rod lying
//! across a sphere's slope slides off without friction or with `μ < tan α`, and is held with
//! `μ > tan α` (Coulomb's cone: on a slope of angle `α` friction holds iff `μ ≥ tan α`).

use glam::DVec3;
use kinema::geometry::{Plane, Shape, Sphere};
use kinema::rods::{Collider, Material, Rod, Settings};

const STIFF: Material =
    Material { youngs_modulus: 1e9, shear_modulus: 4e8, density: 1000.0, radius: [0.002; 2] };

fn straight(origin: DVec3, direction: DVec3, length: f64, edges: usize) -> Vec<DVec3> {
    (0..=edges).map(|i| origin + direction * (length * i as f64 / edges as f64)).collect()
}

/// Dropped flat from 5 cm onto the plane y = 0: after 2 s at dt = 1/60 the rod is at rest
/// (every vertex below 1 mm/s), every vertex sunk (its centreline less than `r` above the
/// plane) by less than twice the mean depth, and the penalty forces `k (r − y)` carry its
/// weight within 0.1 %.
#[test]
fn rod_dropped_on_a_plane_rests_on_it() {
    let k = 1e4;
    let settings = Settings { contact_stiffness: k, ..Settings::default() };
    let points = straight(DVec3::new(0.0, 0.05, 0.0), DVec3::X, 0.2, 20);
    let mut rod = Rod::new(&points, STIFF, settings, None).unwrap();
    let plane = Shape::Plane(Plane { point: DVec3::ZERO, normal: DVec3::Y });
    rod.model_mut().add_collider(Collider { shape: plane, friction: 0.3 }).unwrap();
    rod.step(1.0 / 60.0, 120).unwrap();
    let r = STIFF.radius[0];
    let weight: f64 = rod.model().masses().iter().sum::<f64>() * 9.81;
    let mean = weight / (21.0 * k);
    let mut carried = 0.0;
    for (i, (p, v)) in rod.state().positions().iter().zip(rod.state().velocities()).enumerate() {
        let sunk = r - p.y;
        assert!(sunk > 0.0 && sunk < 2.0 * mean, "vertex {i}: sunk {sunk:e}, mean {mean:e}");
        assert!(v.length() < 1e-3, "vertex {i}: {v}");
        carried += k * sunk;
    }
    println!("contact forces {carried:e} N, weight {weight:e} N");
    assert!((carried / weight - 1.0).abs() < 1e-3);
}

/// A stiff 10 cm rod lies horizontally across a ball of radius 0.5 m (along z, touching at
/// its middle vertex at the polar angle α = 30° from the top), sunk to its equilibrium
/// depth, and is let go under gravity for 1 s at dt = 1/60: with `μ = 0` and `μ = 0.85 tan
/// α` it slides off (its middle moves more than 5 cm), with `μ = 1.15 tan α` it is held
/// (moves less than 2 mm: lagged friction creeps below `ε_v` = 1 mm/s).
#[test]
fn rod_on_a_sphere_slides_below_the_coulomb_angle_and_is_held_above() {
    let (big, alpha, k) = (0.5, 30f64.to_radians(), 1e4);
    let r = STIFF.radius[0];
    let edges = 10;
    let weight = STIFF.density * std::f64::consts::PI * r * r * 0.1 * 9.81;
    let normal = DVec3::new(alpha.sin(), alpha.cos(), 0.0);
    let depth = weight * alpha.cos() / k;
    let middle = normal * (big + r - depth);
    let moved = |mu: f64| {
        // Newton's step tolerance 1e-8 of the length: the rod barely moves while the
        // stretching forces' rounding, amplified by the soft modes, moves the steps by ~1e-10 m.
        let settings = Settings { contact_stiffness: k, tolerance: 1e-8, ..Settings::default() };
        let points = straight(middle - 0.05 * DVec3::Z, DVec3::Z, 0.1, edges);
        let mut rod = Rod::new(&points, STIFF, settings, None).unwrap();
        let ball = Shape::Sphere(Sphere { center: DVec3::ZERO, radius: big });
        rod.model_mut().add_collider(Collider { shape: ball, friction: mu }).unwrap();
        rod.step(1.0 / 60.0, 60).unwrap();
        let d = (rod.state().positions()[edges / 2] - middle).length();
        println!("mu = {mu:.3} (tan α = {:.3}): the middle moved {d:e} m", alpha.tan());
        d
    };
    assert!(moved(0.0) > 0.05);
    assert!(moved(0.85 * alpha.tan()) > 0.05);
    assert!(moved(1.15 * alpha.tan()) < 2e-3);
}
