//! Rigid bodies: mass properties against closed forms and meshes, conservation laws, the
//! Dzhanibekov flip, convergence order, bad input.

use glam::{DMat3, DQuat, DVec3};
use kinema::geometry::Solid as Shape;
use kinema::rigid::{BodyDesc, RotationIntegrator, World};
use std::f64::consts::PI;

fn box_mesh(h: DVec3) -> Shape {
    let v: Vec<DVec3> = (0..8)
        .map(|i| {
            DVec3::new(
                if i & 1 == 0 { -h.x } else { h.x },
                if i & 2 == 0 { -h.y } else { h.y },
                if i & 4 == 0 { -h.z } else { h.z },
            )
        })
        .collect();
    // Outward counter-clockwise faces of the cube with vertex bits (x, y, z).
    let quads =
        [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
    let triangles = quads.iter().flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]).collect();
    Shape::Mesh { vertices: v, triangles }
}

/// An icosphere of radius r with `level` subdivisions (outward, counter-clockwise).
fn icosphere(r: f64, level: usize) -> Shape {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v: Vec<DVec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| DVec3::new(x, y, z).normalize())
    .collect();
    let mut f: Vec<[usize; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..level {
        let mut mid = std::collections::HashMap::new();
        let mut next = Vec::new();
        let mut midpoint = |a: usize, b: usize, v: &mut Vec<DVec3>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                v.push(((v[a] + v[b]) * 0.5).normalize());
                v.len() - 1
            })
        };
        for [a, b, c] in f {
            let (ab, bc, ca) =
                (midpoint(a, b, &mut v), midpoint(b, c, &mut v), midpoint(c, a, &mut v));
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        f = next;
    }
    Shape::Mesh { vertices: v.into_iter().map(|p| p * r).collect(), triangles: f }
}

fn close(a: DMat3, b: DMat3, tol: f64) -> bool {
    (a - b).to_cols_array().iter().all(|x| x.abs() <= tol)
}

#[test]
fn primitive_inertia_closed_forms() {
    let s = Shape::Sphere { radius: 0.5 }.mass_properties(2.0).unwrap();
    let m = 2.0 * 4.0 / 3.0 * PI * 0.125;
    assert!((s.mass - m).abs() < 1e-14);
    assert!(close(s.inertia, DMat3::from_diagonal(DVec3::splat(0.4 * m * 0.25)), 1e-15));

    let b = Shape::Box { half_extents: DVec3::new(1.0, 2.0, 3.0) }.mass_properties(1.0).unwrap();
    assert_eq!(b.mass, 48.0);
    // m/12 (a² + b²) with full sides 2, 4, 6.
    assert!(close(
        b.inertia,
        DMat3::from_diagonal(DVec3::new(4.0 * 52.0, 4.0 * 40.0, 4.0 * 20.0)),
        1e-12
    ));

    let c = Shape::Cylinder { radius: 0.5, height: 2.0 }.mass_properties(1.0).unwrap();
    let m = PI * 0.25 * 2.0;
    assert!(close(
        c.inertia,
        DMat3::from_diagonal(DVec3::new(
            m / 12.0 * (0.75 + 4.0),
            0.5 * m * 0.25,
            m / 12.0 * (0.75 + 4.0)
        )),
        1e-14
    ));

    // A capsule of zero length is a sphere.
    let cap0 = Shape::Capsule { radius: 0.7, height: 0.0 }.mass_properties(3.0).unwrap();
    let sph = Shape::Sphere { radius: 0.7 }.mass_properties(3.0).unwrap();
    assert!((cap0.mass - sph.mass).abs() < 1e-13 && close(cap0.inertia, sph.inertia, 1e-13));
}

