//! Constrained dynamics: drift with and without feedback, energy, no work, solvers agree,
//! curves, custom constraints, penalty and reduced coordinates, degenerate input.

use glam::DVec3;
use kinema::anim::{Extrapolation, Interpolation, Track};
use kinema::constraints::{
    ConstrainedSystem, Constraint, ConstraintFunction, ConstraintSolver, Curve, ReducedBead,
    ReducedPendulum,
};
use kinema::ode::Method;
use kinema::particles::{Force, ParticleSystem};
use std::sync::Arc;

const G: DVec3 = DVec3::new(0.0, -9.81, 0.0);

fn bead(ks: f64, kd: f64) -> (ParticleSystem, ConstrainedSystem) {
    let mut p =
        ParticleSystem::new(&[DVec3::new(1.0, 0.0, 0.0)], &[DVec3::new(0.0, 1.0, 0.0)], &[1.0], 1)
            .unwrap();
    p.add_force(Force::Gravity { g: G }).unwrap();
    let mut c = ConstrainedSystem::new(ks, kd, ConstraintSolver::Cholesky).unwrap();
    c.add(&p, Constraint::OnSphere { i: 0, center: DVec3::ZERO, radius: 1.0 }).unwrap();
    (p, c)
}

fn double_pendulum(
    ks: f64,
    kd: f64,
    solver: ConstraintSolver,
) -> (ParticleSystem, ConstrainedSystem) {
    let xs = [DVec3::ZERO, DVec3::new(1.0, 0.0, 0.0), DVec3::new(1.0, -1.0, 0.0)];
    let mut p = ParticleSystem::new(&xs, &[DVec3::ZERO; 3], &[f64::INFINITY, 1.0, 2.0], 3).unwrap();
    p.add_force(Force::Gravity { g: G }).unwrap();
    let mut c = ConstrainedSystem::new(ks, kd, solver).unwrap();
    c.add(&p, Constraint::Distance { i: 0, j: 1, length: 1.0 }).unwrap();
    c.add(&p, Constraint::Distance { i: 1, j: 2, length: 1.0 }).unwrap();
    (p, c)
}

const CIRCLE: Curve = Curve::Circle { center: DVec3::ZERO, normal: DVec3::Z, radius: 1.0 };

/// The bead of [`bead`] held by `OnCurve` on the unit circle in the XY plane instead.
fn bead_on_curve(curve: Curve, ks: f64, kd: f64) -> (ParticleSystem, ConstrainedSystem) {
    let (p, _) = bead(0.0, 0.0);
    let mut c = ConstrainedSystem::new(ks, kd, ConstraintSolver::Cholesky).unwrap();
    c.add(&p, Constraint::OnCurve { i: 0, curve }).unwrap();
    (p, c)
}

fn position(p: &ParticleSystem, i: usize) -> DVec3 {
    DVec3::from_slice(&p.positions()[3 * i..])
}

fn energy(p: &ParticleSystem) -> f64 {
    p.kinetic_energy() + p.potential_energy()
}

#[test]
fn feedback_keeps_drift_below_1e_8_and_without_it_drift_grows() {
    // The same integrator (RK4, 1 ms) with post-stabilisation off on both sides: only the
    // feedback gains differ.
    for make in [
        bead as fn(f64, f64) -> (ParticleSystem, ConstrainedSystem),
        |ks, kd| bead_on_curve(CIRCLE, ks, kd),
        |ks, kd| double_pendulum(ks, kd, ConstraintSolver::Cholesky),
    ] {
        let mut worst = [0.0_f64; 2];
        for (k, (ks, kd)) in [(100.0, 20.0), (0.0, 0.0)].into_iter().enumerate() {
            let (mut p, mut c) = make(ks, kd);
            c.set_stabilization(false).unwrap();
            for _ in 0..10 {
                c.step(&mut p, 1e-3, 10_000, Method::Rk4).unwrap();
                worst[k] = worst[k].max(c.violation(&p).unwrap().0);
            }
        }
        let [with, without] = worst;
        assert!(with < 1e-8 && without > 100.0 * with, "feedback {with}, none {without}");
    }
}

#[test]
fn bead_drift_over_1e5_steps_at_the_defaults_stays_below_1e_10() {
    for make in [bead as fn(f64, f64) -> (ParticleSystem, ConstrainedSystem), |ks, kd| {
        bead_on_curve(CIRCLE, ks, kd)
    }] {
        // Defaults: ks = kd = 0, post-stabilisation on.
        let (mut p, mut c) = make(0.0, 0.0);
        assert!(c.stabilization());
        let (mut drift, mut rate) = (0.0_f64, 0.0_f64);
        for _ in 0..100 {
            c.step(&mut p, 1e-3, 1_000, Method::Rk4).unwrap();
            let (d, r) = c.violation(&p).unwrap();
            (drift, rate) = (drift.max(d), rate.max(r));
        }
        assert!(drift <= 1e-10 && rate <= 1e-10, "drift {drift} m, rate {rate} m/s");
        // The old behaviour, still reachable: the drift of the integrator alone.
        let (mut p, mut c) = make(0.0, 0.0);
        c.set_stabilization(false).unwrap();
        c.step(&mut p, 1e-3, 100_000, Method::Rk4).unwrap();
        assert!(c.violation(&p).unwrap().0 > 1e3 * drift.max(1e-12));
    }
}

