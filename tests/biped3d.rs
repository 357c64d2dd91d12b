//! The 3-D SIMBICON biped (`kinema::character::{biped3d, Walker3d}`): walking, pushes from
//! every side, slopes, determinism, and the hips applying the torso's servo torque.
//! Reduced sizes here; `cargo test --test biped3d -- --ignored` runs the full ones.

use glam::DVec3;
use kinema::character::{Coronal, Gait, Settings, Walker3d, TORSO_3D};

/// The walker's settings: stiff feet (`m ω²` = 20 kN/m per contact sphere of the 0.5 kg
/// heel and toe halves), as the planar walker's.
fn settings() -> Settings {
    Settings { contact_frequency: 200.0, ..Settings::default() }
}

/// The 3-D walker's documented step (it also walks at up to 3.5e-3 s, measured in session
/// 23; it fell at 1.75e-3 s before session 22's implicit contact damping).
const DT: f64 = 1e-3;

/// What a walk did: the COM at each tenth of a second, the lowest hip height, the largest
/// torso tilt from the vertical (rad), the steps.
#[derive(Debug, PartialEq)]
struct Walk {
    com: Vec<DVec3>,
    lowest_hip: f64,
    largest_tilt: f64,
    steps: u64,
}

impl Walk {
    fn at(&self, t: f64) -> DVec3 {
        self.com[(t * 10.0).round() as usize - 1]
    }

    /// Mean forward speed (m/s) between `from` and `to` seconds.
    fn speed(&self, from: f64, to: f64) -> f64 {
        (self.at(to).x - self.at(from).x) / (to - from)
    }

    fn fell(&self) -> bool {
        self.lowest_hip < 0.7 || self.largest_tilt > 0.8
    }
}

/// Walk `seconds` from 0.3 m/s under the 3-D gait and `coronal` on a slope of `slope` rad;
/// `push`: a force (N, world) on the torso for 0.2 s from the given time (s). Stops at a
/// fall (or a diverged step, counted as one).
fn walk(coronal: Coronal, slope: f64, seconds: f64, push: Option<(f64, DVec3)>) -> Walk {
    let g = 9.81;
    let gravity = DVec3::new(-g * slope.sin(), -g * slope.cos(), 0.0);
    let settings = Settings { gravity, ..settings() };
    let mut w = Walker3d::new(settings, Gait::default_3d(), coronal, 0.3).unwrap();
    let mut out = Walk { com: vec![], lowest_hip: f64::INFINITY, largest_tilt: 0.0, steps: 0 };
    let per = (0.1 / DT).round() as usize;
    let up = -gravity.normalize();
    for k in 0..(seconds * 10.0).round() as usize {
        if let Some((at, force)) = push {
            if (k as f64 * 0.1 - at).abs() < 1e-9 {
                let (model, state) = w.parts_mut();
                state.push(model, TORSO_3D, force, 0.2).unwrap();
            }
        }
        for _ in 0..per {
            if w.step(DT, 1).is_err() {
                out.lowest_hip = f64::NEG_INFINITY;
                break;
            }
            let tree = w.kinematics();
            let (hip, rot) = (tree.positions()[TORSO_3D], tree.orientations()[TORSO_3D]);
            out.lowest_hip = out.lowest_hip.min(hip.y);
            out.largest_tilt = out.largest_tilt.max((rot * DVec3::Y).angle_between(up));
        }
        out.com.push(w.com());
        if out.fell() {
            break;
        }
    }
    out.steps = w.phase().steps;
    out
}

fn walks_forward(seconds: f64) {
    let w = walk(Coronal::default(), 0.0, seconds, None);
    assert!(!w.fell(), "fell at {} s: {w:?}", w.com.len() as f64 / 10.0);
    let speed = w.speed(2.0, seconds);
    assert!((1.0..1.35).contains(&speed), "speed {speed} m/s");
    let drift = w.com.iter().map(|c| c.z.abs()).fold(0.0, f64::max);
    assert!(drift < 0.5, "sideways drift {drift} m");
    assert!(w.largest_tilt < 0.3, "torso tilt {}", w.largest_tilt);
    let per_second = w.steps as f64 / seconds;
    assert!((2.3..3.7).contains(&per_second), "{} steps in {seconds} s", w.steps);
}

#[test]
fn the_3d_walk_walks_forward_in_its_speed_band() {
    walks_forward(6.0);
}

#[test]
#[ignore = "full size: 20 s"]
fn the_3d_walk_walks_twenty_seconds() {
    walks_forward(20.0);
}

/// The walk keeps its speed at 3.5 times the step: 6 s at dt = 3.5e-3 s go as far as at
/// 1e-3 s to 2 % (measured 0.05 %; 20 s at 1, 1.5, 1.75, 2, 2.5, 3, 3.5 ms end within
/// 0.6 % of each other, docs/character.md).
#[test]
fn the_3d_walk_keeps_its_speed_at_three_and_a_half_times_the_step() {
    let at = |dt: f64| {
        let mut w = Walker3d::new(settings(), Gait::default_3d(), Coronal::default(), 0.3).unwrap();
        w.step(dt, (6.0 / dt).round() as usize).unwrap();
        let (x, y) = (w.state().q()[0], w.state().q()[1]);
        assert!(y > 0.8, "fell at dt = {dt}: hips at {y} m");
        x
    };
    let (fine, coarse) = (at(DT), at(3.5e-3));
    assert!((coarse / fine - 1.0).abs() < 0.02, "{coarse} m vs {fine} m at 1e-3 s");
}

