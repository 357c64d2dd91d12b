//! Constraints as model, state and solver: one particle model and one constraint model, one
//! solver pair advancing several state pairs, interleaved, bitwise as each would alone; state
//! snapshots carry the model's fingerprint; recorded trajectories unchanged by the split.

use glam::DVec3;
use kinema::constraints::{
    self, ConstrainedSystem, Constraint, ConstraintFunction, ConstraintSolver, Curve, Particles,
};
use kinema::ode::Method;
use kinema::particles::{self, Force, ParticleSystem};
use kinema::snapshot::{fingerprint, Snapshot, Stamped};
use std::fs;
use std::sync::Arc;

const G: DVec3 = DVec3::new(0.0, -9.81, 0.0);

const HELIX: Curve =
    Curve::Helix { center: DVec3::new(2.0, 0.0, 0.0), axis: DVec3::Y, radius: 0.5, pitch: 0.4 };

/// The particle model of the pairs: 8 slots, gravity and drag.
fn particle_model() -> particles::Model {
    let mut m = particles::Model::new(8);
    m.add_force(Force::Gravity { g: G }).unwrap();
    m.add_force(Force::Drag { linear: 0.01, quadratic: 0.0, wind: DVec3::ZERO }).unwrap();
    m
}

/// A chain of 6 particles (the top one pinned) hanging along -Y, pushed sideways at `push`
/// m/s, a bead on [`HELIX`] at parameter `u` and a free particle; the constraints: the
/// chain's rods and the bead's wire.
fn constraint_model(particles: &particles::Model, solver: ConstraintSolver) -> constraints::Model {
    let mut m = constraints::Model::new(5.0, 1.0, solver).unwrap();
    for i in 0..5 {
        m.add(particles, Constraint::Distance { i, j: i + 1, length: 0.1 }).unwrap();
    }
    m.add(particles, Constraint::OnCurve { i: 6, curve: HELIX }).unwrap();
    m
}

/// A particle state of `model` and the constraint state of `constraints` on it.
fn pair(
    model: &particles::Model,
    constraints: &constraints::Model,
    push: f64,
    u: f64,
) -> (particles::State, constraints::State) {
    let mut x: Vec<DVec3> = (0..6).map(|i| DVec3::new(0.0, -0.1 * i as f64, 0.0)).collect();
    let mut v: Vec<DVec3> = (0..6).map(|i| DVec3::new(push * i as f64, 0.0, 0.0)).collect();
    x.extend([HELIX.eval(u)[0], DVec3::new(-1.0, 0.0, 0.0)]);
    v.extend([DVec3::new(0.0, 0.0, push), DVec3::new(0.0, push, 0.0)]);
    let mut masses = vec![0.05; 8];
    masses[0] = f64::INFINITY;
    let p = particles::State::new(model, &x, &v, &masses).unwrap();
    let c = constraints::State::new(constraints, &p).unwrap();
    (p, c)
}

/// The exact bytes of a state pair.
fn pair_bytes(
    (p, c): &(particles::State, constraints::State),
    pm: &particles::Model,
    cm: &constraints::Model,
) -> Vec<u8> {
    let mut out = p.to_snapshot(pm).unwrap();
    out.extend(c.to_snapshot(cm).unwrap());
    out
}

/// One call on a state pair with a solver pair: `method`, or the projection when `None`.
#[allow(clippy::too_many_arguments)]
fn call(
    pm: &particles::Model,
    cm: &constraints::Model,
    (p, c): &mut (particles::State, constraints::State),
    (psolver, csolver): &mut (particles::Solver, constraints::Solver),
    dt: f64,
    steps: usize,
    method: Option<Method>,
) {
    let particles = Particles { model: pm, state: p, solver: psolver };
    match method {
        Some(m) => csolver.step(cm, c, particles, dt, steps, m).unwrap(),
        None => csolver.step_projection(cm, c, particles, dt, steps).unwrap(),
    }
}

