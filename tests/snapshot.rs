//! Snapshots: a system restored mid-run continues bit for bit as if it had never stopped
//! (integrator history, warm starts, emitter random numbers included); foreign and damaged
//! bytes are refused with a clear error.

use glam::{DQuat, DVec3};
use kinema::cloth::{Cloth, Elasticity, LinearSolver, Material, Mesh, SolveOptions, Triangulation};
use kinema::geometry::{self, Solid as Shape};
use kinema::ode::Method;
use kinema::particles::{Appearance, Collider, Emitter, Force, ParticleSystem};
use kinema::rigid::{BodyDesc, JointDesc, JointKind, JointMethod, RotationIntegrator, World};
use kinema::snapshot::Snapshot;
use kinema::Error;

const G: DVec3 = DVec3::new(0.0, -9.81, 0.0);

/// Run `first` steps, snapshot, run `rest` on both the original and the restored copy, and
/// return both final fingerprints (every `f64` of the observable state, as bits).
fn resume_matches<T: Snapshot>(
    mut system: T,
    step: impl Fn(&mut T),
    state: impl Fn(&T) -> Vec<u64>,
    first: usize,
    rest: usize,
) {
    for _ in 0..first {
        step(&mut system);
    }
    let bytes = system.to_snapshot().unwrap();
    let mut restored = T::from_snapshot(&bytes).unwrap();
    for _ in 0..rest {
        step(&mut system);
        step(&mut restored);
    }
    let (a, b) = (state(&system), state(&restored));
    assert_eq!(a.len(), b.len());
    assert!(a == b, "resumed run differs from the uninterrupted one");
}

fn bits(values: impl IntoIterator<Item = f64>) -> Vec<u64> {
    values.into_iter().map(f64::to_bits).collect()
}

fn vec_bits(values: &[DVec3]) -> Vec<u64> {
    bits(values.iter().flat_map(|v| v.to_array()))
}

#[test]
fn cloth_resumes_bit_for_bit_with_bdf2_history_and_either_solver() {
    for solver in [LinearSolver::BlockSsor, LinearSolver::Cholesky] {
        let mesh = Mesh::grid(8, 8, 1.0, 1.0, Triangulation::Alternating).unwrap();
        let mut cloth = Cloth::new(mesh, Elasticity::BaraffWitkin, Material::default(), G).unwrap();
        cloth.pin(&[0, 7], None).unwrap();
        let options = SolveOptions { solver, ..SolveOptions::default() };
        resume_matches(
            cloth,
            |c: &mut Cloth| c.step(1.0 / 60.0, 1, Method::Bdf2, options).unwrap(),
            |c: &Cloth| [vec_bits(c.positions()), vec_bits(c.velocities())].concat(),
            5,
            10,
        );
    }
}

#[test]
fn particles_resume_bit_for_bit_with_emitters_and_collisions() {
    let mut s =
        ParticleSystem::new(&[DVec3::new(0.0, 1.0, 0.0)], &[DVec3::ZERO], &[1.0], 40).unwrap();
    s.add_force(Force::Gravity { g: G }).unwrap();
    s.add_force(Force::Drag { linear: 0.1, quadratic: 0.01, wind: DVec3::X }).unwrap();
    s.add_collider(Collider {
        shape: geometry::Shape::Plane(geometry::Plane { point: DVec3::ZERO, normal: DVec3::Y }),
        material: geometry::Material { restitution: 0.5, friction: 0.3 },
        velocity: DVec3::ZERO,
        inside: false,
    })
    .unwrap();
    s.add_emitter(Emitter {
        rate: 300.0,
        position: DVec3::new(0.0, 0.5, 0.0),
        position_spread: 0.1,
        velocity: DVec3::new(0.0, 3.0, 0.0),
        velocity_spread: 1.0,
        lifespan: 0.3,
        mass: 0.01,
        seed: 7,
        appearance: Appearance::default(),
    })
    .unwrap();
    resume_matches(
        s,
        |s: &mut ParticleSystem| s.step(1.0 / 120.0, 1, Method::Bdf2).unwrap(),
        |s: &ParticleSystem| {
            let mut v =
                bits(s.positions().iter().chain(s.velocities()).chain(s.ages().iter()).copied());
            v.extend(s.alive().iter().map(|&a| a as u64));
            v
        },
        20,
        40,
    );
}

