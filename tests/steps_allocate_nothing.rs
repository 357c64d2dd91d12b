//! The rule "no allocation in a step", checked for every system and its main paths: once a
//! scene has taken its first steps (which size the work buffers), further steps allocate
//! nothing, in any thread. One test, so that no other test allocates while it counts.

mod common;
use common::process_allocations;

use glam::{DQuat, DVec3};
use kinema::cloth::{
    self, Cloth, Elasticity, LinearSolver, Material, Mesh, SolveOptions, Triangulation,
};
use kinema::constraints::{ConstrainedSystem, Constraint, ConstraintSolver};
use kinema::geometry::{self, Solid as Shape};
use kinema::ode::Method;
use kinema::particles::{Appearance, Collider, Emitter, Force, ParticleSystem};
use kinema::rigid::{
    BodyDesc, JointDesc, JointKind, JointMethod, RotationIntegrator, World, PENALTY_DAMPING,
    PENALTY_STIFFNESS,
};

const G: DVec3 = DVec3::new(0.0, -9.81, 0.0);

/// Allocations made by `step` after `warm_up` calls of it, all made on a thread of rayon's
/// pool. (Each parallel loop started from a thread outside the pool sends one job through
/// rayon's global injector, which allocates a 1.5 kB block for every 63 jobs: rayon's
/// amortised cost of entering the pool, not the step's. A social-force step of 20 substeps,
/// ~120 parallel loops, met two blocks a step that way.)
fn allocations(warm_up: usize, mut step: impl FnMut() + Send) -> usize {
    rayon::scope(|_| {
        for _ in 0..warm_up {
            step();
        }
        let before = process_allocations();
        step();
        process_allocations() - before
    })
}

/// `n` particles in a 1 m cube above the ground, moving.
fn particles(n: usize) -> ParticleSystem {
    let x: Vec<DVec3> = (0..n)
        .map(|i| DVec3::new((i % 97) as f64, (i % 89) as f64 + 1.0, (i % 83) as f64) / 97.0)
        .collect();
    let v: Vec<DVec3> = (0..n).map(|i| DVec3::new(1.0, (i % 7) as f64 - 3.0, 0.5)).collect();
    ParticleSystem::new(&x, &v, &vec![1.0; n], n + 1000).unwrap()
}

fn ground() -> Collider {
    Collider {
        shape: geometry::Shape::Plane(geometry::Plane { point: DVec3::ZERO, normal: DVec3::Y }),
        material: geometry::Material { restitution: 0.5, friction: 0.3 },
        velocity: DVec3::ZERO,
        inside: false,
    }
}

fn particle_scenes() -> Vec<(String, usize)> {
    let mut found = Vec::new();
    // The blocked explicit kernel, on enough particles to run on several threads.
    let mut s = particles(100_000);
    s.add_force(Force::Gravity { g: G }).unwrap();
    s.add_force(Force::Drag { linear: 0.0, quadratic: 0.01, wind: DVec3::ZERO }).unwrap();
    s.add_collider(ground()).unwrap();
    found.push((
        "particles, symplectic Euler kernel".into(),
        allocations(2, || s.step(1e-3, 3, Method::SymplecticEuler).unwrap()),
    ));
    // The general path: springs, a neighbour force, fields, an emitter, a sphere.
    for method in [Method::Rk4, Method::VelocityVerlet, Method::SymplecticEuler] {
        let mut s = particles(2000);
        s.add_force(Force::Gravity { g: G }).unwrap();
        let pairs = (0..1999).map(|i| [i, i + 1]).collect();
        s.add_force(Force::Springs {
            pairs,
            rest: vec![0.01; 1999],
            stiffness: 10.0,
            damping: 0.1,
        })
        .unwrap();
        s.add_force(Force::NeighborRepulsion { radius: 0.02, stiffness: 10.0 }).unwrap();
        s.add_force(Force::Turbulence { strength: 1.0, scale: 0.5, seed: 3 }).unwrap();
        s.add_collider(ground()).unwrap();
        s.add_collider(Collider {
            shape: geometry::Shape::Sphere(geometry::Sphere {
                center: DVec3::new(0.5, 0.5, 0.5),
                radius: 0.2,
            }),
            material: geometry::Material { restitution: 0.2, friction: 0.5 },
            velocity: DVec3::ZERO,
            inside: false,
        })
        .unwrap();
        s.add_emitter(Emitter {
            rate: 5000.0,
            position: DVec3::new(0.5, 1.0, 0.5),
            position_spread: 0.1,
            velocity: DVec3::Y,
            velocity_spread: 0.5,
            lifespan: 0.05,
            mass: 1.0,
            seed: 1,
            appearance: Appearance::default(),
        })
        .unwrap();
        found.push((
            format!("particles, {} with every kind of force", method.name()),
            allocations(30, || s.step(1e-3, 2, method).unwrap()),
        ));
    }
    found
}

