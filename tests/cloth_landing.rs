//! A sheet landing on a sphere (issue #21, the 128² drape's landing): the short substeps of a
//! landing must add no momentum, energy or speed that the fall does not give. Contacts only
//! push, so the sheet's mean vertical velocity can never be faster downward than its free
//! fall; the contacts are inelastic, the material damped and implicit Euler dissipative, so
//! its energy (kinetic, gravitational, elastic) must not grow.

use glam::DVec3;
use kinema::cloth::{Cloth, Collider, Elasticity, Material, Mesh, SolveOptions, Triangulation};
use kinema::geometry::{Shape, Sphere};
use kinema::ode::Method;

const G: f64 = 9.81;
const DT: f64 = 1.0 / 60.0;
/// The sheet's speed when its centre is `GAP` m above the sphere (m/s): the 128² drape of
/// `bench/bench_cloth.py` lands at 1.64 m/s.
const SPEED: f64 = 1.64;
const GAP: f64 = 0.005;

/// A 64² sheet of 1 m of the default material falling at `SPEED`, its centre `GAP` above a
/// sphere of radius 0.3 m (friction 0.5).
fn falling_sheet() -> Cloth {
    let n = 64;
    let mesh = Mesh::grid(n, n, 1.0, 1.0, Triangulation::Alternating).unwrap();
    let gravity = DVec3::new(0.0, -G, 0.0);
    let mut cloth =
        Cloth::new(mesh, Elasticity::BaraffWitkin, Material::default(), gravity).unwrap();
    let x: Vec<DVec3> = cloth.positions().iter().map(|p| *p + DVec3::Y * (0.6 + GAP)).collect();
    cloth.set_state(&x, &vec![DVec3::new(0.0, -SPEED, 0.0); x.len()]).unwrap();
    let sphere = Shape::Sphere(Sphere { center: DVec3::new(0.0, 0.3, 0.0), radius: 0.3 });
    cloth.add_collider(Collider { shape: sphere, velocity: DVec3::ZERO, friction: 0.5 }).unwrap();
    cloth
}

/// What the end of a step shows: largest vertex speed (m/s), mean vertical velocity (m/s,
/// weighted by mass), total energy (J) and the Newton iterations of its last substep.
struct Landing {
    largest_speed: f64,
    mean_vy: f64,
    energy: f64,
    newton_iterations: usize,
}

fn energy(cloth: &Cloth) -> f64 {
    let (kinetic, gravity, elastic) = cloth.energy();
    kinetic + gravity + elastic
}

/// Three steps of `DT` from `falling_sheet`, each taken as `substeps` steps of
/// `DT / substeps` (subdivision by the strain change off, so that the substeps are forced),
/// at the default options otherwise; the energy at the start and the end of each step.
fn land(substeps: usize) -> (f64, Vec<Landing>) {
    let options = SolveOptions { max_strain_change: f64::INFINITY, ..SolveOptions::default() };
    land_with(substeps, options)
}

/// Three steps of `DT` from `falling_sheet`, each as `substeps` steps of `DT / substeps` with
/// `options`; the energy at the start and what the end of each step shows.
fn land_with(substeps: usize, options: SolveOptions) -> (f64, Vec<Landing>) {
    let mut cloth = falling_sheet();
    let start = energy(&cloth);
    let mass: f64 = cloth.masses().iter().sum();
    let steps = (0..3)
        .map(|_| {
            cloth.step(DT / substeps as f64, substeps, Method::ImplicitEuler, options).unwrap();
            let v = cloth.velocities();
            let momentum: f64 = v.iter().zip(cloth.masses()).map(|(v, m)| v.y * m).sum();
            Landing {
                largest_speed: v.iter().map(|v| v.length()).fold(0.0, f64::max),
                mean_vy: momentum / mass,
                energy: energy(&cloth),
                newton_iterations: cloth.stats().newton_iterations,
            }
        })
        .collect();
    (start, steps)
}

/// The landing in one step, in 8 and in 16 substeps: in every step the mean vertical velocity
/// is no faster downward than the free fall's `SPEED + g t`; in the landing step (the first)
/// the largest speed is within 20 % of the free fall's; with substeps the energy never exceeds
/// the start's. (Taken whole, the energy is the next test's.) Before the contacts that pull in a solve were released
/// within the step, 8 substeps ended the landing step with a largest speed of 3.64 m/s (free
/// fall 1.80), a mean vertical velocity of -1.823 m/s (free fall -1.803) and 7.98 J from
/// 7.28 J (seen failing); now 1.90 m/s, -1.613 m/s and 7.08 J.
#[test]
fn a_landing_adds_no_momentum_energy_or_speed_with_or_without_substeps() {
    for substeps in [1, 8, 16] {
        let (start, steps) = land(substeps);
        for (k, step) in steps.iter().enumerate() {
            let t = (k + 1) as f64 * DT;
            let fall = SPEED + G * t;
            println!(
                "{substeps} substeps, t = {t:.4} s: largest speed {:.3} m/s, mean vy {:.3} m/s \
                 (free fall {fall:.3}), energy {:.4} J (start {start:.4}), {} Newton iterations",
                step.largest_speed, step.mean_vy, step.energy, step.newton_iterations
            );
            assert!(
                step.mean_vy >= -fall,
                "{substeps} substeps, step {k}: mean vy {}",
                step.mean_vy
            );
            if k == 0 {
                assert!(
                    step.largest_speed <= 1.2 * fall,
                    "{substeps} substeps: largest speed {} after landing, free fall {fall}",
                    step.largest_speed
                );
            }
            if substeps > 1 {
                assert!(step.energy <= start, "{substeps} substeps, step {k}: {} J", step.energy);
            }
        }
    }
}