#[test]
fn capsule_matches_cylinder_plus_sphere_halves_by_parallel_axes() {
    // Independent check: split the caps into a sphere moved to each end half by half.
    let (r, h, rho) = (0.3, 1.2, 1.0);
    let cap = Shape::Capsule { radius: r, height: h }.mass_properties(rho).unwrap();
    let cyl = Shape::Cylinder { radius: r, height: h }.mass_properties(rho).unwrap();
    let sph = Shape::Sphere { radius: r }.mass_properties(rho).unwrap();
    // Two hemispheres = one sphere in mass; their centres of mass sit at ±(h/2 + 3r/8).
    let d = h / 2.0 + 3.0 * r / 8.0;
    let half_com_i = (0.4 - 9.0 / 64.0) * sph.mass / 2.0 * r * r; // about a hemisphere's own COM
    let side = cyl.inertia.x_axis.x + 2.0 * (half_com_i + sph.mass / 2.0 * d * d);
    assert!((cap.mass - (cyl.mass + sph.mass)).abs() < 1e-14);
    assert!((cap.inertia.x_axis.x - side).abs() < 1e-14);
    assert!((cap.inertia.y_axis.y - (cyl.inertia.y_axis.y + sph.inertia.y_axis.y)).abs() < 1e-14);
}

#[test]
fn meshed_box_is_exact_and_meshed_sphere_converges() {
    let h = DVec3::new(0.5, 1.0, 1.5);
    let exact = Shape::Box { half_extents: h }.mass_properties(7.0).unwrap();
    let mesh = box_mesh(h).mass_properties(7.0).unwrap();
    assert!((mesh.mass - exact.mass).abs() < 1e-12);
    assert!(mesh.center_of_mass.length() < 1e-14);
    assert!(close(mesh.inertia, exact.inertia, 1e-12));

    let exact = Shape::Sphere { radius: 1.0 }.mass_properties(1.0).unwrap();
    let errors: Vec<f64> = (1..5)
        .map(|level| {
            let p = icosphere(1.0, level).mass_properties(1.0).unwrap();
            (p.inertia.x_axis.x - exact.inertia.x_axis.x).abs() / exact.inertia.x_axis.x
        })
        .collect();
    // Inscribed polyhedra: the error falls about 4x per subdivision (second order in edge length).
    for w in errors.windows(2) {
        assert!(w[1] < w[0] / 3.5, "{errors:?}");
    }
    assert!(errors[3] < 4e-3, "{errors:?}");
}

#[test]
fn mesh_moved_and_turned_transforms_its_mass_properties() {
    let h = DVec3::new(0.5, 1.0, 1.5);
    let Shape::Mesh { vertices, triangles } = box_mesh(h) else { unreachable!() };
    let r = DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 0.7);
    let t = DVec3::new(3.0, -2.0, 1.0);
    let moved = Shape::Mesh { vertices: vertices.iter().map(|&v| r * v + t).collect(), triangles };
    let p = moved.mass_properties(1.0).unwrap();
    let exact = Shape::Box { half_extents: h }.mass_properties(1.0).unwrap();
    let rm = DMat3::from_quat(r);
    assert!((p.center_of_mass - t).length() < 1e-13);
    assert!(close(p.inertia, rm * exact.inertia * rm.transpose(), 1e-12));
}

#[test]
fn bad_shapes_are_refused() {
    let Shape::Mesh { vertices, mut triangles } = box_mesh(DVec3::ONE) else { unreachable!() };
    let inverted: Vec<[usize; 3]> = triangles.iter().map(|t| [t[0], t[2], t[1]]).collect();
    let err = Shape::Mesh { vertices: vertices.clone(), triangles: inverted }
        .mass_properties(1.0)
        .unwrap_err();
    assert!(err.to_string().contains("must be positive"), "{err}");
    triangles.pop();
    let err = Shape::Mesh { vertices: vertices.clone(), triangles: triangles.clone() }
        .mass_properties(1.0)
        .unwrap_err();
    assert!(err.to_string().contains("not closed"), "{err}");
    triangles.push([0, 1, 99]);
    assert!(Shape::Mesh { vertices, triangles }
        .mass_properties(1.0)
        .unwrap_err()
        .to_string()
        .contains("out of range"));
    assert!(Shape::Sphere { radius: 0.0 }.mass_properties(1.0).is_err());
    assert!(Shape::Sphere { radius: 1.0 }.mass_properties(-1.0).is_err());
    assert!(Shape::Box { half_extents: DVec3::new(1.0, f64::NAN, 1.0) }
        .mass_properties(1.0)
        .is_err());
}

