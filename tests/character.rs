//! Articulated bodies (`kinema::character`): Featherstone's algorithms against each other
//! and against analytic solutions, conservation laws, observed orders, contact at rest,
//! stable PD's stability margin, ragdolls, several states of one model, snapshots.

use glam::{DMat3, DQuat, DVec3};
use kinema::character::spatial::{spatial, SVec};
use kinema::character::{
    ragdoll, ArticulatedBody, Body, Capsule, Integrator, Joint, Model, RagdollOptions, Servo,
    ServoMode, Settings, Solver, State, Tree,
};
use kinema::snapshot::{Snapshot, Stamped};

/// A small deterministic generator (xorshift64*), uniform in [-1, 1).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let x = self.0.wrapping_mul(0x2545_f491_4f6c_dd1d);
        (x >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
    fn vec(&mut self) -> DVec3 {
        DVec3::new(self.next(), self.next(), self.next())
    }
    fn below(&mut self, n: usize) -> usize {
        (((self.next() + 1.0) * 0.5 * n as f64) as usize).min(n - 1)
    }
}

fn free_settings() -> Settings {
    Settings { ground: false, ..Settings::default() }
}

fn body(
    parent: Option<usize>,
    joint: Joint,
    offset: DVec3,
    mass: f64,
    com: DVec3,
    inertia: DMat3,
) -> Body {
    Body {
        name: String::new(),
        parent,
        joint,
        offset,
        mass,
        com,
        inertia,
        shape: None,
        limits: None,
        damping: 0.0,
        servo: None,
    }
}

/// A random tree of `n` bodies with every joint kind, and a random state for it.
fn random_tree(rng: &mut Rng, n: usize) -> (Model, Vec<f64>, Vec<f64>) {
    let mut model =
        Model::new(Settings { gravity: DVec3::new(0.3, -9.81, 0.2), ..free_settings() });
    for i in 0..n {
        let joint = match rng.below(if i == 0 { 4 } else { 5 }) {
            0 => Joint::Revolute { axis: rng.vec() + DVec3::splat(0.1) },
            1 => Joint::Ball,
            2 => Joint::Free,
            3 => Joint::Planar,
            _ => Joint::Fixed,
        };
        let parent = if i == 0 { None } else { Some(rng.below(i)) };
        let a = DMat3::from_cols(rng.vec(), rng.vec(), rng.vec());
        let spd = a * a.transpose() + DMat3::from_diagonal(DVec3::splat(0.05));
        let inertia = (spd + spd.transpose()) * 0.5;
        let b =
            body(parent, joint, rng.vec(), 0.5 + rng.next().abs() * 3.0, 0.3 * rng.vec(), inertia);
        model.add_body(b).unwrap();
    }
    let mut state = State::new(&model);
    let q: Vec<f64> = (0..model.nq()).map(|_| rng.next() * 2.0).collect();
    state.set_q(&model, &q).unwrap();
    let qd: Vec<f64> = (0..model.nv()).map(|_| rng.next() * 3.0).collect();
    (model, state.q().to_vec(), qd)
}

fn solve(m: &nalgebra::DMatrix<f64>, b: &[f64]) -> Vec<f64> {
    let c = m.clone().cholesky().expect("M is positive definite");
    c.solve(&nalgebra::DVector::from_column_slice(b)).as_slice().to_vec()
}

