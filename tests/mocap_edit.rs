//! Motion editing on real CMU clips: time warping, blending, stitching with root alignment,
//! motion warping; bone lengths kept; bad input refused.

use kinema::mocap::{parse_amc, parse_asf, Edit, Motion, Skeleton};
use std::path::PathBuf;

mod cmu;
use cmu::walk;

fn positions(sk: &Skeleton, m: &Motion) -> Vec<[f64; 3]> {
    let joints = 1 + sk.bones.len();
    let mut p = vec![[0.0; 3]; m.frames * joints];
    let mut o = vec![[0.0; 4]; m.frames * joints];
    sk.forward_kinematics(m, &mut p, &mut o).unwrap();
    p
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Largest change of any bone's length from its rest length over all frames.
fn bone_error(sk: &Skeleton, m: &Motion) -> f64 {
    let p = positions(sk, m);
    let joints = 1 + sk.bones.len();
    let mut worst: f64 = 0.0;
    for f in 0..m.frames {
        for (b, bone) in sk.bones.iter().enumerate() {
            let parent = bone.parent.map_or(0, |q| q + 1);
            let d = dist(p[f * joints + b + 1], p[f * joints + parent]);
            worst = worst.max((d - bone.length).abs());
        }
    }
    worst
}

#[test]
fn time_warp_reproduces_frames_at_integers_and_lies_between_at_halves() {
    let (sk, m) = walk();
    let at: Vec<f64> = (0..m.frames).map(|f| f as f64).collect();
    assert_eq!(sk.time_warp(&m, &at).unwrap().values, m.values);
    let half: Vec<f64> = (0..m.frames - 1).map(|f| f as f64 + 0.5).collect();
    let mid = sk.time_warp(&m, &half).unwrap();
    let (p, q) = (positions(&sk, &m), positions(&sk, &mid));
    let joints = 1 + sk.bones.len();
    for f in (0..m.frames - 1).step_by(37) {
        for j in 0..joints {
            let (a, b, c) = (p[f * joints + j], p[(f + 1) * joints + j], q[f * joints + j]);
            // Between its neighbours: no farther from either than they are from each other
            // (plus the rounding of the chord of a slerped arc).
            assert!(dist(a, c) <= dist(a, b) + 1e-6 && dist(b, c) <= dist(a, b) + 1e-6);
        }
    }
    assert!(bone_error(&sk, &mid) < 1e-9);
    // Slow motion: 2x as many frames, the same start and end.
    let slow: Vec<f64> = (0..2 * m.frames - 1).map(|f| f as f64 / 2.0).collect();
    let s = sk.time_warp(&m, &slow).unwrap();
    assert_eq!(&s.values[..s.stride], &m.values[..m.stride]);
    assert!(sk.time_warp(&m, &[0.0, 2.0, 1.0]).is_err());
    assert!(sk.time_warp(&m, &[-1.0]).is_err());
    assert!(sk.time_warp(&m, &[f64::NAN]).is_err());
    assert!(sk.time_warp(&m, &[m.frames as f64]).is_err());
}

#[test]
fn blend_weights_select_each_motion_and_a_motion_blended_with_itself_is_itself() {
    let (sk, m) = walk();
    let (a, b) = (m.slice(0, 200).unwrap(), m.slice(250, 450).unwrap());
    assert_eq!(sk.blend(&a, &b, &[0.0]).unwrap().values, a.values);
    assert_eq!(sk.blend(&a, &b, &[1.0]).unwrap().values, b.values);
    // Rotation groups go through a quaternion and back (angles may come back as another
    // triple of the same rotation): the same pose, to rounding.
    let same = sk.blend(&a, &a, &[0.3]).unwrap();
    let (p, q) = (positions(&sk, &a), positions(&sk, &same));
    assert!(p.iter().zip(&q).all(|(x, y)| dist(*x, *y) < 1e-9));
    let ramp: Vec<f64> = (0..200).map(|f| f as f64 / 199.0).collect();
    let mixed = sk.blend(&a, &b, &ramp).unwrap();
    assert!(bone_error(&sk, &mixed) < 1e-9);
    assert!(sk.blend(&a, &m, &[0.5]).is_err());
    assert!(sk.blend(&a, &b, &[0.5, 0.5]).is_err());
    assert!(sk.blend(&a, &b, &[f64::NAN]).is_err());
    assert!(sk.blend(&a, &b, &[1.5]).is_err());
}

#[test]
fn stitched_motion_continues_where_the_first_ends() {
    let (sk, m) = walk();
    let (a, b) = (m.slice(0, 250).unwrap(), m.slice(300, 517).unwrap());
    for transition in [0, 10] {
        let s = sk.stitch(&a, &b, transition).unwrap();
        assert_eq!(s.frames, a.frames + b.frames - transition);
        assert!(bone_error(&sk, &s) < 1e-9);
        // The root moves no more at the join than the walk moves in a frame, anywhere.
        let step = |mm: &Motion, f: usize| {
            let r = |k: usize| [mm.values[k * mm.stride], mm.values[k * mm.stride + 2]];
            let (p, q) = (r(f), r(f + 1));
            ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt()
        };
        let typical = (0..m.frames - 1).map(|f| step(&m, f)).fold(0.0, f64::max);
        let join = a.frames - transition;
        for f in join.saturating_sub(2)..join + 2 {
            assert!(
                step(&s, f) <= 1.5 * typical,
                "jump {} at {f} (typical {typical})",
                step(&s, f)
            );
        }
    }
    assert!(sk.stitch(&a, &b, 300).is_err());
}

#[test]
fn warp_passes_through_its_keys_and_keeps_the_ends() {
    let (sk, m) = walk();
    let mut pose = m.values[200 * m.stride..201 * m.stride].to_vec();
    for v in pose.iter_mut().skip(6) {
        *v += 0.1; // every bone turned by 0.1 rad about each of its axes
    }
    let w = sk.warp(&m, &[(200, pose.clone())]).unwrap();
    assert_eq!(&w.values[200 * m.stride..201 * m.stride], &pose[..]);
    let end = (m.frames - 1) * m.stride;
    for (x, y) in w.values[..m.stride]
        .iter()
        .zip(&m.values)
        .chain(w.values[end..].iter().zip(&m.values[end..]))
    {
        assert!((x - y).abs() < 1e-12, "the ends move: {x} vs {y}");
    }
    // The displacement is smooth and the detail is kept: frame-to-frame differences change by
    // no more than the displacement's own (small) slope allows.
    for f in [50, 150, 199, 201, 300, 450] {
        let (d0, d1) = (
            w.values[f * m.stride + 7] - w.values[(f + 1) * m.stride + 7],
            m.values[f * m.stride + 7] - m.values[(f + 1) * m.stride + 7],
        );
        assert!((d0 - d1).abs() < 0.1 / 50.0, "frame {f}: {d0} vs {d1}");
    }
    assert!(bone_error(&sk, &w) < 1e-9);
    assert!(sk.warp(&m, &[]).is_err());
    assert!(sk.warp(&m, &[(m.frames, pose.clone())]).is_err());
    assert!(sk.warp(&m, &[(3, pose.clone()), (3, pose.clone())]).is_err());
    assert!(sk.warp(&m, &[(3, vec![0.0; 2])]).is_err());
}

#[test]
fn bvh_motions_are_edited_the_same_way() {
    use kinema::mocap::{parse_bvh, BvhSkeleton};
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/mocap");
    let text = String::from_utf8_lossy(&std::fs::read(dir.join("01_01.bvh")).unwrap()).into_owned();
    let (sk, m): (BvhSkeleton, Motion) = parse_bvh(&text, "01_01.bvh").unwrap();
    let m = m.slice(1, 601).unwrap(); // frame 0 is the added T-pose
    let joints = sk.joints.len();
    let fk = |mm: &Motion| {
        let mut p = vec![[0.0; 3]; mm.frames * joints];
        let mut o = vec![[0.0; 4]; mm.frames * joints];
        sk.forward_kinematics(mm, &mut p, &mut o).unwrap();
        p
    };
    // Offsets are rigid: every joint keeps its distance to its parent.
    let rigid = |mm: &Motion| {
        let p = fk(mm);
        (0..mm.frames).all(|f| {
            sk.joints.iter().enumerate().skip(1).all(|(j, joint)| {
                let parent = joint.parent.unwrap();
                let d = dist(p[f * joints + j], p[f * joints + parent]);
                (d - joint.offset.length()).abs() < 1e-9 * (1.0 + d)
            })
        })
    };
    let half = sk.resample(&m, m.frame_rate, m.frame_rate / 2.0).unwrap();
    assert_eq!(half.frames, 300);
    assert_eq!(half.values[half.stride..2 * half.stride], m.values[2 * m.stride..3 * m.stride]);
    let (a, b) = (m.slice(0, 300).unwrap(), m.slice(300, 600).unwrap());
    let mixed = sk.blend(&a, &b, &[0.5]).unwrap();
    let joined = sk.stitch(&a, &b, 10).unwrap();
    let mut key = m.values[150 * m.stride..151 * m.stride].to_vec();
    key[6..].iter_mut().for_each(|v| *v += 0.05);
    let warped = sk.warp(&m, &[(150, key.clone())]).unwrap();
    assert_eq!(&warped.values[150 * m.stride..151 * m.stride], &key[..]);
    for edited in [&half, &mixed, &joined, &warped] {
        assert!(rigid(edited));
    }
}

#[test]
fn warp_offsets_across_the_pi_seam_take_the_short_way() {
    // One bone turning about z, held at 170°; the key asks for -170° (= 190°) at frame 10: a
    // turn of +20°, not of -340° through 0°.
    let asf = ":units\n  length 1\n  angle deg\n:root\n  order TX TY TZ RX RY RZ\n  axis XYZ\n  position 0 0 0\n  orientation 0 0 0\n:bonedata\n  begin\n    name arm\n    direction 1 0 0\n    length 1\n    axis 0 0 0 XYZ\n    dof rz\n  end\n:hierarchy\n  begin\n    root arm\n  end\n";
    let sk = parse_asf(asf, "seam.asf").unwrap();
    let amc: String = (1..=21).map(|f| format!("{f}\nroot 0 0 0 0 0 0\narm 170\n")).collect();
    let m = parse_amc(&amc, "seam.amc", &sk).unwrap();
    let deg = std::f64::consts::PI / 180.0;
    let mut key = m.values[10 * m.stride..11 * m.stride].to_vec();
    key[6] = -170.0 * deg;
    let w = sk.warp(&m, &[(10, key)]).unwrap();
    let angles: Vec<f64> = (0..m.frames).map(|f| w.values[f * m.stride + 6] / deg).collect();
    // Every frame turns between 170° and 190°, the key frame by exactly 190° (the same
    // rotation as -170°, continuous with its neighbours), the ends unchanged.
    assert!(angles.iter().all(|a| (170.0 - 1e-9..=190.0 + 1e-9).contains(a)), "{angles:?}");
    assert!((angles[10] - 190.0).abs() < 1e-12, "{}", angles[10]);
    assert!(angles[9] > 180.0 && angles[11] > 180.0, "{angles:?}");
    assert_eq!((angles[0], angles[20]), (170.0, 170.0));
    // A key within the half turn is still copied exactly.
    let mut near = m.values[10 * m.stride..11 * m.stride].to_vec();
    near[6] = 150.0 * deg;
    let w = sk.warp(&m, &[(10, near.clone())]).unwrap();
    assert_eq!(&w.values[10 * m.stride..11 * m.stride], &near[..]);
}
