//! Hair (`kinema::rods::Hair`, `hair.rs`): groomed strands on a still head settle to the
//! static equilibrium of each strand alone; a turning head carries the roots exactly; the
//! result does not depend on the thread count; the rod–rod repulsion keeps crossing strands
//! apart (and without it they pass through each other).

use glam::{DQuat, DVec3};
use kinema::rods::{template, End, Hair, Material, Model, Repulsion, Rod, Settings, State};

/// Stiff hair: `E = 1 GPa`, `r = 100 µm`, `ρ = 1300 kg/m³` (5 cm strands: first bending
/// frequency 62 rad/s, gravity sag 4 mm).
const HAIR: Material =
    Material { youngs_modulus: 1e9, shear_modulus: 4e8, density: 1300.0, radius: [1e-4; 2] };

const OFF: Repulsion = Repulsion { stiffness: 0.0, thickness: 0.0, friction: 0.0 };

/// `count` points on the cap of the unit-less sphere of radius `r` about `+y` within 60°,
/// with their outward normals (a Fibonacci spiral).
fn scalp(count: usize, r: f64) -> (Vec<DVec3>, Vec<DVec3>) {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let normals: Vec<DVec3> = (0..count)
        .map(|i| {
            let y = 1.0 - 0.5 * (i as f64 + 0.5) / count as f64;
            let rho = (1.0 - y * y).sqrt();
            let phi = golden * i as f64;
            DVec3::new(rho * phi.cos(), y, rho * phi.sin())
        })
        .collect();
    (normals.iter().map(|n| r * *n).collect(), normals)
}

fn groomed(count: usize, curl: f64, repulsion: Repulsion) -> Hair {
    let (points, normals) = scalp(count, 0.1);
    let settings = Settings { tolerance: 1e-8, max_iterations: 300, ..Settings::default() };
    Hair::groom(&points, &normals, 0.05, 12, curl, HAIR, settings, repulsion).unwrap()
}

/// A still head: after 120 implicit steps of 1/60 s (the bending modes damped by `10⁻¹⁸`),
/// every curly strand matches the static solve of the same strand as a lone rod, clamped at
/// its root, within 1e-9 m.
#[test]
fn still_head_settles_to_each_strands_static_sag() {
    let mut hair = groomed(6, 0.005, OFF);
    hair.step(1.0 / 60.0, 120).unwrap();
    let rest = template(0.05, 12, 0.005);
    let mut worst: f64 = 0.0;
    for (state, (rotation, translation)) in hair.states().iter().zip(hair.placements()) {
        let points: Vec<DVec3> = rest.iter().map(|p| *rotation * *p + *translation).collect();
        let mut rod = Rod::new(&points, HAIR, Settings::default(), None).unwrap();
        rod.model_mut().clamp(End::First);
        rod.solve_static().unwrap();
        let sag = (rod.state().positions()[12] - points[12]).length();
        assert!(sag > 1e-4, "the strand sags visibly ({sag:e} m)");
        for (a, b) in state.positions().iter().zip(rod.state().positions()) {
            worst = worst.max((*a - *b).length());
        }
    }
    println!("largest distance from the static solve {worst:e} m");
    assert!(worst < 1e-9, "{worst:e}");
}

/// Turning the head by 90° about `z` and shifting it by 2 cm over 30 steps: the two root
/// vertices of every strand are exactly (1e-14 m) on the moved head, and each strand moved
/// with the head (its tip within 1 cm of the rigidly moved tip of its rest shape).
#[test]
fn turning_head_carries_the_roots() {
    let mut hair = groomed(8, 0.0, OFF);
    let (rotation, shift) =
        (DQuat::from_rotation_z(std::f64::consts::FRAC_PI_2), DVec3::new(0.0, 0.02, 0.0));
    hair.set_head(rotation, shift).unwrap();
    hair.step(1.0 / 60.0, 30).unwrap();
    let rest = template(0.05, 12, 0.0);
    for (s, (state, (r, t))) in hair.states().iter().zip(hair.placements()).enumerate() {
        for (i, p) in rest.iter().enumerate().take(2) {
            let want = rotation * (*r * *p + *t) + shift;
            let error = (state.positions()[i] - want).length();
            assert!(error < 1e-14, "strand {s} root {i} off by {error:e}");
        }
        let tip = rotation * (*r * rest[12] + *t) + shift;
        assert!((state.positions()[12] - tip).length() < 0.01, "strand {s} left behind");
    }
    assert_eq!(hair.head(), (rotation, shift));
}