#[test]
fn aba_agrees_with_crba_and_rnea_on_random_trees() {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    for case in 0..200 {
        let n = 1 + case % 9;
        let (model, q, qd) = random_tree(&mut rng, n);
        let nv = model.nv();
        let tau: Vec<f64> = (0..nv).map(|_| 5.0 * rng.next()).collect();
        let f_ext: Vec<SVec> = (0..n).map(|_| spatial(rng.vec(), 4.0 * rng.vec())).collect();
        let mut tree = Tree::default();
        tree.kinematics(&model, &q, &qd);
        tree.f_ext.copy_from_slice(&f_ext);
        let mut qdd = vec![0.0; nv];
        tree.aba(&model, &tau, &mut qdd);
        let mut bias = vec![0.0; nv];
        tree.rnea(&model, &vec![0.0; nv], &mut bias);
        tree.crba(&model);
        let m = tree.mass_matrix.clone();
        assert!((&m - m.transpose()).norm() <= 1e-12 * m.norm(), "M symmetric");
        let eig = m.clone().symmetric_eigen().eigenvalues;
        assert!(eig.iter().all(|&e| e > 0.0), "M positive definite, case {case}");
        let rhs: Vec<f64> = tau.iter().zip(&bias).map(|(t, c)| t - c).collect();
        let expect = solve(&m, &rhs);
        let scale = 1.0 + expect.iter().fold(0.0_f64, |a, b| a.max(b.abs()));
        for (a, b) in qdd.iter().zip(&expect) {
            assert!((a - b).abs() <= 1e-10 * scale, "case {case}: ABA {a} vs CRBA {b}");
        }
        // RNEA inverts the ABA: ID(q, q̇, FD(τ)) = τ.
        let mut back = vec![0.0; nv];
        tree.rnea(&model, &qdd, &mut back);
        for (a, b) in back.iter().zip(&tau) {
            assert!((a - b).abs() <= 1e-9 * (1.0 + scale), "case {case}: RNEA {a} vs τ {b}");
        }
        // The kinetic energy of the bodies equals ½ q̇ᵀ M q̇.
        let v = nalgebra::DVector::from_column_slice(&qd);
        let t = 0.5 * v.dot(&(&m * &v));
        assert!((t - tree.kinetic_energy(&model)).abs() <= 1e-10 * (1.0 + t), "case {case}");
    }
}

/// A chain of 3 hinges about z under a root of kind `root`, thrown in the x–y plane: the
/// planar root at `[x, y, θ]`, `[vx, vy, ω]`, the free root at the same planar pose.
fn thrown_chain(root: Joint) -> ArticulatedBody {
    let settings = Settings { integrator: Integrator::Rk4, ..free_settings() };
    let mut model = Model::new(settings);
    let inertia = DMat3::from_diagonal(DVec3::new(0.02, 0.003, 0.05));
    model.add_body(body(None, root, DVec3::ZERO, 3.0, DVec3::new(0.1, 0.2, 0.0), inertia)).unwrap();
    for i in 1..4 {
        let b = body(
            Some(i - 1),
            Joint::Revolute { axis: DVec3::Z },
            DVec3::new(0.3, -0.1, 0.0),
            1.0 + 0.5 * i as f64,
            DVec3::new(0.2, 0.05, 0.0),
            DMat3::from_diagonal(DVec3::new(0.01, 0.002, 0.02)),
        );
        model.add_body(b).unwrap();
    }
    let (x, y, th, vx, vy, w) = (0.2, 1.5, 0.7, 1.3, 2.0, -3.0);
    let mut c = ArticulatedBody::new(model);
    let (model, state) = c.parts_mut();
    let (mut q, mut qd) = (vec![], vec![]);
    if root == Joint::Planar {
        q.extend([x, y, th]);
        qd.extend([vx, vy, w]);
    } else {
        let r = DQuat::from_rotation_z(th);
        q.extend([x, y, 0.0, r.w, r.x, r.y, r.z]);
        // Free-joint rates: ω in body axes (z is z), v in parent axes.
        qd.extend([0.0, 0.0, w, vx, vy, 0.0]);
    }
    q.extend([0.4, -0.8, 1.1]);
    qd.extend([2.0, -1.0, 0.5]);
    state.set_q(model, &q).unwrap();
    state.set_qd(&qd).unwrap();
    c
}

#[test]
fn a_planar_root_moves_as_a_free_root_kept_in_the_plane() {
    let (mut planar, mut free) = (thrown_chain(Joint::Planar), thrown_chain(Joint::Free));
    for _ in 0..4 {
        planar.step(1e-3, 250).unwrap();
        free.step(1e-3, 250).unwrap();
        let (a, b) = (planar.kinematics().positions().to_vec(), free.kinematics().positions());
        for (p, f) in a.iter().zip(b) {
            assert!((*p - *f).length() < 1e-9, "planar {p} vs free {f}");
        }
    }
    assert!(planar.com().y < 0.0, "the chain falls under gravity");
}

/// A hinge about z at the origin holding a body of `mass` with its centre of mass at
/// `(0, −length, 0)` and inertia `ic` about it.
fn pendulum(length: f64, mass: f64, ic: f64, integrator: Integrator) -> ArticulatedBody {
    let mut model = Model::new(Settings { integrator, ..free_settings() });
    let inertia = DMat3::from_diagonal(DVec3::splat(ic));
    let b = body(
        None,
        Joint::Revolute { axis: DVec3::Z },
        DVec3::ZERO,
        mass,
        -length * DVec3::Y,
        inertia,
    );
    model.add_body(b).unwrap();
    ArticulatedBody::new(model)
}

