//! Kinematic (moving) colliders of articulated bodies (`Model::set_collider`): a ball
//! dropped on a moving belt rolls at the analytic 2/7 of the belt's speed, a ragdoll lying on
//! a moving platform is carried with it (explicit and under stable PD), a capsule on a
//! turntable turns with it, and a failed step leaves the body and its collider where they
//! were.

mod articulated;

use articulated::{capsule, cmu_ragdoll};
use glam::{DQuat, DVec3};
use kinema::character::{ArticulatedBody, Collider, Joint, Model, Servo, ServoMode, Settings};
use kinema::geometry::{Cuboid, Shape};

/// A box of half extents `half` at `center`, level.
fn platform(center: DVec3, half: DVec3) -> Shape {
    Shape::Box(Cuboid { center, rotation: DQuat::IDENTITY, half })
}

/// Make collider `i` of `body` move at `velocity` from where it is now.
fn moving(body: &mut ArticulatedBody, i: usize, velocity: DVec3) {
    let time = body.state().time();
    let c = body.model().colliders()[i];
    let moved = Collider { shape: c.at(time), velocity, since: time, ..c };
    body.model_mut().set_collider(i, moved).unwrap();
}

/// A solid ball resting on a belt that moves at `V` (a box translating along x) is dragged by
/// friction until its contact point moves with the belt, rolling without slipping: the
/// friction impulse `J` gives `m v = J` and `I ω = r J`, so `v + ω r = V` with `I = 2/5 m r²`
/// ends at `v = 2V/7` (and `ω r = 5V/7`), whatever μ. Measured after 2 s (regularised
/// friction: the last of the slip decays as a viscous drag): within 0.5 % of both, the
/// contact point's slip below 1e-3 m/s. With the collider's velocity left out of the friction
/// (a belt that moves but drags nothing) the ball stays at rest.
#[test]
fn a_ball_on_a_moving_belt_rolls_at_two_sevenths_of_its_speed() {
    let (r, speed) = (0.1, 1.0);
    let settings = Settings { ground: false, ..Settings::default() };
    let sink = 9.81 / settings.contact_frequency.powi(2);
    let mut model = Model::new(settings);
    model.add_body(capsule(DVec3::ZERO, DVec3::ZERO, r, DVec3::new(0.0, r - sink, 0.0))).unwrap();
    model
        .add_collider(platform(DVec3::new(0.0, -0.5, 0.0), DVec3::new(50.0, 0.5, 2.0)), None)
        .unwrap();
    let mut ball = ArticulatedBody::new(model);
    moving(&mut ball, 0, DVec3::new(speed, 0.0, 0.0));
    ball.step(1e-3, 2000).unwrap();
    let qd = ball.state().qd();
    // Free joint rates: [ω (body axes); v (world)]; the ball turns about z.
    let q = ball.state().q();
    let turn = DQuat::from_xyzw(q[4], q[5], q[6], q[3]);
    let omega = turn * DVec3::new(qd[0], qd[1], qd[2]);
    let v = DVec3::new(qd[3], qd[4], qd[5]);
    let contact = v + omega.cross(DVec3::new(0.0, -r, 0.0));
    println!("v = {v}, ω r = {}, contact {contact}", omega * r);
    assert!((v.x / speed - 2.0 / 7.0).abs() < 0.005 * 2.0 / 7.0, "v = {v}");
    assert!((omega.z * r / speed - 5.0 / 7.0).abs() < 0.005 * 5.0 / 7.0, "ω = {omega}");
    assert!((contact.x - speed).abs() < 1e-3, "slip {}", contact.x - speed);
}

/// The limp CMU 07 ragdoll (31.7 kg) dropped lying on its back onto a platform (a box, its
/// top 0.4 m above the ground) moving at 0.5 m/s along x is carried with it: its centre of
/// mass moves 0.5 m in the last second of 4 s to 1 %, and it is still on the platform. The
/// same with stable PD servos holding its pose (the contacts' damping then implicit, relative
/// to the platform). Without the platform's velocity in the contacts it slides off behind.
#[test]
fn a_ragdoll_lying_on_a_moving_platform_is_carried_with_it() {
    let speed = 0.5;
    for servos in [false, true] {
        let mut r = ArticulatedBody::new(cmu_ragdoll(0.0, Settings::default()));
        let top = 0.4;
        let deck = platform(DVec3::new(0.0, top - 0.2, 0.0), DVec3::new(3.0, 0.2, 3.0));
        r.model_mut().add_collider(deck, None).unwrap();
        // On its back: the root turned -90° about x (head towards -z), 0.25 m above the deck.
        let (model, state) = r.parts_mut();
        let mut q = state.q().to_vec();
        let lie = DQuat::from_rotation_x(-std::f64::consts::FRAC_PI_2);
        q[3..7].copy_from_slice(&[lie.w, lie.x, lie.y, lie.z]);
        q[1] = top + 0.25 - model.bodies()[0].offset.y;
        state.set_q(model, &q).unwrap();
        if servos {
            state.set_targets(model, &q).unwrap();
            for b in 1..r.model().bodies().len() {
                if matches!(r.model().bodies()[b].joint, Joint::Revolute { .. } | Joint::Ball) {
                    let servo = Servo { kp: 300.0, kd: 30.0, max_torque: f64::INFINITY };
                    r.model_mut().set_servo(b, Some(servo)).unwrap();
                }
            }
            assert_eq!(r.model().settings.servo_mode, ServoMode::Stable);
        }
        moving(&mut r, 0, DVec3::new(speed, 0.0, 0.0));
        let dt = 1.0 / 480.0;
        r.step(dt, 3 * 480).unwrap();
        let before = r.com();
        r.step(dt, 480).unwrap();
        let after = r.com();
        let moved = after - before;
        let Shape::Box(deck) = r.model().colliders()[0].at(r.state().time()) else {
            unreachable!("the platform is a box")
        };
        println!(
            "servos {servos}: moved {moved} in the last second, com {after}, deck {}",
            deck.center
        );
        assert!((moved.x - speed).abs() < 0.01 * speed, "servos {servos}: moved {moved}");
        assert!(moved.y.abs() < 0.01 && moved.z.abs() < 0.01, "servos {servos}: moved {moved}");
        assert!(after.y > top && (after.x - deck.center.x).abs() < 1.5, "fell off: {after}");
    }
}

