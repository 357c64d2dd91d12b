//! Reynolds' (1999) steering behaviours on boids, each against an analytic expectation:
//! arrive stops at its target without overshoot (seek overshoots), pursue intercepts a
//! straight-moving target sooner than seek, flee and evade head away from the (predicted)
//! threat, wander is seeded and stays in its plane, obstacle avoidance keeps boids out of a
//! sphere in their path (which they enter without it), path following brings boids onto a
//! bent path and keeps them within its radius round the corner.

use glam::DVec3;
use kinema::flock::{Behaviour, Flock, Settings, Steering};
use kinema::geometry::{Shape, Sphere};

/// Flocking rules off, speed 2 m/s, force 2 m/s².
fn quiet() -> Settings {
    Settings {
        separation: 0.0,
        alignment: 0.0,
        cohesion: 0.0,
        max_speed: 2.0,
        max_force: 2.0,
        ..Settings::default()
    }
}

fn on(behaviour: Behaviour, boids: [u32; 2]) -> Steering {
    Steering { behaviour, weight: 1.0, boids }
}

fn flock(settings: Settings, p: &[DVec3], v: &[DVec3], steering: &[Steering]) -> Flock {
    let mut f = Flock::new(settings, p, v).unwrap();
    for s in steering {
        f.add_steering(s.clone()).unwrap();
    }
    f
}

/// The largest `x` a boid starting at rest at the origin reaches in 100 s under `behaviour`
/// (target 20 m ahead), and its final distance to the target.
fn approach(behaviour: Behaviour) -> (f64, f64) {
    let mut f = flock(quiet(), &[DVec3::ZERO], &[DVec3::ZERO], &[on(behaviour, [0, 1])]);
    let mut max_x: f64 = 0.0;
    for _ in 0..2000 {
        f.step(0.05, 1).unwrap();
        max_x = max_x.max(f.state().positions()[0].x);
    }
    (max_x, (f.state().positions()[0] - DVec3::new(20.0, 0.0, 0.0)).length())
}

#[test]
fn arrive_stops_at_the_target_without_overshoot_where_seek_overshoots() {
    // Inside the slow radius R the desired speed is v_max x / R and the velocity relaxes to
    // it in 1 s: ẍ + ẋ + (v_max / R) x = 0, overdamped for R = 10 m, v_max = 2 m/s
    // (ζ = 1 / (2 √0.2) ≈ 1.12): no overshoot, exponential arrival.
    let target = DVec3::new(20.0, 0.0, 0.0);
    let (max_x, distance) = approach(Behaviour::Arrive { target, slow_radius: 10.0 });
    assert!(max_x <= 20.0, "overshot to {max_x}");
    assert!(distance < 1e-3, "stopped {distance} m away");
    let (max_x, _) = approach(Behaviour::Seek(target));
    assert!(max_x > 20.5, "seek should overshoot: {max_x}");
}

/// Steps until the pursuer (boid 0, at rest at the origin) comes within 0.5 m of the target
/// (boid 1, from (0, 10) at 1 m/s along x).
fn intercept(behaviour: Behaviour) -> usize {
    let p = [DVec3::ZERO, DVec3::new(0.0, 10.0, 0.0)];
    let v = [DVec3::ZERO, DVec3::new(1.0, 0.0, 0.0)];
    let mut f = flock(quiet(), &p, &v, &[on(behaviour, [0, 1])]);
    for k in 0..4000 {
        let s = f.state().positions();
        if (s[0] - s[1]).length() < 0.5 {
            return k;
        }
        f.step(0.01, 1).unwrap();
    }
    usize::MAX
}

