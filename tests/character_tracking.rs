//! Mocap tracking (`kinema::character::Tracker`): the CMU 07 walk tracked for 10 s by the
//! ragdoll of its skeleton, with PD servos and a measured root assistance; the reference
//! pose against the skeleton's own forward kinematics.

use glam::{DQuat, DVec3};
use kinema::character::{
    FrameReport, RagdollOptions, Settings, Solver, State, Tracker, TrackingOptions,
};
use kinema::mocap::Motion;
use kinema::snapshot::Snapshot;

mod cmu;
use cmu::walk;

fn tracker(options: TrackingOptions) -> Tracker {
    let (skeleton, motion) = walk();
    let ragdoll = RagdollOptions { scale: skeleton.metres_per_unit(), ..RagdollOptions::default() };
    Tracker::new(&skeleton, &motion, &ragdoll, Settings::default(), options).unwrap()
}

fn track(options: TrackingOptions, frames: usize) -> Vec<FrameReport> {
    let mut t = tracker(options);
    (0..frames).map(|_| t.step().unwrap()).collect()
}

fn mean(r: &[FrameReport], f: impl Fn(&FrameReport) -> f64) -> f64 {
    r.iter().map(f).sum::<f64>() / r.len() as f64
}

fn max(r: &[FrameReport], f: impl Fn(&FrameReport) -> f64) -> f64 {
    r.iter().map(f).fold(0.0, f64::max)
}

/// The ragdoll at the reference of a frame is the skeleton's forward kinematics of that
/// frame: every body's origin at its bone's base (the parent's tip) and every body turned
/// as its bone, relative to the root, to 1e-9.
#[test]
fn the_reference_pose_is_the_skeletons_forward_kinematics() {
    let (skeleton, motion) = walk();
    let t = tracker(TrackingOptions::default());
    let model = t.body().model();
    let mut state = State::new(model);
    state.set_q(model, t.reference_q()).unwrap();
    let mut solver = Solver::new(model);
    let tree = solver.kinematics(model, &state);
    let joints = 1 + skeleton.bones.len();
    let one = motion.slice(0, 1).unwrap();
    let (mut pos, mut ori) = (vec![[0.0; 3]; joints], vec![[0.0; 4]; joints]);
    skeleton.forward_kinematics(&one, &mut pos, &mut ori).unwrap();
    let scale = skeleton.metres_per_unit();
    let fk = |i: usize| DVec3::from_array(pos[i]) * scale;
    let turn = |i: usize| DQuat::from_xyzw(ori[i][1], ori[i][2], ori[i][3], ori[i][0]);
    let (p0, r0) = (tree.positions()[0], tree.orientations()[0]);
    assert!(r0.angle_between(turn(0)) < 1e-9);
    for (b, bone) in skeleton.bones.iter().enumerate() {
        let base = bone.parent.map_or(fk(0), |p| fk(p + 1));
        let ours = tree.positions()[b + 1] - p0;
        assert!((ours - (base - fk(0))).length() < 1e-9, "bone {} at {ours}", bone.name);
        let angle = tree.orientations()[b + 1].angle_between(turn(b + 1));
        // A hinge or fixed joint holds only the dofs the ASF gives it: exact as well.
        assert!(angle < 1e-9, "bone {} turned {angle} rad off", bone.name);
    }
    let _ = r0;
}

/// 10 s (the 4.3 s clip looped) at the defaults: the root stays within 0.15 m of the clip's,
/// the joints within 0.15 rad RMS on average, and the hand of God is measured (it carries
/// most of the weight: pure PD tracking has no balance).
#[test]
fn the_cmu_walk_is_tracked_for_ten_seconds_with_a_measured_assistance() {
    let r = track(TrackingOptions::default(), 1200);
    assert!((r[1199].time - 10.0).abs() < 1e-9);
    let weight = 31.7 * 9.81;
    let (root, joint) = (max(&r, |f| f.root_error), mean(&r, |f| f.joint_error));
    let force = mean(&r, |f| f.assist_force);
    println!(
        "root error max {root:.3} m, joint error mean {joint:.3} rad (max {:.3}), \
         assistance {force:.0} N mean ({:.2} of the weight), max {:.0} N, torque mean {:.1} N m",
        max(&r, |f| f.joint_error),
        force / weight,
        max(&r, |f| f.assist_force),
        mean(&r, |f| f.assist_torque)
    );
    assert!(root < 0.15, "root error {root} m");
    assert!(joint < 0.15, "joint error {joint} rad");
    assert!(max(&r, |f| f.joint_error) < 0.3);
    assert!(force > 0.2 * weight && force < 2.0 * weight, "assistance {force} N");
}