/// A hanging rope of `n` rods of 1 cm (1 g particles, the top one pinned) pushed sideways,
/// as in `bench/bench_constraints.py`.
fn rope(n: usize) -> (ParticleSystem, ConstrainedSystem) {
    let xs: Vec<DVec3> = (0..n).map(|i| DVec3::new(0.0, -0.01 * i as f64, 0.0)).collect();
    let vs: Vec<DVec3> = (0..n).map(|i| DVec3::new(0.2 * i as f64 / n as f64, 0.0, 0.0)).collect();
    let mut masses = vec![0.001; n];
    masses[0] = f64::INFINITY;
    let mut p = ParticleSystem::new(&xs, &vs, &masses, n).unwrap();
    p.add_force(Force::Gravity { g: G }).unwrap();
    let mut c = ConstrainedSystem::new(0.0, 0.0, ConstraintSolver::Cholesky).unwrap();
    for i in 0..n - 1 {
        c.add(&p, Constraint::Distance { i, j: i + 1, length: 0.01 }).unwrap();
    }
    (p, c)
}

/// Largest relative rod-length error of the rope over `chunks` calls of `steps` steps.
fn rope_stretch(
    p: &mut ParticleSystem,
    c: &mut ConstrainedSystem,
    dt: f64,
    chunks: usize,
    steps: usize,
    method: Option<Method>,
) -> f64 {
    let mut worst = 0.0_f64;
    for _ in 0..chunks {
        match method {
            Some(m) => c.step(p, dt, steps, m).unwrap(),
            None => c.step_projection(p, dt, steps).unwrap(),
        }
        worst = worst.max(c.violation(p).unwrap().0 / 0.01);
    }
    worst
}

#[test]
fn rope_rods_hold_1e_6_relative_length_at_the_defaults() {
    // Projection at 1/60 s: 1,000 rods of 1 cm for 1 s, where h √(T/(m L)) ≈ 16 at the top
    // (the step without geometric stiffness diverges), and 10,000 rods for 5 steps.
    for (n, steps) in [(1_000, 60), (10_000, 5)] {
        let (mut p, mut c) = rope(n);
        let stretch = rope_stretch(&mut p, &mut c, 1.0 / 60.0, steps, 1, None);
        assert!(stretch < 1e-6, "{n} rods, projection: {stretch}");
        let end = DVec3::from_slice(&p.positions()[3 * (n - 1)..]);
        // The free end was pushed at 0.2 m/s: it has moved along +X.
        assert!(end.x > 1e-3, "{n} rods: the rope swings, end at {end}");
    }
    // Multipliers with RK4 at a step within its stability limit, 1,000 rods for 0.5 s.
    let (mut p, mut c) = rope(1_000);
    let stretch = rope_stretch(&mut p, &mut c, 1e-3, 50, 10, Some(Method::Rk4));
    assert!(stretch < 1e-6, "1000 rods, multipliers: {stretch}");
}

#[test]
fn rope_by_projection_without_stabilisation_holds_its_rods_but_not_their_velocities() {
    // Without post-stabilisation only the velocity projection is skipped: the rods hold, and
    // the velocities (x₁ - x₀)/h keep the component along the rods that the rotation of
    // each rod over the step gives them, of the order of h |v⊥|² / L.
    let (mut p, mut c) = rope(1_000);
    c.set_stabilization(false).unwrap();
    let stretch = rope_stretch(&mut p, &mut c, 1.0 / 60.0, 30, 1, None);
    assert!(stretch < 1e-6, "1000 rods, no velocity projection: {stretch}");
    let (_, rate) = c.violation(&p).unwrap();
    assert!(rate > 1e-8, "velocities not projected: |Ċ| = {rate}");
    let (mut p, mut c) = rope(1_000);
    rope_stretch(&mut p, &mut c, 1.0 / 60.0, 30, 1, None);
    let (_, rate) = c.violation(&p).unwrap();
    assert!(rate < 1e-9, "velocities projected: |Ċ| = {rate}");
}

