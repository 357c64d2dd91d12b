//! Biovision BVH: the CMU 01_01 conversion in tests/data/mocap (header, cross-check against
//! the original ASF/AMC, read → write → read), hand-made files with closed-form answers, and
//! broken input with the line of the fault.
//!
//! `01_01.bvh` (2 070 355 bytes, over the 2 MB limit for tests/data/) is read in place. It
//! comes from facebookresearch/fairmotion @ c16b6590, `tests/data/01_01.bvh`: a BVH conversion
//! of CMU clip 01_01 ("playground - forward jumps, turn around"). The data was obtained from
//! mocap.cs.cmu.edu; the database was created with funding from NSF EIA-0196217.

use kinema::mocap::{parse_amc, parse_asf, parse_bvh, write_bvh, BvhSkeleton, Motion};
use kinema::Error;
use std::path::PathBuf;

fn read(name: &str) -> String {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/mocap");
    assert!(dir.is_dir(), "the motion-capture data is expected at {}", dir.display());
    String::from_utf8_lossy(&std::fs::read(dir.join(name)).unwrap()).into_owned()
}

fn fk(sk: &BvhSkeleton, m: &Motion) -> (Vec<[f64; 3]>, Vec<[f64; 4]>) {
    let joints = sk.joints.len();
    let mut p = vec![[0.0; 3]; m.frames * joints];
    let mut o = vec![[0.0; 4]; m.frames * joints];
    sk.forward_kinematics(m, &mut p, &mut o).unwrap();
    (p, o)
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

fn parse_err(text: &str) -> (usize, String) {
    match parse_bvh(text, "bad.bvh") {
        Err(Error::Parse { file, line, expected }) => {
            assert_eq!(file, "bad.bvh");
            (line, expected)
        }
        Err(e) => panic!("not a parse error: {e}"),
        Ok(_) => panic!("parsed:\n{text}"),
    }
}

#[test]
fn cmu_01_01_matches_its_header() {
    let text = read("01_01.bvh");
    let (sk, m) = parse_bvh(&text, "01_01.bvh").unwrap();
    // Count the header independently of the parser.
    let first = |w: &str| text.lines().filter(|l| l.split_whitespace().next() == Some(w)).count();
    let declared = |key: &str| {
        let line = text.lines().find(|l| l.starts_with(key)).unwrap();
        line[key.len()..].trim().to_string()
    };
    assert_eq!(first("ROOT") + first("JOINT"), 31);
    assert_eq!(sk.joints.len(), first("ROOT") + first("JOINT"));
    assert_eq!(sk.joints.iter().filter(|j| j.end_site.is_some()).count(), first("End"));
    assert_eq!(m.frames, declared("Frames:").parse::<usize>().unwrap());
    assert_eq!(m.frames, 2752);
    assert_eq!(sk.frame_time, declared("Frame Time:").parse::<f64>().unwrap());
    assert_eq!(sk.frame_time, 0.0083333);
    assert_eq!(m.stride, 6 + 30 * 3);
    assert_eq!(m.values.len(), m.frames * m.stride);
    assert_eq!(sk.joints[0].name, "Hips");
    assert_eq!(sk.joints[0].parent, None);
    assert!(sk.joints[1..].iter().all(|j| j.channels.len() == 3));
    let names = sk.joint_names();
    let up_leg = names.iter().position(|n| n == "LeftUpLeg").unwrap();
    let leg = names.iter().position(|n| n == "LeftLeg").unwrap();
    assert_eq!(sk.joints[leg].parent, Some(up_leg));
    assert_eq!(sk.joints[leg].offset.to_array(), [2.44811, -6.72613, 0.0]);
    // Second frame, first values, converted to radians.
    assert_eq!(
        m.values[m.stride..m.stride + 4],
        [9.3722, 17.8693, -17.3198, (-3.2316f64).to_radians()]
    );
}

/// The BVH is a conversion of 01_01.amc with a T-pose put in front. Frame f + 1 of the BVH must
/// put its joints where the ASF/AMC forward kinematics (a different model: bone axes, bones
/// turned by their own dofs) puts the root and the bone tips of frame f, and turn them the same
/// way, to within the BVH's rounding (4 decimals of a degree, 5 of a unit). This checks the
/// intrinsic channel order and the parent-turns-the-offset rule against independent data.
///
/// Only the legs and the spine up to Spine1 (and the joints at zero offset from it) are
/// compared: the conversion drops the ASF `thorax` bone (BVH `Neck` sits at zero offset from
/// `Spine1` where the thorax is 2.06 units long), so the neck, head and arms are moved.
#[test]
fn cmu_bvh_agrees_with_the_original_asf_amc() {
    let (sk, m) = parse_bvh(&read("01_01.bvh"), "01_01.bvh").unwrap();
    let asf = parse_asf(&read("01.asf"), "01.asf").unwrap();
    let amc = parse_amc(&read("01_01.amc"), "01_01.amc", &asf).unwrap();
    assert_eq!(amc.frames + 1, m.frames);
    let (p, o) = fk(&sk, &m);
    let aj = 1 + asf.bones.len();
    let mut q = vec![[0.0; 3]; amc.frames * aj];
    let mut r = vec![[0.0; 4]; amc.frames * aj];
    asf.forward_kinematics(&amc, &mut q, &mut r).unwrap();
    let bvh_names = sk.joint_names();
    let asf_names = asf.joint_names();
    let at = |names: &[String], n: &str| names.iter().position(|x| x == n).unwrap();
    // BVH joint, the ASF joint whose tip it is, the ASF bone its rotation turns.
    let pairs = [
        ("Hips", "root", Some("root")),
        ("LHipJoint", "root", None),
        ("LeftUpLeg", "lhipjoint", Some("lfemur")),
        ("LeftLeg", "lfemur", Some("ltibia")),
        ("LeftFoot", "ltibia", Some("lfoot")),
        ("LeftToeBase", "lfoot", Some("ltoes")),
        ("RHipJoint", "root", None),
        ("RightUpLeg", "rhipjoint", Some("rfemur")),
        ("RightLeg", "rfemur", Some("rtibia")),
        ("RightFoot", "rtibia", Some("rfoot")),
        ("RightToeBase", "rfoot", Some("rtoes")),
        ("LowerBack", "root", Some("lowerback")),
        ("Spine", "lowerback", Some("upperback")),
        ("Spine1", "upperback", None),
        ("Neck", "upperback", None),
        ("LeftShoulder", "upperback", None),
        ("RightShoulder", "upperback", None),
    ];
    let (bj, mut worst_p, mut worst_r) = (sk.joints.len(), 0.0f64, 0.0f64);
    for f in 0..amc.frames {
        for (b, a, rot) in pairs {
            let (b, a) = ((f + 1) * bj + at(&bvh_names, b), f * aj + at(&asf_names, a));
            worst_p = worst_p.max(dist(p[b], q[a]));
            if let Some(bone) = rot {
                let a = f * aj + at(&asf_names, bone);
                let dot: f64 = o[b].iter().zip(&r[a]).map(|(x, y)| x * y).sum();
                worst_r = worst_r.max(2.0 * dot.abs().min(1.0).acos());
            }
        }
        for w in &o[(f + 1) * bj..(f + 2) * bj] {
            assert!((w.iter().map(|c| c * c).sum::<f64>() - 1.0).abs() < 1e-12);
        }
    }
    assert!(worst_p < 2e-4, "positions differ by up to {worst_p} units");
    assert!(worst_r < 1e-5, "orientations differ by up to {worst_r} rad");
    // All channels zero is the rest pose: every joint sits at the sum of its offsets.
    let rest =
        Motion { values: vec![0.0; m.stride], stride: m.stride, frames: 1, frame_rate: 120.0 };
    let (p, _) = fk(&sk, &rest);
    for (j, joint) in sk.joints.iter().enumerate().skip(1) {
        let parent = joint.parent.unwrap();
        let d = [0, 1, 2].map(|a| p[j][a] - p[parent][a]);
        assert!(dist(d, joint.offset.to_array()) < 1e-12, "{}", joint.name);
    }
}

#[test]
fn read_write_read_is_the_identity() {
    let (sk, m) = parse_bvh(&read("01_01.bvh"), "01_01.bvh").unwrap();
    let text = write_bvh(&sk, &m).unwrap();
    let (sk2, m2) = parse_bvh(&text, "written.bvh").unwrap();
    assert_eq!(sk2, sk);
    assert_eq!((m2.frames, m2.stride), (m.frames, m.stride));
    // Every number is written so that it reads back to the same f64.
    assert!(m.values.iter().zip(&m2.values).all(|(a, b)| a.to_bits() == b.to_bits()));
    let (p, o) = fk(&sk, &m);
    let (p2, o2) = fk(&sk2, &m2);
    let worst = p.iter().zip(&p2).map(|(a, b)| dist(*a, *b)).fold(0.0, f64::max);
    assert!(worst <= 1e-9, "{worst}");
    let worst = o
        .iter()
        .zip(&o2)
        .flat_map(|(a, b)| a.iter().zip(b).map(|(x, y)| (x - y).abs()))
        .fold(0.0, f64::max);
    assert!(worst <= 1e-12, "{worst}");
    // Writing again gives the same text; the angles keep the file's digits.
    assert_eq!(write_bvh(&sk2, &m2).unwrap(), text);
    let second = text.lines().skip_while(|l| !l.starts_with("Frame Time")).nth(2).unwrap();
    assert!(
        second.starts_with("9.3722 17.8693 -17.3198 -3.2316 -7.597 -2.0168 0 0 0 "),
        "{second}"
    );
}

/// A chain root → a → b with the given root rotation channels and values (degrees).
fn chain(channels: &str, values: &str) -> Vec<[f64; 3]> {
    let n = channels.split_whitespace().count();
    let text = format!(
        "HIERARCHY\nROOT r\n{{\n  OFFSET 0 0 0\n  CHANNELS {n} {channels}\n  JOINT a\n  {{\n    OFFSET 0 1 0\n    CHANNELS 3 Zrotation Xrotation Yrotation\n    End Site\n    {{\n      OFFSET 0 1 0\n    }}\n  }}\n}}\nMOTION\nFrames: 1\nFrame Time: 0.01\n{values} 0 0 0\n"
    );
    let (sk, m) = parse_bvh(&text, "chain.bvh").unwrap();
    fk(&sk, &m).0
}

fn close(a: [f64; 3], b: [f64; 3]) -> bool {
    dist(a, b) < 1e-12
}

#[test]
fn hand_made_files_have_closed_form_answers() {
    // Intrinsic order: `Zrotation Xrotation` is Rz(90)·Rx(90): y -> z (by Rx), z stays (by Rz).
    let p = chain("Zrotation Xrotation", "90 90");
    assert!(close(p[1], [0.0, 0.0, 1.0]), "{:?}", p[1]);
    // `Xrotation Zrotation` is Rx(90)·Rz(90): y -> -x (by Rz), -x stays (by Rx).
    let p = chain("Xrotation Zrotation", "90 90");
    assert!(close(p[1], [-1.0, 0.0, 0.0]), "{:?}", p[1]);
    // Position channels replace the offset, per axis; the rotation turns the child's offset.
    let text = "HIERARCHY\r\nROOT hips\r\n{\r\n\tOFFSET 5 6 7\r\n\tCHANNELS 4 Yposition Xposition Zrotation Yrotation\r\n\r\n\tJOINT arm {\r\n\t\tOFFSET 2 0 0\r\n\t\tCHANNELS 6 Zrotation Xposition Yposition Zposition Xrotation Yrotation\r\n\t\tEnd Site\r\n\t\t{\r\n\t\t\tOFFSET 0 3 0\r\n\t\t}\r\n\t}\r\n}\r\nMOTION\r\nFrames:\t2\r\nFrame Time: 0.5\r\n1 2 0 0 0 0 0 0 0 0\r\n\r\n-1 -2 90 0 90 1 0 0 0 0\r\n";
    let (sk, m) = parse_bvh(text, "crlf.bvh").unwrap();
    assert_eq!(sk.frame_time, 0.5);
    assert_eq!(sk.joints[1].end_site.unwrap().to_array(), [0.0, 3.0, 0.0]);
    let (p, o) = fk(&sk, &m);
    // Frame 0: root at (2, 1, 7) (y, x from the channels, z from OFFSET), arm at root + (0,0,0).
    assert!(close(p[0], [2.0, 1.0, 7.0]) && close(p[1], [2.0, 1.0, 7.0]), "{p:?}");
    // Frame 1: root at (-2, -1, 7) turned 90° about z; the arm's own translation (1, 0, 0) is
    // turned by the root to (0, 1, 0); the arm's rotation turns only what hangs below it.
    assert!(close(p[2], [-2.0, -1.0, 7.0]) && close(p[3], [-2.0, 0.0, 7.0]), "{p:?}");
    let s = std::f64::consts::FRAC_1_SQRT_2;
    assert!(o[2].iter().zip([s, 0.0, 0.0, s]).all(|(a, b)| (a - b).abs() < 1e-12), "{:?}", o[2]);
    // Root Rz(90), arm Rz(90)·Rx(0)·Ry(0): together Rz(180) = (0, 0, 0, 1).
    assert!(o[3].iter().zip([0.0, 0.0, 0.0, 1.0]).all(|(a, b)| (a.abs() - b).abs() < 1e-12));
    // The written file reads back the same.
    let (sk2, m2) = parse_bvh(&write_bvh(&sk, &m).unwrap(), "w.bvh").unwrap();
    assert_eq!((sk2, m2), (sk, m));
}

#[test]
fn several_roots_and_empty_channel_lists_round_trip() {
    let text = "hierarchy\nroot a\n{\noffset 1 2 3\nchannels 3 Xposition Yposition Zposition\n}\nROOT b c\n{\nOFFSET 0 0 0\nCHANNELS 0\nJOINT d\n{\nOFFSET 1 0 0\nCHANNELS 1 Yrotation\n}\n}\nMOTION\nFrames: 1\nFrame Time: 1\n4 5 6 30\n";
    let (sk, m) = parse_bvh(text, "two.bvh").unwrap();
    assert_eq!(sk.joint_names(), ["a", "b c", "d"]);
    assert_eq!(sk.joints.iter().map(|j| j.parent).collect::<Vec<_>>(), [None, None, Some(1)]);
    let (p, _) = fk(&sk, &m);
    assert!(close(p[0], [4.0, 5.0, 6.0]) && close(p[2], [1.0, 0.0, 0.0]));
    let (sk2, m2) = parse_bvh(&write_bvh(&sk, &m).unwrap(), "w.bvh").unwrap();
    assert_eq!((sk2, m2), (sk, m));
}

const GOOD: &str = "HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
  JOINT Leg
  {
    OFFSET 0 -1 0
    CHANNELS 3 Zrotation Yrotation Xrotation
    End Site
    {
      OFFSET 0 -1 0
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.0083333
0 1 2 3 4 5 6 7 8
0 1 2 3 4 5 6 7 8
";

/// `GOOD` with line `n` (1-based) replaced.
fn with_line(n: usize, new: &str) -> String {
    GOOD.lines()
        .enumerate()
        .map(|(i, l)| if i + 1 == n { new } else { l })
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn malformed_files_give_the_line() {
    assert!(parse_bvh(GOOD, "good.bvh").is_ok());
    let cases: Vec<(String, usize, &str)> = vec![
        (with_line(1, "HIERARCHIE"), 1, "HIERARCHY"),
        (with_line(3, "  OFFSET 0 0 0"), 3, "{ after the joint name"),
        (with_line(4, "  OFFSET 0 zero 0"), 4, "three numbers after OFFSET"),
        (with_line(4, "  OFFSET 0 0 nan"), 4, "three numbers after OFFSET"),
        (
            with_line(
                5,
                "  CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Wrotation",
            ),
            5,
            "channel names",
        ),
        (with_line(5, "  CHANNELS six Xposition"), 5, "channel count"),
        (
            with_line(
                5,
                "  CHANNELS 6 Xposition Xposition Zposition Zrotation Yrotation Xrotation",
            ),
            5,
            "each position channel once",
        ),
        (with_line(9, "    CHANNELS 4 Zrotation Yrotation Xrotation"), 10, "channel names"),
        (with_line(6, "  JOINT"), 6, "a joint name"),
        (with_line(8, "    OFSET 0 -1 0"), 8, "OFFSET, CHANNELS, JOINT, End Site or }"),
        (with_line(8, "    "), 14, "an OFFSET in joint \"Leg\""),
        (with_line(10, "    End Sight"), 10, "Site after End"),
        (with_line(12, "      OFFSET 0 -1"), 13, "three numbers after OFFSET"),
        (with_line(15, ""), 16, "} to close joint \"Hips\" opened at line 2"),
        (with_line(16, "MOTIONS"), 16, "ROOT or MOTION"),
        (with_line(17, "Frames 2"), 17, "Frames: and a value"),
        (with_line(17, "Frames: two"), 17, "frame count"),
        (with_line(18, "Frame Time: -1"), 18, "positive Frame Time"),
        (with_line(18, "Frame Rate: 120"), 18, "Frame Time: and a value"),
        (with_line(19, "0 1 2 3 4 5 6 7"), 19, "9 values in frame 1, found 8"),
        (with_line(20, "0 1 2 3 4 5 6 7 8 9"), 20, "9 values in frame 2, found 10"),
        (with_line(20, "0 1 2 3 4 5 6 7 inf"), 20, "finite number"),
        (with_line(17, "Frames: 3"), 20, "3 frames (Frames: 3), found 2"),
        (with_line(17, "Frames: 1"), 20, "the end of the file after 1 frames"),
        (GOOD.replace("MOTION\n", ""), 16, "ROOT or MOTION"),
        (GOOD[..GOOD.find("MOTION").unwrap()].to_string(), 15, "MOTION after the hierarchy"),
        (GOOD[..GOOD.find("  JOINT").unwrap()].to_string(), 5, "} to close joint \"Hips\""),
        ("HIERARCHY\nMOTION\nFrames: 0\nFrame Time: 1\n".to_string(), 2, "a ROOT joint"),
        (with_line(6, "  ROOT Leg"), 6, "found ROOT"),
        (with_line(11, "    {{"), 11, "{ after End Site"),
        (format!("{GOOD}\n}}\n"), 22, "the end of the file after 2 frames"),
        (with_line(14, "  }\n}"), 16, "ROOT or MOTION, found an unmatched }"),
    ];
    for (text, line, expected) in cases {
        let (l, e) = parse_err(&text);
        assert!(e.contains(expected), "{e:?} should say {expected:?}\n{text}");
        assert_eq!(l, line, "{e}\n{text}");
    }
    // The message names the file and the line.
    let e = parse_bvh(&with_line(19, "0 1 2"), "x.bvh").unwrap_err();
    assert_eq!(e.to_string(), "x.bvh:19: expected 9 values in frame 1, found 3");
}

#[test]
fn bad_skeletons_and_motions_are_refused() {
    let (sk, m) = parse_bvh(GOOD, "good.bvh").unwrap();
    let other = Motion { values: vec![0.0; 8], stride: 8, frames: 1, frame_rate: 120.0 };
    assert!(matches!(write_bvh(&sk, &other), Err(Error::InvalidInput { .. })));
    let mut p = vec![[0.0; 3]; 2];
    let mut o = vec![[0.0; 4]; 2];
    assert!(sk.forward_kinematics(&other, &mut p, &mut o).is_err());
    assert!(sk.forward_kinematics(&m, &mut p[..1], &mut o[..1]).is_err());
    let mut bad = sk.clone();
    bad.joints[1].name = "two  spaces".into();
    assert!(write_bvh(&bad, &m).is_err());
    let mut bad = sk.clone();
    bad.joints[0].parent = Some(1);
    assert!(write_bvh(&bad, &m).is_err());
    let mut bad = sk.clone();
    bad.frame_time = 0.0;
    assert!(write_bvh(&bad, &m).is_err());
    let mut nan = m.clone();
    nan.values[3] = f64::NAN;
    assert!(write_bvh(&sk, &nan).is_err());
}
