//! Static colliders of articulated bodies (`Model::add_collider`): capsules resting on a box
//! at the analytic penetration, sticking and sliding on tilted planes at Coulomb's numbers,
//! contact forces along a box's closest-point normal on its side and edge, the CMU ragdoll
//! falling limp down a staircase of boxes, snapshots and bad input.

mod articulated;

use articulated::{capsule, cmu_ragdoll};
use glam::{DQuat, DVec3};
use kinema::character::{ArticulatedBody, Joint, Model, Servo, Settings};
use kinema::geometry::{Cuboid, Plane, Shape};
use kinema::snapshot::Snapshot;
use kinema::Error;

const G: f64 = 9.81;

/// A box of half extents `half` at `center` turned by `rotation`.
fn cuboid(center: DVec3, rotation: DQuat, half: DVec3) -> Shape {
    Shape::Box(Cuboid { center, rotation, half })
}

/// The world position of the free root's frame origin.
fn root(b: &ArticulatedBody) -> DVec3 {
    let q = b.state().q();
    b.model().bodies()[0].offset + DVec3::new(q[0], q[1], q[2])
}

/// A ball and a level capsule dropped on a box's top face (no ground) rest at the
/// documented penetration: one point of stiffness `m ω²` sinks `g/ω²`, a level capsule on its
/// two end contacts `g/(2ω²)` (a third, inner contact on the face would give `g/(3ω²)`);
/// without the collider they fall through.
#[test]
fn capsules_rest_on_a_box_top_at_the_analytic_penetration() {
    let w = Settings::default().contact_frequency;
    let top = 0.3;
    let block =
        cuboid(DVec3::new(0.1, top - 0.2, -0.1), DQuat::IDENTITY, DVec3::new(0.6, 0.2, 0.5));
    let r = 0.05;
    let cases = [
        (DVec3::ZERO, DVec3::ZERO, G / (w * w)),
        (DVec3::new(-0.2, 0.0, 0.0), DVec3::new(0.2, 0.0, 0.1), G / (2.0 * w * w)),
    ];
    for (a, b, sink) in cases {
        for with_box in [true, false] {
            let mut model = Model::new(Settings { ground: false, ..Settings::default() });
            model.add_body(capsule(a, b, r, DVec3::new(0.0, top + 0.2, 0.0))).unwrap();
            if with_box {
                model.add_collider(block, None).unwrap();
            }
            let mut body = ArticulatedBody::new(model);
            body.step(1.0 / 480.0, 960).unwrap();
            let height = root(&body).y;
            if with_box {
                let expect = top + r - sink;
                assert!((height - expect).abs() < 1e-3 * sink, "{a} {b}: {height} vs {expect}");
                assert!(body.energy().0 < 1e-12, "still moving: {:e} J", body.energy().0);
            } else {
                assert!(height < 0.0, "fell through to {height}");
            }
        }
    }
}

/// A capsule lying down the slope of a plane tilted by θ (no ground, friction μ = 0.5 on
/// the plane): below the friction angle it sticks, creeping at the regularised friction's
/// speed `v_s tan θ / μ` (viscous below the slip speed `v_s`: the tolerance of "sticks");
/// above, it slides with the acceleration `g (sin θ − μ cos θ)` to 0.5 %. The same with a
/// servoed child (stable PD: the contacts' damping taken implicitly along the plane's
/// normal; with it along +Y instead the sliding acceleration is 2.4 % off).
#[test]
fn a_capsule_sticks_below_the_friction_angle_and_slides_above_it() {
    let mu = 0.5;
    for servoed in [false, true] {
        for degrees in [20.0_f64, 35.0] {
            let theta = degrees.to_radians();
            let normal = DVec3::new(theta.sin(), theta.cos(), 0.0);
            let down = DVec3::new(theta.cos(), -theta.sin(), 0.0);
            let settings = Settings { ground: false, ..Settings::default() };
            let mut model = Model::new(settings);
            let r = 0.05;
            let rest = normal * (r - 0.002);
            model.add_body(capsule(-0.2 * down, 0.2 * down, r, rest)).unwrap();
            if servoed {
                let mut child = capsule(DVec3::ZERO, DVec3::ZERO, 0.03, 0.1 * normal);
                (child.parent, child.joint, child.shape) =
                    (Some(0), Joint::Revolute { axis: DVec3::Z }, None);
                child.servo = Some(Servo { kp: 50.0, kd: 1.0, max_torque: f64::INFINITY });
                model.add_body(child).unwrap();
            }
            let plane = Shape::Plane(Plane { point: DVec3::ZERO, normal });
            model.add_collider(plane, Some(mu)).unwrap();
            let mut body = ArticulatedBody::new(model);
            let dt = 1e-3;
            let velocity = |b: &ArticulatedBody| DVec3::from_slice(&b.state().qd()[3..6]).dot(down);
            body.step(dt, 500).unwrap();
            let v0 = velocity(&body);
            body.step(dt, 1000).unwrap();
            let v1 = velocity(&body);
            let slip = Settings::default().slip_speed;
            if theta.tan() < mu {
                let creep = slip * theta.tan() / mu;
                assert!((v1 / creep - 1.0).abs() < 0.02, "{degrees}°: {v1} vs {creep}");
                assert!((v1 - v0).abs() < 1e-3 * creep, "{degrees}°: not steady");
            } else {
                let expect = G * (theta.sin() - mu * theta.cos());
                let a = v1 - v0;
                assert!((a / expect - 1.0).abs() < 5e-3, "{degrees}° {servoed}: {a} vs {expect}");
            }
        }
    }
}