#[test]
fn a_failed_projection_step_leaves_the_particles_as_they_were() {
    // A particle on the planes y = 0 and y = 3 has no point with C = 0: the step fails with
    // the particles as before it.
    let mut p =
        ParticleSystem::new(&[DVec3::ZERO, DVec3::X], &[DVec3::ZERO; 2], &[1.0, 1.0], 2).unwrap();
    p.add_force(Force::Gravity { g: G }).unwrap();
    let mut c = ConstrainedSystem::new(0.0, 0.0, ConstraintSolver::Cholesky).unwrap();
    c.add(&p, Constraint::Distance { i: 0, j: 1, length: 1.0 }).unwrap();
    c.step_projection(&mut p, 1.0 / 60.0, 3).unwrap();
    let before = (p.positions().to_vec(), p.velocities().to_vec(), p.time());
    c.add(&p, Constraint::OnPlane { i: 0, point: DVec3::ZERO, normal: DVec3::Y }).unwrap();
    c.add(&p, Constraint::OnPlane { i: 0, point: DVec3::new(0.0, 3.0, 0.0), normal: DVec3::Y })
        .unwrap();
    let err = c.step_projection(&mut p, 1.0 / 60.0, 1).unwrap_err();
    assert!(matches!(err, kinema::Error::SolverFailed { .. }), "{err}");
    assert_eq!(before, (p.positions().to_vec(), p.velocities().to_vec(), p.time()));
}

#[test]
fn energy_is_conserved_to_the_integrator_order() {
    let error = |dt: f64| {
        let (mut p, mut c) = double_pendulum(0.0, 0.0, ConstraintSolver::Cholesky);
        let e0 = energy(&p);
        c.step(&mut p, dt, (2.0 / dt).round() as usize, Method::Rk4).unwrap();
        (energy(&p) - e0).abs()
    };
    let (coarse, fine) = (error(4e-3), error(2e-3));
    let order = (coarse / fine).log2();
    assert!(order > 3.5, "energy error {coarse} -> {fine}, order {order}");
}

#[test]
fn constraint_force_does_no_work_on_legal_velocities() {
    let (mut p, mut c) = double_pendulum(0.0, 0.0, ConstraintSolver::Cholesky);
    c.step(&mut p, 1e-3, 700, Method::Rk4).unwrap();
    let forces = c.constraint_forces(&mut p).unwrap();
    // Legal velocities: the ones the pendulum has (J v = 0 to the integrator's accuracy), and
    // the exact tangent directions built from the rods.
    let x = |i: usize| DVec3::from_slice(&p.positions()[3 * i..]);
    let (d1, d2) = (x(1) - x(0), x(2) - x(1));
    let legal = [
        (d1.cross(DVec3::Z), d1.cross(DVec3::Z) + d2.cross(DVec3::Z)),
        (DVec3::ZERO, d2.cross(DVec3::Z)),
    ];
    for (v1, v2) in legal {
        let power = forces[1].dot(v1) + forces[2].dot(v2);
        let scale = forces[1].length() * v1.length() + forces[2].length() * v2.length();
        assert!(power.abs() <= 1e-14 * scale, "{power} vs {scale}");
    }
}

#[test]
fn constraint_force_is_the_tension_of_a_pendulum_rod() {
    // A rod of 1 m from a fixed pivot, 1.5 kg released horizontally: the rod pulls with
    // T = m (g·d̂ + |v|²/L) along -d̂ (radial balance), whatever the state.
    let xs = [DVec3::ZERO, DVec3::X];
    let mut p = ParticleSystem::new(&xs, &[DVec3::ZERO; 2], &[f64::INFINITY, 1.5], 2).unwrap();
    p.add_force(Force::Gravity { g: G }).unwrap();
    let mut c = ConstrainedSystem::new(0.0, 0.0, ConstraintSolver::Cholesky).unwrap();
    c.add(&p, Constraint::Distance { i: 0, j: 1, length: 1.0 }).unwrap();
    for _ in 0..5 {
        c.step(&mut p, 1e-3, 150, Method::Rk4).unwrap();
        let (d, v) = (position(&p, 1), DVec3::from_slice(&p.velocities()[3..]));
        let dir = d / d.length();
        let tension = 1.5 * (G.dot(dir) + v.length_squared() / d.length());
        let f = c.constraint_forces(&mut p).unwrap()[1];
        assert!((f + tension * dir).length() <= 1e-8 * tension, "{f} vs {tension} along {dir}");
    }
}

#[test]
fn cholesky_and_conjugate_gradient_agree() {
    let (mut p1, mut c1) = double_pendulum(10.0, 5.0, ConstraintSolver::Cholesky);
    let (mut p2, mut c2) = double_pendulum(10.0, 5.0, ConstraintSolver::ConjugateGradient);
    c1.step(&mut p1, 1e-3, 2000, Method::Rk4).unwrap();
    c2.step(&mut p2, 1e-3, 2000, Method::Rk4).unwrap();
    for (a, b) in p1.positions().iter().zip(p2.positions()) {
        assert!((a - b).abs() < 1e-9);
    }
    assert!(c2.iterations() > 0);
}

