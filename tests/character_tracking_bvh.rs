//! Mocap tracking of a BVH clip (`kinema::character::Tracker` from a `BvhSkeleton`): the
//! reference pose against the hierarchy's own forward kinematics, the CMU 01_01 clip (its BVH
//! conversion) and the CMU 07_05 walk (converted by `kinema::mocap::asf_to_bvh`) tracked for
//! a few seconds with the errors and the assistance measured.

use glam::{DQuat, DVec3};
use kinema::character::{
    FrameReport, RagdollOptions, Settings, Solver, State, Tracker, TrackingOptions,
};
use kinema::mocap::{parse_bvh, BvhSkeleton, Motion};

mod cmu;

/// Metres per unit of the CMU conversions (the ASF's length unit, 1/0.45 inch).
const SCALE: f64 = 0.0254 / 0.45;

/// The CMU 01_01 clip without its first frame (a T-pose the conversion adds), from `start`.
fn clip(start: usize) -> (BvhSkeleton, Motion) {
    let text = std::fs::read_to_string("tests/data/mocap/01_01.bvh").unwrap();
    let (skeleton, motion) = parse_bvh(&text, "01_01.bvh").unwrap();
    let motion = motion.slice(1 + start, motion.frames).unwrap();
    (skeleton, motion)
}

fn tracker(start: usize, options: TrackingOptions) -> (BvhSkeleton, Motion, Tracker) {
    let (skeleton, motion) = clip(start);
    let ragdoll = RagdollOptions { scale: SCALE, ..RagdollOptions::default() };
    let t = Tracker::new(&skeleton, &motion, &ragdoll, Settings::default(), options).unwrap();
    (skeleton, motion, t)
}

fn mean(r: &[FrameReport], f: impl Fn(&FrameReport) -> f64) -> f64 {
    r.iter().map(f).sum::<f64>() / r.len() as f64
}

fn max(r: &[FrameReport], f: impl Fn(&FrameReport) -> f64) -> f64 {
    r.iter().map(f).fold(0.0, f64::max)
}

/// The ragdoll at the reference of a frame is the hierarchy's forward kinematics of that
/// frame: every body's origin at its joint and every body turned as its joint, relative to
/// the root, to 1e-9 (at frames 0 and 400 of the clip, mid-jump).
#[test]
fn the_bvh_reference_pose_is_the_hierarchys_forward_kinematics() {
    for start in [0, 400] {
        let (skeleton, motion, t) = tracker(start, TrackingOptions::default());
        let model = t.body().model();
        let mut state = State::new(model);
        state.set_q(model, t.reference_q()).unwrap();
        let mut solver = Solver::new(model);
        let tree = solver.kinematics(model, &state);
        let joints = skeleton.joints.len();
        assert_eq!(model.bodies().len(), joints);
        let one = motion.slice(0, 1).unwrap();
        let (mut pos, mut ori) = (vec![[0.0; 3]; joints], vec![[0.0; 4]; joints]);
        skeleton.forward_kinematics(&one, &mut pos, &mut ori).unwrap();
        let fk = |i: usize| DVec3::from_array(pos[i]) * SCALE;
        let turn = |i: usize| DQuat::from_xyzw(ori[i][1], ori[i][2], ori[i][3], ori[i][0]);
        let p0 = tree.positions()[0];
        for (i, joint) in skeleton.joints.iter().enumerate() {
            let ours = tree.positions()[i] - p0;
            let want = fk(i) - fk(0);
            assert!((ours - want).length() < 1e-9, "joint {} at {ours}, not {want}", joint.name);
            let (ours, want) = (tree.orientations()[i], turn(i));
            let off = (ours - want).length().min((ours + want).length());
            assert!(off < 1e-9, "joint {} turned {ours}, not {want}", joint.name);
        }
    }
}

/// The jumps of CMU 01_01 (frames 1–601 of the BVH, 5 s) tracked at the defaults by the
/// ragdoll of the BVH hierarchy (31 bodies, unlimited ball joints): every frame reported, the
/// root within 0.4 m of the clip's (measured 0.248 at most, 0.059 on average), the joints
/// within 0.15 rad RMS on average (0.085), and the hand of God measured, finite and carrying
/// between half and twice the weight on average (0.86; up to 3.8 times at the jumps).
#[test]
fn the_cmu_jumps_are_tracked_from_the_bvh_with_a_measured_assistance() {
    let (_, _, mut t) = tracker(0, TrackingOptions::default());
    let r: Vec<FrameReport> = (0..600).map(|_| t.step().unwrap()).collect();
    assert!((r[599].time - 600.0 / t.frame_rate()).abs() < 1e-9); // Frame Time .0083333 s
    let weight = t.body().model().mass() * 9.81;
    let (root, joint) = (max(&r, |f| f.root_error), mean(&r, |f| f.joint_error));
    let force = mean(&r, |f| f.assist_force);
    println!(
        "mass {:.1} kg; root error mean {:.3} max {root:.3} m, joint error mean {joint:.3} rad \
         (max {:.3}), assistance {force:.0} N mean ({:.2} of the weight), max {:.0} N, \
         torque mean {:.1} max {:.1} N m",
        t.body().model().mass(),
        mean(&r, |f| f.root_error),
        max(&r, |f| f.joint_error),
        force / weight,
        max(&r, |f| f.assist_force),
        mean(&r, |f| f.assist_torque),
        max(&r, |f| f.assist_torque)
    );
    assert!(r.iter().all(|f| f.assist_force.is_finite() && f.assist_torque.is_finite()));
    assert!(root < 0.4 && joint < 0.15, "root {root} m, joints {joint} rad");
    assert!(force > 0.5 * weight && force < 2.0 * weight, "assistance {force} N");
}

