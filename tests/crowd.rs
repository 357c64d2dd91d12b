//! Crowds: ORCA's guarantees on RVO2's scenes (head-on pair, circle crossing), the extremes
//! (agents on top of each other, unreachable goals), obstacles, several states of one model,
//! determinism across thread counts, snapshots; social forces through a door.

use glam::DVec2;
use kinema::crowd::{metrics, Crowd, Kind, Model, Settings, SocialForce, Solver, State};
use kinema::snapshot::Stamped;
use std::f64::consts::TAU;

/// `n` agents evenly on a circle of `radius` (m), each going to its antipode.
fn circle(n: usize, radius: f64) -> (Vec<DVec2>, Vec<DVec2>) {
    let p: Vec<DVec2> = (0..n)
        .map(|i| {
            let a = i as f64 * TAU / n as f64;
            radius * DVec2::new(a.cos(), a.sin())
        })
        .collect();
    let g = p.iter().map(|&x| -x).collect();
    (p, g)
}

/// Step until every agent has arrived or `max_steps` pass; returns the steps taken.
fn run(crowd: &mut Crowd, dt: f64, max_steps: usize) -> usize {
    for k in 0..max_steps {
        if crowd.state().arrival_times().iter().all(|t| t.is_finite()) {
            return k;
        }
        crowd.step(dt, 1).unwrap();
    }
    max_steps
}

fn min_distance(p: &[DVec2]) -> f64 {
    let mut best = f64::INFINITY;
    for i in 0..p.len() {
        for j in i + 1..p.len() {
            best = best.min((p[i] - p[j]).length());
        }
    }
    best
}

#[test]
fn head_on_pair_passes_without_overlap() {
    let settings = Settings {
        radius: 0.5,
        max_speed: 1.5,
        preferred_speed: 1.0,
        perturbation: 0.0,
        ..Settings::rvo2_circle()
    };
    let mut crowd = Crowd::new(settings).unwrap();
    // Exactly head-on and unperturbed: the symmetric case, resolved by both turning to the
    // same side.
    let p = [DVec2::new(-10.0, 0.0), DVec2::new(10.0, 0.0)];
    crowd.add_agents(&p, &[p[1], p[0]]).unwrap();
    let mut closest = f64::INFINITY;
    let mut swerve: f64 = 0.0;
    for _ in 0..400 {
        crowd.step(0.1, 1).unwrap();
        let q = crowd.state().positions();
        closest = closest.min((q[0] - q[1]).length());
        swerve = swerve.max(q[0].y.abs());
    }
    assert!(crowd.state().arrival_times().iter().all(|t| t.is_finite()));
    assert!(closest >= 1.0 - 1e-9, "closest approach {closest}");
    assert!(swerve > 0.3, "they must step aside: {swerve}");
    assert_eq!(crowd.state().tally().agent_collisions, 0);
    // Reciprocity: each takes half the avoidance, so the paths are point-symmetric.
    let q = crowd.state().positions();
    assert!((q[0] + q[1]).length() < 1e-9, "{q:?}");
}

/// The exactly symmetric 16-agent ring (circle of 20 m) closes into a ring and stops
/// without perturbation, and with RVO2's 10⁻⁴ m/s (RVO2 through pyrvo 0.4.3 deadlocks there
/// too); the deterministic perturbation of 0.05 m/s (5 % of the preferred speed) breaks it:
/// all arrive (mean 222.2 s with the default planning margin 0.1, 51.3 s without; 38.5 s
/// unhindered), none overlapping another.
#[test]
fn exactly_symmetric_circle_deadlocks_unless_perturbed() {
    let arrived = |perturbation: f64| {
        let settings = Settings { perturbation, ..Settings::rvo2_circle() };
        let mut crowd = Crowd::new(settings).unwrap();
        let (p, g) = circle(16, 20.0);
        crowd.add_agents(&p, &g).unwrap();
        run(&mut crowd, 0.25, 1500);
        let s = crowd.state();
        assert_eq!(s.tally().agent_collisions, 0);
        s.arrival_times().iter().filter(|t| t.is_finite()).count()
    };
    assert_eq!(arrived(0.0), 0, "the symmetric ring should deadlock without perturbation");
    assert_eq!(arrived(1e-4), 0, "RVO2's perturbation does not break it");
    assert_eq!(arrived(0.05), 16);
}