fn cloth_scenes() -> Vec<(String, usize)> {
    let mut found = Vec::new();
    let runs = [
        (Elasticity::BaraffWitkin, Method::ImplicitEuler, LinearSolver::BlockSsor),
        (Elasticity::BaraffWitkin, Method::ImplicitEuler, LinearSolver::Cholesky),
        (Elasticity::BaraffWitkin, Method::Bdf2, LinearSolver::BlockSsor),
        (Elasticity::MassSpring, Method::ImplicitEuler, LinearSolver::BlockSsor),
        (Elasticity::BaraffWitkin, Method::ImplicitEuler, LinearSolver::Multigrid),
    ];
    for (k, (model, method, solver)) in runs.into_iter().enumerate() {
        let mesh = Mesh::grid(16, 16, 1.0, 1.0, Triangulation::Alternating).unwrap();
        let mut c = Cloth::new(mesh, model, Material::default(), G).unwrap();
        if k == 0 {
            c.set_self_collision(Some(cloth::SelfCollision::default())).unwrap();
        }
        if k == 1 {
            // A moving triangle-mesh collider (a tetrahedron rising into the sheet).
            let v = [[0.0, -0.4, 0.0], [0.3, -0.4, 0.0], [0.0, -0.4, 0.3], [0.1, -0.1, 0.1]];
            let tet = cloth::MeshCollider::new(
                v.map(DVec3::from_array).to_vec(),
                vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]],
                Some(vec![DVec3::new(0.0, 1.0, 0.0); 4]),
                0.5,
            )
            .unwrap();
            c.add_mesh_collider(tet);
        }
        c.pin(&[0, 15], None).unwrap();
        c.add_collider(cloth::Collider {
            shape: geometry::Shape::Sphere(geometry::Sphere {
                center: DVec3::new(0.5, -0.3, 0.5),
                radius: 0.25,
            }),
            velocity: DVec3::ZERO,
            friction: 0.3,
        })
        .unwrap();
        let options = SolveOptions { solver, ..SolveOptions::default() };
        found.push((
            format!("cloth, {model:?} {} {solver:?}", method.name()),
            allocations(5, || c.step(1.0 / 60.0, 1, method, options).unwrap()),
        ));
    }
    found
}

fn rigid_scenes() -> Vec<(String, usize)> {
    let body = |shape, position| BodyDesc {
        shape,
        density: None,
        mass: Some(0.5),
        position,
        orientation: DQuat::from_rotation_z(0.1),
        velocity: DVec3::ZERO,
        angular_velocity: DVec3::ZERO,
        fixed: false,
        restitution: 0.2,
        friction: 0.6,
    };
    let mut found = Vec::new();
    // Boxes falling onto the ground and onto each other: contacts come and go.
    let mut w = World::new(G, RotationIntegrator::Splitting);
    w.add_plane(DVec3::Y, 0.0, 0.2, 0.6).unwrap();
    for i in 0..27 {
        let p = DVec3::new((i % 3) as f64 * 0.25, 0.2 + (i / 3) as f64 * 0.3, (i % 2) as f64 * 0.1);
        w.add_body(&body(Shape::Box { half_extents: DVec3::splat(0.1) }, p)).unwrap();
    }
    found.push((
        "rigid, boxes in contact".into(),
        allocations(240, || w.step(1.0 / 240.0, 4).unwrap()),
    ));
    // A hinged chain that falls onto the ground, in every joint formulation.
    for method in
        [JointMethod::Penalty, JointMethod::Lagrange, JointMethod::Impulse, JointMethod::Xpbd]
    {
        let mut w = World::new(G, RotationIntegrator::Splitting);
        w.add_plane(DVec3::Y, 0.0, 0.2, 0.6).unwrap();
        for i in 0..5 {
            let half = DVec3::new(0.2, 0.02, 0.02);
            w.add_body(&body(
                Shape::Box { half_extents: half },
                DVec3::new(0.2 + 0.4 * i as f64, 0.3, 0.0),
            ))
            .unwrap();
            w.add_joint(&JointDesc {
                kind: JointKind::Hinge { limits: Some((-1.0, 1.0)), motor: None },
                method,
                a: i,
                b: if i == 0 { None } else { Some(i - 1) },
                anchor: DVec3::new(0.4 * i as f64, 0.3, 0.0),
                axis: DVec3::Z,
                stiffness: PENALTY_STIFFNESS,
                damping: PENALTY_DAMPING,
            })
            .unwrap();
        }
        // Penalty springs are explicit forces: stable for this chain below ≈ 2.2 ms.
        let dt = if method == JointMethod::Penalty { 1e-3 } else { 1.0 / 240.0 };
        found.push((
            format!("rigid, hinged chain ({method:?})"),
            allocations(240, || w.step(dt, 4).unwrap()),
        ));
    }
    found
}