#[test]
fn a_rope_of_rods_swings_at_a_sixtieth_of_a_second_with_projection() {
    // A hanging rope of 200 rods (5 cm each, 10 m), pinned at the top and pushed sideways.
    let n = 200;
    let xs: Vec<DVec3> = (0..n).map(|i| DVec3::new(0.0, -(i as f64) * 0.05, 0.0)).collect();
    let vs: Vec<DVec3> = (0..n).map(|i| DVec3::new(0.5 * i as f64 / n as f64, 0.0, 0.0)).collect();
    let mut masses = vec![0.01; n];
    masses[0] = f64::INFINITY;
    let mut p = ParticleSystem::new(&xs, &vs, &masses, n).unwrap();
    p.add_force(Force::Gravity { g: G }).unwrap();
    let mut ends = Vec::new();
    for solver in [ConstraintSolver::Cholesky, ConstraintSolver::ConjugateGradient] {
        let mut q = p.clone();
        let mut c = ConstrainedSystem::new(0.0, 0.0, solver).unwrap();
        for i in 0..n - 1 {
            c.add(&q, Constraint::Distance { i, j: i + 1, length: 0.05 }).unwrap();
        }
        c.step_projection(&mut q, 1.0 / 60.0, 10).unwrap();
        ends.push(DVec3::from_slice(&q.positions()[3 * (n - 1)..]));
        c.step_projection(&mut q, 1.0 / 60.0, 110).unwrap();
        let (drift, _) = c.violation(&q).unwrap();
        assert!(drift < 1e-8, "{solver:?}: {drift}");
        let end = DVec3::from_slice(&q.positions()[3 * (n - 1)..]);
        assert!(end.x.abs() > 0.05 && end.length() <= 9.95 + 1e-6, "{solver:?}: {end}");
    }
    // The two solvers agree (to the CG tolerance) before the chaotic motion amplifies it.
    assert!((ends[0] - ends[1]).length() < 1e-8, "{ends:?}");
}

#[test]
fn degenerate_input_is_refused_or_regularised() {
    let mut p = ParticleSystem::new(&[DVec3::ZERO, DVec3::ZERO], &[DVec3::ZERO; 2], &[1.0, 1.0], 2)
        .unwrap();
    p.add_force(Force::Gravity { g: G }).unwrap();
    let mut c = ConstrainedSystem::new(0.0, 0.0, ConstraintSolver::Cholesky).unwrap();
    assert!(c
        .add(&p, Constraint::Distance { i: 0, j: 1, length: 1.0 })
        .unwrap_err()
        .to_string()
        .contains("coincide"));
    assert!(c.add(&p, Constraint::Distance { i: 0, j: 0, length: 1.0 }).is_err());
    assert!(c.add(&p, Constraint::OnSphere { i: 0, center: DVec3::ZERO, radius: 0.0 }).is_err());
    assert!(c.add(&p, Constraint::Fixed { i: 5, point: DVec3::ZERO }).is_err());
    assert!(ConstrainedSystem::new(-1.0, 0.0, ConstraintSolver::Cholesky).is_err());
    // Everything pinned: nothing moves, nothing fails.
    let mut pinned =
        ParticleSystem::new(&[DVec3::ZERO, DVec3::X], &[DVec3::ZERO; 2], &[f64::INFINITY; 2], 2)
            .unwrap();
    pinned.add_force(Force::Gravity { g: G }).unwrap();
    let mut c = ConstrainedSystem::new(1.0, 1.0, ConstraintSolver::Cholesky).unwrap();
    c.add(&pinned, Constraint::Distance { i: 0, j: 1, length: 2.0 }).unwrap();
    c.step(&mut pinned, 1e-2, 10, Method::Rk4).unwrap();
    assert_eq!(&pinned.positions()[..6], &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0]);
    // Degenerate curves, custom constraints, penalty and reduced systems.
    let mut c = ConstrainedSystem::new(0.0, 0.0, ConstraintSolver::Cholesky).unwrap();
    for (curve, arg) in [
        (Curve::Circle { center: DVec3::ZERO, normal: DVec3::Z, radius: 0.0 }, "radius"),
        (Curve::Circle { center: DVec3::ZERO, normal: DVec3::ZERO, radius: 1.0 }, "normal"),
        (Curve::Line { point: DVec3::ZERO, direction: DVec3::ZERO }, "direction"),
        (Curve::Helix { center: DVec3::ZERO, axis: DVec3::Y, radius: 1.0, pitch: 0.0 }, "pitch"),
    ] {
        let err = c.add(&p, Constraint::OnCurve { i: 0, curve }).unwrap_err().to_string();
        assert!(err.starts_with(arg), "{err}");
    }
    let flat = Track::new(&[0.0, 1.0], &[0.0, 1.0], 1, Interpolation::Linear, Extrapolation::Hold);
    let err = c.add(&p, Constraint::OnCurve { i: 0, curve: Curve::Track(flat.unwrap()) });
    assert!(err.unwrap_err().to_string().contains("3 channels"));
    let rod = Arc::new(Rod { length: 1.0, fail_after: usize::MAX.into() });
    let same = Constraint::Custom { particles: vec![1, 1], function: rod.clone() };
    assert!(c.add(&p, same).unwrap_err().to_string().contains("distinct"));
    let none = Constraint::Custom { particles: vec![], function: rod };
    assert!(c.add(&p, none).is_err());
    assert!(ConstrainedSystem::penalty(0.0, 1.0).unwrap_err().to_string().starts_with("stiffness"));
    assert!(ConstrainedSystem::penalty(1.0, -1.0).unwrap_err().to_string().starts_with("damping"));
    let mut pen = ConstrainedSystem::penalty(1e3, 0.0).unwrap();
    assert!(pen.step_projection(&mut p, 1e-3, 1).is_err());
    assert!(ReducedPendulum::new(DVec3::ZERO, &[1.0; 3], &[1.0; 3], &[0.0; 3], &[0.0; 3], 9.81)
        .is_err());
    assert!(ReducedPendulum::new(DVec3::ZERO, &[1.0], &[0.0], &[0.0], &[0.0], 9.81).is_err());
    assert!(ReducedBead::new(CIRCLE, -1.0, G, 0.0, 0.0).is_err());
    // A bead run off the end of a held track: a solver error, the state kept.
    let held = Track::new(
        &[0.0, 1.0],
        &[0.0, 0.0, 0.0, 1.0, -1.0, 0.0],
        3,
        Interpolation::Linear,
        Extrapolation::Hold,
    )
    .unwrap();
    let mut q =
        ParticleSystem::new(&[DVec3::new(0.9, -0.9, 0.0)], &[DVec3::ZERO], &[1.0], 1).unwrap();
    q.add_force(Force::Gravity { g: G }).unwrap();
    let mut c = ConstrainedSystem::new(0.0, 0.0, ConstraintSolver::Cholesky).unwrap();
    c.add(&q, Constraint::OnCurve { i: 0, curve: Curve::Track(held) }).unwrap();
    let err = c.step(&mut q, 1e-2, 1000, Method::Rk4).unwrap_err();
    assert!(matches!(err, kinema::Error::SolverFailed { .. }), "{err}");
    assert!(q.positions().iter().all(|v| v.is_finite()));
}