/// The perturbation moves every preferred velocity by exactly its length, in a direction
/// fixed by the seed, the step and the agent (so the same on any thread count), and changes
/// the trajectories: one seed repeats them bit for bit, another does not.
#[test]
fn perturbation_moves_preferred_velocities_by_its_length_per_seed() {
    let run_with = |perturbation: f64, seed: u64| {
        let settings = Settings { perturbation, seed, ..Settings::rvo2_circle() };
        let mut crowd = Crowd::new(settings).unwrap();
        let (p, g) = circle(16, 20.0);
        crowd.add_agents(&p, &g).unwrap();
        run(&mut crowd, 0.25, 40);
        let s = crowd.state();
        (s.preferred_velocities().to_vec(), s.positions().to_vec())
    };
    let (_, plain_x) = run_with(0.0, 7);
    let (nudged, nudged_x) = run_with(0.01, 7);
    let (again, again_x) = run_with(0.01, 7);
    let (_, other_x) = run_with(0.01, 8);
    assert_eq!((&again, &again_x), (&nudged, &nudged_x));
    assert_ne!(other_x, nudged_x);
    assert_ne!(nudged_x, plain_x);
    // The last step's preferred velocities from the same positions differ by the nudge alone.
    let settings = Settings { perturbation: 0.01, seed: 7, ..Settings::rvo2_circle() };
    let mut crowd = Crowd::new(settings).unwrap();
    crowd.add_agents(&plain_x, &circle(16, 20.0).1).unwrap();
    run(&mut crowd, 0.25, 1);
    let mut unperturbed = Crowd::new(Settings::rvo2_circle()).unwrap();
    unperturbed.add_agents(&plain_x, &circle(16, 20.0).1).unwrap();
    run(&mut unperturbed, 0.25, 1);
    let a = crowd.state().preferred_velocities();
    let b = unperturbed.state().preferred_velocities();
    for (x, y) in a.iter().zip(b) {
        assert!(((*x - *y).length() - 0.01).abs() < 1e-12, "{x} {y}");
    }
}

/// `n` agents on a circle of `radius` (m) going to their antipodes, each start moved by up to
/// 6 mm along x (perfectly symmetric starts deadlock: the agents form a ring and stop).
fn perturbed_circle(n: usize, radius: f64) -> (Vec<DVec2>, Vec<DVec2>) {
    let (mut p, g) = circle(n, radius);
    for (i, x) in p.iter_mut().enumerate() {
        x.x += 1e-3 * ((i * 7919 % 13) as f64 - 6.0);
    }
    (p, g)
}

/// Overlapping pairs by brute force.
fn overlapping_pairs(p: &[DVec2], radius: f64) -> u64 {
    let mut count = 0;
    for i in 0..p.len() {
        for j in i + 1..p.len() {
            count += u64::from((p[i] - p[j]).length() < 2.0 * radius - metrics::EPSILON);
        }
    }
    count
}