#[test]
fn pendulum_has_its_small_angle_period_and_keeps_its_energy() {
    let (l, m, ic) = (0.8, 2.0, 0.01);
    let mut p = pendulum(l, m, ic, Integrator::Rk4);
    let theta0 = 1e-3;
    let (model, state) = p.parts_mut();
    state.set_q(model, &[theta0]).unwrap();
    let period = 2.0 * std::f64::consts::PI * ((ic + m * l * l) / (m * 9.81 * l)).sqrt();
    let dt = 1e-3;
    let mut crossings = Vec::new();
    let mut last = theta0;
    for k in 1..=6000 {
        p.step(dt, 1).unwrap();
        let now = p.state().q()[0];
        if last > 0.0 && now <= 0.0 {
            crossings.push((k - 1) as f64 * dt + dt * last / (last - now));
        }
        last = now;
    }
    let measured = crossings[2] - crossings[1];
    eprintln!("period {measured} vs {period}: {:e}", measured / period - 1.0);
    assert!((measured / period - 1.0).abs() < 1e-5, "period {measured} vs {period}");
    // At a large amplitude RK4 keeps the energy to its order.
    let mut p = pendulum(l, m, ic, Integrator::Rk4);
    let (model, state) = p.parts_mut();
    state.set_q(model, &[1.2]).unwrap();
    let e0 = {
        let (t, v) = p.energy();
        t + v
    };
    p.step(1e-3, 2000).unwrap();
    let e1 = {
        let (t, v) = p.energy();
        t + v
    };
    assert!((e1 - e0).abs() < 1e-9 * e0.abs().max(1.0), "energy {e0} -> {e1}");
}

/// A planar chain of `n` hinged rods of length 0.5 m hanging from the origin, bent.
fn chain(n: usize, integrator: Integrator) -> ArticulatedBody {
    let mut model = Model::new(Settings { integrator, ..free_settings() });
    for i in 0..n {
        let inertia = DMat3::from_diagonal(DVec3::new(0.02, 0.001, 0.02));
        let offset = if i == 0 { DVec3::ZERO } else { DVec3::new(0.5, 0.0, 0.0) };
        let b = body(
            i.checked_sub(1),
            Joint::Revolute { axis: DVec3::Z },
            offset,
            1.0,
            DVec3::new(0.25, 0.0, 0.0),
            inertia,
        );
        model.add_body(b).unwrap();
    }
    let mut c = ArticulatedBody::new(model);
    let q: Vec<f64> = (0..n).map(|i| if i == 0 { 0.3 } else { 0.4 }).collect();
    let (model, state) = c.parts_mut();
    state.set_q(model, &q).unwrap();
    c
}

/// Largest energy deviation over 1 s of the 3-link chain at step `dt`.
fn energy_drift(integrator: Integrator, dt: f64) -> f64 {
    let mut c = chain(3, integrator);
    let e = |c: &mut ArticulatedBody| {
        let (t, v) = c.energy();
        t + v
    };
    let e0 = e(&mut c);
    let steps = (1.0 / dt).round() as usize;
    let mut worst = 0.0_f64;
    for _ in 0..steps {
        c.step(dt, 1).unwrap();
        worst = worst.max((e(&mut c) - e0).abs());
    }
    worst
}

#[test]
fn chain_energy_is_conserved_to_the_integrators_order() {
    for (integrator, order) in [(Integrator::Rk4, 4.0), (Integrator::SymplecticEuler, 1.0)] {
        let errors: Vec<f64> =
            [0.004, 0.002, 0.001].iter().map(|&dt| energy_drift(integrator, dt)).collect();
        for w in errors.windows(2) {
            let observed = (w[0] / w[1]).log2();
            assert!(
                (observed - order).abs() < 0.3,
                "{integrator:?}: order {observed}, errors {errors:?}"
            );
        }
    }
}

