//! Corrupt snapshots cannot panic: for every snapshot type, damaged bytes (bit flips,
//! truncations, runs of random bytes, at fixed seeds) either are refused by `from_snapshot`
//! with an error, or load into a system whose next steps (or evaluations) return `Ok` or an
//! error — never a panic.

use std::panic::{catch_unwind, AssertUnwindSafe};

use glam::{DQuat, DVec3};
use kinema::anim::{
    ArcLengthCurve, Extrapolation, Interpolation, RotationInterpolation, RotationTrack, Track,
};
use kinema::cloth::{
    Cloth, Collider as ClothCollider, Elasticity, LinearSolver, Material, Mesh, SolveOptions,
    Triangulation,
};
use kinema::constraints::{ConstrainedSystem, Constraint, ConstraintSolver};
use kinema::geometry::{self, Solid as Shape};
use kinema::mocap::{parse_amc, parse_asf, parse_bvh, BvhSkeleton, Motion, Skeleton};
use kinema::ode::Method;
use kinema::particles::{Appearance, Collider, Emitter, Force, ParticleSystem};
use kinema::rigid::{BodyDesc, JointDesc, JointKind, JointMethod, RotationIntegrator, World};
use kinema::snapshot::Snapshot;

const G: DVec3 = DVec3::new(0.0, -9.81, 0.0);
/// Damaged copies tried per snapshot type.
const CASES: usize = 400;

/// A small deterministic generator (xorshift64*), so every run tries the same bytes.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// Damaged copies of `bytes`; the first 16 bytes (the tag and version) are left alone so that
/// the damage reaches the decoder and the validation behind it.
fn mutants(bytes: &[u8], seed: u64) -> Vec<Vec<u8>> {
    let mut rng = Rng(seed);
    let head = bytes.len().min(16);
    (0..CASES)
        .map(|k| {
            let mut b = bytes.to_vec();
            let at = |rng: &mut Rng| head + rng.below(bytes.len() - head);
            match k % 4 {
                0 => b.truncate(at(&mut rng)),
                1 | 2 => {
                    for _ in 0..1 + rng.below(3) {
                        let i = at(&mut rng);
                        b[i] ^= 1 << rng.below(8);
                    }
                }
                _ => {
                    let i = at(&mut rng);
                    let end = (i + 1 + rng.below(8)).min(b.len());
                    for byte in &mut b[i..end] {
                        *byte = rng.next() as u8;
                    }
                }
            }
            b
        })
        .collect()
}

/// Every damaged copy of `system`'s snapshot is refused or survives `exercise` without a
/// panic; returns how many were refused and how many loaded.
fn no_panic<T: Snapshot>(system: &T, seed: u64, exercise: impl Fn(&mut T)) -> (usize, usize) {
    let bytes = system.to_snapshot().unwrap();
    let (mut refused, mut loaded) = (0, 0);
    for (k, damaged) in mutants(&bytes, seed).into_iter().enumerate() {
        let outcome = catch_unwind(AssertUnwindSafe(|| match T::from_snapshot(&damaged) {
            Err(_) => true,
            Ok(mut restored) => {
                exercise(&mut restored);
                false
            }
        }));
        match outcome {
            Ok(true) => refused += 1,
            Ok(false) => loaded += 1,
            Err(_) => panic!("damaged snapshot {k} of {} (seed {seed}) panicked", T::TAG),
        }
    }
    assert!(refused > CASES / 8, "{}: only {refused} of {CASES} refused", T::TAG);
    (refused, loaded)
}

fn cloth() -> Cloth {
    let mesh = Mesh::grid(4, 4, 1.0, 1.0, Triangulation::Alternating).unwrap();
    let mut c = Cloth::new(mesh, Elasticity::BaraffWitkin, Material::default(), G).unwrap();
    c.pin(&[0, 3], None).unwrap();
    c.add_collider(ClothCollider {
        shape: geometry::Shape::Plane(geometry::Plane {
            point: DVec3::new(0.0, -0.5, 0.0),
            normal: DVec3::Y,
        }),
        velocity: DVec3::ZERO,
        friction: 0.3,
    })
    .unwrap();
    c.step(0.01, 2, Method::Bdf2, SolveOptions::default()).unwrap();
    c
}