/// RVO2's circle crossing at a quarter of its size: every agent arrives and, with ORCA's
/// position-level separation, no two agents overlap after any step (brute force, every step).
#[test]
fn circle_crossing_64_agents_reach_antipodes_without_any_collision() {
    let mut crowd = Crowd::new(Settings::rvo2_circle()).unwrap();
    let (p, g) = perturbed_circle(64, 60.0);
    crowd.add_agents(&p, &g).unwrap();
    let (mut steps, mut brute, mut fallbacks) = (0, 0, 0);
    while steps < 2000 && !crowd.state().arrival_times().iter().all(|t| t.is_finite()) {
        crowd.step(0.25, 1).unwrap();
        brute += overlapping_pairs(crowd.state().positions(), 1.5);
        fallbacks += crowd.stats.fallbacks;
        steps += 1;
    }
    let s = crowd.state();
    assert!(s.arrival_times().iter().all(|t| t.is_finite()), "not all arrived in {steps} steps");
    assert_eq!(brute, 0, "{:?}", s.tally());
    assert_eq!(s.tally().agent_collisions, 0);
    assert_eq!(s.tally().steps_with_collisions, 0);
    assert_eq!(s.tally().steps, steps as u64);
    assert!(fallbacks > 0, "the dense centre must need the fallback program");
    let mean: f64 = s.arrival_times().iter().sum::<f64>() / 64.0;
    // 120 m at 1 m/s less the 1.5 m tolerance is 118.5 s without anyone in the way.
    // Measured 188.0 s with the default planning margin 0.1, 261.8 s without it.
    assert!(mean > 118.0 && mean < 2.0 * 118.5, "mean time to goal {mean}");
    eprintln!(
        "64 agents: mean time to goal {mean:.2} s, {steps} steps, {fallbacks} fallbacks, {:?}",
        s.tally()
    );
}

/// RVO2's example at full size (250 agents exactly on a circle of 200 m, preferred
/// velocities perturbed by 10⁻⁴ m/s as the example does), ten perturbation seeds: every agent
/// arrives and no two overlap after any step. The time to goal depends on the perturbation by
/// ±15 % (chaos in the packed centre), so the means over seeds are compared: RVO2 (pyrvo 0.4.3,
/// `bench/bench_crowd.py`'s perturbation, seeds 0–5) 678.0 s (one run had 139931 overlapping
/// pair-steps); kinema with its default planning margin 0.1 (`Settings::planning_margin`),
/// seeds 0–9, 678.1 s without overlap (855 s without the margin, docs/crowd.md). Asserts the
/// issue's 5 %. Run with `--ignored` (26 s in this test profile).
#[test]
#[ignore = "26 s: cargo test --test crowd -- --ignored"]
fn circle_crossing_250_agents_without_collisions_against_rvo2_time_to_goal() {
    let mut means = Vec::new();
    for seed in 0..10 {
        let settings = Settings { perturbation: 1e-4, seed, ..Settings::rvo2_circle() };
        let mut crowd = Crowd::new(settings).unwrap();
        let (p, g) = circle(250, 200.0);
        crowd.add_agents(&p, &g).unwrap();
        let steps = run(&mut crowd, 0.25, 6000);
        let s = crowd.state();
        let arrived = s.arrival_times().iter().filter(|t| t.is_finite()).count();
        assert_eq!(arrived, 250, "seed {seed}: {steps} steps, {:?}", s.tally());
        assert_eq!(s.tally().steps_with_collisions, 0, "seed {seed}: {:?}", s.tally());
        let mean: f64 = s.arrival_times().iter().sum::<f64>() / 250.0;
        eprintln!("seed {seed}: mean time to goal {mean:.2} s, {steps} steps");
        means.push(mean);
    }
    let mean = means.iter().sum::<f64>() / means.len() as f64;
    assert!((mean / 678.0 - 1.0).abs() < 0.05, "mean over seeds {mean} against RVO2's 678.0");
}

/// With a planning margin `m` the agents of a head-on pair pass at least `2 r (1 + m)` apart
/// (ORCA keeps the inflated discs apart while its programs are feasible), and without it they
/// come closer.
#[test]
fn planning_margin_widens_the_passing_distance() {
    let closest = |planning_margin: f64| {
        let settings = Settings { radius: 0.5, planning_margin, ..Settings::rvo2_circle() };
        let mut crowd = Crowd::new(settings).unwrap();
        let p = [DVec2::new(-10.0, 0.0), DVec2::new(10.0, 0.0)];
        crowd.add_agents(&p, &[p[1], p[0]]).unwrap();
        let mut closest = f64::INFINITY;
        for _ in 0..400 {
            crowd.step(0.1, 1).unwrap();
            let q = crowd.state().positions();
            closest = closest.min((q[0] - q[1]).length());
        }
        assert!(crowd.state().arrival_times().iter().all(|t| t.is_finite()));
        closest
    };
    let (plain, wide) = (closest(0.0), closest(0.2));
    eprintln!("closest approach: {plain} without a margin, {wide} with 0.2");
    assert!(wide >= 1.2 - 1e-9, "closest approach {wide}");
    assert!(plain < 1.2 - 0.05, "closest approach {plain}");
}