fn run_on(threads: usize) -> Vec<DVec3> {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    pool.install(|| {
        let mut hair =
            groomed(70, 0.005, Repulsion { stiffness: 1e2, thickness: 2e-3, friction: 0.0 });
        hair.set_head(DQuat::from_rotation_x(0.6), DVec3::ZERO).unwrap();
        hair.step(1.0 / 60.0, 20).unwrap();
        assert!(hair.stats.iterations > 0);
        hair.states().iter().flat_map(|s| s.positions().to_vec()).collect()
    })
}

/// 70 dense curly strands (5 tasks, repulsion active) turned by a head: bitwise the same
/// positions on 1 and 2 threads.
#[test]
fn bitwise_identical_on_one_and_two_threads() {
    let (one, two) = (run_on(1), run_on(2));
    assert!(one.iter().zip(&two).all(|(a, b)| a.to_array() == b.to_array()));
}

/// Two horizontal strands of 10 cm (`E = 1 MPa`, `r = 1 mm`) clamped at their roots, one
/// along `x` 5 mm above the other along `y`, crossing 9 cm from both roots, pushed towards
/// each other by 15 µN per vertex (a static deflection of 3 cm at the crossing) for 1 s at dt = 1/240: the smallest distance between
/// their centrelines over the run, and the least signed height of the upper one over the
/// lower one at the crossing (vertex 18 of each).
fn crossing(repulsion: Repulsion) -> (f64, f64) {
    let soft =
        Material { youngs_modulus: 1e6, shear_modulus: 3e5, density: 1000.0, radius: [1e-3; 2] };
    let settings = Settings { gravity: DVec3::ZERO, tolerance: 1e-6, ..Settings::default() };
    let model = Model::new(&template(0.1, 20, 0.0), soft, settings).unwrap();
    let placements = [
        (DQuat::from_rotation_arc(DVec3::Z, DVec3::X), DVec3::new(-0.09, 0.0, 0.005)),
        (DQuat::from_rotation_arc(DVec3::Z, DVec3::Y), DVec3::new(0.0, -0.09, -0.005)),
    ];
    let mut hair = Hair::new(model, &placements, repulsion).unwrap();
    for (state, sign) in hair.states_mut().iter_mut().zip([-1.0, 1.0]) {
        for i in 0..=20 {
            state.set_force(i, DVec3::new(0.0, 0.0, sign * 1.5e-5)).unwrap();
        }
    }
    let (mut closest, mut lowest) = (f64::INFINITY, f64::INFINITY);
    let z = |s: &State, i: usize| s.positions()[i].z;
    for k in 0..240 {
        hair.step(1.0 / 240.0, 1).unwrap_or_else(|e| panic!("step {k}: {e}"));
        let [a, b] = [0, 1].map(|s| hair.states()[s].positions().to_vec());
        for p in a.windows(2) {
            for q in b.windows(2) {
                let (x, y) =
                    kinema::geometry::segment::closest_points_of_segments(p[0], p[1], q[0], q[1]);
                closest = closest.min((x - y).length());
            }
        }
        lowest = lowest.min(z(&hair.states()[0], 18) - z(&hair.states()[1], 18));
    }
    (closest, lowest)
}

/// With the repulsion (`k = 1e4 N/m`, thickness 2 mm = the radii's sum) the strands never
/// come closer than 2 mm less 10 % (measured 1.85 mm: each strand keeps the thickness from
/// where the other was at the start of the step, and both move), and the upper one stays
/// above; without it they pass through each other.
#[test]
fn repulsion_keeps_crossing_strands_apart() {
    let thickness = 2e-3;
    let (closest, above) = crossing(Repulsion { stiffness: 0.0, thickness, friction: 0.0 });
    println!("without: closest {closest:e} m, height at the crossing {above:e} m");
    let (closest2, above2) = crossing(Repulsion { stiffness: 1e4, thickness, friction: 0.0 });
    println!("with repulsion: closest {closest2:e} m, height at the crossing {above2:e} m");
    assert!(closest2 > 0.9 * thickness, "{closest2:e}");
    assert!(above2 > 0.9 * thickness, "{above2:e}");
    assert!(above < -thickness, "they did not pass through each other: {above:e}");
    assert!(closest < 0.5 * thickness);
}

