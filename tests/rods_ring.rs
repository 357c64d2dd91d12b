//! Closed rods (`kinema::rods::Model::closed`): Michell's instability of a twisted ring.
//!
//! Theory (Michell 1889, "On the stability of a bent and twisted wire", Messenger of Math.
//! 18; see Goriely 2006, "Twisted elastic rings and the rediscoveries of Michell's
//! instability", J. Elasticity 84): a naturally straight, isotropic rod of bending stiffness
//! `B = EI` and twisting stiffness `C = GJ` closed into a planar circle and twisted by a
//! total angle `Tw` (rad) is an equilibrium for every `Tw`, stable iff
//! `Tw < Tw_c = 2π √3 B / C`; past it the ring buckles out of its plane (the mode of two
//! waves, `n = 2`).

use glam::DVec3;
use kinema::rods::{Material, Model, Settings, Solver, State};
use std::f64::consts::TAU;

/// Round rod, 1 cm thick, of 1 m circumference.
fn material(shear_modulus: f64) -> Material {
    Material { youngs_modulus: 1e6, shear_modulus, density: 1000.0, radius: [0.01; 2] }
}

/// A naturally straight rod of `m` edges closed into a circle of 1 m circumference in the
/// `xy` plane, no gravity.
fn ring(m: usize, shear_modulus: f64) -> Model {
    let radius = 1.0 / TAU;
    let points: Vec<DVec3> = (0..m)
        .map(|i| {
            let phi = TAU * i as f64 / m as f64;
            DVec3::new(radius * phi.cos(), radius * phi.sin(), 0.0)
        })
        .collect();
    let settings = Settings { gravity: DVec3::ZERO, max_iterations: 500, ..Settings::default() };
    let mut model = Model::closed(&points, material(shear_modulus), settings).unwrap();
    model.straighten();
    model
}

/// `B / C` of the rings of `shear_modulus` (round: `J = 2I`).
fn ratio(shear_modulus: f64) -> f64 {
    1e6 / (2.0 * shear_modulus)
}

/// The largest distance of a vertex from the ring's plane (m).
fn off_plane(state: &State) -> f64 {
    state.positions().iter().map(|p| p.z.abs()).fold(0.0, f64::max)
}

/// Time step of the quasi-static ramp and of the disturbed motion (s): the slowest bending
/// period of the untwisted ring is about 0.3 s.
const DT: f64 = 0.02;

/// A ring twisted to `tw` (rad) quasi-statically: in turns under a quarter turn
/// ([`State::twist_ring`]), each followed by steps.
fn twisted(model: &Model, solver: &mut Solver, tw: f64) -> State {
    let mut state = State::new(model);
    let turns = (tw / 1.5).ceil() as usize;
    for _ in 0..turns {
        state.twist_ring(model, tw / turns as f64).unwrap();
        solver.step(model, &mut state, DT, 5).unwrap();
    }
    state
}

/// Whether the ring twisted to `tw` is unstable: disturbed out of its plane by a velocity in
/// its two-wave mode (1 mm/s, an excursion of about 0.1 mm), does it leave the plane (by
/// more than 1 cm within 6 s)? A stable ring oscillates about its plane and is damped; an
/// unstable one grows at a rate that vanishes at the threshold, so twists above it by less
/// than about 0.1 % count as stable (6 s is then too short to grow 100-fold).
fn unstable(model: &Model, tw: f64) -> bool {
    let mut solver = Solver::new(model);
    let mut state = twisted(model, &mut solver, tw);
    assert!(off_plane(&state) < 1e-12, "the twisted planar ring is an equilibrium");
    let v: Vec<DVec3> = state
        .positions()
        .iter()
        .map(|p| DVec3::new(0.0, 0.0, 1e-3 * (2.0 * p.y.atan2(p.x)).cos()))
        .collect();
    state.set_velocities(&v).unwrap();
    for _ in 0..60 {
        solver.step(model, &mut state, DT, 5).unwrap();
        if off_plane(&state) > 1e-2 {
            return true;
        }
    }
    false
}

/// The twist at which a ring of `m` edges loses stability, by bisection (to 0.6 % of
/// `theory`) between a stable twist and an unstable one.
fn threshold(m: usize, shear_modulus: f64, theory: f64) -> f64 {
    let model = ring(m, shear_modulus);
    let (mut lo, mut hi) = (0.8 * theory, 1.2 * theory);
    assert!(!unstable(&model, lo) && unstable(&model, hi));
    for _ in 0..6 {
        let mid = 0.5 * (lo + hi);
        if unstable(&model, mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The twisted planar ring is an equilibrium that holds its twist uniformly: the twist
/// angles step by `Tw / m` from edge to edge, and the energy grows by `C Tw² / (2 L)`
/// (less the bending energy's discrete twist coupling).
#[test]
fn a_twisted_ring_spreads_its_twist_uniformly() {
    let (m, g) = (24, 5e5);
    let model = ring(m, g);
    let mut solver = Solver::new(&model);
    let untwisted = State::new(&model);
    let tw = 4.0;
    let state = twisted(&model, &mut solver, tw);
    assert!(off_plane(&state) < 1e-12);
    let t = state.twists();
    for j in 1..m {
        assert!((t[j] - t[j - 1] - tw / m as f64).abs() < 1e-9, "{j}: {}", t[j] - t[j - 1]);
    }
    let length: f64 = model.rest_lengths().iter().sum();
    let c = model.twisting_stiffness();
    let bending = solver.energy(&model, &untwisted);
    let gained = solver.energy(&model, &state) - bending;
    // The curvature of a stencil is measured in its two edges' averaged material frame,
    // which a twist of `Tw / m` between them shortens by `cos(Tw / 2m)`.
    let want = c * tw * tw / (2.0 * length) - bending * (tw / (2.0 * m as f64)).sin().powi(2);
    assert!((gained / want - 1.0).abs() < 1e-6, "{gained} {want}");
    assert!((state.seam() - tw).abs() < 1e-15);
}

/// Michell's threshold `Tw_c = 2π √3 B / C` is found within 5 % at 24 edges, for `B = C`
/// and for `B / C = 3/2` (`G = E/3`).
#[test]
fn a_twisted_ring_buckles_past_michells_twist() {
    for g in [5e5, 1e6 / 3.0] {
        let theory = TAU * 3f64.sqrt() * ratio(g);
        let found = threshold(24, g, theory);
        println!(
            "B/C = {}: Michell {theory:.4} rad, found {found:.4} ({:+.2} %)",
            ratio(g),
            100.0 * (found / theory - 1.0)
        );
        assert!((found / theory - 1.0).abs() < 0.05, "{found} {theory}");
    }
}