/// An exact circle of 100 agents (80 m) does not deadlock: all reach their antipodes, and
/// none overlaps another after any step.
#[test]
fn exact_circle_of_100_agents_reaches_the_antipodes() {
    let settings = Settings { perturbation: 1e-4, ..Settings::rvo2_circle() };
    let mut crowd = Crowd::new(settings).unwrap();
    let (p, g) = circle(100, 80.0);
    crowd.add_agents(&p, &g).unwrap();
    let steps = run(&mut crowd, 0.25, 2500);
    let s = crowd.state();
    assert!(s.arrival_times().iter().all(|t| t.is_finite()), "{steps} steps");
    let mean: f64 = s.arrival_times().iter().sum::<f64>() / 100.0;
    eprintln!("100 agents: mean time to goal {mean:.2} s, {steps} steps, {:?}", s.tally());
    // 160 m at 1 m/s less the 1.5 m tolerance is 158.5 s unhindered; measured 344.5 s with
    // the default planning margin 0.1, 412.3 s without it.
    assert!(mean > 158.0 && mean < 2.5 * 158.5, "mean time to goal {mean}");
    assert_eq!(s.tally().steps_with_collisions, 0, "{:?}", s.tally());
}

#[test]
fn agents_starting_on_one_point_separate() {
    let settings = Settings { radius: 0.5, ..Settings::rvo2_circle() };
    let mut crowd = Crowd::new(settings).unwrap();
    let p = [DVec2::new(1.0, 2.0); 4];
    let g = [
        DVec2::new(10.0, 2.0),
        DVec2::new(-10.0, 2.0),
        DVec2::new(1.0, 12.0),
        DVec2::new(1.0, -8.0),
    ];
    crowd.add_agents(&p, &g).unwrap();
    // The separation parts them in the first step: no overlap after it, nor after any other.
    crowd.step(0.1, 1).unwrap();
    let q = crowd.state().positions();
    assert!(q.iter().all(|x| x.is_finite()));
    assert!(min_distance(q) >= 1.0 - metrics::EPSILON, "{q:?}");
    crowd.step(0.1, 219).unwrap();
    assert_eq!(crowd.state().tally().agent_collisions, 0, "{:?}", crowd.state().tally());
    assert!(crowd.state().arrival_times().iter().all(|t| t.is_finite()));
    assert!(min_distance(crowd.state().positions()) >= 1.0 - metrics::EPSILON);
}

#[test]
fn unreachable_goal_inside_an_obstacle_does_not_hang() {
    let settings = Settings { radius: 0.5, ..Settings::rvo2_circle() };
    let mut crowd = Crowd::new(settings).unwrap();
    // A counterclockwise square; the goal is its centre.
    let square = [
        DVec2::new(-2.0, -2.0),
        DVec2::new(2.0, -2.0),
        DVec2::new(2.0, 2.0),
        DVec2::new(-2.0, 2.0),
    ];
    crowd.add_obstacle(&square).unwrap();
    crowd.add_agents(&[DVec2::new(-10.0, 0.3)], &[DVec2::ZERO]).unwrap();
    crowd.step(0.1, 500).unwrap();
    let s = crowd.state();
    assert!(s.arrival_times()[0].is_infinite());
    assert!(s.positions()[0].x < -2.5 + 1e-6, "{}", s.positions()[0]);
    assert_eq!(s.tally().obstacle_collisions, 0, "{:?}", s.tally());
}

