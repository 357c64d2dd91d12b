//! The 3-D SIMBICON biped (`kinema::character::{biped3d, Walker3d}`): walking, pushes from
//! every side, slopes, determinism, and the hips applying the torso's servo torque.
//! Reduced sizes here; `cargo test --test biped3d -- --ignored` runs the full ones.

use glam::{DQuat, DVec3};
use kinema::character::{Coronal, Gait, Settings, Walker3d, TORSO_3D};

/// The walker's settings: stiff feet (`m ω²` = 20 kN/m per contact sphere of the 0.5 kg
/// heel and toe halves), as the planar walker's.
fn settings() -> Settings {
    Settings { contact_frequency: 200.0, ..Settings::default() }
}

const DT: f64 = 2e-3;

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

/// Walk `seconds` from 0.3 m/s under the paper's gait on a slope of `slope` rad, with steps
/// of `dt`; `push`: a force (N, world) on the torso for 0.2 s from the given time (s).
fn walk(slope: f64, dt: f64, seconds: f64, push: Option<(f64, DVec3)>) -> Walk {
    let g = 9.81;
    let gravity = DVec3::new(-g * slope.sin(), -g * slope.cos(), 0.0);
    let settings = Settings { gravity, ..settings() };
    let mut w = Walker3d::new(settings, Gait::default(), Coronal::default(), 0.3).unwrap();
    let mut out = Walk { com: vec![], lowest_hip: f64::INFINITY, largest_tilt: 0.0, steps: 0 };
    let per = (0.1 / dt).round() as usize;
    let up = -gravity.normalize();
    for k in 0..(seconds * 10.0).round() as usize {
        if let Some((at, force)) = push {
            if (k as f64 * 0.1 - at).abs() < 1e-9 {
                let (model, state) = w.parts_mut();
                state.push(model, TORSO_3D, force, 0.2).unwrap();
            }
        }
        for _ in 0..per {
            w.step(dt, 1).unwrap();
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

#[test]
fn diag() {
    for dt in [5e-4, 1e-3, 2e-3] {
        let w = walk(0.0, dt, 8.0, None);
        eprintln!(
            "dt {dt}: fell {} at {} s, steps {}, speed {:.3}, com {:?}, tilt {:.3}",
            w.fell(),
            w.com.len() as f64 / 10.0,
            w.steps,
            if w.com.len() >= 60 { w.speed(2.0, 6.0) } else { f64::NAN },
            w.com.last(),
            w.largest_tilt
        );
    }
    let _ = DQuat::IDENTITY;
}