fn body(shape: Shape, w: DVec3) -> BodyDesc {
    BodyDesc {
        shape,
        density: None,
        mass: Some(1.0),
        position: DVec3::ZERO,
        orientation: DQuat::IDENTITY,
        velocity: DVec3::ZERO,
        angular_velocity: w,
        fixed: false,
        restitution: 0.0,
        friction: 0.5,
    }
}

/// A box whose principal moments are distinct: I_x < I_y < I_z (half extents 1, 0.6, 0.2
/// give I ∝ (0.4, 1.04, 1.36)).
fn tumbling_box() -> Shape {
    Shape::Box { half_extents: DVec3::new(1.0, 0.6, 0.2) }
}

#[test]
fn world_angular_momentum_is_conserved_by_splitting() {
    let mut world = World::new(DVec3::ZERO, RotationIntegrator::Splitting);
    world.add_body(&body(tumbling_box(), DVec3::new(0.3, 5.0, 0.2))).unwrap();
    let l0 = world.angular_momentum();
    let e0 = world.kinetic_energy();
    world.step(1e-3, 10_000).unwrap();
    let l1 = world.angular_momentum();
    assert!((l1 - l0).length() / l0.length() < 1e-10, "{l0} {l1}");
    assert!(((world.kinetic_energy() - e0) / e0).abs() < 1e-4);
}

#[test]
fn explicit_euler_gains_energy_while_implicit_loses_it() {
    let run = |method| {
        let mut world = World::new(DVec3::ZERO, method);
        world.add_body(&body(tumbling_box(), DVec3::new(0.3, 5.0, 0.2))).unwrap();
        let e0 = world.kinetic_energy();
        world.step(1e-2, 1000).unwrap();
        world.kinetic_energy() / e0 - 1.0
    };
    assert!(run(RotationIntegrator::ExplicitEuler) > 1e-2);
    let implicit = run(RotationIntegrator::ImplicitGyroscopic);
    assert!(implicit < 0.0 && implicit > -0.5, "{implicit}");
    assert!(run(RotationIntegrator::Splitting).abs() < 1e-3);
}

/// Sign changes of the body-frame angular velocity along body axis `axis` over `steps` steps.
fn flips(axis: usize, w0: DVec3) -> usize {
    let mut world = World::new(DVec3::ZERO, RotationIntegrator::Splitting);
    world.add_body(&body(tumbling_box(), w0)).unwrap();
    let mut sign = w0[axis].signum();
    let mut count = 0;
    for _ in 0..4000 {
        world.step(5e-3, 1).unwrap();
        let w_body = world.orientation(0).conjugate() * world.angular_velocity(0);
        if w_body[axis].signum() != sign {
            sign = w_body[axis].signum();
            count += 1;
        }
    }
    count
}

#[test]
fn dzhanibekov_flip_about_the_intermediate_axis_only() {
    let eps = 1e-3;
    // Intermediate axis (y): the spin reverses periodically.
    assert!(flips(1, DVec3::new(eps, 8.0, eps)) >= 2);
    // Minor (x) and major (z) axes are stable: no reversal.
    assert_eq!(flips(0, DVec3::new(8.0, eps, eps)), 0);
    assert_eq!(flips(2, DVec3::new(eps, eps, 8.0)), 0);
}