#[test]
fn spinning_free_body_keeps_its_angular_momentum() {
    let mut model = Model::new(Settings {
        gravity: DVec3::ZERO,
        integrator: Integrator::Rk4,
        ..free_settings()
    });
    let inertia = DMat3::from_diagonal(DVec3::new(0.1, 0.3, 0.5));
    model
        .add_body(body(None, Joint::Free, DVec3::ZERO, 2.0, DVec3::new(0.1, 0.0, -0.05), inertia))
        .unwrap();
    let mut b = ArticulatedBody::new(model);
    b.state_mut().set_qd(&[0.2, 3.0, 0.1, 0.5, -0.2, 0.3]).unwrap();
    let m = b.model().clone();
    let h0 = b.kinematics().momentum(&m);
    b.step(1e-3, 3000).unwrap();
    let h1 = b.kinematics().momentum(&m);
    let drift = (h1.0 - h0.0).length() / h0.0.length();
    eprintln!("angular momentum drift {drift:e}");
    assert!(drift < 1e-6, "angular {:?} -> {:?}", h0.0, h1.0);
    assert!((h1.1 - h0.1).length() < 1e-6 * h0.1.length(), "linear {:?} -> {:?}", h0.1, h1.1);
}

#[test]
fn a_dropped_ball_rests_at_the_documented_penetration() {
    let mut model = Model::new(Settings::default());
    let shape = Capsule { a: DVec3::ZERO, b: DVec3::ZERO, radius: 0.1 };
    let (mass, com, inertia) = shape.mass_properties(1000.0);
    let b = Body {
        shape: Some(shape),
        ..body(None, Joint::Free, DVec3::new(0.0, 0.5, 0.0), mass, com, inertia)
    };
    model.add_body(b).unwrap();
    let mut ball = ArticulatedBody::new(model);
    ball.step(1.0 / 240.0, 720).unwrap();
    let depth = 0.1 - (0.5 + ball.state().q()[1]);
    let w = Settings::default().contact_frequency;
    let expect = 9.81 / (w * w);
    assert!((depth / expect - 1.0).abs() < 1e-3, "depth {depth} vs g/ω² = {expect}");
    assert!(ball.energy().0 < 1e-10);
}

/// A chain of `n` capsules on a free root, lying bent in the air.
fn capsule_chain(n: usize, height: f64) -> ArticulatedBody {
    let mut model = Model::new(Settings::default());
    for i in 0..n {
        let shape = Capsule { a: DVec3::ZERO, b: DVec3::new(0.4, 0.0, 0.0), radius: 0.05 };
        let (mass, com, inertia) = shape.mass_properties(1000.0);
        let (joint, offset) = if i == 0 {
            (Joint::Free, DVec3::new(0.0, height, 0.0))
        } else {
            (Joint::Ball, DVec3::new(0.4, 0.0, 0.0))
        };
        let b = Body {
            shape: Some(shape),
            damping: 0.05,
            ..body(i.checked_sub(1), joint, offset, mass, com, inertia)
        };
        model.add_body(b).unwrap();
    }
    let mut c = ArticulatedBody::new(model);
    let (model, state) = c.parts_mut();
    let mut q = state.q().to_vec();
    let tilt = DQuat::from_rotation_z(0.4) * DQuat::from_rotation_x(0.3);
    q[3..7].copy_from_slice(&[tilt.w, tilt.x, tilt.y, tilt.z]);
    for i in 1..n {
        let bend = DQuat::from_rotation_y(0.5);
        q[7 + 4 * (i - 1)..11 + 4 * (i - 1)].copy_from_slice(&[bend.w, bend.x, bend.y, bend.z]);
    }
    state.set_q(model, &q).unwrap();
    c
}

#[test]
fn a_dropped_chain_comes_to_rest_on_the_ground() {
    let mut c = capsule_chain(4, 1.0);
    let (t0, v0) = c.energy();
    let mut last = t0 + v0;
    for _ in 0..12 {
        c.step(1.0 / 480.0, 240).unwrap();
        let (t, v) = c.energy();
        // Contact and damping only take energy out (to the springs' stored energy).
        assert!(t + v < last + 0.05, "energy rose: {last} -> {}", t + v);
        last = t + v;
    }
    let (t, _) = c.energy();
    assert!(t < 1e-4, "kinetic energy at the end {t}");
    let tree = c.kinematics();
    let lowest = (0..4)
        .flat_map(|i| {
            [
                tree.positions()[i],
                tree.positions()[i] + tree.orientations()[i] * DVec3::new(0.4, 0.0, 0.0),
            ]
        })
        .map(|p| p.y - 0.05)
        .fold(f64::INFINITY, f64::min);
    assert!(lowest > -0.01 && lowest < 1e-3, "lowest point {lowest}");
}