/// Two state pairs of one particle model and one constraint model, stepped interleaved by one
/// solver pair in calls of different lengths and steps, give bitwise the trajectories of each
/// stepped alone by a fresh solver pair, and a call on one leaves the other bitwise as it
/// was. Covered: every warm start (the conjugate gradient's multipliers, the implicit
/// projection's, the helix's tracked parameter and axis) and BDF2's previous step, with
/// Cholesky and CG.
#[test]
fn one_solver_pair_steps_interleaved_state_pairs_as_separate_solvers() {
    let pm = particle_model();
    for solver in [ConstraintSolver::Cholesky, ConstraintSolver::ConjugateGradient] {
        let cm = constraint_model(&pm, solver);
        for method in [Some(Method::Rk4), Some(Method::Bdf2), None] {
            let fresh = || (particles::Solver::new(&pm).unwrap(), constraints::Solver::new(&cm));
            let mut shared = fresh();
            let mut states = [pair(&pm, &cm, 1.0, 0.3), pair(&pm, &cm, -0.4, 2.0)];
            let mut alone: Vec<_> = states.iter().map(|s| (s.clone(), fresh())).collect();
            for round in 0..8 {
                for k in [0, 1] {
                    let (dt, steps) = match (method, k) {
                        (None, 0) => (1.0 / 60.0, 1 + round % 3),
                        (None, _) => (1.0 / 90.0, 2),
                        (_, 0) => (2e-3, 1 + round % 3),
                        _ => (1.5e-3, 2),
                    };
                    let other = pair_bytes(&states[1 - k], &pm, &cm);
                    call(&pm, &cm, &mut states[k], &mut shared, dt, steps, method);
                    assert!(pair_bytes(&states[1 - k], &pm, &cm) == other, "the other changed");
                    let (s, solvers) = &mut alone[k];
                    call(&pm, &cm, s, solvers, dt, steps, method);
                    let same = pair_bytes(&states[k], &pm, &cm) == pair_bytes(s, &pm, &cm);
                    assert!(same, "{solver:?} {method:?}: state {k}, round {round}");
                }
            }
            let (c0, c1) = (&states[0].1, &states[1].1);
            let u = |c: &constraints::State| c.curve_parameter(&cm, 5).unwrap();
            assert!((u(c0) - u(c1)).abs() > 0.1, "the beads went different ways");
            if solver == ConstraintSolver::ConjugateGradient && method.is_some() {
                assert!(c0.iterations() > 0 && c0.multipliers() != c1.multipliers());
            }
        }
    }
}

/// A state snapshot restores onto its model bitwise and goes on as the original; onto a
/// model of another fingerprint it is refused naming the model, and a state of another model
/// or of other particles is refused by a step naming it.
#[test]
fn state_snapshots_record_the_model_fingerprint_and_mismatches_are_refused() {
    let pm = particle_model();
    let cm = constraint_model(&pm, ConstraintSolver::ConjugateGradient);
    let mut solvers = (particles::Solver::new(&pm).unwrap(), constraints::Solver::new(&cm));
    let mut s = pair(&pm, &cm, 1.0, 0.3);
    call(&pm, &cm, &mut s, &mut solvers, 2e-3, 4, Some(Method::Bdf2));
    let data = s.1.to_snapshot(&cm).unwrap();
    let mut back = (s.0.clone(), constraints::State::from_snapshot(&cm, &data).unwrap());
    assert!(pair_bytes(&back, &pm, &cm) == pair_bytes(&s, &pm, &cm));
    call(&pm, &cm, &mut s, &mut solvers, 2e-3, 3, Some(Method::Bdf2));
    call(&pm, &cm, &mut back, &mut solvers, 2e-3, 3, Some(Method::Bdf2));
    assert!(pair_bytes(&back, &pm, &cm) == pair_bytes(&s, &pm, &cm));

    let mut other = cm.clone();
    other.add(&pm, Constraint::OnPlane { i: 7, point: DVec3::ZERO, normal: DVec3::Z }).unwrap();
    assert_ne!(other.fingerprint(), cm.fingerprint());
    let err = constraints::State::from_snapshot(&other, &data).unwrap_err().to_string();
    assert!(err.starts_with("model"), "{err}");
    let cholesky = constraint_model(&pm, ConstraintSolver::Cholesky);
    let err = constraints::State::from_snapshot(&cholesky, &data).unwrap_err().to_string();
    assert!(err.starts_with("model"), "{err}");
    let err = constraints::State::from_snapshot(&cm, &data[..data.len() - 1]).unwrap_err();
    assert!(err.to_string().starts_with("data"), "{err}");

    // The state of `cm` does not fit `other` (a constraint more).
    let mut fresh = (particles::Solver::new(&pm).unwrap(), constraints::Solver::new(&other));
    let (p, c) = &mut s;
    let particles = Particles { model: &pm, state: p, solver: &mut fresh.0 };
    let err = fresh.1.step(&other, c, particles, 1e-3, 1, Method::Rk4).unwrap_err();
    assert!(err.to_string().starts_with("state"), "{err}");
    // Nor do particles of another model, whether the constraints refer beyond their slots or
    // the particle state does not fit the particle model it comes with.
    let small = particles::Model::new(6);
    let few = particles::State::new(&small, &[DVec3::ZERO], &[DVec3::ZERO], &[1.0]).unwrap();
    let err = constraints::State::new(&cm, &few).unwrap_err().to_string();
    assert!(err.starts_with("particles"), "{err}");
    let mut few =
        particles::State::new(&small, &[DVec3::ZERO; 6], &[DVec3::ZERO; 6], &[1.0; 6]).unwrap();
    let particles = Particles { model: &pm, state: &mut few, solver: &mut fresh.0 };
    let err = solvers.1.step(&cm, &mut s.1, particles, 1e-3, 1, Method::Rk4).unwrap_err();
    assert!(err.to_string().starts_with("state"), "{err}");
}