#[test]
fn damaged_cloth_snapshots_never_panic() {
    let mut springs = Cloth::new(
        Mesh::grid(3, 3, 1.0, 1.0, Triangulation::Regular).unwrap(),
        Elasticity::MassSpring,
        Material::default(),
        G,
    )
    .unwrap();
    springs.step(0.01, 1, Method::ImplicitEuler, SolveOptions::default()).unwrap();
    for (seed, c) in [(1, cloth()), (2, springs)] {
        no_panic(&c, seed, |c| {
            for solver in [LinearSolver::BlockSsor, LinearSolver::Cholesky] {
                let options = SolveOptions { solver, ..SolveOptions::default() };
                let _ = c.step(0.01, 1, Method::Bdf2, options);
                let _ = c.step(0.01, 1, Method::ImplicitEuler, options);
            }
            let _ = c.step(0.001, 1, Method::Rk4, SolveOptions::default());
            let _ = c.energy();
        });
    }
}

#[test]
fn damaged_particle_snapshots_never_panic() {
    let x: Vec<DVec3> = (0..6).map(|i| DVec3::new(0.1 * i as f64, 1.0, 0.0)).collect();
    let mut s = ParticleSystem::new(&x, &[DVec3::ZERO; 6], &[1.0; 6], 12).unwrap();
    s.add_force(Force::Gravity { g: G }).unwrap();
    s.add_force(Force::Springs {
        pairs: vec![[0, 1], [1, 2]],
        rest: vec![0.1, 0.1],
        stiffness: 50.0,
        damping: 0.5,
    })
    .unwrap();
    s.add_force(Force::NeighborRepulsion { radius: 0.15, stiffness: 10.0 }).unwrap();
    s.add_collider(Collider {
        shape: geometry::Shape::Plane(geometry::Plane { point: DVec3::ZERO, normal: DVec3::Y }),
        material: geometry::Material { restitution: 0.5, friction: 0.3 },
        velocity: DVec3::ZERO,
        inside: false,
    })
    .unwrap();
    s.add_emitter(Emitter {
        rate: 100.0,
        position: DVec3::new(0.0, 0.5, 0.0),
        position_spread: 0.1,
        velocity: DVec3::new(0.0, 3.0, 0.0),
        velocity_spread: 1.0,
        lifespan: 0.05,
        mass: 0.01,
        seed: 7,
        appearance: Appearance::default(),
    })
    .unwrap();
    s.step(0.01, 3, Method::SymplecticEuler).unwrap();
    no_panic(&s, 3, |s| {
        for method in [Method::SymplecticEuler, Method::Rk4, Method::ImplicitEuler, Method::Bdf2] {
            let _ = s.step(0.01, 2, method);
        }
        let _ = (s.kinetic_energy(), s.potential_energy());
    });
}

#[test]
fn damaged_constrained_snapshots_never_panic() {
    let x: Vec<DVec3> = (0..4).map(|i| DVec3::new(0.3 * i as f64, 1.0, 0.0)).collect();
    let mut p = ParticleSystem::new(&x, &[DVec3::ZERO; 4], &[1.0; 4], 4).unwrap();
    p.add_force(Force::Gravity { g: G }).unwrap();
    for (seed, solver) in
        [(4, ConstraintSolver::Cholesky), (5, ConstraintSolver::ConjugateGradient)]
    {
        let mut c = ConstrainedSystem::new(1.0, 1.0, solver).unwrap();
        for i in 0..3 {
            c.add(&p, Constraint::Distance { i, j: i + 1, length: 0.3 }).unwrap();
        }
        let mut q = p.clone();
        c.step(&mut q, 0.01, 2, Method::Rk4).unwrap();
        no_panic(&c, seed, |c| {
            let mut q = p.clone();
            let _ = c.step(&mut q, 0.01, 2, Method::Rk4);
        });
    }
}

fn body(shape: Shape, position: DVec3) -> BodyDesc {
    BodyDesc {
        shape,
        density: None,
        mass: Some(1.0),
        position,
        orientation: DQuat::from_rotation_y(0.2),
        velocity: DVec3::ZERO,
        angular_velocity: DVec3::new(0.0, 0.5, 0.0),
        fixed: false,
        restitution: 0.0,
        friction: 0.5,
    }
}