/// A room (four wall segments, 20 m square) whose door in the right wall has zero width (the
/// wall's two halves meet end to end), the agents' goals outside it: no agent passes or
/// penetrates a wall, none overlaps another, nothing diverges, with and without the
/// navigation layer (which finds no path and walks them straight at the wall).
#[test]
fn zero_width_door_stops_everyone_without_penetration() {
    for navigation in [None, Some(0.5)] {
        let settings = Settings { radius: 0.5, ..Settings::rvo2_circle() };
        let mut crowd = Crowd::new(settings).unwrap();
        let c = |x: f64, y: f64| DVec2::new(x, y);
        for wall in [
            [c(-10.0, -10.0), c(10.0, -10.0)],
            [c(10.0, -10.0), c(10.0, 0.0)],
            [c(10.0, 0.0), c(10.0, 10.0)],
            [c(10.0, 10.0), c(-10.0, 10.0)],
            [c(-10.0, 10.0), c(-10.0, -10.0)],
        ] {
            crowd.add_obstacle(&wall).unwrap();
        }
        crowd.set_navigation(navigation).unwrap();
        let p: Vec<DVec2> =
            (0..20).map(|i| c(-3.0 - (i / 5) as f64, (i % 5) as f64 - 2.0)).collect();
        let g: Vec<DVec2> = p.iter().map(|x| c(20.0, x.y)).collect();
        crowd.add_agents(&p, &g).unwrap();
        crowd.step(0.1, 600).unwrap();
        let s = crowd.state();
        assert!(s.positions().iter().all(|x| x.is_finite() && x.x <= 9.5 + 1e-6), "{navigation:?}");
        assert!(s.arrival_times().iter().all(|t| t.is_infinite()));
        assert_eq!(s.tally().obstacle_collisions, 0, "{navigation:?} {:?}", s.tally());
        assert_eq!(s.tally().agent_collisions, 0, "{navigation:?} {:?}", s.tally());
        // They reach the wall: the nearest stands at one radius from it.
        let nearest = s.positions().iter().map(|x| 10.0 - x.x).fold(f64::INFINITY, f64::min);
        assert!(nearest < 0.5 + 0.05, "{navigation:?}: nearest {nearest}");
    }
}

#[test]
fn agent_walks_around_an_obstacle_without_penetrating_it() {
    let settings = Settings { radius: 0.5, obstacle_time_horizon: 2.0, ..Settings::rvo2_circle() };
    let mut crowd = Crowd::new(settings).unwrap();
    let square = [
        DVec2::new(-2.0, -2.0),
        DVec2::new(2.0, -2.0),
        DVec2::new(2.0, 2.0),
        DVec2::new(-2.0, 2.0),
    ];
    crowd.add_obstacle(&square).unwrap();
    // The straight line to the goal grazes the square's corner (-2, 2); ORCA is local, so a
    // goal straight behind the square would stop the agent at the wall.
    crowd.add_agents(&[DVec2::new(-10.0, 0.3)], &[DVec2::new(10.0, 4.5)]).unwrap();
    let mut closest = f64::INFINITY;
    for _ in 0..600 {
        crowd.step(0.1, 1).unwrap();
        let p = crowd.state().positions()[0];
        let outside = DVec2::new((p.x.abs() - 2.0).max(0.0), (p.y.abs() - 2.0).max(0.0)).length();
        closest = closest.min(outside);
    }
    assert!(crowd.state().arrival_times()[0].is_finite());
    assert!(closest >= 0.5 - 1e-6, "closest approach to the square {closest}");
    assert!(closest < 0.6, "the corner must be grazed: {closest}");
    assert_eq!(crowd.state().tally().obstacle_collisions, 0);
}