fn constrained_scenes() -> Vec<(String, usize)> {
    let mut found = Vec::new();
    for solver in [ConstraintSolver::Cholesky, ConstraintSolver::ConjugateGradient] {
        let xs: Vec<DVec3> = (0..20).map(|i| DVec3::new(0.05 * i as f64, 0.0, 0.0)).collect();
        let mut masses = vec![1.0; 20];
        masses[0] = f64::INFINITY;
        let mut p = ParticleSystem::new(&xs, &vec![DVec3::ZERO; 20], &masses, 20).unwrap();
        p.add_force(Force::Gravity { g: G }).unwrap();
        let mut c = ConstrainedSystem::new(100.0, 20.0, solver).unwrap();
        for i in 0..19 {
            c.add(&p, Constraint::Distance { i, j: i + 1, length: 0.05 }).unwrap();
        }
        found.push((
            format!("constraints, rope ({solver:?})"),
            allocations(5, || c.step(&mut p, 1e-3, 2, Method::Rk4).unwrap()),
        ));
        found.push((
            format!("constraints, rope by projection ({solver:?})"),
            allocations(5, || c.step_projection(&mut p, 1.0 / 60.0, 1).unwrap()),
        ));
    }
    found
}

/// 2000 agents in a block walking together (neighbour lists that do not grow), by ORCA and
/// by social forces; 5000 boids flying together.
fn crowd_scenes() -> Vec<(String, usize)> {
    use glam::DVec2;
    use kinema::crowd::{Crowd, Kind, Settings, SocialForce};
    let orca = Settings { radius: 0.25, neighbour_distance: 2.0, ..Settings::rvo2_circle() };
    let social = Settings { kind: Kind::SocialForce(SocialForce::default()), ..orca };
    let mut found = Vec::new();
    for (name, settings) in [("crowd, ORCA", orca), ("crowd, social forces", social)] {
        let mut crowd = Crowd::new(settings).unwrap();
        let p: Vec<DVec2> =
            (0..2000).map(|i| DVec2::new((i % 50) as f64, (i / 50) as f64)).collect();
        let g: Vec<DVec2> = p.iter().map(|q| *q + DVec2::new(1000.0, 0.0)).collect();
        crowd.add_agents(&p, &g).unwrap();
        // An obstacle far aside: its edges are visited each step, never in range.
        crowd.add_obstacle(&[DVec2::new(0.0, -500.0), DVec2::new(2000.0, -500.0)]).unwrap();
        found.push((name.into(), allocations(3, || crowd.step(0.1, 1).unwrap())));
    }
    let boids: Vec<DVec3> =
        (0..5000).map(|i| DVec3::new((i % 70) as f64, (i / 70) as f64, 0.0)).collect();
    let mut flock =
        kinema::flock::Flock::new(Default::default(), &boids, &vec![DVec3::X; 5000]).unwrap();
    found.push(("flock".into(), allocations(3, || flock.step(0.1, 1).unwrap())));
    found
}

/// The CMU ragdoll falling limp onto the ground (contacts and joint limits active), and the
/// planar and 3-D SIMBICON walkers.
fn character_scenes() -> Vec<(String, usize)> {
    use kinema::character::{
        ragdoll, ArticulatedBody, Coronal, Gait, RagdollOptions, Settings, Walker, Walker3d,
    };
    let text = std::fs::read_to_string("tests/data/mocap/07-walk.asf").unwrap();
    let skeleton = kinema::mocap::parse_asf(&text, "07-walk.asf").unwrap();
    let options = RagdollOptions {
        scale: skeleton.metres_per_unit(),
        clearance: 0.3,
        ..RagdollOptions::default()
    };
    let mut body = ArticulatedBody::new(ragdoll(&skeleton, &options, Settings::default()).unwrap());
    let mut planar = Walker::new(Settings::default(), Gait::default(), 0.3).unwrap();
    let mut spatial =
        Walker3d::new(Settings::default(), Gait::default_3d(), Coronal::default(), 0.3).unwrap();
    vec![
        ("character, ragdoll".into(), allocations(120, || body.step(1.0 / 480.0, 4).unwrap())),
        ("character, planar walker".into(), allocations(50, || planar.step(1e-3, 4).unwrap())),
        ("character, 3-D walker".into(), allocations(50, || spatial.step(1e-3, 4).unwrap())),
    ]
}