/// Without the servos (limp) the joints are far from the clip even with the root held;
/// without the assistance the walker falls and the root is far from the clip's.
#[test]
fn limp_joints_and_no_assistance_are_far_from_the_clip() {
    // A limp ragdoll held by its root needs a smaller step (its limit springs).
    let limp = TrackingOptions { kp: 0.0, kd: 0.0, substeps: 8, ..TrackingOptions::default() };
    let r = track(limp, 240);
    let joint = mean(&r[120..], |f| f.joint_error);
    assert!(joint > 0.8, "limp joint error {joint} rad");
    let free = TrackingOptions { assist_frequency: 0.0, ..TrackingOptions::default() };
    let r = track(free, 480);
    assert!(mean(&r, |f| f.assist_force) == 0.0);
    assert!(r[479].root_error > 1.0, "root error without assistance {} m", r[479].root_error);
}

#[test]
fn bad_options_are_named() {
    let (skeleton, motion) = walk();
    let ragdoll = RagdollOptions { scale: skeleton.metres_per_unit(), ..RagdollOptions::default() };
    let new = |o: TrackingOptions| {
        Tracker::new(&skeleton, &motion, &ragdoll, Settings::default(), o).unwrap_err().to_string()
    };
    assert!(new(TrackingOptions { kp: f64::NAN, ..TrackingOptions::default() }).contains("kp"));
    assert!(new(TrackingOptions { substeps: 0, ..TrackingOptions::default() }).contains("substeps"));
    let short = motion.slice(0, 4).unwrap();
    let err = Tracker::new(&skeleton, &short, &ragdoll, Settings::default(), Default::default());
    assert!(err.unwrap_err().to_string().contains("motion"));
}

/// A tracker restored from its snapshot goes on bit for bit as the original: the ragdoll's
/// state, the frame and the reports of the next frames.
#[test]
fn a_restored_tracker_continues_bit_for_bit() {
    let mut t = tracker(TrackingOptions::default());
    for _ in 0..30 {
        t.step().unwrap();
    }
    let mut back = Tracker::from_snapshot(&t.to_snapshot().unwrap()).unwrap();
    assert_eq!(back.frame(), 30);
    for _ in 0..30 {
        assert_eq!(t.step().unwrap(), back.step().unwrap());
    }
    assert_eq!(t.body().state(), back.body().state());
    assert_eq!(t.reference_q(), back.reference_q());
}

/// A tracker started at frame k (`start_at`) is at the clip's frame k, pose and rates, and
/// tracks as the tracker of the clip sliced at k (the way before `start_at`), up to the
/// clip's lift onto the ground, which the slice takes again from its own frames: without the
/// ground, which alone sees the height, the two differ by that lift, to 1e-9, for 60 frames.
/// A frame at or past the loop's end is refused, naming `start_frame`.
#[test]
fn starting_at_a_frame_tracks_as_the_clip_sliced_there() {
    let (skeleton, motion) = walk();
    let ragdoll = RagdollOptions { scale: skeleton.metres_per_unit(), ..RagdollOptions::default() };
    let settings = Settings { ground: false, ..Settings::default() };
    let new = |m: &Motion| {
        Tracker::new(&skeleton, m, &ragdoll, settings, TrackingOptions::default()).unwrap()
    };
    let k = 40;
    let mut at = new(&motion);
    at.start_at(k).unwrap();
    let mut cut = new(&motion.slice(k, motion.frames).unwrap());
    assert_eq!((at.frame(), cut.frame()), (k, 0));
    let lift = at.reference_q()[1] - cut.reference_q()[1];
    let apart = |a: &Tracker, b: &Tracker| -> f64 {
        let (sa, sb) = (a.body().state(), b.body().state());
        let q = sa.q().iter().zip(sb.q()).enumerate();
        let dq = q.map(|(i, (x, y))| (x - y - if i == 1 { lift } else { 0.0 }).abs());
        let dv = sa.qd().iter().zip(sb.qd()).map(|(x, y)| (x - y).abs());
        dq.chain(dv).fold(0.0, f64::max)
    };
    assert!(apart(&at, &cut) < 1e-9, "start {}", apart(&at, &cut));
    assert!(lift.abs() > 1e-4, "the slice is lifted by {lift} m: the test needs a difference");
    for f in 0..60 {
        let (a, b) = (at.step().unwrap(), cut.step().unwrap());
        let reports = [
            (a.root_error, b.root_error),
            (a.joint_error, b.joint_error),
            (a.assist_force, b.assist_force),
            (a.assist_torque, b.assist_torque),
        ];
        for (x, y) in reports {
            assert!((x - y).abs() < 1e-9 * (1.0 + x.abs()), "frame {f}: {x} and {y}");
        }
        assert!(apart(&at, &cut) < 1e-9, "frame {f}: {}", apart(&at, &cut));
    }
    assert_eq!(at.frame(), k + 60);
    let end = at.loop_span().1;
    let err = at.start_at(end).unwrap_err().to_string();
    assert!(err.contains("start_frame"), "{err}");
    assert_eq!(at.frame(), k + 60);
}
