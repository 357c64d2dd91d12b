//! The cloth as Model / State / Solver (issue #20): two states of one model stepped by one
//! solver in any interleaving are bit for bit the states stepped alone with their own solvers,
//! and stepping one leaves the other untouched; state snapshots carry the model's fingerprint.

use glam::DVec3;
use kinema::cloth::{
    Cloth, Collider, Elasticity, LinearSolver, Material, Mesh, Model, SolveOptions, Solver, State,
    Triangulation,
};
use kinema::geometry::{Shape, Sphere};
use kinema::ode::Method;
use kinema::snapshot::Stamped;
use kinema::Error;

const G: DVec3 = DVec3::new(0.0, -9.81, 0.0);

fn model(elasticity: Elasticity) -> Model {
    let mesh = Mesh::grid(7, 7, 1.0, 1.0, Triangulation::Alternating).unwrap();
    Model::new(mesh, elasticity, Material::default(), G).unwrap()
}

/// Two different states of `model`: both pinned at two corners above a sphere (so contacts,
/// their warm-started impulses, the BDF2 history and the PCG warm start all matter), the second
/// shifted, moving sideways and pinned at other corners.
fn two_states(model: &Model) -> (State, State) {
    let sphere = |x: f64| Collider {
        shape: Shape::Sphere(Sphere { center: DVec3::new(x, -0.35, 0.0), radius: 0.3 }),
        velocity: DVec3::new(0.0, 0.1, 0.0),
        friction: 0.4,
    };
    let mut a = model.state();
    a.pin(&[0, 6], None).unwrap();
    a.add_collider(sphere(0.0)).unwrap();
    let mut b = model.state();
    let x: Vec<DVec3> = b.positions().iter().map(|p| *p + DVec3::new(0.1, 0.05, 0.0)).collect();
    let v = vec![DVec3::new(0.3, 0.0, -0.2); x.len()];
    b.set_motion(&x, &v).unwrap();
    b.pin(&[42, 48], None).unwrap();
    b.add_collider(sphere(0.2)).unwrap();
    (a, b)
}

/// A mix of every path: BDF2 and implicit Euler with any linear solver, and an explicit one.
const RUNS: [(Method, LinearSolver, f64); 6] = [
    (Method::Bdf2, LinearSolver::BlockSsor, 0.01),
    (Method::ImplicitEuler, LinearSolver::Multigrid, 0.01),
    (Method::Bdf2, LinearSolver::BlockSsor, 0.02),
    (Method::ImplicitEuler, LinearSolver::Cholesky, 0.01),
    (Method::Bdf2, LinearSolver::Cholesky, 0.01),
    (Method::Rk4, LinearSolver::BlockSsor, 1e-4),
];

fn step(solver: &mut Solver, model: &Model, state: &mut State, run: usize) {
    let (method, linear, dt) = RUNS[run % RUNS.len()];
    let options = SolveOptions { solver: linear, ..SolveOptions::default() };
    solver.step(model, state, dt, 1, method, options).unwrap();
}

/// The state's bits (its snapshot).
fn bits(model: &Model, state: &State) -> Vec<u8> {
    state.to_snapshot(model).unwrap()
}

#[test]
fn two_states_of_one_model_share_one_solver_bit_for_bit() {
    for elasticity in [Elasticity::BaraffWitkin, Elasticity::MassSpring] {
        let model = model(elasticity);
        let (a0, b0) = two_states(&model);
        // Each alone, with its own fresh solver: the trajectories after every step.
        let alone = |mut s: State| {
            let mut solver = Solver::new(&model);
            (0..12)
                .map(|k| {
                    step(&mut solver, &model, &mut s, k);
                    bits(&model, &s)
                })
                .collect::<Vec<_>>()
        };
        let (ta, tb) = (alone(a0.clone()), alone(b0.clone()));
        assert_ne!(ta, tb, "different initial conditions, different trajectories");
        // Interleaved on one solver, in an irregular order.
        let mut solver = Solver::new(&model);
        let (mut a, mut b) = (a0, b0);
        let (mut ka, mut kb) = (0, 0);
        for turn in [0, 1, 1, 0, 0, 0, 1, 0, 1, 1, 1, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 1, 1, 0] {
            let (mine, other, k) =
                if turn == 0 { (&mut a, &b, &mut ka) } else { (&mut b, &a, &mut kb) };
            let before = bits(&model, other);
            step(&mut solver, &model, mine, *k);
            assert_eq!(bits(&model, other), before, "stepping one state changed the other");
            let expected = if turn == 0 { &ta[*k] } else { &tb[*k] };
            assert!(bits(&model, mine) == *expected, "{elasticity:?}: step {k} of state {turn}");
            *k += 1;
        }
        assert_eq!((ka, kb), (12, 12));
    }
}

