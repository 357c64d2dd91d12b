//! Flocks: the polarisation order parameter rises for an aligned flock and stays low without
//! alignment, and the flock stays one cluster while it orders; separation keeps boids apart; 2-D stays planar; several states of one model;
//! bitwise the same on one and two threads; snapshots; bad arguments.

use glam::DVec3;
use kinema::flock::{cohesion, polarisation, Flock, Settings, Solver, State};
use kinema::snapshot::{Snapshot, Stamped};

/// Uniform numbers in `[0, 1)` (Knuth's MMIX LCG).
fn uniform(mut seed: u64) -> impl FnMut() -> f64 {
    move || {
        seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// `n` boids uniformly in a `side` m square of the plane z = 0, flying at 1 m/s in random
/// directions.
fn square(n: usize, side: f64, seed: u64) -> (Vec<DVec3>, Vec<DVec3>) {
    let mut rnd = uniform(seed);
    let p = (0..n).map(|_| DVec3::new(rnd() * side, rnd() * side, 0.0)).collect();
    let v = (0..n)
        .map(|_| {
            let a = rnd() * std::f64::consts::TAU;
            DVec3::new(a.cos(), a.sin(), 0.0)
        })
        .collect();
    (p, v)
}

fn settings() -> Settings {
    Settings {
        separation: 2.0,
        neighbour_radius: 5.0,
        separation_distance: 1.5,
        ..Settings::default()
    }
}

fn min_distance(p: &[DVec3]) -> f64 {
    let mut best = f64::INFINITY;
    for i in 0..p.len() {
        for j in i + 1..p.len() {
            best = best.min((p[i] - p[j]).length());
        }
    }
    best
}

/// The polarisation and the cohesion (largest cluster at the neighbour radius) every 50 steps
/// over 400 steps of 0.1 s.
fn polarisations(settings: Settings) -> (Vec<f64>, Vec<f64>) {
    let (p, v) = square(100, 10.0, 3);
    let mut flock = Flock::new(settings, &p, &v).unwrap();
    let measure = |f: &Flock| {
        let p = f.state().positions();
        (polarisation(f.state().velocities()), cohesion(p, settings.neighbour_radius).unwrap())
    };
    let (mut phi, mut together) = (Vec::new(), Vec::new());
    for k in 0..9 {
        if k > 0 {
            flock.step(0.1, 50).unwrap();
        }
        let (a, b) = measure(&flock);
        phi.push(a);
        together.push(b);
        assert!(flock.state().positions().iter().all(|p| p.z == 0.0), "a 2-D flock stays planar");
    }
    (phi, together)
}

#[test]
fn polarisation_rises_with_alignment_and_stays_low_without() {
    let (aligned, together) = polarisations(settings());
    eprintln!("aligned {aligned:.3?}, largest cluster {together:.3?}");
    assert!(aligned[0] < 0.2, "random headings start disordered: {aligned:?}");
    assert!(aligned[8] > 0.9, "{aligned:?}");
    assert!(together.iter().all(|&c| c >= 0.95), "the flock stays one cluster: {together:?}");
    let (free, apart) = polarisations(Settings { alignment: 0.0, ..settings() });
    eprintln!("without alignment {free:.3?}, largest cluster {apart:.3?}");
    assert!(free.iter().all(|&phi| phi < 0.4), "{free:?}");
    let (_, scattered) = polarisations(Settings { alignment: 0.0, cohesion: 0.0, ..settings() });
    eprintln!("neither alignment nor cohesion: largest cluster {scattered:.3?}");
    assert!(scattered[8] < 0.8, "without cohesion the flock breaks up: {scattered:?}");
}

/// The cohesion measure on configurations of known clusters: a chain of boids 1 m apart is
/// one cluster at radius 1.5 m and single boids at 0.9 m; two chains of 6 and 4 boids 10 m
/// apart give 0.6; 3-D, no boids, bad radius and positions.
#[test]
fn cohesion_is_the_largest_clusters_fraction() {
    let chain = |n: usize, x0: f64| (0..n).map(move |k| DVec3::new(x0 + k as f64, 0.5, -2.0));
    let one: Vec<DVec3> = chain(10, 0.0).collect();
    assert_eq!(cohesion(&one, 1.5).unwrap(), 1.0);
    assert_eq!(cohesion(&one, 0.9).unwrap(), 0.1);
    let two: Vec<DVec3> = chain(4, 20.0).chain(chain(6, 0.0)).collect();
    assert_eq!(cohesion(&two, 1.5).unwrap(), 0.6);
    let helix: Vec<DVec3> = (0..50)
        .map(|k| {
            let a = 0.3 * k as f64;
            DVec3::new(3.0 * a.cos(), 3.0 * a.sin(), 0.2 * k as f64)
        })
        .collect();
    assert_eq!(cohesion(&helix, 1.0).unwrap(), 1.0);
    assert_eq!(cohesion(&helix, 0.5).unwrap(), 0.02);
    assert_eq!(cohesion(&[], 1.0).unwrap(), 0.0);
    assert!(cohesion(&one, 0.0).unwrap_err().to_string().contains("radius"));
    let mut bad = one.clone();
    bad[3].y = f64::NAN;
    assert!(cohesion(&bad, 1.0).unwrap_err().to_string().contains("positions"));
}

#[test]
fn separation_keeps_a_minimum_distance() {
    let closest = |separation: f64| {
        let s = Settings { separation, cohesion: 0.5, max_force: 3.0, ..settings() };
        let (p, v) = square(100, 10.0, 5);
        let mut flock = Flock::new(s, &p, &v).unwrap();
        flock.step(0.1, 100).unwrap();
        let mut closest = f64::INFINITY;
        for _ in 0..300 {
            flock.step(0.1, 1).unwrap();
            closest = closest.min(min_distance(flock.state().positions()));
        }
        closest
    };
    let (with, without) = (closest(6.0), closest(0.0));
    eprintln!("closest approach: {with:.3} m with separation, {without:.3} m without");
    assert!(with > 0.5 * 1.5, "{with}");
    assert!(without < 0.25, "{without}");
}

#[test]
fn three_d_flock_aligns() {
    let mut rnd = uniform(11);
    let p: Vec<DVec3> = (0..100).map(|_| DVec3::new(rnd(), rnd(), rnd()) * 6.0).collect();
    let v: Vec<DVec3> =
        (0..100).map(|_| DVec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5).normalize()).collect();
    let mut flock = Flock::new(settings(), &p, &v).unwrap();
    let before = polarisation(flock.state().velocities());
    flock.step(0.1, 400).unwrap();
    let after = polarisation(flock.state().velocities());
    eprintln!("3-D polarisation {before:.3} -> {after:.3}");
    assert!(before < 0.3 && after > 0.9, "{before} {after}");
    assert!(flock.state().velocities().iter().any(|v| v.z.abs() > 1e-3));
}

#[test]
fn two_states_of_one_model_step_as_if_alone() {
    let flock = |seed| {
        let (p, v) = square(300, 20.0, seed);
        Flock::new(settings(), &p, &v).unwrap()
    };
    let (a, b) = (flock(1), flock(2));
    let model = a.model().clone();
    let (mut sa, mut sb) = (a.state().clone(), b.state().clone());
    let mut solver = Solver::new(&model);
    for _ in 0..20 {
        let before: State = sb.clone();
        solver.step(&model, &mut sa, 0.1, 2).unwrap();
        assert_eq!(sb, before, "stepping one state left the other unchanged");
        solver.step(&model, &mut sb, 0.1, 3).unwrap();
    }
    let (mut alone_a, mut alone_b) = (a, b);
    for _ in 0..20 {
        alone_a.step(0.1, 2).unwrap();
        alone_b.step(0.1, 3).unwrap();
    }
    assert_eq!(&sa, alone_a.state());
    assert_eq!(&sb, alone_b.state());
}

/// Bitwise the same on one and two threads, and however the steps are split into calls (the
/// boids stay sorted by cell from step to step within a call).
#[test]
fn bitwise_the_same_on_one_and_two_threads() {
    let run = |threads, calls: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            let (p, v) = square(3000, 60.0, 9);
            let mut flock = Flock::new(settings(), &p, &v).unwrap();
            for _ in 0..calls {
                flock.step(0.1, 40 / calls).unwrap();
            }
            flock.state().clone()
        })
    };
    let once = run(1, 1);
    assert_eq!(once, run(2, 1));
    assert_eq!(once, run(2, 40));
}