#[test]
fn pursue_intercepts_a_straight_moving_target_sooner_than_seek() {
    let pursue = intercept(Behaviour::Pursue(1));
    // Seeking the current position of a boid at (t, 10) chases a moving point.
    let seek = {
        let p = [DVec3::ZERO, DVec3::new(0.0, 10.0, 0.0)];
        let v = [DVec3::ZERO, DVec3::new(1.0, 0.0, 0.0)];
        let mut f = flock(quiet(), &p, &v, &[]);
        let mut steps = usize::MAX;
        for k in 0..4000 {
            let s = f.state().positions().to_vec();
            if (s[0] - s[1]).length() < 0.5 {
                steps = k;
                break;
            }
            let mut g =
                flock(quiet(), &s, f.state().velocities(), &[on(Behaviour::Seek(s[1]), [0, 1])]);
            g.step(0.01, 1).unwrap();
            f = g;
        }
        steps
    };
    assert!(pursue < seek, "pursue {pursue} steps, seek {seek}");
    // The straight-line bound: 10 m at best 2 m/s after accelerating at 2 m/s² takes ≥ 5 s.
    assert!(pursue as f64 * 0.01 > 5.0);
}

#[test]
fn flee_and_evade_accelerate_away_from_the_predicted_threat() {
    // Boid 0 at rest at the origin; boid 1 at (10, 0) flying (0, 2): predicted ahead by its
    // distance over the maximum speed, 5 s, to (10, 10).
    let p = [DVec3::ZERO, DVec3::new(10.0, 0.0, 0.0)];
    let v = [DVec3::ZERO, DVec3::new(0.0, 2.0, 0.0)];
    let dt = 0.01;
    for (behaviour, away) in [
        (Behaviour::Evade(1), DVec3::new(-1.0, -1.0, 0.0).normalize()),
        (Behaviour::Flee(p[1]), DVec3::new(-1.0, 0.0, 0.0)),
    ] {
        let mut f = flock(quiet(), &p, &v, &[on(behaviour.clone(), [0, 1])]);
        f.step(dt, 1).unwrap();
        // The desired velocity is 2 m/s away; from rest the steering is clamped to 2 m/s².
        let got = f.state().velocities()[0];
        assert!((got - away * 2.0 * dt).length() < 1e-12, "{behaviour:?}: {got}");
    }
}

#[test]
fn wander_is_seeded_bounded_and_stays_in_its_plane() {
    let run = |seed: u64| {
        let w = Behaviour::Wander { distance: 2.0, radius: 1.0, seed, planar: true };
        let p = [DVec3::ZERO];
        let v = [DVec3::new(1.0, 0.0, 0.0)];
        let mut f = flock(quiet(), &p, &v, &[on(w, [0, 1])]);
        f.step(0.1, 200).unwrap();
        (f.state().positions()[0], f.state().velocities()[0])
    };
    let (a, va) = run(1);
    assert_eq!((a, va), run(1));
    assert_ne!(a, run(2).0);
    assert_eq!(a.z, 0.0);
    assert!(va.length() <= 2.0 + 1e-12);
    // It wandered: not on the straight line it started on.
    assert!(a.y.abs() > 0.1, "{a}");
}

#[test]
fn avoidance_keeps_boids_out_of_a_sphere_in_their_path() {
    let sphere = Shape::Sphere(Sphere { center: DVec3::new(10.0, 0.0, 0.0), radius: 2.0 });
    let p: Vec<DVec3> =
        (0..21).map(|k| DVec3::new(0.0, -1.5 + 0.15 * k as f64, 0.05 * (k % 3) as f64)).collect();
    let v = vec![DVec3::new(2.0, 0.0, 0.0); p.len()];
    let deepest = |steering: &[Steering]| {
        let settings = Settings { max_force: 4.0, ..quiet() };
        let mut f = flock(settings, &p, &v, steering);
        let mut min: f64 = f64::INFINITY;
        for _ in 0..1000 {
            f.step(0.01, 1).unwrap();
            for q in f.state().positions() {
                min = min.min(sphere.distance(*q).0);
            }
        }
        min
    };
    let avoid = Behaviour::Avoid { shape: sphere, horizon: 2.0, clearance: 0.5 };
    let with = deepest(&[on(avoid, [0, 21])]);
    assert!(with > 0.0, "a boid entered the sphere: distance {with}");
    assert!(deepest(&[]) < -1.0);
}