#[test]
fn rigid_stack_resumes_bit_for_bit_with_warm_started_contacts() {
    let mut w = World::new(G, RotationIntegrator::Splitting);
    w.add_plane(DVec3::Y, 0.0, 0.0, 0.5).unwrap();
    for k in 0..3 {
        w.add_body(&BodyDesc {
            shape: Shape::Box { half_extents: DVec3::splat(0.1) },
            density: None,
            mass: Some(1.0),
            position: DVec3::new(0.01 * k as f64, 0.1 + 0.21 * k as f64, 0.0),
            orientation: DQuat::from_rotation_y(0.1 * k as f64),
            velocity: DVec3::ZERO,
            angular_velocity: DVec3::ZERO,
            fixed: false,
            restitution: 0.0,
            friction: 0.5,
        })
        .unwrap();
    }
    resume_matches(
        w,
        |w: &mut World| w.step(1.0 / 60.0, 1).unwrap(),
        |w: &World| {
            bits((0..w.len()).flat_map(|i| {
                let (x, q) = (w.position(i), w.orientation(i));
                let (v, om) = (w.velocity(i), w.angular_velocity(i));
                [x.to_array(), v.to_array(), om.to_array()].concat().into_iter().chain(q.to_array())
            }))
        },
        30,
        30,
    );
}

#[test]
fn jointed_chains_resume_bit_for_bit_in_every_formulation() {
    // Lagrange keeps a faer factorisation (left out of the snapshot and rebuilt), impulses and
    // XPBD keep warm starts and substep state.
    for method in
        [JointMethod::Lagrange, JointMethod::Impulse, JointMethod::Xpbd, JointMethod::Penalty]
    {
        let mut w = World::new(G, RotationIntegrator::Splitting);
        w.add_plane(DVec3::Y, -1.0, 0.0, 0.5).unwrap();
        for i in 0..4 {
            w.add_body(&BodyDesc {
                shape: Shape::Box { half_extents: DVec3::new(0.2, 0.02, 0.02) },
                density: None,
                mass: Some(0.5),
                position: DVec3::new(0.2 + 0.4 * i as f64, 0.0, 0.0),
                orientation: DQuat::IDENTITY,
                velocity: DVec3::ZERO,
                angular_velocity: DVec3::ZERO,
                fixed: false,
                restitution: 0.0,
                friction: 0.5,
            })
            .unwrap();
            w.add_joint(&JointDesc {
                kind: JointKind::Hinge { limits: None, motor: None },
                method,
                a: i,
                b: if i == 0 { None } else { Some(i - 1) },
                anchor: DVec3::new(0.4 * i as f64, 0.0, 0.0),
                axis: DVec3::Z,
                stiffness: 1e4,
                damping: 10.0,
            })
            .unwrap();
        }
        resume_matches(
            w,
            |w: &mut World| w.step(1.0 / 240.0, 1).unwrap(),
            |w: &World| {
                bits(
                    (0..w.len()).flat_map(|i| {
                        [w.position(i).to_array(), w.velocity(i).to_array()].concat()
                    }),
                )
            },
            50,
            50,
        );
    }
}

#[test]
fn foreign_damaged_and_truncated_snapshots_are_refused() {
    let mesh = Mesh::grid(3, 3, 1.0, 1.0, Triangulation::Regular).unwrap();
    let cloth = Cloth::new(mesh, Elasticity::MassSpring, Material::default(), G).unwrap();
    let bytes = cloth.to_snapshot().unwrap();
    let message = |r: Result<World, Error>| r.unwrap_err().to_string();
    assert!(message(World::from_snapshot(&bytes)).contains("'Cloth'"));
    let reason = |r: kinema::Result<Cloth>| r.unwrap_err().to_string();
    assert!(
        reason(Cloth::from_snapshot(b"PK\x03\x04 a zip file")).contains("not a kinema snapshot")
    );
    assert!(reason(Cloth::from_snapshot(&bytes[..bytes.len() / 2])).contains("damaged"));
    let mut longer = bytes.clone();
    longer.push(0);
    assert!(reason(Cloth::from_snapshot(&longer)).contains("trailing"));
    // Another snapshot version is refused, not misread.
    let mut old = bytes.clone();
    old[13] ^= 0xff; // first byte of the version after "kinema:Cloth:"
    assert!(reason(Cloth::from_snapshot(&old)).contains("version"));
    assert_eq!(Cloth::from_snapshot(&bytes).unwrap().positions(), cloth.positions());
}