#[test]
fn damaged_rigid_snapshots_never_panic() {
    for (seed, method) in
        [(6, JointMethod::Lagrange), (7, JointMethod::Impulse), (8, JointMethod::Xpbd)]
    {
        let mut w = World::new(G, RotationIntegrator::Splitting);
        w.add_plane(DVec3::Y, 0.0, 0.0, 0.5).unwrap();
        w.add_body(&body(
            Shape::Box { half_extents: DVec3::splat(0.1) },
            DVec3::new(0.0, 0.1, 0.0),
        ))
        .unwrap();
        w.add_body(&body(Shape::Sphere { radius: 0.1 }, DVec3::new(0.05, 0.3, 0.0))).unwrap();
        w.add_body(&body(
            Shape::Box { half_extents: DVec3::splat(0.1) },
            DVec3::new(0.5, 0.5, 0.0),
        ))
        .unwrap();
        w.add_joint(&JointDesc {
            kind: JointKind::Hinge { limits: None, motor: None },
            method,
            a: 2,
            b: None,
            anchor: DVec3::new(0.5, 0.7, 0.0),
            axis: DVec3::Z,
            stiffness: 1e4,
            damping: 10.0,
        })
        .unwrap();
        w.step(0.01, 3).unwrap();
        no_panic(&w, seed, |w| {
            let _ = w.step(0.01, 3);
            let _ = w.kinetic_energy();
        });
    }
}

#[test]
fn damaged_track_snapshots_never_panic() {
    let times = [0.0, 0.5, 1.0, 2.0];
    let values = [0.0, 1.0, 0.5, 0.2, 1.0, 0.0, 0.3, 0.3];
    let probe = [-1.0, 0.0, 0.3, 0.99, 1.5, 2.0, 7.0];
    for (seed, scheme) in [
        (9, Interpolation::Polynomial),
        (10, Interpolation::NaturalCubic),
        (15, Interpolation::Step),
    ] {
        let t = Track::new(&times, &values, 2, scheme, Extrapolation::Cycle).unwrap();
        no_panic(&t, seed, |t| {
            let mut out = vec![0.0; probe.len() * t.dim()];
            for order in 0..3 {
                let _ = t.eval_many(&probe, order, &mut out);
            }
        });
    }
    let quats: Vec<[f64; 4]> =
        (0..4).map(|i| DQuat::from_rotation_x(0.7 * i as f64).to_array()).collect();
    let r = RotationTrack::new(&times, &quats, RotationInterpolation::Squad, &[true; 3]).unwrap();
    no_panic(&r, 11, |r| {
        let mut out = vec![[0.0; 4]; probe.len()];
        let _ = r.eval_many(&probe, &mut out);
    });
    let t = Track::new(&times, &values, 2, Interpolation::NaturalCubic, Extrapolation::Hold);
    let curve = ArcLengthCurve::new(t.unwrap(), 1e-8).unwrap();
    no_panic(&curve, 16, |c| {
        let s: Vec<[f64; 1]> = probe.iter().map(|&p| [p]).collect();
        let mut out = vec![[0.0]; s.len()];
        let _ = c.times_at(&s, &mut out);
    });
}

const BVH: &str = "HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Chest
  {
    OFFSET 0 5 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0 5 0
    }
  }
}
MOTION
Frames: 3
Frame Time: 0.0333333
0 10 0 0 0 0 0 0 0
1 10 0 10 0 0 5 0 0
2 10 0 20 0 0 10 0 0
";

fn fk_skeleton(s: &Skeleton, m: &Motion) {
    let joints = 1 + s.bones.len();
    let mut x = vec![[0.0; 3]; joints * m.frames.min(64)];
    let mut q = vec![[0.0; 4]; x.len()];
    if m.frames <= 64 {
        let _ = s.forward_kinematics(m, &mut x, &mut q);
    }
}

#[test]
fn damaged_mocap_snapshots_never_panic() {
    let asf = include_str!("data/mocap/09-run.asf");
    let amc: String =
        include_str!("data/mocap/09_06-run.amc").split("\n4\n").next().unwrap().to_string();
    let skeleton = parse_asf(asf, "09-run.asf").unwrap();
    let motion = parse_amc(&amc, "09_06-run.amc", &skeleton).unwrap();
    assert_eq!(motion.frames, 3);
    no_panic(&skeleton, 12, |s| fk_skeleton(s, &motion));
    no_panic(&motion, 13, |m| fk_skeleton(&skeleton, m));
    let (bvh, bvh_motion): (BvhSkeleton, Motion) = parse_bvh(BVH, "inline.bvh").unwrap();
    no_panic(&bvh, 14, |s| {
        let mut x = vec![[0.0; 3]; 3 * 3];
        let mut q = vec![[0.0; 4]; x.len()];
        let _ = s.forward_kinematics(&bvh_motion, &mut x, &mut q);
    });
}