/// Bad hair input: errors naming the argument.
#[test]
fn bad_hair_arguments_are_named() {
    let (points, normals) = scalp(3, 0.1);
    let s = Settings::default();
    let err = |r: kinema::error::Result<Hair>| r.unwrap_err().to_string();
    assert!(err(Hair::groom(&points, &normals[..2], 0.1, 4, 0.0, HAIR, s, OFF)).contains("normals"));
    assert!(err(Hair::groom(&points, &normals, -0.1, 4, 0.0, HAIR, s, OFF)).contains("length"));
    assert!(err(Hair::groom(&points, &normals, 0.1, 0, 0.0, HAIR, s, OFF)).contains("segments"));
    assert!(err(Hair::groom(&points, &normals, 0.1, 4, f64::NAN, HAIR, s, OFF)).contains("curl"));
    let bad = Repulsion { stiffness: -1.0, thickness: 1e-3, friction: 0.0 };
    let e = err(Hair::groom(&points, &normals, 0.1, 4, 0.0, HAIR, s, bad));
    assert!(e.contains("repulsion_stiffness"), "{e}");
    let mut hair = groomed(3, 0.0, OFF);
    let before: Vec<DVec3> = hair.states()[0].positions().to_vec();
    assert!(hair.step(f64::NAN, 1).unwrap_err().to_string().contains("dt"));
    assert!(hair.set_head(DQuat::from_xyzw(0.0, 0.0, 0.0, 2.0), DVec3::ZERO).is_err());
    assert_eq!(hair.states()[0].positions(), &before[..]);
}

/// The demo's hair (`kinema demo hair`, fewer strands): curly strands of 12 cm in 16
/// segments, `r = 100 µm`, `E = 1 GPa`, the repulsion on, the head turned and nodded for
/// 1 s at 1/60 s from the groomed shape. Returns the positions and the Newton iterations
/// and line-search halvings per strand and step.
fn demo_hair(tolerance: f64) -> (Vec<DVec3>, f64, f64) {
    let (points, normals) = scalp(60, 0.1);
    let material = Material { shear_modulus: 1e9 / 3.0, ..HAIR };
    let settings = Settings { tolerance, ..Settings::default() };
    let repulsion = Repulsion { stiffness: 10.0, thickness: 2e-4, friction: 0.0 };
    let mut hair =
        Hair::groom(&points, &normals, 0.12, 16, 0.01, material, settings, repulsion).unwrap();
    let (mut iterations, mut halvings) = (0, 0);
    let steps = 60;
    for k in 1..=steps {
        let t = k as f64 / 60.0;
        let yaw = 0.7 * (std::f64::consts::TAU * t / 2.0).sin();
        let pitch = 0.3 * (std::f64::consts::TAU * t / 1.3).sin();
        let head = DQuat::from_rotation_y(yaw) * DQuat::from_rotation_x(pitch);
        hair.set_head(head, DVec3::ZERO).unwrap();
        hair.step(1.0 / 60.0, 1).unwrap();
        iterations += hair.stats.iterations;
        halvings += hair.stats.halvings;
    }
    let per = (steps * hair.states().len()) as f64;
    let x = hair.states().iter().flat_map(|s| s.positions().to_vec()).collect();
    (x, iterations as f64 / per, halvings as f64 / per)
}