#[test]
fn bad_steering_is_named() {
    let mut f = Flock::new(quiet(), &[DVec3::ZERO], &[DVec3::ZERO]).unwrap();
    let err = |f: &mut Flock, s: Steering| f.add_steering(s).unwrap_err().to_string();
    let bad_weight = Steering { weight: -1.0, ..on(Behaviour::Seek(DVec3::X), [0, 1]) };
    assert!(err(&mut f, bad_weight).contains("weight"));
    let arrive = Behaviour::Arrive { target: DVec3::X, slow_radius: 0.0 };
    assert!(err(&mut f, on(arrive, [0, 1])).contains("slow_radius"));
    assert!(err(&mut f, on(Behaviour::Seek(DVec3::NAN), [0, 1])).contains("target"));
    // Pursuing a boid that does not exist is refused at the step, the flock unchanged.
    f.add_steering(on(Behaviour::Pursue(5), [0, 1])).unwrap();
    let before = f.state().clone();
    assert!(f.step(0.1, 1).unwrap_err().to_string().contains("target"));
    assert_eq!(*f.state(), before);
}

/// An L-shaped path (50 m along +x, then 50 m along +y), radius 1 m, lookahead 1 s: five
/// boids starting 6-10 m off it, some flying the wrong way, join it within 15 s, then stay
/// within the radius plus the turning overshoot `v² / a_max` = 2 m (speed 2 m/s, force
/// 2 m/s²) while going round the corner, and progress along it; without the behaviour they
/// fly straight on.
#[test]
fn path_following_joins_the_path_and_stays_within_its_radius() {
    let path = vec![DVec3::ZERO, DVec3::new(50.0, 0.0, 0.0), DVec3::new(50.0, 50.0, 0.0)];
    let segment = |p: DVec3, a: DVec3, b: DVec3| {
        let t = ((p - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
        (p - (a + t * (b - a))).length()
    };
    let distance = |p: DVec3| segment(p, path[0], path[1]).min(segment(p, path[1], path[2]));
    let p: Vec<DVec3> = (0..5).map(|i| DVec3::new(2.0 * i as f64, 6.0 + i as f64, 0.0)).collect();
    let v: Vec<DVec3> =
        (0..5).map(|i| DVec3::new(if i % 2 == 0 { 1.0 } else { -1.0 }, 0.0, 0.0)).collect();
    let follow = Behaviour::Follow { path: path.clone(), radius: 1.0, lookahead: 1.0 };
    let mut f = flock(quiet(), &p, &v, &[on(follow, [0, 5])]);
    let mut worst: f64 = 0.0;
    for step in 0..1000 {
        f.step(0.05, 1).unwrap();
        if step >= 300 {
            for &q in f.state().positions() {
                worst = worst.max(distance(q));
            }
        }
    }
    assert!(worst < 1.0 + 2.0, "left the path by {worst} m");
    // 50 s at up to 2 m/s: all have turned the corner and gone up the second leg.
    for &q in f.state().positions() {
        assert!(q.y > 20.0 && (q.x - 50.0).abs() < 3.0, "{q}");
    }
    let mut plain = flock(quiet(), &p, &v, &[]);
    plain.step(0.05, 1000).unwrap();
    assert!(plain.state().positions().iter().all(|q| (q.y - 6.0).abs() < 5.0));
}

#[test]
fn path_following_rejects_bad_paths() {
    let mut f = flock(quiet(), &[DVec3::ZERO], &[DVec3::X], &[]);
    for (path, radius, arg) in [
        (vec![DVec3::ZERO], 1.0, "path"),
        (vec![DVec3::ZERO, DVec3::ZERO], 1.0, "path"),
        (vec![DVec3::ZERO, DVec3::X], 0.0, "radius"),
        (vec![DVec3::ZERO, DVec3::new(f64::NAN, 0.0, 0.0)], 1.0, "path"),
    ] {
        let err = f
            .add_steering(on(Behaviour::Follow { path, radius, lookahead: 1.0 }, [0, 1]))
            .unwrap_err()
            .to_string();
        assert!(err.contains(arg), "{err}");
    }
    assert!(f.model().steering().is_empty());
}