#[test]
fn without_coronal_feedback_the_3d_walk_falls_sideways() {
    let w = walk(Coronal { cv: 0.0, ..Coronal::default() }, 0.0, 6.0, None);
    assert!(w.fell(), "walked without coronal feedback: {w:?}");
    assert!(w.com.last().unwrap().z.abs() > 0.2, "fell sideways: {:?}", w.com.last());
}

/// Two phases of the sweep of `bench/bench_biped.py --pushes` (0.2 s on the torso at
/// t = 4.0 … 4.6 s), the paper's 350 N from the front, from behind and from each side. 350 N from behind failed at every phase before the stance hip's torque about the
/// stance leg's axis was capped by the foot's grip (session 23: the trailing stance foot,
/// lifted in the flight after the push, spun the leg about its axis, checked: it falls at
/// 4.0 and 4.4 s without the cap).
#[test]
fn pushes_from_every_side_are_survived() {
    for at in [4.0, 4.4] {
        for force in [
            DVec3::new(-350.0, 0.0, 0.0),
            DVec3::new(350.0, 0.0, 0.0),
            DVec3::new(0.0, 0.0, 350.0),
            DVec3::new(0.0, 0.0, -350.0),
        ] {
            let w = walk(Coronal::default(), 0.0, 7.0, Some((at, force)));
            assert!(!w.fell(), "fell after {force} N at {at} s");
        }
    }
}

#[test]
fn the_3d_walk_climbs_a_five_degree_slope() {
    let w = walk(Coronal::default(), 5f64.to_radians(), 10.0, None);
    assert!(!w.fell(), "fell climbing: {w:?}");
    let speed = w.speed(5.0, 10.0);
    assert!((0.5..0.9).contains(&speed), "climbs at {speed} m/s");
}

/// Down 5° it walks 20 s, faster than on flat ground (1.6 m/s). Before the stance hip's
/// torque about the stance leg's axis was capped by the foot's grip it fell at 16.8 s
/// (the feet spun about the vertical up to 2.5 rad; checked), and with the torso upright
/// against gravity (the planar walker's rule) at 3.4 s.
#[test]
fn the_3d_walk_descends_a_five_degree_slope_for_twenty_seconds() {
    let w = walk(Coronal::default(), -5f64.to_radians(), 20.0, None);
    assert!(!w.fell(), "fell descending at {} s", w.com.len() as f64 / 10.0);
    let speed = w.speed(5.0, 20.0);
    assert!((1.3..1.9).contains(&speed), "descends at {speed} m/s");
}

#[test]
fn the_3d_walk_is_deterministic_and_a_refused_step_changes_nothing() {
    let run = || {
        let mut w = Walker3d::new(settings(), Gait::default_3d(), Coronal::default(), 0.3).unwrap();
        w.step(DT, 1500).unwrap();
        w
    };
    let (mut a, b) = (run(), run());
    assert_eq!(a.state(), b.state());
    assert_eq!(a.phase(), b.phase());
    assert!(a.step(f64::NAN, 3).is_err());
    a.gait.kp = -1.0;
    assert!(a.step(DT, 3).is_err());
    assert_eq!((a.state(), a.phase()), (b.state(), b.phase()));
}

/// 450 N from each side (0.2 s on the torso; the paper's pushes are 350 N), walking on to
/// 9 s, at the phases where the margin was thinnest: with the coronal `c_v` of 0.4
/// (sessions 24–28) 350 N was the largest survived there (from the left at 4.5 and 4.6 s,
/// from the right at 4.2 s); with 0.3, 500–600 N are.
#[test]
fn side_pushes_of_450_newtons_are_survived() {
    for (at, side) in [(4.5, 1.0), (4.6, 1.0), (4.2, -1.0)] {
        let force = DVec3::new(0.0, 0.0, 450.0 * side);
        let w = walk(Coronal::default(), 0.0, 9.0, Some((at, force)));
        assert!(!w.fell(), "fell after {force} N at {at} s");
    }
}

/// Every phase of `bench/bench_biped.py --pushes` (4.0 … 4.6 s), 450 N from each side,
/// walking on to 9 s.
#[test]
#[ignore = "full size: 14 walks of 9 s"]
fn side_pushes_of_450_newtons_are_survived_at_every_phase() {
    let mut fell = vec![];
    for k in 0..7 {
        let at = 4.0 + 0.1 * k as f64;
        for side in [1.0, -1.0] {
            let force = DVec3::new(0.0, 0.0, 450.0 * side);
            if walk(Coronal::default(), 0.0, 9.0, Some((at, force))).fell() {
                fell.push((at, side));
            }
        }
    }
    assert!(fell.is_empty(), "fell after 450 N at (time, side): {fell:?}");
}