/// Newton's iterations per strand and step on the demo's hair stay few (measured 7.5, with
/// 0.04 line-search halvings; 27 and 9.9 with the straight line search alone), and the
/// result is that of a 100 times tighter tolerance within 1 µm.
#[test]
fn few_newton_iterations_per_hair_step() {
    let (x, iterations, halvings) = demo_hair(1e-8);
    let (tight, ..) = demo_hair(1e-10);
    let worst = x.iter().zip(&tight).map(|(a, b)| (*a - *b).length()).fold(0.0, f64::max);
    println!("{iterations:.2} iterations, {halvings:.2} halvings per strand step; {worst:e} m");
    assert!(worst < 1e-6, "{worst:e}");
    assert!(iterations < 10.0 && halvings < 0.5, "{iterations} {halvings}");
}

/// FNV-1a over the bits of `values`.
fn fingerprint(values: impl IntoIterator<Item = f64>) -> u64 {
    values.into_iter().fold(0xcbf2_9ce4_8422_2325, |h: u64, v| {
        (h ^ v.to_bits()).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// Without friction between strands (`μ = 0`) the repulsion is what it was before friction
/// existed, bitwise: the fingerprints of the 70 dense strands turned by the head and of the
/// pressed crossing strands were recorded from the code before friction was added
/// (`print_old_fingerprints` run at commit 7145366).
#[test]
fn zero_strand_friction_is_the_old_repulsion_bitwise() {
    let dense = run_on(1);
    let (closest, lowest) = crossing(Repulsion { stiffness: 1e4, thickness: 2e-3, ..OFF });
    assert_eq!(fingerprint(dense.iter().flat_map(|p| p.to_array())), DENSE_BEFORE_FRICTION);
    assert_eq!(fingerprint([closest, lowest]), CROSSING_BEFORE_FRICTION);
}
const DENSE_BEFORE_FRICTION: u64 = 0xb269_7479_56ab_655b;
const CROSSING_BEFORE_FRICTION: u64 = 0xc749_14ac_c510_ca10;

/// Soft hair that hangs (15 cm in 16 segments, `r = 50 µm`, `E = 1 GPa`) from 60 roots on the
/// upper cap (60°) of a 10 cm head, the head turned (±0.7 rad), nodded (±0.3 rad) and moved
/// sideways (±3 cm) for 1 s at 1/60 s: the deepest any non-root vertex's centreline gets
/// inside the head ball (m).
fn deepest_in_head(collider: bool) -> f64 {
    let (points, normals) = scalp(60, 0.1);
    let material = Material {
        youngs_modulus: 1e9,
        shear_modulus: 1e9 / 3.0,
        density: 1300.0,
        radius: [5e-5; 2],
    };
    let settings = Settings { tolerance: 1e-8, max_iterations: 300, ..Settings::default() };
    let mut hair = Hair::groom(&points, &normals, 0.15, 16, 0.0, material, settings, OFF).unwrap();
    if collider {
        let ball = kinema::geometry::Sphere { center: DVec3::ZERO, radius: 0.1 };
        hair.set_head_collider(ball).unwrap();
    }
    let mut deepest: f64 = f64::NEG_INFINITY;
    for k in 1..=60 {
        let t = k as f64 / 60.0;
        let yaw = 0.7 * (std::f64::consts::TAU * t / 2.0).sin();
        let pitch = 0.3 * (std::f64::consts::TAU * t / 1.3).sin();
        let head = DQuat::from_rotation_y(yaw) * DQuat::from_rotation_x(pitch);
        let shift = DVec3::new(0.03 * (std::f64::consts::TAU * t).sin(), 0.0, 0.0);
        hair.set_head(head, shift).unwrap();
        hair.step(1.0 / 60.0, 1).unwrap_or_else(|e| panic!("collider {collider}, step {k}: {e}"));
        for s in hair.states() {
            for x in &s.positions()[2..] {
                deepest = deepest.max(0.1 - (*x - shift).length());
            }
        }
    }
    deepest
}

/// The head as a moving collider: with it no strand's centreline gets inside the turning,
/// nodding head (deepest measured below); without it hanging strands fall centimetres into it.
#[test]
fn head_collider_keeps_strands_out_of_the_moving_head() {
    let (with, without) = (deepest_in_head(true), deepest_in_head(false));
    println!("deepest inside the head: with the collider {with:e} m, without {without:e} m");
    assert!(with < 1e-4, "{with:e}");
    assert!(without > 1e-2, "{without:e}");
}
