//! Particles as model, state and solver: one model and one solver advance several states,
//! interleaved, bitwise as each would alone; state snapshots carry the model's fingerprint.

use glam::DVec3;
use kinema::geometry::{Material, Plane, Shape};
use kinema::ode::Method;
use kinema::particles::{Appearance, Collider, Emitter, Force, Model, Solver, State, StepStats};
use kinema::snapshot::Stamped;

/// A model of 300 slots with gravity, drag, a ground plane and an emitter whose particles live
/// 6 ms (so slots are born and die within a few calls) when `emitter`, and springs when
/// `springs` (which send every method through the general path).
fn model(springs: bool, emitter: bool) -> Model {
    let mut m = Model::new(300);
    m.add_force(Force::Gravity { g: DVec3::new(0.0, -9.81, 0.0) }).unwrap();
    m.add_force(Force::Drag { linear: 0.05, quadratic: 0.01, wind: DVec3::X }).unwrap();
    if springs {
        let pairs: Vec<[usize; 2]> = (0..20).map(|i| [i, i + 1]).collect();
        let rest = vec![0.1; pairs.len()];
        m.add_force(Force::Springs { pairs, rest, stiffness: 200.0, damping: 0.5 }).unwrap();
    }
    m.add_collider(Collider {
        shape: Shape::Plane(Plane { point: DVec3::ZERO, normal: DVec3::Y }),
        material: Material { restitution: 0.4, friction: 0.3 },
        velocity: DVec3::ZERO,
        inside: false,
    })
    .unwrap();
    if !emitter {
        return m;
    }
    m.add_emitter(Emitter {
        rate: 4000.0,
        position: DVec3::new(0.0, 0.05, 0.0),
        position_spread: 0.05,
        velocity: DVec3::new(0.0, -2.0, 0.0),
        velocity_spread: 0.5,
        lifespan: 0.006,
        mass: 0.2,
        seed: 7,
        appearance: Appearance::default(),
    })
    .unwrap();
    m
}

/// A state of `model` with 40 particles on a line at `height` falling at `speed`.
fn state(model: &Model, height: f64, speed: f64) -> State {
    let x: Vec<DVec3> = (0..40).map(|i| DVec3::new(0.1 * i as f64, height, 0.0)).collect();
    let v = vec![DVec3::new(0.3, -speed, 0.0); 40];
    State::new(model, &x, &v, &[0.5; 40]).unwrap()
}

/// Every bit of a state that a reader sees: positions, velocities, ages, masses, flags,
/// colours, sizes, time.
fn bits(s: &State) -> Vec<u64> {
    let f = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let mut out = f(s.positions());
    out.extend(f(s.velocities()));
    out.extend(f(&s.ages()));
    out.extend(f(s.masses()));
    out.extend(s.alive().iter().map(|&a| u64::from(a)));
    out.extend(s.colors().iter().flat_map(|c| f(c)));
    out.extend(f(s.sizes()));
    out.push(s.time().to_bits());
    out
}

/// Two states of one model stepped interleaved by one solver, in calls of different lengths
/// and steps, give bitwise the trajectories of each stepped alone by a fresh solver, and a
/// call on one leaves the other bitwise as it was. Covered: the explicit kernel (symplectic
/// Euler without pair forces, certified calls and copies), the general path with each
/// explicit and implicit method, births, deaths and contacts, and BDF2 without an emitter
/// (every birth restarts it) so that its previous step is read from the state.
#[test]
fn one_solver_steps_interleaved_states_as_separate_solvers() {
    for (springs, emitter, method) in [
        (false, true, Method::SymplecticEuler),
        (true, true, Method::SymplecticEuler),
        (true, true, Method::Rk4),
        (false, true, Method::Bdf2),
        (true, true, Method::ImplicitEuler),
        (true, false, Method::Bdf2),
    ] {
        let m = model(springs, emitter);
        let mut shared = Solver::new(&m).unwrap();
        let mut states = [state(&m, 0.002, 1.0), state(&m, 0.8, 0.2)];
        let mut alone: Vec<(State, Solver)> =
            states.iter().map(|s| (s.clone(), Solver::new(&m).unwrap())).collect();
        let mut seen = StepStats::default();
        for call in 0..12 {
            for k in [0, 1] {
                let (dt, steps) = if k == 0 { (1e-3, 1 + call % 3) } else { (7e-4, 2) };
                let other = bits(&states[1 - k]);
                let got = shared.step(&m, &mut states[k], dt, steps, method).unwrap();
                assert_eq!(bits(&states[1 - k]), other, "the other state changed");
                let (s, solver) = &mut alone[k];
                let want = solver.step(&m, s, dt, steps, method).unwrap();
                assert_eq!(got, want, "{method:?} springs {springs}: counters, state {k}");
                assert!(bits(&states[k]) == bits(s), "{method:?} springs {springs}: state {k}");
                seen.emitted += got.emitted;
                seen.expired += got.expired;
                seen.contacts += got.contacts;
            }
        }
        let covered = (seen.emitted > 0 && seen.expired > 0) == emitter && seen.contacts > 0;
        assert!(covered, "{method:?}: births, deaths and contacts happened: {seen:?}");
    }
}

/// A state snapshot restores onto its model bitwise and goes on as the original; onto a
/// model of another fingerprint it is refused naming the model.
#[test]
fn state_snapshots_record_the_model_fingerprint() {
    let m = model(true, false);
    let mut solver = Solver::new(&m).unwrap();
    let mut s = state(&m, 0.3, 1.0);
    solver.step(&m, &mut s, 1e-3, 5, Method::Bdf2).unwrap();
    let data = s.to_snapshot(&m).unwrap();
    let mut back = State::from_snapshot(&m, &data).unwrap();
    assert_eq!(bits(&back), bits(&s));
    solver.step(&m, &mut s, 1e-3, 5, Method::Bdf2).unwrap();
    solver.step(&m, &mut back, 1e-3, 5, Method::Bdf2).unwrap();
    assert_eq!(bits(&back), bits(&s), "the BDF2 history came back too");
    let other = model(false, false);
    assert_ne!(other.fingerprint(), m.fingerprint());
    let err = State::from_snapshot(&other, &data).unwrap_err();
    assert!(matches!(&err, kinema::Error::InvalidInput { arg, .. } if arg == "model"), "{err}");
}

/// A state that does not fit the model (another capacity, or made before an emitter was
/// added) is refused naming the state, and is fitted by `State::fit`.
#[test]
fn states_of_another_model_are_refused() {
    let small = Model::new(10);
    let m = model(false, true);
    let mut solver = Solver::new(&m).unwrap();
    let mut wrong = State::new(&small, &[DVec3::ZERO], &[DVec3::ZERO], &[1.0]).unwrap();
    let err = solver.step(&m, &mut wrong, 1e-3, 1, Method::Rk4).unwrap_err();
    assert!(matches!(&err, kinema::Error::InvalidInput { arg, .. } if arg == "state"), "{err}");
    let mut m2 = Model::new(300);
    let mut s = state(&m2, 0.5, 0.0);
    m2.add_emitter(m.emitters()[0].clone()).unwrap();
    assert!(solver.step(&m2, &mut s, 1e-3, 1, Method::Rk4).is_err());
    s.fit(&m2);
    solver.step(&m2, &mut s, 1e-3, 1, Method::Rk4).unwrap();
}