/// One particle of 2 kg at `y0` moving at 0.5 m/s along +X under gravity, held by the planes
/// `y = 0` (twice: redundant) and `y = 3` (conflicting with them).
fn between_conflicting_planes(y0: f64, ks: f64, kd: f64) -> (ParticleSystem, ConstrainedSystem) {
    let x = [DVec3::new(0.0, y0, 0.0)];
    let mut p = ParticleSystem::new(&x, &[DVec3::new(0.5, 0.0, 0.0)], &[2.0], 1).unwrap();
    p.add_force(Force::Gravity { g: G }).unwrap();
    let mut c = ConstrainedSystem::new(ks, kd, ConstraintSolver::Cholesky).unwrap();
    for y in [0.0, 0.0, 3.0] {
        let point = DVec3::new(0.0, y, 0.0);
        c.add(&p, Constraint::OnPlane { i: 0, point, normal: DVec3::Y }).unwrap();
    }
    (p, c)
}

#[test]
fn redundant_constraints_hold_and_conflicting_ones_fail_or_reach_least_squares() {
    // Redundant only (the plane y = 0 twice): the defaults hold the particle on it exactly
    // while it slides along X.
    let (mut p, mut c) = between_conflicting_planes(0.0, 0.0, 0.0);
    let mut redundant = ConstrainedSystem::new(0.0, 0.0, ConstraintSolver::Cholesky).unwrap();
    for k in 0..2 {
        redundant.add(&p, c.constraints()[k].clone()).unwrap();
    }
    redundant.step(&mut p, 1e-3, 1000, Method::Rk4).unwrap();
    let x = position(&p, 0);
    assert!(x.y.abs() <= 1e-12 && (x.x - 0.5).abs() < 1e-12, "{x}");
    // Conflicting, at the defaults (post-stabilisation): no point satisfies them, so the step
    // fails with a solver error naming the residual, and nothing moves.
    let (mut p, _) = between_conflicting_planes(0.0, 0.0, 0.0);
    let before = (p.positions().to_vec(), p.velocities().to_vec(), p.time());
    let err = c.step(&mut p, 1e-3, 10, Method::Rk4).unwrap_err();
    assert!(matches!(err, kinema::Error::SolverFailed { .. }), "{err}");
    assert!(err.to_string().contains("conflict"), "{err}");
    assert_eq!((p.positions().to_vec(), p.velocities().to_vec(), p.time()), before);
    let err = c.step_projection(&mut p, 1e-3, 10).unwrap_err();
    assert!(err.to_string().contains("conflict"), "{err}");
    assert_eq!((p.positions().to_vec(), p.velocities().to_vec(), p.time()), before);
    // Without post-stabilisation the multipliers solve the rows in the least-squares sense:
    // feedback (critically damped, ω = 10/s) drives the particle to the least-squares point of
    // C = (y, y, y - 3), y = 1, where the constraint force carries its weight; X is free.
    let (mut p, mut c) = between_conflicting_planes(0.0, 100.0, 20.0);
    c.set_stabilization(false).unwrap();
    c.step(&mut p, 1e-3, 3000, Method::Rk4).unwrap();
    let x = position(&p, 0);
    // To ~1e-6: the rounding of the multipliers' null-space components (~|C|/ε) as they cancel.
    assert!((x.y - 1.0).abs() < 1e-5 && (x.x - 1.5).abs() < 1e-12 && x.z == 0.0, "{x}");
    assert!((c.violation(&p).unwrap().0 - 2.0).abs() < 1e-5);
    let f = c.constraint_forces(&mut p).unwrap()[0];
    assert!((f - DVec3::new(0.0, 2.0 * 9.81, 0.0)).length() < 1e-2, "{f}");
}