#[test]
fn snapshots_round_trip_and_continue_bitwise() {
    let (p, v) = square(200, 15.0, 4);
    let mut flock = Flock::new(settings(), &p, &v).unwrap();
    flock.step(0.1, 10).unwrap();
    let mut copy = Flock::from_snapshot(&flock.to_snapshot().unwrap()).unwrap();
    let state =
        State::from_snapshot(flock.model(), &flock.state().to_snapshot(flock.model()).unwrap())
            .unwrap();
    assert_eq!(&state, flock.state());
    flock.step(0.1, 10).unwrap();
    copy.step(0.1, 10).unwrap();
    assert_eq!(flock.state(), copy.state());
    let other = Flock::new(Settings { cohesion: 0.5, ..settings() }, &p, &v).unwrap();
    let bytes = flock.state().to_snapshot(flock.model()).unwrap();
    assert!(State::from_snapshot(other.model(), &bytes).is_err());
}

#[test]
fn bad_arguments_are_named_and_leave_the_flock_unchanged() {
    let (p, v) = square(10, 5.0, 1);
    let err = |r: Result<Flock, kinema::error::Error>| r.unwrap_err().to_string();
    assert!(
        err(Flock::new(Settings { max_speed: 0.0, ..settings() }, &p, &v)).contains("max_speed")
    );
    assert!(err(Flock::new(Settings { field_of_view: 7.0, ..settings() }, &p, &v))
        .contains("field_of_view"));
    assert!(err(Flock::new(settings(), &p, &v[..9])).contains("velocities"));
    let mut bad = p.clone();
    bad[3].y = f64::NAN;
    assert!(err(Flock::new(settings(), &bad, &v)).contains("positions"));
    let mut flock = Flock::new(settings(), &p, &v).unwrap();
    let before = flock.state().clone();
    assert!(flock.step(0.0, 1).unwrap_err().to_string().contains("dt"));
    assert_eq!(flock.state(), &before);
    // No boids, and boids on one point: finite, no panic.
    Flock::new(settings(), &[], &[]).unwrap().step(0.1, 3).unwrap();
    let mut piled = Flock::new(settings(), &[DVec3::ONE; 5], &[DVec3::ZERO; 5]).unwrap();
    piled.step(0.1, 10).unwrap();
    assert!(piled.state().positions().iter().all(|p| p.is_finite()));
    assert_eq!(polarisation(&[]), 0.0);
}