/// A hair of 100 curly strands on a turning head (repulsion with friction between strands
/// active, the head a collider, several tasks), a rod on a plane with friction, and a pinned
/// inextensible rod with the quasi-static twist.
fn rod_scenes() -> Vec<(String, usize)> {
    use kinema::rods::{Collider, Hair, Material, Repulsion, Rod, Settings};
    let material =
        Material { youngs_modulus: 1e9, shear_modulus: 4e8, density: 1300.0, radius: [1e-4; 2] };
    let normals: Vec<DVec3> = (0..100)
        .map(|i| DVec3::new((i % 10) as f64 * 0.05 - 0.25, 1.0, (i / 10) as f64 * 0.05 - 0.25))
        .collect();
    let points: Vec<DVec3> = normals.iter().map(|n| 0.1 * n.normalize()).collect();
    let repulsion = Repulsion { stiffness: 1e2, thickness: 2e-4, friction: 0.3 };
    let settings = Settings::default();
    let mut hair =
        Hair::groom(&points, &normals, 0.05, 16, 0.004, material, settings, repulsion).unwrap();
    hair.set_head_collider(geometry::Sphere { center: DVec3::ZERO, radius: 0.1 }).unwrap();
    let mut angle = 0.0;
    let mut turn = || {
        angle += 0.05;
        hair.set_head(DQuat::from_rotation_y(angle), DVec3::ZERO).unwrap();
        hair.step(1.0 / 60.0, 2).unwrap();
    };
    let mut found = vec![("rods, hair".to_string(), allocations(3, &mut turn))];
    let points: Vec<DVec3> = (0..=20).map(|i| DVec3::new(0.01 * i as f64, 0.01, 0.0)).collect();
    let mut rod = Rod::new(&points, material, settings, None).unwrap();
    let plane = geometry::Shape::Plane(geometry::Plane { point: DVec3::ZERO, normal: DVec3::Y });
    rod.model_mut().add_collider(Collider { shape: plane, friction: 0.3 }).unwrap();
    found
        .push(("rods, rod on a plane".into(), allocations(3, || rod.step(1.0 / 60.0, 2).unwrap())));
    let constrained = Settings { inextensible: true, quasistatic_twist: true, ..settings };
    let mut rod = Rod::new(&points, material, constrained, None).unwrap();
    rod.model_mut().pin(0).unwrap();
    found.push((
        "rods, inextensible rod with the quasi-static twist".into(),
        allocations(3, || rod.step(1.0 / 60.0, 2).unwrap()),
    ));
    found
}

/// A dam of fluid in a tank with a sphere moving through it: DFSPH (the default) with the
/// implicit viscosity, WCSPH with XSPH and surface tension, and PBF.
fn fluid_scenes() -> Vec<(String, usize)> {
    use kinema::fluid::{Collider, Fluid, Pressure, Settings, Viscosity, Wall};
    let s = 0.02;
    let runs = [
        ("DFSPH, implicit viscosity", Pressure::DFSPH, Viscosity::Implicit(1e-3), 0.0),
        ("WCSPH, XSPH and surface tension", Pressure::WCSPH, Viscosity::Xsph(0.01), 0.05),
        ("PBF", Pressure::PBF, Viscosity::Xsph(0.01), 0.0),
    ];
    let mut found = Vec::new();
    for (name, pressure, viscosity, surface_tension) in runs {
        let settings = Settings { pressure, viscosity, surface_tension, ..Settings::new(s) };
        let mut fluid = Fluid::new(settings).unwrap();
        fluid.add_wall(Wall::Box { lower: DVec3::ZERO, upper: DVec3::new(0.4, 0.3, 0.2) }).unwrap();
        let ball = geometry::Sphere { center: DVec3::new(0.3, 0.08, 0.1), radius: 0.05 };
        let velocity = DVec3::new(-0.2, 0.0, 0.0);
        fluid.add_collider(Collider { shape: geometry::Shape::Sphere(ball), velocity }).unwrap();
        let lower = DVec3::splat(0.5 * s);
        fluid.add_block(lower, DVec3::new(0.16, 0.2, 0.2 - 0.5 * s), DVec3::ZERO).unwrap();
        found.push((
            format!("fluid, {name}"),
            allocations(3, || fluid.step(1.0 / 240.0, 1).unwrap()),
        ));
    }
    found
}

#[test]
fn steps_allocate_nothing_once_warmed_up() {
    let found: Vec<(String, usize)> = [
        particle_scenes(),
        cloth_scenes(),
        rigid_scenes(),
        constrained_scenes(),
        crowd_scenes(),
        character_scenes(),
        rod_scenes(),
        fluid_scenes(),
    ]
    .into_iter()
    .flatten()
    .collect();
    let allocating: Vec<&(String, usize)> = found.iter().filter(|(_, n)| *n > 0).collect();
    assert!(allocating.is_empty(), "steps that allocated (scene, allocations): {allocating:?}");
}