/// Track `frames` frames of CMU 07_05 (the slow walk) from its ASF/AMC files, or from their
/// BVH conversion (`tests/data/mocap/07_05-walk.bvh`), at the defaults; returns the reports
/// and the weight (N).
fn track_walk(bvh: bool, frames: usize) -> (Vec<FrameReport>, f64) {
    let mut t = if bvh {
        let text = std::fs::read_to_string("tests/data/mocap/07_05-walk.bvh").unwrap();
        let (skeleton, motion) = parse_bvh(&text, "07_05-walk.bvh").unwrap();
        let ragdoll = RagdollOptions { scale: SCALE, ..RagdollOptions::default() };
        let options = TrackingOptions::default();
        Tracker::new(&skeleton, &motion, &ragdoll, Settings::default(), options).unwrap()
    } else {
        let (skeleton, motion) = cmu::walk();
        let ragdoll = RagdollOptions { scale: SCALE, ..RagdollOptions::default() };
        let options = TrackingOptions::default();
        Tracker::new(&skeleton, &motion, &ragdoll, Settings::default(), options).unwrap()
    };
    let r = (0..frames).map(|_| t.step().unwrap()).collect();
    (r, t.body().model().mass() * 9.81)
}

/// CMU 07_05 (a slow walk) tracked for 5 s (600 frames, looped) from its BVH conversion, by
/// the BVH ragdoll (a body per joint, unlimited ball joints), against the ASF ragdoll
/// tracking the ASF/AMC clip at the same defaults: every frame reported, the BVH tracker's
/// root within 0.2 m of the clip's at most (measured 0.116), its joints within 0.15 rad RMS
/// on average and 0.3 at most (0.094, 0.167), its hand of God finite and carrying between
/// half and twice the weight on average (0.89), each mean within 1 cm, 0.01 rad and 5 % of
/// the ASF tracker's (measured 0.066 against 0.063 m, 0.094 against 0.094 rad, 276 against
/// 277 N); the figures of both are printed (docs/character.md, "BVH clips").
#[test]
fn the_cmu_walk_is_tracked_from_its_bvh_conversion() {
    let mut rows = vec![];
    for bvh in [false, true] {
        let (r, weight) = track_walk(bvh, 600);
        let row = [
            mean(&r, |f| f.root_error),
            max(&r, |f| f.root_error),
            mean(&r, |f| f.joint_error),
            max(&r, |f| f.joint_error),
            mean(&r, |f| f.assist_force),
            max(&r, |f| f.assist_force),
            mean(&r, |f| f.assist_torque),
            max(&r, |f| f.assist_torque),
        ];
        println!(
            "{}: weight {weight:.0} N; root error {:.3} / {:.3} m, joint error {:.3} / {:.3} \
             rad, assistance {:.0} / {:.0} N ({:.2} / {:.2} of the weight), torque {:.3} / \
             {:.3} N m (mean / max)",
            if bvh { "BVH" } else { "ASF" },
            row[0],
            row[1],
            row[2],
            row[3],
            row[4],
            row[5],
            row[4] / weight,
            row[5] / weight,
            row[6],
            row[7]
        );
        assert!(r.iter().all(|f| f.assist_force.is_finite() && f.assist_torque.is_finite()));
        rows.push((row, weight));
    }
    let ([root_mean, root, joint, joint_max, force, ..], weight) = rows[1];
    assert!(root < 0.2 && root_mean < 0.1, "root {root_mean} / {root} m");
    assert!(joint < 0.15 && joint_max < 0.3, "joints {joint} / {joint_max} rad");
    assert!(force > 0.5 * weight && force < 2.0 * weight, "assistance {force} N");
    // The same clip: the ASF tracker's figures to 1 cm, 0.01 rad and 5 %.
    let asf = rows[0].0;
    assert!((root_mean - asf[0]).abs() < 0.01, "root {root_mean} m, ASF {} m", asf[0]);
    assert!((joint - asf[2]).abs() < 0.01, "joints {joint} rad, ASF {} rad", asf[2]);
    assert!((force / asf[4] - 1.0).abs() < 0.05, "assistance {force} N, ASF {} N", asf[4]);
}