#[test]
fn splitting_is_second_order_and_euler_first() {
    let state_after = |method, h: f64| {
        let mut world = World::new(DVec3::ZERO, method);
        world.add_body(&body(tumbling_box(), DVec3::new(1.0, 2.0, 0.5))).unwrap();
        world.step(h, (1.0 / h).round() as usize).unwrap();
        world.orientation(0)
    };
    let order = |method| {
        let reference = state_after(RotationIntegrator::Splitting, 1e-4);
        let e1 =
            kinema::rotation::rotation_angle(state_after(method, 1e-2) * reference.conjugate());
        let e2 =
            kinema::rotation::rotation_angle(state_after(method, 5e-3) * reference.conjugate());
        (e1 / e2).log2()
    };
    let p = order(RotationIntegrator::Splitting);
    assert!((p - 2.0).abs() < 0.1, "{p}");
    let p = order(RotationIntegrator::SymplecticEuler);
    assert!((p - 1.0).abs() < 0.15, "{p}");
}

#[test]
fn projectile_and_forces() {
    let mut world = World::new(DVec3::new(0.0, -9.81, 0.0), RotationIntegrator::Splitting);
    let mut desc = body(Shape::Sphere { radius: 0.1 }, DVec3::ZERO);
    desc.velocity = DVec3::new(3.0, 4.0, 0.0);
    world.add_body(&desc).unwrap();
    world.step(0.01, 100).unwrap();
    let expected = DVec3::new(3.0, 4.0 - 0.5 * 9.81, 0.0);
    assert!((world.position(0) - expected).length() < 1e-12);
    assert!((world.linear_momentum() - DVec3::new(3.0, 4.0 - 9.81, 0.0)).length() < 1e-12);

    // A force through the centre of mass does not spin the body; an offset one does.
    let mut world = World::new(DVec3::ZERO, RotationIntegrator::Splitting);
    world.add_body(&body(Shape::Box { half_extents: DVec3::ONE }, DVec3::ZERO)).unwrap();
    world.apply_force(0, DVec3::X, DVec3::ZERO).unwrap();
    world.step(0.1, 1).unwrap();
    assert!(world.angular_velocity(0).length() < 1e-15);
    world.apply_force(0, DVec3::X, world.position(0) + DVec3::Y).unwrap();
    world.step(0.1, 1).unwrap();
    // τ = y × x = -z; ω = τ h / I with I = m (1 + 1)/3 = 2/3.
    assert!((world.angular_velocity(0) - DVec3::new(0.0, 0.0, -0.1 * 1.5)).length() < 1e-12);
}

#[test]
fn bad_input_and_divergence_leave_the_world_unchanged() {
    let mut world = World::new(DVec3::ZERO, RotationIntegrator::ExplicitEuler);
    let mut desc = body(Shape::Sphere { radius: 1.0 }, DVec3::ZERO);
    desc.mass = Some(0.0);
    assert!(world.add_body(&desc).is_err());
    desc.mass = Some(1.0);
    desc.density = Some(1.0);
    assert!(world.add_body(&desc).is_err());
    desc.density = None;
    desc.position = DVec3::new(f64::NAN, 0.0, 0.0);
    assert!(world.add_body(&desc).is_err());
    assert!(world.is_empty());

    // Spinning at 1e150 rad/s (kinetic energy ~1e300 J, still finite): an explicit Euler
    // step's energy overflows, which is divergence.
    world.add_body(&body(tumbling_box(), DVec3::new(1e150, 1e150, 1e150))).unwrap();
    let before = (world.orientation(0), world.angular_velocity(0));
    let err = world.step(1.0, 3).unwrap_err();
    assert!(matches!(err, kinema::Error::Diverged { index: 0, .. }), "{err}");
    assert_eq!((world.orientation(0), world.angular_velocity(0)), before);
    assert!(world.step(0.0, 1).is_err());
    assert!(world.apply_force(3, DVec3::X, DVec3::ZERO).is_err());
}