/// Whether a gravity-free 3-link chain with PD servos of gain `kp` (`kd = kp / 10`) stays
/// bounded over 10 s at step `dt` from a bent start (rates below 100 rad/s, no divergence),
/// and its largest final joint error (rad).
fn servo_run(mode: ServoMode, kp: f64, dt: f64) -> (bool, f64) {
    let mut c = chain(3, Integrator::SymplecticEuler);
    c.model_mut().settings.servo_mode = mode;
    c.model_mut().settings.gravity = DVec3::ZERO;
    for i in 0..3 {
        c.model_mut()
            .set_servo(i, Some(Servo { kp, kd: kp / 10.0, max_torque: f64::INFINITY }))
            .unwrap();
    }
    let target = [-1.2, 0.5, 0.5];
    let (model, state) = c.parts_mut();
    state.set_targets(model, &target).unwrap();
    let mut worst = 0.0_f64;
    for _ in 0..600 {
        if c.step(dt, 1).is_err() {
            return (false, f64::INFINITY);
        }
        worst = worst.max(c.state().qd().iter().fold(0.0_f64, |a, b| a.max(b.abs())));
    }
    let err = c.state().q().iter().zip(target).fold(0.0_f64, |a, (q, t)| a.max((q - t).abs()));
    (worst < 100.0, err)
}

#[test]
fn stable_pd_is_stable_at_ten_times_the_explicit_limit() {
    let dt = 1.0 / 60.0;
    // The largest gain of the grid 2^(k/4) at which explicit PD still settles.
    let grid: Vec<f64> = (0..80).map(|k| 2f64.powf(k as f64 / 4.0)).collect();
    let limit = grid
        .iter()
        .copied()
        .take_while(|&kp| servo_run(ServoMode::Explicit, kp, dt).0)
        .last()
        .unwrap();
    assert!(
        limit > 1.0 && !servo_run(ServoMode::Explicit, 2.0 * limit, dt).0,
        "explicit limit {limit}"
    );
    for factor in [10.0, 100.0] {
        let (bounded, err) = servo_run(ServoMode::Stable, factor * limit, dt);
        assert!(bounded && err < 1e-3, "stable PD at {factor} x {limit}: error {err}");
    }
    eprintln!("explicit PD limit at dt = 1/60: kp = {limit} N m/rad");
}

#[test]
fn two_states_of_one_model_step_as_if_alone() {
    let c = capsule_chain(3, 0.6);
    let model = c.model().clone();
    let mut a = c.state().clone();
    let mut b = c.state().clone();
    b.set_qd(&[0.0, 1.0, 0.0, 0.5, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, -2.0, 0.0]).unwrap();
    b.push(&model, 1, DVec3::new(30.0, 0.0, 0.0), 0.1).unwrap();
    let (mut alone_a, mut alone_b) = (a.clone(), b.clone());
    let mut shared = Solver::new(&model);
    for _ in 0..50 {
        let before_b = b.clone();
        shared.step(&model, &mut a, 1.0 / 240.0, 3).unwrap();
        assert_eq!(b, before_b, "stepping one state leaves the other unchanged");
        shared.step(&model, &mut b, 1.0 / 240.0, 3).unwrap();
    }
    Solver::new(&model).step(&model, &mut alone_a, 1.0 / 240.0, 150).unwrap();
    Solver::new(&model).step(&model, &mut alone_b, 1.0 / 240.0, 150).unwrap();
    assert_eq!(a, alone_a);
    assert_eq!(b, alone_b);
}

#[test]
fn snapshots_resume_bit_for_bit_and_refuse_another_model() {
    let mut c = capsule_chain(3, 0.6);
    c.step(1.0 / 240.0, 100).unwrap();
    let bytes = c.to_snapshot().unwrap();
    let mut back = ArticulatedBody::from_snapshot(&bytes).unwrap();
    c.step(1.0 / 240.0, 100).unwrap();
    back.step(1.0 / 240.0, 100).unwrap();
    assert_eq!(c.state(), back.state());
    let state_bytes = c.state().to_snapshot(c.model()).unwrap();
    assert_eq!(&State::from_snapshot(c.model(), &state_bytes).unwrap(), c.state());
    let other = capsule_chain(4, 0.6);
    let err = State::from_snapshot(other.model(), &state_bytes).unwrap_err();
    assert!(err.to_string().contains("model"), "{err}");
}