/// The composed `Cloth` is the model, a state and a solver: a state taken from it and stepped
/// with a solver of its model is bit for bit the cloth's own trajectory, and a state put back
/// with `clone_from` resumes it.
#[test]
fn cloth_is_model_state_and_solver() {
    let mesh = Mesh::grid(6, 6, 1.0, 1.0, Triangulation::Regular).unwrap();
    let mut cloth = Cloth::new(mesh, Elasticity::BaraffWitkin, Material::default(), G).unwrap();
    cloth.pin(&[0, 5], None).unwrap();
    let options = SolveOptions::default();
    cloth.step(0.01, 3, Method::Bdf2, options).unwrap();
    let (model, mut state) = (cloth.model().clone(), cloth.state().clone());
    let mark = state.clone();
    let mut solver = Solver::new(&model);
    solver.step(&model, &mut state, 0.01, 4, Method::Bdf2, options).unwrap();
    cloth.step(0.01, 4, Method::Bdf2, options).unwrap();
    assert!(bits(&model, &state) == bits(&model, cloth.state()));
    assert_eq!(solver.stats().iterations, cloth.stats().iterations);
    let x = cloth.positions().as_ptr();
    cloth.state_mut().clone_from(&mark);
    assert_eq!(cloth.positions().as_ptr(), x, "buffers copied into, not replaced");
    cloth.step(0.01, 4, Method::Bdf2, options).unwrap();
    assert!(bits(&model, &state) == bits(&model, cloth.state()));
}

/// A state snapshot resumes bit for bit on its model and is refused, naming the argument, on a
/// model with another fingerprint or when the bytes are not a cloth state; a state of another
/// size is refused by a step, which leaves it unchanged.
#[test]
fn state_snapshots_are_stamped_with_the_model_fingerprint() {
    let model = model(Elasticity::BaraffWitkin);
    let (mut a, _) = two_states(&model);
    let mut solver = Solver::new(&model);
    solver.step(&model, &mut a, 0.01, 3, Method::Bdf2, SolveOptions::default()).unwrap();
    let saved = a.to_snapshot(&model).unwrap();
    let restored = State::from_snapshot(&model, &saved).unwrap();
    assert!(bits(&model, &restored) == saved);
    assert_eq!(model.fingerprint(), model.clone().fingerprint());

    let mut thicker = model.clone();
    thicker.set_thickness(2e-3).unwrap();
    assert_ne!(thicker.fingerprint(), model.fingerprint());
    let arg = |r: kinema::Result<State>| match r.unwrap_err() {
        Error::InvalidInput { arg, .. } => arg,
        other => panic!("{other:?}"),
    };
    assert_eq!(arg(State::from_snapshot(&thicker, &saved)), "model");
    assert_eq!(arg(State::from_snapshot(&model, b"kinema:Cloth:junk")), "data");

    let small = Mesh::grid(3, 3, 1.0, 1.0, Triangulation::Regular).unwrap();
    let other = Model::new(small, Elasticity::BaraffWitkin, Material::default(), G).unwrap();
    let mut wrong = other.state();
    let before = bits(&other, &wrong);
    let err = solver.step(&model, &mut wrong, 0.01, 1, Method::Bdf2, SolveOptions::default());
    assert!(matches!(err, Err(Error::InvalidInput { ref arg, .. }) if arg == "state"), "{err:?}");
    assert!(bits(&other, &wrong) == before);
}