#[test]
fn two_states_of_one_model_step_as_if_alone() {
    let mut model = Model::new(Settings::rvo2_circle()).unwrap();
    model.add_obstacle(&[DVec2::new(-5.0, 30.0), DVec2::new(5.0, 30.0)]).unwrap();
    let mut a = State::new(&model);
    let (p, g) = perturbed_circle(24, 40.0);
    a.add_agents(&p, &g).unwrap();
    let mut b = State::new(&model);
    b.add_agents(&g[..10], &p[..10]).unwrap();
    let (mut a_alone, mut b_alone) = (a.clone(), b.clone());
    let mut solver = Solver::new(&model);
    for _ in 0..30 {
        solver.step(&model, &mut a, 0.25, 2).unwrap();
        let b_before = b.clone();
        solver.step(&model, &mut b, 0.25, 1).unwrap();
        solver.step(&model, &mut b, 0.25, 1).unwrap();
        assert_ne!(b, b_before);
    }
    let mut fresh = Solver::new(&model);
    fresh.step(&model, &mut a_alone, 0.25, 60).unwrap();
    Solver::new(&model).step(&model, &mut b_alone, 0.25, 60).unwrap();
    assert_eq!(a, a_alone);
    assert_eq!(b, b_alone);
    // A state snapshot restores only onto its model.
    let bytes = a.to_snapshot(&model).unwrap();
    assert_eq!(State::from_snapshot(&model, &bytes).unwrap(), a);
    let other = Model::new(Settings::rvo2_circle()).unwrap();
    let err = State::from_snapshot(&other, &bytes).unwrap_err().to_string();
    assert!(err.contains("model"), "{err}");
}

#[test]
fn bitwise_the_same_on_one_and_two_threads() {
    for kind in [Kind::Orca, Kind::SocialForce(SocialForce::default())] {
        let run = |threads| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| {
                let settings = Settings {
                    radius: 0.3,
                    neighbour_distance: 3.0,
                    kind,
                    ..Settings::rvo2_circle()
                };
                let mut crowd = Crowd::new(settings).unwrap();
                let (p, g) = perturbed_circle(700, 60.0);
                crowd.add_agents(&p, &g).unwrap();
                crowd.step(0.1, 30).unwrap();
                crowd.state().clone()
            })
        };
        assert_eq!(run(1), run(2), "{kind:?}");
    }
}

#[test]
fn crowd_snapshot_round_trips_and_continues_bitwise() {
    use kinema::snapshot::Snapshot;
    let mut crowd = Crowd::new(Settings::rvo2_circle()).unwrap();
    crowd
        .add_obstacle(&[DVec2::new(-3.0, -3.0), DVec2::new(3.0, -3.0), DVec2::new(0.0, 3.0)])
        .unwrap();
    let (p, g) = perturbed_circle(16, 30.0);
    crowd.add_agents(&p, &g).unwrap();
    crowd.step(0.25, 10).unwrap();
    let mut copy = Crowd::from_snapshot(&crowd.to_snapshot().unwrap()).unwrap();
    crowd.step(0.25, 20).unwrap();
    copy.step(0.25, 20).unwrap();
    assert_eq!(crowd.state(), copy.state());
}

#[test]
fn bad_arguments_are_named_and_leave_the_crowd_unchanged() {
    let bad = Settings { radius: -1.0, ..Settings::rvo2_circle() };
    assert!(Crowd::new(bad).unwrap_err().to_string().contains("radius"));
    let mut crowd = Crowd::new(Settings::rvo2_circle()).unwrap();
    let err = crowd.add_agents(&[DVec2::new(f64::NAN, 0.0)], &[DVec2::ZERO]).unwrap_err();
    assert!(err.to_string().contains("positions"), "{err}");
    let err = crowd.add_agents(&[DVec2::ZERO], &[]).unwrap_err();
    assert!(err.to_string().contains("goals"), "{err}");
    let err = crowd.add_obstacle(&[DVec2::ZERO]).unwrap_err();
    assert!(err.to_string().contains("polygon"), "{err}");
    let err = crowd.add_obstacle(&[DVec2::ZERO, DVec2::ZERO]).unwrap_err();
    assert!(err.to_string().contains("polygon"), "{err}");
    crowd.add_agents(&[DVec2::ZERO], &[DVec2::X]).unwrap();
    let before = crowd.state().clone();
    for dt in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(crowd.step(dt, 1).unwrap_err().to_string().contains("dt"));
    }
    assert_eq!(*crowd.state(), before);
}