/// The gains of the servos that make the ragdoll below diverge after some steps of a call.
const GAIN: f64 = 1e4;

/// A step that diverges on a moving platform leaves the body bit for bit as it was and its
/// collider where it was (the collider's pose is a function of the body's time, which is put
/// back; the model is not written by a step).
#[test]
fn a_failed_step_on_a_moving_platform_changes_nothing() {
    let mut r = ArticulatedBody::new(cmu_ragdoll(0.3, Settings::default()));
    let deck = platform(DVec3::new(0.0, -0.2, 0.0), DVec3::new(3.0, 0.2, 3.0));
    r.model_mut().add_collider(deck, None).unwrap();
    moving(&mut r, 0, DVec3::new(0.5, 0.0, 0.3));
    r.step(1.0 / 480.0, 200).unwrap();
    // An absurd explicit PD servo on every hinge and ball joint (as in tests/character.rs):
    // it explodes within a few steps.
    r.model_mut().settings.servo_mode = ServoMode::Explicit;
    for b in 1..r.model().bodies().len() {
        if matches!(r.model().bodies()[b].joint, Joint::Revolute { .. } | Joint::Ball) {
            let servo = Servo { kp: GAIN, kd: GAIN, max_torque: f64::INFINITY };
            r.model_mut().set_servo(b, Some(servo)).unwrap();
        }
    }
    let (model, state) = r.parts_mut();
    let q = state.q().to_vec();
    state.set_targets(model, &q).unwrap();
    let bits = |b: &ArticulatedBody| {
        let s = b.state();
        let values = s.q().iter().chain(s.qd()).chain(s.targets()).chain(s.torques());
        let collider = b.model().colliders()[0].at(s.time());
        (values.map(|v| v.to_bits()).collect::<Vec<_>>(), s.time().to_bits(), collider)
    };
    let before = bits(&r);
    let err = r.step(1.0 / 480.0, 100).unwrap_err();
    assert!(
        matches!(err, kinema::Error::Diverged { step, .. } if step > 0),
        "expected a divergence after the first step, got {err}"
    );
    assert_eq!(bits(&r), before, "the failed call changed the body or its collider");
}

/// Bad moving colliders are refused, naming the argument, and leave the collider as it was.
#[test]
fn bad_moving_colliders_are_named() {
    let mut model = Model::new(Settings::default());
    model.add_body(capsule(DVec3::ZERO, DVec3::ZERO, 0.1, DVec3::Y)).unwrap();
    let deck = platform(DVec3::ZERO, DVec3::ONE);
    model.add_collider(deck, None).unwrap();
    let good = model.colliders()[0];
    let other = Collider { shape: platform(DVec3::X, DVec3::splat(2.0)), ..good };
    let ball = Collider {
        shape: Shape::Sphere(kinema::geometry::Sphere { center: DVec3::ZERO, radius: 1.0 }),
        ..good
    };
    let fast = Collider { velocity: DVec3::new(f64::NAN, 0.0, 0.0), ..good };
    let late = Collider { since: f64::INFINITY, ..good };
    for (collider, arg) in [(other, "shape"), (ball, "shape"), (fast, "velocity"), (late, "since")]
    {
        let err = model.set_collider(0, collider).unwrap_err().to_string();
        assert!(err.contains(arg), "{arg}: {err}");
        assert_eq!(model.colliders()[0], good);
    }
    assert!(model.set_collider(1, good).unwrap_err().to_string().contains("index"));
}