/// A body whose kinetic energy would overflow is refused, naming the argument; just below,
/// the energy is computed without overflow (`|π/√I|²/2`, not `π²/(2I)`).
#[test]
fn kinetic_energy_is_finite_or_the_body_is_refused() {
    let mut world = World::new(DVec3::ZERO, RotationIntegrator::Splitting);
    for (w, v, arg) in [
        (DVec3::splat(1e300), DVec3::ZERO, "angular_velocity"),
        (DVec3::ZERO, DVec3::new(1e160, 0.0, 0.0), "velocity"),
    ] {
        let mut desc = body(Shape::Sphere { radius: 1.0 }, w);
        desc.velocity = v;
        match world.add_body(&desc) {
            Err(kinema::Error::InvalidInput { arg: a, .. }) => assert_eq!(a, arg),
            other => panic!("{other:?}"),
        }
    }
    assert!(world.is_empty());
    // A light sphere spinning fast: pi = I w = 1e-10 * 0.4 * 1e155 overflows when squared,
    // the energy I w^2 / 2 = 2e299 J does not.
    let mut desc = body(Shape::Sphere { radius: 1.0 }, DVec3::new(1e155, 0.0, 0.0));
    desc.mass = Some(1e-10);
    world.add_body(&desc).unwrap();
    let expected = 0.5 * (0.4 * 1e-10) * 1e155 * 1e155;
    let e = world.kinetic_energy();
    assert!(e.is_finite() && (e - expected).abs() <= 1e-12 * expected, "{e} vs {expected}");
}

/// A failed step leaves the world exactly as it was: positions, velocities, orientations,
/// angular momenta bit for bit, and the steps after it (which read the contact warm starts)
/// bit for bit those of a copy that never tried it.
#[test]
fn failed_rigid_step_leaves_nothing_behind() {
    use kinema::snapshot::Snapshot;
    let mut world = World::new(DVec3::new(0.0, -9.81, 0.0), RotationIntegrator::Splitting);
    world.add_plane(DVec3::Y, 0.0, 0.0, 0.5).unwrap();
    for k in 0..3 {
        let mut desc = body(Shape::Box { half_extents: DVec3::splat(0.1) }, DVec3::ZERO);
        desc.position = DVec3::new(0.01 * k as f64, 0.1 + 0.21 * k as f64, 0.0);
        world.add_body(&desc).unwrap();
    }
    world.step(1.0 / 60.0, 20).unwrap();
    let snapshot = world.to_snapshot().unwrap();
    let mut twin = World::from_snapshot(&snapshot).unwrap();
    let state = |w: &World| -> Vec<u64> {
        (0..w.len())
            .flat_map(|i| {
                let (x, v, q, l) =
                    (w.position(i), w.velocity(i), w.orientation(i), w.spin_angular_momentum(i));
                [x.to_array(), v.to_array(), l.to_array()]
                    .concat()
                    .into_iter()
                    .chain(q.to_array())
                    .map(f64::to_bits)
                    .collect::<Vec<_>>()
            })
            .collect()
    };
    assert!(world.step(1e300, 1).is_err());
    assert_eq!(state(&world), state(&twin));
    world.step(1.0 / 60.0, 10).unwrap();
    twin.step(1.0 / 60.0, 10).unwrap();
    assert_eq!(state(&world), state(&twin));
}

/// A step so large that a speculative contact's closing speed is lost in rounding (a ball
/// 2.5 m above the ground at dt = 1e9 s used to stop in mid-air) is refused naming `dt`, and
/// leaves the world as it was; ordinary large steps still land the ball on the ground.
#[test]
fn huge_step_with_ground_is_refused_not_frozen_in_the_air() {
    let mut world = World::new(DVec3::new(0.0, -9.81, 0.0), RotationIntegrator::Splitting);
    world.add_plane(DVec3::Y, 0.0, 0.0, 0.5).unwrap();
    let mut desc = body(Shape::Sphere { radius: 0.5 }, DVec3::ZERO);
    desc.position = DVec3::new(0.0, 3.0, 0.0);
    world.add_body(&desc).unwrap();
    match world.step(1e9, 1) {
        Err(kinema::Error::InvalidInput { arg, .. }) => assert_eq!(arg, "dt"),
        other => panic!("{other:?}"),
    }
    assert_eq!(world.position(0), DVec3::new(0.0, 3.0, 0.0));
    assert_eq!(world.velocity(0), DVec3::ZERO);
    // One step of 10 s: the speculative contact lands it exactly on the ground.
    world.step(10.0, 1).unwrap();
    assert!((world.position(0).y - 0.5).abs() < 1e-9, "{}", world.position(0));
}