#[test]
fn a_failed_step_leaves_the_state_as_it_was() {
    let mut c = chain(3, Integrator::SymplecticEuler);
    c.state_mut().set_torques(&[1e12, -1e12, 1e12]).unwrap();
    let before = c.state().clone();
    assert!(c.step(0.01, 50).is_err());
    assert_eq!(c.state(), &before);
    assert!(c.step(f64::NAN, 1).is_err());
}

#[test]
fn a_limp_ragdoll_falls_and_rests_on_the_ground() {
    let text = std::fs::read_to_string("tests/data/mocap/07-walk.asf").unwrap();
    let skeleton = kinema::mocap::parse_asf(&text, "07-walk.asf").unwrap();
    let options = RagdollOptions {
        scale: skeleton.metres_per_unit(),
        clearance: 0.3,
        ..RagdollOptions::default()
    };
    let model = ragdoll(&skeleton, &options, Settings::default()).unwrap();
    assert_eq!(model.bodies().len(), skeleton.bones.len() + 1);
    let mass = model.mass();
    assert!(mass > 20.0 && mass < 120.0, "ragdoll mass {mass} kg");
    eprintln!("ragdoll mass {mass} kg");
    let mut r = ArticulatedBody::new(model);
    let total = |r: &mut ArticulatedBody| {
        let (t, v) = r.energy();
        t + v
    };
    let e0 = total(&mut r);
    r.step(1.0 / 480.0, 480 * 3).unwrap();
    let e1 = total(&mut r);
    assert!(e1 < e0 - 0.2 * 9.81 * mass, "energy {e0} -> {e1}");
    assert!(r.energy().0 < 0.5, "still moving: {} J", r.energy().0);
    assert!(r.state().q().iter().all(|v| v.is_finite()));
    let model = r.model().clone();
    let tree = r.kinematics();
    let lowest = model
        .bodies()
        .iter()
        .enumerate()
        .filter_map(|(i, b)| b.shape.map(|s| (i, s)))
        .flat_map(|(i, s)| {
            [s.a, s.b].map(|p| (tree.positions()[i] + tree.orientations()[i] * p).y - s.radius)
        })
        .fold(f64::INFINITY, f64::min);
    assert!(lowest > -0.02, "deepest penetration {lowest} m");
}

/// The bits of everything a step changes: coordinates, rates, targets, torques, time.
fn bits(s: &State) -> (Vec<u64>, u64, usize) {
    let values = s.q().iter().chain(s.qd()).chain(s.targets()).chain(s.torques());
    (values.map(|v| v.to_bits()).collect(), s.time().to_bits(), s.pushes().len())
}

#[test]
fn a_ragdoll_that_diverges_mid_call_is_put_back_bit_for_bit() {
    let text = std::fs::read_to_string("tests/data/mocap/07-walk.asf").unwrap();
    let skeleton = kinema::mocap::parse_asf(&text, "07-walk.asf").unwrap();
    let options = RagdollOptions {
        scale: skeleton.metres_per_unit(),
        clearance: 0.3,
        ..RagdollOptions::default()
    };
    let mut r = ArticulatedBody::new(ragdoll(&skeleton, &options, Settings::default()).unwrap());
    r.step(1.0 / 480.0, 60).unwrap();
    // An absurd explicit PD servo on every hinge and ball joint, aimed at the current pose:
    // stable for no step (kd dt / I far above 2), so the state explodes within a few steps.
    r.model_mut().settings.servo_mode = ServoMode::Explicit;
    for b in 1..r.model().bodies().len() {
        if matches!(r.model().bodies()[b].joint, Joint::Revolute { .. } | Joint::Ball) {
            let servo = Servo { kp: 1e9, kd: 1e9, max_torque: f64::INFINITY };
            r.model_mut().set_servo(b, Some(servo)).unwrap();
        }
    }
    let (model, state) = r.parts_mut();
    let q = state.q().to_vec();
    state.set_targets(model, &q).unwrap();
    let before = bits(r.state());
    let err = r.step(1.0 / 480.0, 100).unwrap_err();
    assert!(
        matches!(err, kinema::Error::Diverged { step, .. } if step > 0),
        "expected a divergence after the first step, got {err}"
    );
    assert_eq!(bits(r.state()), before, "the failed call left the state changed");
}