/// A ball rolling on a turntable (a box turning about y at Ω = 2 rad/s about its centre):
/// once it rolls without slipping, `v + ω × (−r ŷ) = Ω × x` with `m v̇ = F`,
/// `I ω̇ = (−r ŷ) × F`, `I = 2/5 m r²`, give `v̇ = (2/7) Ω × v`: its centre's velocity keeps
/// its length and turns at `2Ω/7` (it circles a fixed point). Dropped at rest 0.5 m from the
/// axis, it slips for a moment, then between 0.5 s and 2.5 s its velocity turns by
/// `2/7 Ω × 2 s` = 1.1428571 rad, within 1e-4 (measured 1.1428565), at a speed constant
/// within 1e-3. With the table's angular velocity left out of the contacts it stays at rest.
#[test]
fn a_ball_on_a_turntable_circles_at_two_sevenths_of_its_rate() {
    let (omega, r) = (2.0, 0.1);
    let settings = Settings { ground: false, ..Settings::default() };
    let sink = 9.81 / settings.contact_frequency.powi(2);
    let mut model = Model::new(settings);
    let at = DVec3::new(0.5, r - sink, 0.0);
    model.add_body(capsule(DVec3::ZERO, DVec3::ZERO, r, at)).unwrap();
    model
        .add_collider(platform(DVec3::new(0.0, -0.2, 0.0), DVec3::new(3.0, 0.2, 3.0)), None)
        .unwrap();
    let mut ball = ArticulatedBody::new(model);
    let c = ball.model().colliders()[0];
    let table = Collider { angular_velocity: DVec3::new(0.0, omega, 0.0), ..c };
    ball.model_mut().set_collider(0, table).unwrap();
    let velocity = |b: &ArticulatedBody| {
        let qd = b.state().qd();
        DVec3::new(qd[3], qd[4], qd[5])
    };
    ball.step(1e-3, 500).unwrap();
    let v1 = velocity(&ball);
    ball.step(1e-3, 2000).unwrap();
    let v2 = velocity(&ball);
    let turned = v1.cross(v2).y.atan2(v1.dot(v2));
    let want = 2.0 / 7.0 * omega * 2.0;
    println!("v1 {v1}, v2 {v2}, turned {turned} rad, want {want}");
    assert!(v1.length() > 0.1, "the table did not drag the ball: {v1}");
    assert!((turned - want).abs() < 1e-4 * want, "turned {turned} rad, not {want}");
    assert!((v2.length() / v1.length() - 1.0).abs() < 1e-3, "{v1} → {v2}");
}

/// `Collider::at` for every kind of shape: after 0.5 s at π/2 rad/s about y (a turn of π/4)
/// and 1 m/s along x, a capsule along x turns about
/// its midpoint, a plane's normal turns about its point, a box's orientation composes with the
/// turn, a sphere only moves; each centre moves by 0.5 m along x. The surface velocity at a
/// point 1 m along z from the centre is `v + ω × (0, 0, 1)`.
#[test]
fn colliders_turn_about_their_centres_and_move() {
    use kinema::geometry::{Capsule, Plane, Sphere};
    let w = std::f64::consts::FRAC_PI_2;
    let turn = DQuat::from_rotation_y(w * 0.5);
    let shapes = [
        Shape::Capsule(Capsule {
            a: DVec3::new(1.0, 0.0, 0.0),
            b: DVec3::new(3.0, 0.0, 0.0),
            radius: 0.1,
        }),
        Shape::Plane(Plane { point: DVec3::new(0.0, 1.0, 0.0), normal: DVec3::X }),
        Shape::Box(Cuboid {
            center: DVec3::Z,
            rotation: DQuat::from_rotation_x(0.3),
            half: DVec3::ONE,
        }),
        Shape::Sphere(Sphere { center: DVec3::Y, radius: 0.5 }),
    ];
    let moved = DVec3::new(0.5, 0.0, 0.0);
    for shape in shapes {
        let c = Collider {
            shape,
            friction: None,
            velocity: DVec3::X,
            angular_velocity: DVec3::new(0.0, w, 0.0),
            since: 2.0,
        };
        let at = c.at(2.5);
        let centre = shape.centre();
        assert!((at.centre() - (centre + moved)).length() < 1e-15, "{at:?}");
        match (shape, at) {
            (Shape::Capsule(k), Shape::Capsule(m)) => {
                assert!((m.a - (centre + moved + turn * (k.a - centre))).length() < 1e-15);
                assert!((m.b - (centre + moved + turn * (k.b - centre))).length() < 1e-15);
            }
            (Shape::Plane(p), Shape::Plane(m)) => {
                assert!((m.normal - turn * p.normal).length() < 1e-15)
            }
            (Shape::Box(b), Shape::Box(m)) => {
                assert!((m.rotation - turn * b.rotation).length() < 1e-15)
            }
            (Shape::Sphere(s), Shape::Sphere(m)) => assert_eq!(m.radius, s.radius),
            _ => panic!("the kind changed: {at:?}"),
        }
        let p = at.centre() + DVec3::Z;
        let want = DVec3::X + DVec3::new(0.0, w, 0.0).cross(DVec3::Z);
        assert!((c.surface_velocity(&at, p) - want).length() < 1e-15);
    }
}