/// A flat flock 2³⁴ m from the origin (its cells beyond ±2³¹, which the AVX2 lanes' step
/// leaves to the boid-by-boid cells and bounds) flies as the same flock at the origin, to the
/// rounding of positions there (2⁻¹⁸ m): the far cells and bounds find the same neighbours
/// (with the fallback's cells left unwritten, boid 0 is 0.14 m and 0.57 m/s off).
#[test]
fn far_flock_flies_as_at_the_origin() {
    let offset = DVec3::new(2f64.powi(34), -(2f64.powi(34)), 0.0);
    let (p, v) = square(400, 40.0, 11);
    let far: Vec<DVec3> = p.iter().map(|p| *p + offset).collect();
    let (mut near, mut away) =
        (Flock::new(settings(), &p, &v).unwrap(), Flock::new(settings(), &far, &v).unwrap());
    near.step(0.1, 5).unwrap();
    away.step(0.1, 5).unwrap();
    let (a, b) = (near.state(), away.state());
    for i in 0..400 {
        let dp = (b.positions()[i] - offset - a.positions()[i]).length();
        let dv = (b.velocities()[i] - a.velocities()[i]).length();
        assert!(dp < 1e-4 && dv < 1e-4, "boid {i}: {dp} m, {dv} m/s");
    }
    assert!(a.velocities().iter().zip(&v).any(|(a, v)| (*a - *v).length() > 0.05));
}
