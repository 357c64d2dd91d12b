//! Model / State / Solver of the rigid world: several states of one model advanced by one
//! solver in any interleaving, each bit for bit as alone with a solver of its own; states
//! share nothing mutable; state snapshots carry the model's fingerprint.

use glam::{DQuat, DVec3};
use kinema::geometry::Solid as Shape;
use kinema::rigid::{
    BodyDesc, JointDesc, JointKind, JointMethod, Model, RotationIntegrator, Solver, State, World,
    PENALTY_DAMPING, PENALTY_STIFFNESS,
};
use kinema::snapshot::Stamped;

const G: DVec3 = DVec3::new(0.0, -9.81, 0.0);
const DT: f64 = 1.0 / 120.0;

fn body(shape: Shape, position: DVec3, angle: f64) -> BodyDesc {
    BodyDesc {
        shape,
        density: None,
        mass: Some(1.0),
        position,
        orientation: DQuat::from_rotation_z(angle),
        velocity: DVec3::ZERO,
        angular_velocity: DVec3::ZERO,
        fixed: false,
        restitution: 0.1,
        friction: 0.5,
    }
}

/// A model that reads every warm start: a stack of boxes on the ground (contacts warm-start
/// from the previous step), a box and a sphere touching each other, and a chain of two hinged
/// bars, one joint by impulses (warm-started) and one by Lagrange multipliers.
fn model() -> Model {
    let mut m = Model::new(G, RotationIntegrator::Splitting);
    m.add_plane(DVec3::Y, 0.0, 0.1, 0.5).unwrap();
    for k in 0..3 {
        let half = DVec3::splat(0.1);
        let p = DVec3::new(0.02 * k as f64, 0.1 + 0.205 * k as f64, 0.0);
        m.add_body(&body(Shape::Box { half_extents: half }, p, 0.05 * k as f64)).unwrap();
    }
    m.add_body(&body(Shape::Sphere { radius: 0.1 }, DVec3::new(0.5, 0.1, 0.0), 0.0)).unwrap();
    let bar = Shape::Box { half_extents: DVec3::new(0.2, 0.02, 0.02) };
    for (i, method) in [(0, JointMethod::Impulse), (1, JointMethod::Lagrange)] {
        let a = m.add_body(&body(bar.clone(), DVec3::new(1.2 + 0.4 * i as f64, 0.6, 0.0), 0.0));
        let a = a.unwrap();
        let desc = JointDesc {
            kind: JointKind::Hinge { limits: Some((-0.5, 0.5)), motor: None },
            method,
            a,
            b: if i == 0 { None } else { Some(a - 1) },
            anchor: DVec3::new(1.0 + 0.4 * i as f64, 0.6, 0.0),
            axis: DVec3::Z,
            stiffness: PENALTY_STIFFNESS,
            damping: PENALTY_DAMPING,
        };
        let pose = m.state();
        m.add_joint(&desc, &pose).unwrap();
    }
    m
}

/// A second initial condition: the stack's top box thrown sideways, the sphere rolling, the
/// chain pushed, and a force on the first box in the first step.
fn other_state(m: &Model) -> State {
    let mut s = m.state();
    s.v[2] = DVec3::new(0.8, 0.5, 0.1);
    s.v[3] = DVec3::new(-1.0, 0.0, 0.0);
    s.v[5] = DVec3::new(0.0, 0.0, 0.7);
    s.apply_force(0, DVec3::new(3.0, 0.0, 0.0), DVec3::new(0.0, 0.15, 0.05)).unwrap();
    s
}

/// The state's every bit (bodies, applied forces, contacts and joint warm starts).
fn bits(m: &Model, s: &State) -> Vec<u8> {
    s.to_snapshot(m).unwrap()
}

/// The trajectory of `s` stepped alone with a fresh solver: its bits after each step.
fn alone(m: &Model, mut s: State, steps: usize) -> Vec<Vec<u8>> {
    let mut solver = Solver::new(m).unwrap();
    (0..steps)
        .map(|_| {
            solver.step(m, &mut s, DT, 1).unwrap();
            bits(m, &s)
        })
        .collect()
}