#[test]
fn damping_decays_a_free_bodys_velocity_and_spin_at_the_analytic_rate() {
    // Without contacts the update is exact: v(t) = e^{−ct} v₀ + (1 − e^{−ct})/c g,
    // x(t) = x₀ + (1 − e^{−ct})/c v₀ + (t − (1 − e^{−ct})/c)/c g, and the world angular
    // momentum L(t) = e^{−c_ω t} L₀ (the damping torque −c_ω L keeps its direction).
    let g = DVec3::new(0.0, -9.81, 0.0);
    let (c, cw, t) = (0.7, 0.4, 2.0);
    let mut world = World::new(g, RotationIntegrator::Splitting);
    let mut desc = body(tumbling_box(), DVec3::new(0.3, 5.0, 0.2));
    desc.velocity = DVec3::new(3.0, 4.0, -1.0);
    world.add_body(&desc).unwrap();
    world.set_damping(0, c, cw).unwrap();
    let (x0, v0, l0) = (world.position(0), world.velocity(0), world.angular_momentum());
    world.step(0.01, 200).unwrap();
    let s = (1.0 - (-c * t).exp()) / c;
    let v = (-c * t).exp() * v0 + s * g;
    let x = x0 + s * v0 + (t - s) / c * g;
    assert!((world.velocity(0) - v).length() < 1e-13 * v.length(), "{} vs {v}", world.velocity(0));
    assert!((world.position(0) - x).length() < 1e-13 * x.length(), "{} vs {x}", world.position(0));
    let l = (-cw * t).exp() * (l0 - x0.cross(v0)) + world.position(0).cross(world.velocity(0));
    assert!((world.angular_momentum() - l).length() < 1e-12 * l.length());

    // A sphere spinning about a fixed axis turns by ω₀ (1 − e^{−c_ω t})/c_ω in all.
    let mut world = World::new(DVec3::ZERO, RotationIntegrator::Splitting);
    let w0 = DVec3::new(0.0, 0.0, 3.0);
    world.add_body(&body(Shape::Sphere { radius: 0.5 }, w0)).unwrap();
    world.set_damping(0, 0.0, cw).unwrap();
    world.step(0.01, 200).unwrap();
    assert!((world.angular_velocity(0) - (-cw * t).exp() * w0).length() < 1e-14);
    let angle = 3.0 * (1.0 - (-cw * t).exp()) / cw;
    let turned = world.orientation(0) * DQuat::from_rotation_z(angle).conjugate();
    assert!(kinema::rotation::rotation_angle(turned) < 1e-13, "{}", world.orientation(0));

    // With a ground the step is first order, but each step still multiplies the velocity and
    // the spin by e^{−c h} exactly: a sphere flying far above it decays at the exact rate.
    let mut world = World::new(g, RotationIntegrator::Splitting);
    world.add_plane(DVec3::Y, 0.0, 0.0, 0.5).unwrap();
    let mut desc = body(Shape::Sphere { radius: 0.5 }, w0);
    desc.position = DVec3::new(0.0, 100.0, 0.0);
    desc.velocity = DVec3::new(2.0, 0.0, 1.0);
    world.add_body(&desc).unwrap();
    world.set_damping(0, c, cw).unwrap();
    world.step(0.01, 200).unwrap();
    let horizontal = world.velocity(0) * DVec3::new(1.0, 0.0, 1.0);
    assert!((horizontal - (-c * t).exp() * desc.velocity).length() < 1e-13);
    assert!((world.angular_velocity(0) - (-cw * t).exp() * w0).length() < 1e-13);
    // The vertical speed follows v_{n+1} = e^{−ch} (v_n + g h): g h e^{−ch}/(1 − e^{−ch})
    // times (1 − e^{−ct}).
    let e = (-c * 0.01).exp();
    let vy = -9.81 * 0.01 * e / (1.0 - e) * (1.0 - (-c * t).exp());
    assert!((world.velocity(0).y - vy).abs() < 1e-12, "{} vs {vy}", world.velocity(0).y);
}

