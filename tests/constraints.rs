//! Constrained dynamics: drift with and without feedback, energy, no work, solvers agree,
//! degenerate input.

use glam::DVec3;
use kinema::constraints::{ConstrainedSystem, Constraint, ConstraintSolver};
use kinema::ode::Method;
use kinema::particles::{Force, ParticleSystem};

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

fn energy(p: &ParticleSystem) -> f64 {
    p.kinetic_energy() + p.potential_energy()
}

#[test]
fn feedback_keeps_drift_below_1e_8_and_without_it_drift_grows() {
    for make in [bead as fn(f64, f64) -> (ParticleSystem, ConstrainedSystem), |ks, kd| {
        double_pendulum(ks, kd, ConstraintSolver::Cholesky)
    }] {
        let (mut p, mut c) = make(100.0, 20.0);
        for _ in 0..10 {
            c.step(&mut p, 1e-3, 10_000, Method::Rk4).unwrap();
            assert!(c.violation(&p).0 < 1e-8, "{:?}", c.violation(&p));
        }
        let (mut p, mut c) = make(0.0, 0.0);
        c.step(&mut p, 1e-3, 1_000, Method::Midpoint).unwrap();
        let early = c.violation(&p).0;
        c.step(&mut p, 1e-3, 99_000, Method::Midpoint).unwrap();
        let late = c.violation(&p).0;
        assert!(late > 2.0 * early && late > 1e-6, "no feedback: {early} -> {late}");
    }
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
        let (drift, _) = c.violation(&q);
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
    // Conflicting and redundant constraints: a finite, regularised answer.
    c.add(&p, Constraint::OnPlane { i: 0, point: DVec3::ZERO, normal: DVec3::Y }).unwrap();
    c.add(&p, Constraint::OnPlane { i: 0, point: DVec3::ZERO, normal: DVec3::Y }).unwrap();
    c.add(&p, Constraint::OnPlane { i: 0, point: DVec3::Y, normal: DVec3::Y }).unwrap();
    c.step(&mut p, 1e-3, 100, Method::Rk4).unwrap();
    assert!(p.positions().iter().all(|v| v.is_finite()));
    // Everything pinned: nothing moves, nothing fails.
    let mut pinned =
        ParticleSystem::new(&[DVec3::ZERO, DVec3::X], &[DVec3::ZERO; 2], &[f64::INFINITY; 2], 2)
            .unwrap();
    pinned.add_force(Force::Gravity { g: G }).unwrap();
    let mut c = ConstrainedSystem::new(1.0, 1.0, ConstraintSolver::Cholesky).unwrap();
    c.add(&pinned, Constraint::Distance { i: 0, j: 1, length: 2.0 }).unwrap();
    c.step(&mut pinned, 1e-2, 10, Method::Rk4).unwrap();
    assert_eq!(&pinned.positions()[..6], &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0]);
}