#[test]
fn two_states_of_one_model_share_one_solver_bit_for_bit() {
    let m = model();
    let steps = 120;
    let (a0, b0) = (m.state(), other_state(&m));
    let (alone_a, alone_b) = (alone(&m, a0.clone(), steps), alone(&m, b0.clone(), steps));
    assert_ne!(alone_a.last(), alone_b.last(), "the two initial conditions must differ");
    let mut solver = Solver::new(&m).unwrap();
    let (mut a, mut b) = (a0, b0);
    // Interleaved unevenly: a, b, b, a, ... so that each step follows the other state's.
    let (mut ka, mut kb) = (0, 0);
    for round in 0..2 * steps {
        let step_a = (round % 3 == 0 && ka < steps) || kb == steps;
        let (mine, other, k, want) =
            if step_a { (&mut a, &b, &mut ka, &alone_a) } else { (&mut b, &a, &mut kb, &alone_b) };
        let before = bits(&m, other);
        solver.step(&m, mine, DT, 1).unwrap();
        assert_eq!(bits(&m, other), before, "stepping one state changed the other");
        assert!(bits(&m, mine) == want[*k], "state {} differs at step {k}", round % 3);
        *k += 1;
        if ka == steps && kb == steps {
            break;
        }
    }
    assert_eq!((ka, kb), (steps, steps));
}

#[test]
fn a_state_snapshot_resumes_bit_for_bit_and_refuses_another_model() {
    let m = model();
    let mut solver = Solver::new(&m).unwrap();
    let mut s = other_state(&m);
    solver.step(&m, &mut s, DT, 30).unwrap();
    let bytes = s.to_snapshot(&m).unwrap();
    let mut restored = State::from_snapshot(&m, &bytes).unwrap();
    let mut fresh = Solver::new(&m).unwrap();
    solver.step(&m, &mut s, DT, 30).unwrap();
    fresh.step(&m, &mut restored, DT, 30).unwrap();
    assert_eq!(bits(&m, &s), bits(&m, &restored));
    // Another model: one setting changed is enough.
    let mut changed = model();
    changed.contact_iterations += 1;
    assert_ne!(changed.fingerprint(), m.fingerprint());
    assert_eq!(model().fingerprint(), m.fingerprint());
    let err = State::from_snapshot(&changed, &bytes).unwrap_err().to_string();
    assert!(err.contains("model"), "{err}");
    // A state of another number of bodies cannot be stepped, nor set into a world.
    let mut small = Model::new(G, RotationIntegrator::Splitting);
    small.add_body(&body(Shape::Sphere { radius: 0.1 }, DVec3::Y, 0.0)).unwrap();
    let err = solver.step(&m, &mut small.state(), DT, 1).unwrap_err().to_string();
    assert!(err.contains("state"), "{err}");
    let mut w = World::new(G, RotationIntegrator::Splitting);
    assert!(w.set_state(&s).unwrap_err().to_string().contains("state"));
}

#[test]
fn a_world_is_its_model_state_and_solver() {
    let m = model();
    let mut s = other_state(&m);
    let mut world = World::from_model(m.clone());
    world.set_state(&s).unwrap();
    Solver::new(&m).unwrap().step(&m, &mut s, DT, 40).unwrap();
    world.step(DT, 40).unwrap();
    assert_eq!(bits(&m, world.state()), bits(&m, &s));
    assert_eq!(world.model().fingerprint(), m.fingerprint());
    // A body added after stepping enters the state as added, the others go on.
    let extra = body(Shape::Sphere { radius: 0.05 }, DVec3::new(-1.0, 2.0, 0.0), 0.0);
    let i = world.add_body(&extra).unwrap();
    assert_eq!(world.state().len(), i + 1);
    assert_eq!(world.position(i), DVec3::new(-1.0, 2.0, 0.0));
    assert_eq!(world.position(0), s.position(&m, 0));
}