/// The Rust example of `docs/constraints.md` is the doctest of `kinema::constraints`, which
/// `cargo test` compiles and runs.
#[test]
fn the_docs_example_is_the_module_doctest() {
    let root = env!("CARGO_MANIFEST_DIR");
    let docs = fs::read_to_string(format!("{root}/docs/constraints.md")).unwrap();
    let example = docs.split("```rust\n").nth(1).unwrap().split("```").next().unwrap();
    let module = fs::read_to_string(format!("{root}/src/constraints/mod.rs")).unwrap();
    let doc: Vec<&str> = module
        .lines()
        .filter_map(|l| l.strip_prefix("//!"))
        .map(|l| l.strip_prefix(' ').unwrap_or(l))
        .collect();
    let start = doc.iter().position(|l| *l == "```").unwrap() + 1;
    let end = start + doc[start..].iter().position(|l| *l == "```").unwrap();
    let doctest: Vec<&str> =
        doc[start..end].iter().filter(|l| !l.starts_with("# ")).copied().collect();
    assert_eq!(example.lines().collect::<Vec<_>>(), doctest);
}

/// A hanging chain of `n` rods of 0.1 m (the top particle pinned), pushed sideways, with a
/// bead on a helix tied to its last particle's neighbour plane and a bead on a circle.
fn scene(n: usize, solver: ConstraintSolver, push: f64) -> (ParticleSystem, ConstrainedSystem) {
    let mut xs: Vec<DVec3> = (0..n).map(|i| DVec3::new(0.0, -0.1 * i as f64, 0.0)).collect();
    let mut vs: Vec<DVec3> =
        (0..n).map(|i| DVec3::new(push * i as f64 / n as f64, 0.0, 0.0)).collect();
    let mut masses = vec![0.05; n];
    masses[0] = f64::INFINITY;
    let helix =
        Curve::Helix { center: DVec3::new(2.0, 0.0, 0.0), axis: DVec3::Y, radius: 0.5, pitch: 0.4 };
    xs.push(helix.eval(0.3)[0]);
    vs.push(DVec3::new(0.0, 0.0, push));
    masses.push(0.2);
    xs.push(DVec3::new(-1.0, 0.0, 0.0));
    vs.push(DVec3::new(0.0, push, 0.0));
    masses.push(0.3);
    let m = xs.len();
    let mut p = ParticleSystem::new(&xs, &vs, &masses, m).unwrap();
    p.add_force(Force::Gravity { g: G }).unwrap();
    p.add_force(Force::Drag { linear: 0.01, quadratic: 0.0, wind: DVec3::ZERO }).unwrap();
    let mut c = ConstrainedSystem::new(5.0, 1.0, solver).unwrap();
    for i in 0..n - 1 {
        c.add(&p, Constraint::Distance { i, j: i + 1, length: 0.1 }).unwrap();
    }
    c.add(&p, Constraint::OnCurve { i: n, curve: helix }).unwrap();
    let circle = Curve::Circle { center: DVec3::ZERO, normal: DVec3::Z, radius: 1.0 };
    c.add(&p, Constraint::OnCurve { i: n + 1, curve: circle }).unwrap();
    (p, c)
}

/// Every bit a reader sees of the pair: positions, velocities, time, curve parameters, CG
/// iterations.
fn bits(p: &ParticleSystem, c: &ConstrainedSystem) -> Vec<u64> {
    let mut out: Vec<u64> =
        p.positions().iter().chain(p.velocities()).map(|x| x.to_bits()).collect();
    out.push(p.time().to_bits());
    out.extend((0..c.constraints().len()).filter_map(|k| c.curve_parameter(k)).map(f64::to_bits));
    out.push(c.iterations() as u64);
    out
}