/// A ball pressed into a box (no gravity, at rest, so no damping or friction) is pushed
/// along the box's closest-point normal with the force `m ω² d`: into a side face along
/// its normal, into an edge along the direction from the edge to the centre, into a
/// corner likewise (a box turned about two axes). One step gives `Δv = f dt / m`.
#[test]
fn contacts_on_a_box_side_and_edge_push_along_its_closest_point_normal() {
    let rotation = DQuat::from_rotation_y(0.5) * DQuat::from_rotation_z(0.3);
    let half = DVec3::new(0.4, 0.3, 0.2);
    let block = Cuboid { center: DVec3::new(0.2, 1.0, -0.3), rotation, half };
    let r = 0.1;
    let depth = 0.01;
    let w = Settings::default().contact_frequency;
    // Box-frame directions from the centre: a side face, an edge, a corner.
    for local in [DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::new(-1.0, 1.0, 1.0)] {
        let surface = half * local; // a point of that face, edge or corner
        let outward = rotation * local.normalize();
        let centre = block.center + rotation * surface + (r - depth) * outward;
        let settings = Settings { ground: false, gravity: DVec3::ZERO, ..Settings::default() };
        let mut model = Model::new(settings);
        let ball = capsule(DVec3::ZERO, DVec3::ZERO, r, centre);
        let mass = ball.mass;
        model.add_body(ball).unwrap();
        model.add_collider(Shape::Box(block), None).unwrap();
        let (d, n) = Shape::Box(block).distance(centre);
        assert!((n - outward).length() < 1e-12 && (d - (r - depth)).abs() < 1e-12);
        let mut body = ArticulatedBody::new(model);
        let dt = 1e-4;
        body.step(dt, 1).unwrap();
        let dv = DVec3::from_slice(&body.state().qd()[3..6]);
        let expect = mass * w * w * depth * dt / mass * outward;
        assert!((dv - expect).length() < 1e-12, "{local}: {dv} vs {expect}");
        let spin = DVec3::from_slice(&body.state().qd()[0..3]);
        assert!(spin.length() < 1e-12, "{local}: torque about the centre {spin}");
    }
}

/// A capsule lying across the ridge of a box turned 45° (its edge up), both ends off the
/// box, is held by the contact at its axis's deepest point: pressed `d` into the ridge at
/// rest without gravity, one step gives `Δv = ω² d dt` straight up. Slid along its axis so
/// that the ridge passes its end, the force changes continuously (by less than 5 % of the
/// centred force between positions 0.1 mm apart; the steepest change, where the end's
/// contact begins, is 2.7 %): the inner contact fades in over one radius from the end, where the end's own
/// contact takes over (at full weight there the force would double).
#[test]
fn a_capsule_across_a_box_edge_is_held_by_its_inner_contact() {
    let ridge = Cuboid {
        center: DVec3::new(0.0, -0.2 * 2f64.sqrt(), 0.0),
        rotation: DQuat::from_rotation_z(std::f64::consts::FRAC_PI_4),
        half: DVec3::new(0.2, 0.2, 1.0),
    };
    let (r, depth, half) = (0.05, 0.004, 0.3);
    let w = Settings::default().contact_frequency;
    let dt = 1e-4;
    let kick = |x: f64| {
        let settings = Settings { ground: false, gravity: DVec3::ZERO, ..Settings::default() };
        let mut model = Model::new(settings);
        let at = DVec3::new(x, r - depth, 0.0);
        model.add_body(capsule(-half * DVec3::X, half * DVec3::X, r, at)).unwrap();
        model.add_collider(Shape::Box(ridge), None).unwrap();
        let mut body = ArticulatedBody::new(model);
        body.step(dt, 1).unwrap();
        DVec3::from_slice(&body.state().qd()[3..6])
    };
    let centred = kick(0.0);
    let expect = w * w * depth * dt * DVec3::Y;
    assert!((centred - expect).length() < 1e-7 * expect.length(), "{centred} vs {expect}");
    let mut last = kick(half - 0.03).y;
    for k in 1..=600 {
        let now = kick(half - 0.03 + 0.0001 * k as f64).y;
        assert!((now - last).abs() < 0.05 * centred.y, "at {k}: {last} -> {now}");
        last = now;
    }
}