#[test]
fn a_bead_on_a_circle_is_the_same_by_curve_by_sphere_and_plane_and_by_its_angle() {
    let (mut p1, mut c1) = bead(0.0, 0.0);
    c1.add(&p1, Constraint::OnPlane { i: 0, point: DVec3::ZERO, normal: DVec3::Z }).unwrap();
    let (mut p2, mut c2) = bead_on_curve(CIRCLE, 0.0, 0.0);
    let mut reduced = ReducedBead::new(CIRCLE, 1.0, G, 0.0, 1.0).unwrap();
    c1.step(&mut p1, 1e-3, 2000, Method::Rk4).unwrap();
    c2.step(&mut p2, 1e-3, 2000, Method::Rk4).unwrap();
    reduced.step(1e-3, 2000, Method::Rk4).unwrap();
    let (a, b, r) = (position(&p1, 0), position(&p2, 0), reduced.position());
    assert!((a - b).length() < 1e-8 && (b - r).length() < 1e-9, "{a} {b} {r}");
    // The tracked parameter is the angle, as in reduced coordinates.
    assert!((c2.curve_parameter(0).unwrap() - reduced.state()[0]).abs() < 1e-9);
    assert!(c2.curve_parameter(1).is_none());
}

fn spline() -> Curve {
    let keys = [0.0, 0.0, 0.0, 1.0, -0.5, 0.3, 2.0, -0.6, -0.2, 3.0, -1.5, 0.4];
    let track = Track::new(
        &[0.0, 1.0, 2.0, 3.0],
        &keys,
        3,
        Interpolation::NaturalCubic,
        Extrapolation::Linear,
    )
    .unwrap();
    Curve::Track(track)
}

#[test]
fn beads_on_a_helix_and_a_spline_agree_with_reduced_coordinates_and_keep_energy() {
    let helix = Curve::Helix { center: DVec3::ZERO, axis: DVec3::Y, radius: 1.0, pitch: 0.7 };
    // The natural spline is only C²: RK4 loses an order where its third derivative jumps (at
    // the keys), hence the looser agreement.
    for (curve, u0, tol) in [(helix, 0.0, 1e-8), (spline(), 0.5, 1e-7)] {
        let x0 = curve.eval(u0)[0];
        let mut p = ParticleSystem::new(&[x0], &[DVec3::ZERO], &[2.0], 1).unwrap();
        p.add_force(Force::Gravity { g: G }).unwrap();
        let mut c = ConstrainedSystem::new(100.0, 20.0, ConstraintSolver::Cholesky).unwrap();
        c.add(&p, Constraint::OnCurve { i: 0, curve: curve.clone() }).unwrap();
        let mut reduced = ReducedBead::new(curve.clone(), 2.0, G, u0, 0.0).unwrap();
        let (e0, r0) = (energy(&p), reduced.energy());
        for _ in 0..10 {
            c.step(&mut p, 1e-3, 100, Method::Rk4).unwrap();
            reduced.step(1e-3, 100, Method::Rk4).unwrap();
            let drift = c.violation(&p).unwrap().0;
            assert!(drift < tol, "{curve:?}: {drift}");
            // No work: the constraint force is normal to the curve (up to the tangential part
            // of the exact gradient off the curve, proportional to the distance).
            let f = c.constraint_forces(&mut p).unwrap()[0];
            let t = curve.eval(c.curve_parameter(0).unwrap())[1].normalize();
            let along = f.dot(t).abs() / f.length();
            assert!(along < 1e-12 + 100.0 * drift, "{curve:?}: {along} at drift {drift}");
        }
        let (a, b) = (position(&p, 0), reduced.position());
        assert!((a - b).length() < tol, "{curve:?}: {a} vs {b}");
        let (de, dr) = ((energy(&p) - e0).abs(), (reduced.energy() - r0).abs());
        assert!(de < 10.0 * tol && dr < 10.0 * tol, "{curve:?}: energy errors {de}, {dr}");
        assert!(a.y < x0.y - 0.05, "the bead slid down: {a}");
    }
}

