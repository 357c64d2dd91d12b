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
/// weighted by mass) and total energy (J).
struct Landing {
    largest_speed: f64,
    mean_vy: f64,
    energy: f64,
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
            }
        })
        .collect();
    (start, steps)
}

/// The landing in one step, in 8 and in 16 substeps: in every step the mean vertical velocity
/// is no faster downward than the free fall's `SPEED + g t`; in the landing step (the first)
/// the largest speed is within 20 % of the free fall's; with substeps the energy never exceeds
/// the start's. (Taken whole, the landing's energy grows, 7.28 J to 7.50, 10.3 and 22.2 J in
/// the three steps, nearly all of it elastic: a defect of the whole step, not of the
/// substeps, noted in docs/cloth.md.) Before the contacts that pull in a solve were released
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
                 (free fall {fall:.3}), energy {:.4} J (start {start:.4})",
                step.largest_speed, step.mean_vy, step.energy
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

/// The landing in whole steps at the default options (the step subdivided where it changes a
/// stretch ratio by more than 1 %): the energy never exceeds the start's, nor the largest speed
/// the free fall's by more than 10 % (1.86, 2.10, 2.29 m/s against 1.80, 1.97, 2.13; taken
/// whole with the subdivision off 2.04 and 2.60 m/s in the first two steps). Taken whole with the
/// subdivision off (`max_strain_change = inf`, the test above) the one linearised solve adds
/// stretch energy, 7.28 J to 7.50, 10.26 and 22.23 J (docs/cloth.md, "The whole-step
/// landing's energy traced"): this test fails so (seen failing by running it with
/// `max_strain_change = inf`). At the defaults 7.06, 6.63 and 6.15 J (Python, release).
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