/// Steps of a staircase going down along +x: `n` boxes, step `k` from `x = k depth` to
/// `(k + 1) depth` (the top one from `x = −1`) and from the floor `y = 0` to `(n − k) rise`.
fn stairs(n: usize, rise: f64, depth: f64) -> Vec<Shape> {
    (0..n)
        .map(|k| {
            let (x0, x1) = (if k == 0 { -1.0 } else { k as f64 * depth }, (k + 1) as f64 * depth);
            let top = (n - k) as f64 * rise;
            let half = DVec3::new(0.5 * (x1 - x0), 0.5 * top, 1.5);
            cuboid(DVec3::new(0.5 * (x0 + x1), 0.5 * top, 0.0), DQuat::IDENTITY, half)
        })
        .collect()
}

/// The deepest penetration (m) of any capsule into any of `shapes` or the ground, and the
/// body it is on: the least signed distance along its axis ([`Shape::deepest_on_segment`])
/// against its radius.
fn deepest(body: &mut ArticulatedBody, shapes: &[Shape]) -> (f64, usize) {
    let model = body.model().clone();
    let tree = body.kinematics();
    let ground = Shape::Plane(Plane { point: DVec3::ZERO, normal: DVec3::Y });
    let mut worst = (0.0, 0);
    for (i, b) in model.bodies().iter().enumerate() {
        let Some(c) = b.shape else { continue };
        let at = |p: DVec3| tree.positions()[i] + tree.orientations()[i] * p;
        let (a, e) = (at(c.a), at(c.b));
        for s in shapes.iter().chain([&ground]) {
            let d = c.radius - s.distance(a.lerp(e, s.deepest_on_segment(a, e))).0;
            if d > worst.0 {
                worst = (d, i);
            }
        }
    }
    worst
}

/// The limp CMU ragdoll (58 kg, 31 bodies) thrown forward at 1.5 m/s from the top of five
/// steps of 0.18 m by 0.30 m (limp: explicit contacts, the viscous coefficients capped at
/// `m / (4 dt)`): it tumbles down, ends at rest on the floor past the last step, its energy
/// (kinetic plus gravitational, sampled every 10 ms) never rises above its start, and no
/// capsule sinks into a step or the floor deeper than the bound of its spring. A body of
/// mass `m` on its contact spring `k = m ω²` sinks `g/ω²` under its own weight; an impact at
/// normal speed `v` into a spring whose body drags an effective mass `M_e` compresses it by at
/// most `v √(M_e / k)`; with `M_e` the whole ragdoll's mass `M` (the bound of every point's
/// effective mass) and `v` the fastest fall (from 1.1 m: `√(2 g h) = 4.6 m/s`) the bound is
/// `v / ω √(M/m) + (M/m) g / ω²`, checked per body.
#[test]
fn the_limp_cmu_ragdoll_tumbles_down_stairs_and_rests_at_the_bottom() {
    let (n, rise, depth) = (5, 0.18, 0.30);
    let settings = Settings { self_collision: true, ..Settings::default() };
    let mut model = cmu_ragdoll(0.05, settings);
    let shapes = stairs(n, rise, depth);
    for &s in &shapes {
        model.add_collider(s, Some(0.4)).unwrap();
    }
    let w = model.settings.contact_frequency;
    let total = model.mass();
    let bound: Vec<f64> = model
        .bodies()
        .iter()
        .map(|b| {
            let ratio = total / b.mass;
            (2.0 * G * 1.1).sqrt() / w * ratio.sqrt() + ratio * G / (w * w)
        })
        .collect();
    let mut body = ArticulatedBody::new(model);
    let (m, s) = body.parts_mut();
    let mut q = s.q().to_vec();
    q[0] -= 0.3;
    q[1] += n as f64 * rise;
    s.set_q(m, &q).unwrap();
    let mut qd = s.qd().to_vec();
    qd[3] = 1.5;
    s.set_qd(&qd).unwrap();
    let energy = |b: &mut ArticulatedBody| {
        let (t, v) = b.energy();
        t + v
    };
    let start = energy(&mut body);
    let (mut worst, mut depth) = ((0.0_f64, 0), 0.0_f64);
    let mut most = f64::NEG_INFINITY;
    let dt = 1.0 / 480.0;
    for _ in 0..1000 {
        body.step(dt, 5).unwrap();
        most = most.max(energy(&mut body));
        let (d, i) = deepest(&mut body, &shapes);
        depth = depth.max(d);
        if d / bound[i] > worst.0 {
            worst = (d / bound[i], i);
        }
    }
    let com = body.com();
    eprintln!(
        "stairs: energy {start:.1} J -> {:.1} J (most {most:.1} J), com {com}, deepest \
         {depth:.4} m, deepest/bound {:.3} on body {}",
        energy(&mut body),
        worst.0,
        worst.1
    );
    assert!(most <= start, "energy rose from {start} J to {most} J");
    assert!(worst.0 < 1.0, "penetration {:.3} of its bound on body {}", worst.0, worst.1);
    assert!(com.x > n as f64 * depth, "stopped on the stairs at x = {}", com.x);
    assert!(com.y < 0.3, "not lying on the floor: com {com}");
    assert!(body.energy().0 < 0.05, "still moving: {} J", body.energy().0);
}