/// The rod `|x₀ - x₁| - length` written as a user constraint.
#[derive(Debug)]
struct Rod {
    length: f64,
    fail_after: std::sync::atomic::AtomicUsize,
}

impl ConstraintFunction for Rod {
    fn rows(&self) -> usize {
        1
    }
    fn value(&self, x: &[f64], value: &mut [f64]) -> kinema::Result<()> {
        let d = DVec3::from_slice(&x[..3]) - DVec3::from_slice(&x[3..]);
        value[0] = d.length() - self.length;
        Ok(())
    }
    fn gradient(&self, x: &[f64], gradient: &mut [f64]) -> kinema::Result<()> {
        use std::sync::atomic::Ordering;
        if self.fail_after.fetch_sub(1, Ordering::Relaxed) == 0 {
            return Err(kinema::Error::invalid("gradient", "failed on purpose"));
        }
        let d = DVec3::from_slice(&x[..3]) - DVec3::from_slice(&x[3..]);
        let u = d / d.length();
        gradient[..3].copy_from_slice(&u.to_array());
        gradient[3..].copy_from_slice(&(-u).to_array());
        Ok(())
    }
}

#[test]
fn a_custom_rod_moves_like_the_built_in_one_and_a_failure_keeps_the_state() {
    let (mut p1, mut c1) = double_pendulum(10.0, 5.0, ConstraintSolver::Cholesky);
    let xs = [DVec3::ZERO, DVec3::new(1.0, 0.0, 0.0), DVec3::new(1.0, -1.0, 0.0)];
    let mut p2 =
        ParticleSystem::new(&xs, &[DVec3::ZERO; 3], &[f64::INFINITY, 1.0, 2.0], 3).unwrap();
    p2.add_force(Force::Gravity { g: G }).unwrap();
    let mut c2 = ConstrainedSystem::new(10.0, 5.0, ConstraintSolver::Cholesky).unwrap();
    let rod = Arc::new(Rod { length: 1.0, fail_after: usize::MAX.into() });
    c2.add(&p2, Constraint::Distance { i: 0, j: 1, length: 1.0 }).unwrap();
    c2.add(&p2, Constraint::Custom { particles: vec![1, 2], function: rod.clone() }).unwrap();
    c1.step(&mut p1, 1e-3, 2000, Method::Rk4).unwrap();
    c2.step(&mut p2, 1e-3, 2000, Method::Rk4).unwrap();
    for (a, b) in p1.positions().iter().zip(p2.positions()) {
        assert!((a - b).abs() < 1e-8, "{a} vs {b}");
    }
    // A failing callback: the error comes back and the particles stay at the last good step.
    let before = p2.positions().to_vec();
    rod.fail_after.store(5, std::sync::atomic::Ordering::Relaxed);
    let err = c2.step(&mut p2, 1e-3, 1, Method::Rk4).unwrap_err();
    assert!(err.to_string().contains("on purpose"), "{err}");
    assert_eq!(p2.positions(), &before[..]);
}

#[test]
fn penalty_drift_falls_with_stiffness_and_so_does_the_stable_step() {
    let run = |k: f64, dt: f64, t: f64| -> Option<(f64, f64)> {
        let (mut p, _) = bead(0.0, 0.0);
        let mut c = ConstrainedSystem::penalty(k, 0.0).unwrap();
        c.add(&p, Constraint::OnCurve { i: 0, curve: CIRCLE }).unwrap();
        let e0 = energy(&p);
        let mut drift = 0.0_f64;
        for _ in 0..(t / dt).round() as usize {
            c.step(&mut p, dt, 1, Method::Rk4).ok()?;
            drift = drift.max(c.violation(&p).unwrap().0);
        }
        let e = (energy(&p) - e0).abs();
        (e < 1.0).then_some((drift, e))
    };
    let stiffness = [1e4, 1e6, 1e8];
    let drifts: Vec<f64> = stiffness.iter().map(|&k| run(k, 1e-4, 1.0).unwrap().0).collect();
    for w in drifts.windows(2) {
        assert!(w[1] < 0.05 * w[0], "drift {drifts:?}");
    }
    // Largest stable step on a grid of factors √2: it shrinks about as 1/√k.
    let stable: Vec<f64> = stiffness
        .iter()
        .map(|&k| {
            (0..40)
                .map(|j| 0.1 * 0.5_f64.powf(j as f64 / 2.0))
                .find(|&dt| run(k, dt, 1.0).is_some())
                .unwrap()
        })
        .collect();
    for w in stable.windows(2) {
        let ratio = w[0] / w[1];
        assert!((4.0..25.0).contains(&ratio), "stable steps {stable:?}");
    }
}