/// The landing in three whole steps with the subdivision off (issue #21): the landing step
/// ends below the start's energy with its largest speed within 10 % of the free fall's, and
/// the two steps after it gain less than 20 % and 80 % of the start's energy. With the one
/// linearised solve of Baraff & Witkin, as until session 28, the steps ended at 7.50, 10.26
/// and 22.23 J from 7.28 J and the landing step at 2.04 m/s (free fall 1.80): seen failing
/// with the Newton iterations taken out (`NEWTON = 0`). With them 7.23, 8.59 and 12.96 J and
/// 1.91 m/s. The gain left in the second and third steps is not the linearisation's: Newton
/// iterated to convergence (12 iterations, the last changing no velocity by more than
/// 7 mm/s) ends them higher, at 8.73 and 13.48 J (docs/cloth.md, "The whole-step landing's
/// Newton iterations").
#[test]
fn a_landing_in_whole_steps_with_the_subdivision_off_gains_no_energy_in_its_landing_step() {
    let (start, steps) = land(1);
    let fall = SPEED + G * DT;
    assert!(steps[0].energy <= start, "landing step: {} J from {start} J", steps[0].energy);
    assert!(
        steps[0].largest_speed <= 1.1 * fall,
        "landing step: largest speed {} m/s, free fall {fall} m/s",
        steps[0].largest_speed
    );
    assert!(steps[1].energy <= 1.2 * start, "second step: {} J from {start} J", steps[1].energy);
    assert!(steps[2].energy <= 1.8 * start, "third step: {} J from {start} J", steps[2].energy);
    assert!(steps[0].newton_iterations > 0);
}

/// The landing in whole steps at the default options (the step subdivided where it changes a
/// stretch ratio by more than 1 %): the energy never exceeds the start's, nor the largest speed
/// the free fall's by more than 10 % (1.86, 2.10, 2.29 m/s against 1.80, 1.97, 2.13; taken
/// whole with the subdivision off 2.04 and 2.60 m/s in the first two steps). Taken whole with the
/// subdivision off (`max_strain_change = inf`, the test above) the steps after the landing step
/// still gain energy (docs/cloth.md, "The whole-step landing's energy traced"): this test
/// fails so. At the defaults 7.06, 6.63 and 6.15 J, with and without the Newton iterations
/// (to 0.01 J; only the first substep iterates).
#[test]
fn a_landing_in_whole_steps_at_the_default_options_loses_energy() {
    let (start, steps) = land_with(1, SolveOptions::default());
    for (k, step) in steps.iter().enumerate() {
        let fall = SPEED + G * (k + 1) as f64 * DT;
        println!(
            "defaults, step {k}: largest speed {:.3} m/s (free fall {fall:.3}), mean vy {:.3} \
             m/s, energy {:.4} J (start {start:.4})",
            step.largest_speed, step.mean_vy, step.energy
        );
        assert!(step.mean_vy >= -fall, "step {k}: mean vy {}", step.mean_vy);
        assert!(step.energy <= start, "step {k}: {} J from {start} J", step.energy);
        assert!(
            step.largest_speed <= 1.1 * fall,
            "step {k}: largest speed {} m/s, free fall {fall} m/s",
            step.largest_speed
        );
    }
}

/// A 64² sheet of the default material hung from two corners, 1 s at the default options
/// from flat: its solves add no energy, so no step pays a Newton iteration (the check costs
/// one evaluation of the elastic energy a substep).
#[test]
fn a_hanging_sheet_takes_no_newton_iterations() {
    let n = 64;
    let mesh = Mesh::grid(n, n, 1.0, 1.0, Triangulation::Alternating).unwrap();
    let gravity = DVec3::new(0.0, -G, 0.0);
    let mut cloth =
        Cloth::new(mesh, Elasticity::BaraffWitkin, Material::default(), gravity).unwrap();
    cloth.pin(&[0, n - 1], None).unwrap();
    let mut newton = 0;
    for _ in 0..60 {
        cloth.step(DT, 1, Method::ImplicitEuler, SolveOptions::default()).unwrap();
        newton += cloth.stats().newton_iterations;
    }
    assert_eq!(newton, 0);
}