/// A ragdoll on a box, saved mid-fall and restored, goes on bit for bit (the colliders are
/// in the snapshot); a snapshot with a collider made invalid is refused naming it.
#[test]
fn snapshots_keep_the_colliders() {
    let mut model = cmu_ragdoll(0.05, Settings::default());
    let block = cuboid(DVec3::new(0.3, 0.2, 0.0), DQuat::from_rotation_z(0.2), DVec3::splat(0.4));
    model.add_collider(block, Some(0.3)).unwrap();
    let mut a = ArticulatedBody::new(model);
    let (m, s) = a.parts_mut();
    let mut q = s.q().to_vec();
    q[1] += 0.7;
    s.set_q(m, &q).unwrap();
    a.step(1.0 / 480.0, 200).unwrap();
    let mut b = ArticulatedBody::from_snapshot(&a.to_snapshot().unwrap()).unwrap();
    assert_eq!(b.model().colliders(), a.model().colliders());
    a.step(1.0 / 480.0, 200).unwrap();
    b.step(1.0 / 480.0, 200).unwrap();
    let bits = |x: &ArticulatedBody| x.state().q().iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a), bits(&b));
    let mut bytes = a.to_snapshot().unwrap();
    // The collider's friction 0.3 (its last 8 bytes, before the state): made negative.
    let at = bytes.windows(8).rposition(|w| w == 0.3_f64.to_le_bytes()).unwrap();
    bytes[at..at + 8].copy_from_slice(&(-0.3_f64).to_le_bytes());
    let err = ArticulatedBody::from_snapshot(&bytes).unwrap_err().to_string();
    assert!(err.contains("friction"), "{err}");
}

/// Bad colliders are refused naming the argument, and the model is unchanged.
#[test]
fn bad_colliders_are_refused_naming_the_argument() {
    let mut model = Model::new(Settings::default());
    let arg = |e: Error| match e {
        Error::InvalidInput { arg, .. } => arg,
        other => panic!("{other:?}"),
    };
    let good = cuboid(DVec3::ZERO, DQuat::IDENTITY, DVec3::ONE);
    let nan = DVec3::new(f64::NAN, 0.0, 0.0);
    for (shape, friction, name) in [
        (cuboid(nan, DQuat::IDENTITY, DVec3::ONE), None, "center"),
        (cuboid(DVec3::ZERO, DQuat::IDENTITY, DVec3::new(1.0, 0.0, 1.0)), None, "half_extents"),
        (
            cuboid(DVec3::ZERO, DQuat::from_xyzw(0.0, 0.0, 0.0, 2.0), DVec3::ONE),
            None,
            "orientation",
        ),
        (Shape::Plane(Plane { point: DVec3::ZERO, normal: DVec3::ZERO }), None, "normal"),
        (good, Some(-1.0), "friction"),
        (good, Some(f64::INFINITY), "friction"),
    ] {
        assert_eq!(arg(model.add_collider(shape, friction).unwrap_err()), name);
    }
    assert!(model.colliders().is_empty());
}
