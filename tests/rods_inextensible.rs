//! Inextensible rods (`Settings::inextensible`): every step ends with a fast projection of
//! the vertices onto the edge-length constraints (Goldenthal et al. 2007). Edges hold their
//! rest lengths to the tolerance at dt = 1/60 under loads that stretch the elastic rod by
//! several per cent (open, pinned in the middle, closed, symplectic Euler), and the
//! cantilever still matches Euler–Bernoulli.

use glam::DVec3;
use kinema::rods::{End, Integrator, Material, Rod, Settings};
use std::f64::consts::PI;

/// A soft rope: `EA` = 31 N against its own weight of 3 N, so it stretches by per cents.
/// `G = E`: with `G = E / 3` Newton needs up to 2560 iterations in the steps where the
/// whipping rope passes under its clamp (elastic and inextensible alike; docs/rods.md,
/// "Not yet"), with `G = E` at most 5.
const ROPE: Material =
    Material { youngs_modulus: 1e5, shear_modulus: 1e5, density: 1000.0, radius: [0.01; 2] };

/// The largest relative strain `| |e| / l̄ − 1 |` of the rod's edges (a ring's closing edge
/// included).
fn strain(rod: &Rod) -> f64 {
    let x = rod.state().positions();
    let v = x.len();
    let l = rod.model().rest_lengths();
    (0..l.len()).map(|j| ((x[(j + 1) % v] - x[j]).length() / l[j] - 1.0).abs()).fold(0.0, f64::max)
}

/// A straight rod along +x from the origin, `n` edges over 1 m.
fn straight(n: usize, material: Material, settings: Settings) -> Rod {
    let points: Vec<DVec3> = (0..=n).map(|i| DVec3::new(i as f64 / n as f64, 0.0, 0.0)).collect();
    Rod::new(&points, material, settings, None).unwrap()
}

/// The soft rope clamped horizontally, with a tip load of its own weight, falls and swings
/// for 2 s at dt = 1/60: elastic, it stretches by more than 5 %; inextensible, no edge by
/// more than 1e-9 (the tolerance 1e-10 bounds the projection's residual), and it still
/// swings down (the tip below the clamp by most of its length).
#[test]
fn a_falling_rope_keeps_its_edge_lengths() {
    let weight = ROPE.density * PI * 1e-4 * 9.81;
    for inextensible in [false, true] {
        let settings = Settings { inextensible, ..Settings::default() };
        let mut rod = straight(20, ROPE, settings);
        rod.model_mut().clamp(End::First);
        rod.state_mut().set_force(20, DVec3::new(0.0, -weight, 0.0)).unwrap();
        let mut worst: f64 = 0.0;
        for _ in 0..120 {
            rod.step(1.0 / 60.0, 1).unwrap();
            worst = worst.max(strain(&rod));
        }
        let tip = rod.state().positions()[20];
        println!("inextensible {inextensible}: largest strain {worst:e}, tip {tip}");
        assert!(tip.y < -0.8, "{tip}");
        if inextensible {
            assert!(worst < 1e-9, "{worst:e}");
        } else {
            assert!(worst > 0.05, "{worst:e}");
        }
    }
}

/// The extremes: a rope pinned at its middle vertex and at one end, and a ring of rope
/// pinned at one vertex (the cyclic system), dropped at dt = 1/60 for 1 s; a rope under
/// symplectic Euler at 1e-4 s (the projection's correction of the velocities): every edge
/// within 1e-9 of its rest length.
#[test]
fn pinned_closed_and_explicit_rods_keep_their_edge_lengths() {
    let settings = Settings { inextensible: true, ..Settings::default() };
    let mut rod = straight(20, ROPE, settings);
    rod.model_mut().pin(0).unwrap();
    rod.model_mut().pin(10).unwrap();
    rod.step(1.0 / 60.0, 60).unwrap();
    println!("pinned: strain {:e}", strain(&rod));
    assert!(strain(&rod) < 1e-9);
    assert!(rod.state().positions()[20].y < -0.3);

    let points: Vec<DVec3> = (0..24)
        .map(|k| {
            let a = 2.0 * PI * k as f64 / 24.0;
            DVec3::new(a.cos(), 0.0, a.sin()) / (2.0 * PI)
        })
        .collect();
    let mut ring =
        Rod::from_model(kinema::rods::Model::closed(&points, ROPE, settings).unwrap(), None)
            .unwrap();
    ring.model_mut().pin(0).unwrap();
    ring.step(1.0 / 60.0, 60).unwrap();
    println!("ring: strain {:e}, lowest {}", strain(&ring), ring.state().positions()[12].y);
    assert!(strain(&ring) < 1e-9);
    assert!(ring.state().positions()[12].y < -0.1);

    let explicit = Settings { integrator: Integrator::SymplecticEuler, ..settings };
    let mut rod = straight(10, ROPE, explicit);
    rod.model_mut().clamp(End::First);
    rod.step(1e-4, 2000).unwrap();
    println!("symplectic: strain {:e}", strain(&rod));
    assert!(strain(&rod) < 1e-9);
    assert!(rod.state().positions()[10].y < -0.1);
}

/// The cantilever of `tests/rods.rs` (`E = 1 MPa`, `r = 1 cm`, 1 m from the middle of the
/// clamped edge, 40 edges) under a tip load `F L²/(EI)` = 0.0127, made inextensible and
/// stepped to rest by implicit Euler (300 steps of 0.5 s, 13 periods): the tip deflection
/// matches `F L³ / (3 E I)` within 1 %, as the elastic rod's static solve does.
#[test]
fn the_inextensible_cantilever_matches_euler_bernoulli() {
    let soft =
        Material { youngs_modulus: 1e6, shear_modulus: 4e5, density: 1000.0, radius: [0.01; 2] };
    let n = 40;
    let h = 1.0 / (n as f64 + 0.5);
    let points: Vec<DVec3> =
        (0..=n + 1).map(|i| DVec3::new((i as f64 - 0.5) * h, 0.0, 0.0)).collect();
    let settings = Settings { gravity: DVec3::ZERO, inextensible: true, ..Settings::default() };
    let mut rod = Rod::new(&points, soft, settings, None).unwrap();
    rod.model_mut().clamp(End::First);
    let f = 1e-4;
    rod.state_mut().set_force(n + 1, DVec3::new(0.0, -f, 0.0)).unwrap();
    rod.step(0.5, 300).unwrap();
    let exact = f / (3.0 * soft.youngs_modulus * PI * 1e-8 / 4.0);
    let got = -rod.state().positions()[n + 1].y;
    println!(
        "inextensible tip {got:e} m, Euler-Bernoulli {exact:e} m, error {:e}",
        got / exact - 1.0
    );
    assert!((got / exact - 1.0).abs() < 0.01);
    assert!(strain(&rod) < 1e-9);
}
