//! The planar SIMBICON biped (`kinema::character::{planar_biped, Walker}`): standing under
//! stiff servos, walking, pushes, and the balance feedback that keeps it up.

use glam::DVec3;
use kinema::character::{
    hip_height, planar_biped, Gait, Servo, Settings, Solver, State, Walker, TORSO,
};

/// The walker's settings: stiff feet (`m ω²` = 40 kN/m per contact for the 1 kg feet).
fn settings() -> Settings {
    Settings { contact_frequency: 200.0, ..Settings::default() }
}

const DT: f64 = 1e-4;

#[test]
fn a_standing_biped_under_stiff_stable_pd_stays_up_and_the_ground_carries_its_weight() {
    let stiff = Settings { contact_frequency: 400.0, ..Settings::default() };
    let mut model = planar_biped(stiff).unwrap();
    for body in 1..model.bodies().len() {
        let servo = Servo { kp: 30000.0, kd: 3000.0, max_torque: f64::INFINITY };
        model.set_servo(body, Some(servo)).unwrap();
    }
    let mut state = State::new(&model);
    let mut q = model.neutral();
    q[1] = hip_height();
    state.set_q(&model, &q).unwrap();
    let mut solver = Solver::new(&model);
    let dt = 1.0 / 1000.0;
    let (mut lowest, mut highest) = (f64::INFINITY, f64::NEG_INFINITY);
    for _ in 0..50 {
        solver.step(&model, &mut state, dt, 100).unwrap();
        let y = solver.kinematics(&model, &state).com(&model).y;
        (lowest, highest) = (lowest.min(y), highest.max(y));
    }
    assert!(highest - lowest < 0.01, "COM height within [{lowest}, {highest}] over 5 s");
    assert!(state.q()[2].abs() < 0.01, "torso upright: {}", state.q()[2]);
    let weight = model.mass() * 9.81;
    let f = solver.ground_force(&model, &state, dt);
    assert!((f.y - weight).abs() < 0.02 * weight, "ground force {f} vs weight {weight} N");
    assert!(f.x.abs() < 0.01 * weight, "no horizontal force at rest: {f}");
}

/// What a walk did: the COM's x at each tenth of a second, the lowest hip height, the
/// largest torso lean, the steps, and the feet's touchdowns seen from outside.
struct Walk {
    x: Vec<f64>,
    lowest_hip: f64,
    largest_lean: f64,
    steps: u64,
    touchdowns: u64,
}

impl Walk {
    /// Mean forward speed (m/s) between `from` and `to` seconds.
    fn speed(&self, from: f64, to: f64) -> f64 {
        let at = |t: f64| self.x[(t * 10.0).round() as usize - 1];
        (at(to) - at(from)) / (to - from)
    }

    fn fell(&self) -> bool {
        self.lowest_hip < 0.7 || self.largest_lean > 0.8
    }
}

/// Walk `seconds` under `gait` from standing at 0.3 m/s; `push`: a force (N, world) on the
/// torso for 0.2 s starting at the given time (s).
fn walk(gait: Gait, seconds: f64, push: Option<(f64, DVec3)>) -> Walk {
    let mut w = Walker::new(settings(), gait, 0.3).unwrap();
    let mut record = Walk {
        x: Vec::new(),
        lowest_hip: f64::INFINITY,
        largest_lean: 0.0,
        steps: 0,
        touchdowns: 0,
    };
    let mut feet = w.feet_in_contact();
    let per = 100; // steps of DT between checks (10 ms)
    for k in 0..(seconds / DT) as usize / per {
        if let Some((at, force)) = push {
            if k == (at / (per as f64 * DT)).round() as usize {
                let (model, state) = w.parts_mut();
                state.push(model, TORSO, force, 0.2).unwrap();
            }
        }
        w.step(DT, per).unwrap();
        let now = w.feet_in_contact();
        record.touchdowns += now.iter().zip(&feet).filter(|(n, f)| **n && !**f).count() as u64;
        feet = now;
        let q = w.state().q();
        record.lowest_hip = record.lowest_hip.min(q[1]);
        record.largest_lean = record.largest_lean.max(q[2].abs());
        if k % 10 == 9 {
            record.x.push(w.com().x);
        }
        if record.fell() {
            break;
        }
    }
    record.steps = w.phase().steps;
    record
}

#[test]
fn simbicon_walks_forward_in_its_speed_band_and_counts_its_steps() {
    let r = walk(Gait::default(), 6.0, None);
    assert!(!r.fell(), "hip down to {} m, lean up to {} rad", r.lowest_hip, r.largest_lean);
    let v = r.speed(2.0, 6.0);
    assert!((0.45..0.75).contains(&v), "speed {v} m/s");
    // One strike per swing; the swing lasts about 0.4 s.
    assert!((12..=20).contains(&r.steps), "{} steps in 6 s", r.steps);
    // Every strike is a touchdown of the swing foot; the stance foot may also lift and land
    // within a step, never less.
    assert!(r.touchdowns >= r.steps, "{} touchdowns, {} steps", r.touchdowns, r.steps);
}

#[test]
fn simbicon_recovers_from_pushes_from_the_front_and_the_back() {
    for force in [-250.0, 250.0] {
        let r = walk(Gait::default(), 6.0, Some((2.0, DVec3::new(force, 0.0, 0.0))));
        assert!(!r.fell(), "{force} N: hip {} m, lean {} rad", r.lowest_hip, r.largest_lean);
        let v = r.speed(5.0, 6.0);
        assert!((0.3..0.9).contains(&v), "{force} N: speed {v} m/s after the push");
    }
}

#[test]
fn without_balance_feedback_simbicon_falls() {
    let mut gait = Gait::default();
    for pose in [&mut gait.lift, &mut gait.strike] {
        (pose.cd, pose.cv) = (0.0, 0.0);
    }
    // The gait without feedback is stable too (it runs away to 1.9 m/s), but a 400 N push
    // from behind for 0.2 s, which SIMBICON with feedback walks through, fells it.
    let push = Some((2.0, DVec3::new(400.0, 0.0, 0.0)));
    let r = walk(gait, 5.0, push);
    assert!(r.fell(), "hip down to {} m, lean up to {} rad", r.lowest_hip, r.largest_lean);
    let r = walk(Gait::default(), 5.0, push);
    assert!(!r.fell(), "with feedback: hip {} m, lean {} rad", r.lowest_hip, r.largest_lean);
}