#[test]
fn damping_is_refused_when_negative_or_not_finite() {
    let mut world = World::new(DVec3::ZERO, RotationIntegrator::Splitting);
    world.add_body(&body(Shape::Sphere { radius: 0.5 }, DVec3::ZERO)).unwrap();
    for (l, a, arg) in [
        (-1.0, 0.0, "linear_damping"),
        (f64::NAN, 0.0, "linear_damping"),
        (0.0, f64::INFINITY, "angular_damping"),
    ] {
        let err = world.set_damping(0, l, a).unwrap_err().to_string();
        assert!(err.contains(arg), "{err}");
    }
    assert!(world.set_damping(1, 0.0, 0.0).is_err());
    assert_eq!(world.damping(0), (0.0, 0.0));
}

/// The bits of the position, velocity, orientation and angular velocity of a tumbling box
/// pushed off-centre in its first step, after 300 steps of 1/240 s in a free world (the
/// closed-form update) and in a world with a ground plane far below it (the contact step,
/// with no contact).
fn undamped_fingerprint() -> Vec<u64> {
    let mut out = Vec::new();
    for ground in [false, true] {
        let mut world = World::new(DVec3::new(0.0, -9.81, 0.0), RotationIntegrator::Splitting);
        if ground {
            world.add_plane(DVec3::Y, -1e3, 0.0, 0.5).unwrap();
        }
        let mut desc = body(tumbling_box(), DVec3::new(0.3, 5.0, 0.2));
        desc.velocity = DVec3::new(1.0, 2.0, 3.0);
        world.add_body(&desc).unwrap();
        world.apply_force(0, DVec3::new(3.0, 0.0, 1.0), DVec3::new(0.1, 0.2, 0.3)).unwrap();
        world.step(1.0 / 240.0, 300).unwrap();
        let q = world.orientation(0);
        for v in [world.position(0), world.velocity(0), world.angular_velocity(0)] {
            out.extend(v.to_array().map(f64::to_bits));
        }
        out.extend([q.w, q.x, q.y, q.z].map(f64::to_bits));
    }
    out
}

#[test]
fn zero_damping_leaves_the_undamped_steps_bit_for_bit() {
    // The bits of the same scenario on the commit before damping existed (857cd90, checked
    // 2026-11-26): zero damping changes nothing (the free update takes the undamped closed
    // form, the contact step multiplies by e^0 = 1).
    const BEFORE: [u64; 26] = [
        0x3ff43fe4b17e4b1e,
        0xc014a7fffffffffb,
        0x400e0aa61d950c8d,
        0x3ff0333333333333,
        0xc024866666666659,
        0x4008088888888889,
        0x3feba60d726e7238,
        0x4013ea25285da7ea,
        0x3fe17ae570bea4e6,
        0xbfefa228eff533c5,
        0xbfc2bc50f93088a1,
        0x3f801238417c0129,
        0xbfa26873c4ef2ed1,
        0x3ff4400000000006,
        0xc014c228f5c28f57,
        0x400e0aaaaaaaaab3,
        0x3ff0333333333333,
        0xc024866666666659,
        0x4008088888888889,
        0x3febb05b75b3b69c,
        0x4013ea13adaf6a7f,
        0x3fe17ebb644b655d,
        0xbfefa1e65fd93ba5,
        0xbfc2c2cb635be238,
        0x3f80103d06b78b94,
        0xbfa2715e764bbefc,
    ];
    assert_eq!(undamped_fingerprint(), BEFORE);
}
