//! Rods as model, state and solver: one model and one solver advance two states,
//! interleaved, bitwise as each would alone; a failed step leaves the state as it was;
//! snapshots carry the model's fingerprint; steps allocate nothing once warmed up.

mod common;
use common::thread_allocations;

use glam::DVec3;
use kinema::rods::{End, Integrator, Material, Model, Rod, Settings, Solver, State};
use kinema::snapshot::{Snapshot, Stamped};

const MATERIAL: Material =
    Material { youngs_modulus: 5e6, shear_modulus: 2e6, density: 1100.0, radius: [0.004, 0.003] };

/// A curly rod (natural curvature) of 24 edges clamped at its first end.
fn model(settings: Settings) -> Model {
    let points: Vec<DVec3> = (0..25)
        .map(|i| {
            let s = 0.3 * i as f64;
            DVec3::new(0.02 * i as f64, 0.03 * s.sin(), 0.03 * (1.0 - s.cos()))
        })
        .collect();
    let mut m = Model::new(&points, MATERIAL, settings).unwrap();
    m.clamp(End::First);
    m
}

/// Every bit a reader sees of a state.
fn bits(s: &State) -> Vec<u64> {
    let mut out: Vec<u64> = s
        .positions()
        .iter()
        .chain(s.velocities())
        .flat_map(|p| p.to_array())
        .map(f64::to_bits)
        .collect();
    out.extend(s.twists().iter().map(|t| t.to_bits()));
    out.push(s.time().to_bits());
    out
}

fn second(model: &Model) -> State {
    let mut b = State::new(model);
    let v: Vec<DVec3> = (0..25).map(|i| DVec3::new(0.0, 0.0, 0.01 * i as f64)).collect();
    b.set_velocities(&v).unwrap();
    b.set_force(24, DVec3::new(0.0, 0.0, -0.01)).unwrap();
    b.set_twists(&(0..24).map(|j| 0.05 * j as f64).collect::<Vec<_>>()).unwrap();
    b
}

#[test]
fn two_states_of_one_model_step_bitwise_as_alone() {
    for integrator in [Integrator::ImplicitEuler, Integrator::SymplecticEuler] {
        let model = model(Settings { integrator, ..Settings::default() });
        let dt = if integrator == Integrator::ImplicitEuler { 1.0 / 60.0 } else { 2e-5 };
        let (mut a, mut b) = (State::new(&model), second(&model));
        let (mut alone_a, mut alone_b) = (a.clone(), b.clone());
        let mut shared = Solver::new(&model);
        let (mut solver_a, mut solver_b) = (Solver::new(&model), Solver::new(&model));
        for _ in 0..5 {
            let before_b = bits(&b);
            shared.step(&model, &mut a, dt, 3).unwrap();
            assert_eq!(bits(&b), before_b, "stepping a changed b");
            shared.step(&model, &mut b, dt, 3).unwrap();
            solver_a.step(&model, &mut alone_a, dt, 3).unwrap();
            solver_b.step(&model, &mut alone_b, dt, 3).unwrap();
            assert_eq!(bits(&a), bits(&alone_a), "{integrator:?}");
            assert_eq!(bits(&b), bits(&alone_b), "{integrator:?}");
        }
        assert_ne!(bits(&a), bits(&b));
    }
}

/// Newton allowed one iteration cannot converge; a symplectic step far beyond its limit
/// diverges; a bad `dt` is refused. Each leaves the state bitwise as it was.
#[test]
fn a_failed_step_leaves_the_state_as_it_was() {
    let tight = model(Settings { max_iterations: 1, ..Settings::default() });
    let explicit =
        model(Settings { integrator: Integrator::SymplecticEuler, ..Settings::default() });
    for (m, dt, steps) in [(&tight, 0.1, 1), (&explicit, 0.01, 400), (&tight, f64::NAN, 1)] {
        let mut s = second(m);
        Solver::new(m).step(m, &mut s, 1e-3, 2).ok();
        let before = bits(&s);
        let err = Solver::new(m).step(m, &mut s, dt, steps).unwrap_err();
        println!("{err}");
        assert_eq!(bits(&s), before);
    }
}

#[test]
fn snapshots_restore_bitwise_and_only_onto_their_model() {
    let m = model(Settings::default());
    let mut rod = Rod::new(m.rest_positions(), MATERIAL, Settings::default(), None).unwrap();
    rod.model_mut().clamp(End::First);
    rod.step(1.0 / 60.0, 5).unwrap();
    let copy = Rod::from_snapshot(&rod.to_snapshot().unwrap()).unwrap();
    assert_eq!(bits(copy.state()), bits(rod.state()));
    let (mut a, mut b) = (rod.clone(), copy);
    a.step(1.0 / 60.0, 5).unwrap();
    b.step(1.0 / 60.0, 5).unwrap();
    assert_eq!(bits(a.state()), bits(b.state()));
    let data = a.state().to_snapshot(a.model()).unwrap();
    let restored = State::from_snapshot(a.model(), &data).unwrap();
    assert_eq!(bits(&restored), bits(a.state()));
    let mut other = a.model().clone();
    other.pin(10).unwrap();
    let err = State::from_snapshot(&other, &data).unwrap_err();
    assert!(err.to_string().starts_with("model:"), "{err}");
}

#[test]
fn steps_allocate_nothing_once_warmed_up() {
    for integrator in [Integrator::ImplicitEuler, Integrator::SymplecticEuler] {
        let model = model(Settings { integrator, ..Settings::default() });
        let mut state = second(&model);
        let mut solver = Solver::new(&model);
        solver.step(&model, &mut state, 1e-4, 2).unwrap();
        solver.solve_static(&model, &mut state).unwrap();
        let before = thread_allocations();
        solver.step(&model, &mut state, 1e-4, 3).unwrap();
        solver.solve_static(&model, &mut state).unwrap();
        assert_eq!(thread_allocations() - before, 0, "{integrator:?}");
    }
}