#[test]
fn reduced_pendulums_have_no_drift_keep_energy_to_order_and_match_multipliers() {
    // Double pendulum of the multiplier tests: θ₁ = π/2 (first rod along +X), θ₂ = 0.
    let make = || {
        ReducedPendulum::new(
            DVec3::ZERO,
            &[1.0, 1.0],
            &[1.0, 2.0],
            &[std::f64::consts::FRAC_PI_2, 0.0],
            &[0.0, 0.0],
            9.81,
        )
        .unwrap()
    };
    let mut r = make();
    let (mut p, mut c) = double_pendulum(0.0, 0.0, ConstraintSolver::Cholesky);
    r.step(1e-3, 1000, Method::Rk4).unwrap();
    c.step(&mut p, 1e-3, 1000, Method::Rk4).unwrap();
    let xv = r.positions_velocities();
    for (k, (x, v)) in xv.iter().enumerate() {
        assert!((*x - position(&p, k + 1)).length() < 1e-8);
        assert!((*v - DVec3::from_slice(&p.velocities()[3 * (k + 1)..])).length() < 1e-7);
    }
    assert!(
        (xv[0].0.length() - 1.0).abs() < 1e-15
            && ((xv[1].0 - xv[0].0).length() - 1.0).abs() < 1e-15
    );
    let e0 = -9.81 * 2.0; // the second particle starts 1 m below the pivot
    assert!((r.energy() - e0).abs() < 1e-7 && (energy(&p) - e0).abs() < 1e-7);
    // Energy error at the integrator's order, and bounded with a symplectic method.
    let error = |dt: f64, method| {
        let mut r = make();
        let e0 = r.energy();
        r.step(dt, (2.0 / dt).round() as usize, method).unwrap();
        (r.energy() - e0).abs()
    };
    let order = (error(4e-3, Method::Rk4) / error(2e-3, Method::Rk4)).log2();
    assert!(order > 3.5, "RK4 energy order {order}");
    let order = (error(4e-3, Method::Midpoint) / error(2e-3, Method::Midpoint)).log2();
    assert!(order > 1.5, "midpoint energy order {order}");
    let mut one = ReducedPendulum::new(DVec3::Y, &[2.0], &[1.0], &[1.0], &[0.0], 9.81).unwrap();
    let e0 = one.energy();
    one.step(1e-2, 100_000, Method::VelocityVerlet).unwrap();
    assert!((one.energy() - e0).abs() < 1e-3 * e0.abs());
    assert!((one.positions_velocities()[0].0 - DVec3::Y).length() - 2.0 < 1e-15);
}

/// A failed step leaves the particles and the constraint system exactly as they were: the
/// particles and the whole constraint snapshot (multipliers, iteration count, tracked curve
/// parameters, the integrator's history and counters) bit for bit, and the steps after it
/// bit for bit those of a copy that never tried it — with explicit and BDF2 steps, with
/// post-stabilisation (whose failure comes after the integrator's step) and with the
/// projection step.
#[test]
fn failed_constrained_step_leaves_nothing_behind() {
    use kinema::snapshot::Snapshot;
    let bits = |p: &ParticleSystem| -> Vec<u64> {
        let (x, v) = (p.positions().iter(), p.velocities().iter());
        x.chain(v).chain([&p.time()]).map(|v| v.to_bits()).collect()
    };
    let stabilized = |(p, mut c): (ParticleSystem, ConstrainedSystem)| {
        c.set_stabilization(true).unwrap();
        (p, c)
    };
    let systems = [
        (double_pendulum(10.0, 5.0, ConstraintSolver::ConjugateGradient), Method::Rk4),
        (double_pendulum(10.0, 5.0, ConstraintSolver::Cholesky), Method::Bdf2),
        (stabilized(double_pendulum(0.0, 0.0, ConstraintSolver::Cholesky)), Method::Bdf2),
        (bead_on_curve(CIRCLE, 10.0, 5.0), Method::Rk4),
        (stabilized(bead_on_curve(CIRCLE, 0.0, 0.0)), Method::Bdf2),
    ];
    for ((mut p, mut c), method) in systems {
        c.step(&mut p, 1e-3, 10, method).unwrap();
        let (mut p2, mut c2) =
            (p.clone(), ConstrainedSystem::from_snapshot(&c.to_snapshot().unwrap()).unwrap());
        let before = c.to_snapshot().unwrap();
        assert!(c.step(&mut p, 1e200, 1, method).is_err(), "{method:?}");
        assert_eq!(bits(&p), bits(&p2));
        assert!(c.to_snapshot().unwrap() == before, "{method:?}: the constraint state changed");
        c.step(&mut p, 1e-3, 5, method).unwrap();
        c2.step(&mut p2, 1e-3, 5, method).unwrap();
        assert_eq!(bits(&p), bits(&p2));
        assert_eq!(c.iterations(), c2.iterations());
        if c.formulation() == kinema::constraints::Formulation::Multipliers {
            let before = c.to_snapshot().unwrap();
            assert!(c.step_projection(&mut p, 1e200, 1).is_err());
            assert!(c.to_snapshot().unwrap() == before, "projection: the state changed");
        }
    }
}