/// The scenes of [`trajectories`]: `(name, hash of the bits after each call)`.
fn trajectories() -> Vec<(String, u64)> {
    let mut out = Vec::new();
    for solver in [ConstraintSolver::Cholesky, ConstraintSolver::ConjugateGradient] {
        for (label, method) in [
            ("rk4", Some(Method::Rk4)),
            ("bdf2", Some(Method::Bdf2)),
            ("symplectic", Some(Method::SymplecticEuler)),
            ("projection", None),
        ] {
            let (mut p, mut c) = scene(6, solver, 1.0);
            let mut seen = Vec::new();
            let dt = if method.is_some() { 2e-3 } else { 1.0 / 60.0 };
            for call in 0..8 {
                let steps = 1 + call % 3;
                match method {
                    Some(m) => c.step(&mut p, dt, steps, m).unwrap(),
                    None => c.step_projection(&mut p, dt, steps).unwrap(),
                }
                if call == 4 {
                    // A snapshot round trip in the middle.
                    c = ConstrainedSystem::from_snapshot(&c.to_snapshot().unwrap()).unwrap();
                }
                seen.extend(bits(&p, &c));
            }
            let forces = c.constraint_forces(&mut p).unwrap();
            seen.extend(forces.iter().flat_map(|f| f.to_array()).map(f64::to_bits));
            let (a, b) = c.violation(&p).unwrap();
            seen.extend([a.to_bits(), b.to_bits()]);
            out.push((format!("{solver:?} {label}"), fingerprint(&seen)));
        }
    }
    let (mut p, _) = scene(6, ConstraintSolver::Cholesky, 1.0);
    let mut c = ConstrainedSystem::penalty(2e3, 5.0).unwrap();
    for i in 0..5 {
        c.add(&p, Constraint::Distance { i, j: i + 1, length: 0.1 }).unwrap();
    }
    let mut seen = Vec::new();
    for _ in 0..5 {
        c.step(&mut p, 1e-3, 3, Method::Rk4).unwrap();
        seen.extend(bits(&p, &c));
    }
    out.push(("penalty rk4".into(), fingerprint(&seen)));
    let (mut p, mut c) = scene(6, ConstraintSolver::Cholesky, 1.0);
    let gap = (DVec3::from_slice(&p.positions()[18..]) - DVec3::from_slice(&p.positions()[21..]))
        .length();
    c.add(&p, Constraint::Custom { particles: vec![6, 7], function: Arc::new(Gap(gap)) }).unwrap();
    let mut seen = Vec::new();
    for _ in 0..5 {
        c.step(&mut p, 1e-3, 3, Method::Rk4).unwrap();
        seen.extend(bits(&p, &c));
    }
    out.push(("custom rk4".into(), fingerprint(&seen)));
    out
}

/// `|x₀ - x₁|² - d²` as a user constraint.
#[derive(Debug)]
struct Gap(f64);

impl ConstraintFunction for Gap {
    fn rows(&self) -> usize {
        1
    }
    fn value(&self, x: &[f64], value: &mut [f64]) -> kinema::Result<()> {
        let d = DVec3::from_slice(&x[..3]) - DVec3::from_slice(&x[3..]);
        value[0] = d.length_squared() - self.0 * self.0;
        Ok(())
    }
    fn gradient(&self, x: &[f64], gradient: &mut [f64]) -> kinema::Result<()> {
        let d = DVec3::from_slice(&x[..3]) - DVec3::from_slice(&x[3..]);
        gradient[..3].copy_from_slice(&(2.0 * d).to_array());
        gradient[3..].copy_from_slice(&(-2.0 * d).to_array());
        Ok(())
    }
}

/// Hashes of [`trajectories`] recorded before the split into model, state and solver
/// (commit 9c441b7): the split changed no result.
const RECORDED: [(&str, u64); 10] = [
    ("Cholesky rk4", 0xa7746fdeaf8396c2),
    ("Cholesky bdf2", 0x310df85c37571181),
    ("Cholesky symplectic", 0x8f777631b846ad4c),
    ("Cholesky projection", 0x3dc5b3b319f167e4),
    ("ConjugateGradient rk4", 0x7de2dd34dff47a33),
    ("ConjugateGradient bdf2", 0x8d3f9b2c5fb9c7be),
    ("ConjugateGradient symplectic", 0xf0aab8a5a9c77a67),
    ("ConjugateGradient projection", 0xce51f5e17eef8a69),
    ("penalty rk4", 0xee5c69113008123d),
    ("custom rk4", 0x6d6fcb94c4c7c051),
];

#[test]
fn trajectories_are_bitwise_those_before_the_split() {
    let got = trajectories();
    for ((name, hash), (want_name, want)) in got.iter().zip(RECORDED) {
        assert_eq!((name.as_str(), *hash), (want_name, want), "{name} changed");
    }
    assert_eq!(got.len(), RECORDED.len());
}
