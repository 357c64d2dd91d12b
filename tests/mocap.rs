//! Acclaim ASF/AMC on the real CMU files in tests/data/mocap, on hand-made skeletons with
//! closed-form answers, and on broken input.

use kinema::mocap::{parse_amc, parse_asf, Edit, Motion, Skeleton};
use kinema::Error;
use std::path::PathBuf;

fn data(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/mocap");
    assert!(dir.is_dir(), "the motion-capture data is expected at {}", dir.display());
    dir.join(name)
}

fn read(name: &str) -> String {
    let bytes = std::fs::read(data(name)).unwrap();
    String::from_utf8_lossy(&bytes).into_owned()
}

fn fk(sk: &Skeleton, m: &Motion) -> (Vec<[f64; 3]>, Vec<[f64; 4]>) {
    let joints = 1 + sk.bones.len();
    let mut p = vec![[0.0; 3]; m.frames * joints];
    let mut o = vec![[0.0; 4]; m.frames * joints];
    sk.forward_kinematics(m, &mut p, &mut o).unwrap();
    (p, o)
}

const CMU: [(&str, &str, usize); 6] = [
    ("01.asf", "01_01.amc", 2751),
    ("11.asf", "11_01.amc", 597),
    ("07-walk.asf", "07_05-walk.amc", 517),
    ("09-run.asf", "09_06-run.amc", 141),
    ("pirouette.asf", "pirouette.amc", 591),
    ("backflip.asf", "backflip.amc", 247),
];

#[test]
fn every_cmu_clip_parses_and_keeps_its_bone_lengths() {
    for (asf, amc, frames) in CMU {
        let sk = parse_asf(&read(asf), asf).unwrap();
        assert_eq!(sk.length_unit, 0.45, "{asf}");
        assert_eq!(sk.bones.len(), 30, "{asf}");
        let m = parse_amc(&read(amc), amc, &sk).unwrap();
        assert_eq!(m.frames, frames, "{amc}");
        let (p, _) = fk(&sk, &m);
        let joints = 1 + sk.bones.len();
        for f in 0..m.frames {
            for (b, bone) in sk.bones.iter().enumerate() {
                let parent = bone.parent.map_or(0, |q| q + 1);
                let (a, c) = (p[f * joints + parent], p[f * joints + b + 1]);
                let d =
                    ((a[0] - c[0]).powi(2) + (a[1] - c[1]).powi(2) + (a[2] - c[2]).powi(2)).sqrt();
                assert!(
                    (d - bone.length).abs() < 1e-9 * bone.length.max(1.0),
                    "{amc} frame {f} bone {}",
                    bone.name
                );
            }
        }
    }
}

#[test]
fn walking_feet_touch_a_common_ground() {
    let sk = parse_asf(&read("07-walk.asf"), "07-walk.asf").unwrap();
    let m = parse_amc(&read("07_05-walk.amc"), "07_05-walk.amc", &sk).unwrap();
    let (p, _) = fk(&sk, &m);
    let joints = 1 + sk.bones.len();
    let names = sk.joint_names();
    let feet: Vec<usize> = ["lfoot", "ltoes", "rfoot", "rtoes"]
        .iter()
        .map(|j| names.iter().position(|n| n == j).unwrap())
        .collect();
    // The clip's first 7 frames carry `rfoot 0 0`: unfilled marker data, not a pose. Frames
    // whose foot dofs are exactly zero are left out.
    let offset = |name: &str| {
        let mut k = sk.root_order.len();
        for b in &sk.bones {
            if b.name == name {
                return (k, b.dofs.len());
            }
            k += b.dofs.len();
        }
        unreachable!()
    };
    let foot_dofs = [offset("lfoot"), offset("rfoot")];
    let valid = |f: usize| {
        foot_dofs.iter().all(|&(k, n)| {
            m.values[f * m.stride + k..f * m.stride + k + n].iter().any(|v| *v != 0.0)
        })
    };
    let lowest: Vec<f64> = (0..m.frames)
        .filter(|&f| valid(f))
        .map(|f| feet.iter().map(|&j| p[f * joints + j][1]).fold(f64::INFINITY, f64::min))
        .collect();
    assert!(lowest.len() > 500);
    // The capture floor is slightly tilted along the walk, so remove the linear trend of the
    // lowest point over time; what remains is how far the supporting foot leaves the floor.
    let n = lowest.len() as f64;
    let (mx, my) = ((n - 1.0) / 2.0, lowest.iter().sum::<f64>() / n);
    let sxy: f64 = lowest.iter().enumerate().map(|(i, y)| (i as f64 - mx) * (y - my)).sum();
    let sxx: f64 = (0..lowest.len()).map(|i| (i as f64 - mx).powi(2)).sum();
    let slope = sxy / sxx;
    let residual: Vec<f64> =
        lowest.iter().enumerate().map(|(i, y)| y - my - slope * (i as f64 - mx)).collect();
    let (lo, hi) =
        residual.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &y| (a.min(y), b.max(y)));
    // Less than 1 unit (5.6 cm under the CMU reading) of lift over the whole walk.
    assert!(
        hi - lo < 1.0,
        "lowest foot point leaves the floor by {lo}..{hi} (trend {slope} per frame)"
    );
}

const ONE_BONE: &str = ":version 1.10\n:name test\n:units\n  length 1\n  angle deg\n:root\n  order TX TY TZ RX RY RZ\n  axis XYZ\n  position 0 0 0\n  orientation 0 0 0\n:bonedata\n  begin\n    id 1\n    name arm\n    direction 1 0 0\n    length 2\n    axis AXIS XYZ\n    dof DOF\n    limits (-180 180)\n  end\n:hierarchy\n  begin\n    root arm\n  end\n";

fn one_bone(axis: &str, dof: &str, value: f64) -> [f64; 3] {
    let asf = ONE_BONE.replace("AXIS", axis).replace("DOF", dof);
    let sk = parse_asf(&asf, "one.asf").unwrap();
    let amc = format!(":FULLY-SPECIFIED\n:DEGREES\n1\nroot 1 2 3 0 0 0\narm {value}\n");
    let m = parse_amc(&amc, "one.amc", &sk).unwrap();
    let (p, _) = fk(&sk, &m);
    [p[1][0] - 1.0, p[1][1] - 2.0, p[1][2] - 3.0]
}

#[test]
fn hand_made_skeletons_have_closed_form_answers() {
    let close = |a: [f64; 3], b: [f64; 3]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-12);
    // No axis: rz = 90° turns the x-pointing bone to +y.
    assert!(close(one_bone("0 0 0", "rz", 90.0), [0.0, 2.0, 0.0]));
    // Axis rotated 90° about z: the local x is the global y, so rx = 90° turns about y: x -> -z.
    assert!(close(one_bone("0 0 90", "rx", 90.0), [0.0, 0.0, -2.0]));
    // Root translation and rotation: rotating the root by 90° about z carries the bone along.
    let asf = ONE_BONE.replace("AXIS", "0 0 0").replace("DOF", "rz");
    let sk = parse_asf(&asf, "one.asf").unwrap();
    let m = parse_amc("1\nroot 0 0 0 0 0 90\narm 0\n", "r.amc", &sk).unwrap();
    let (p, _) = fk(&sk, &m);
    assert!(close(p[1], [0.0, 2.0, 0.0]));
}

#[test]
fn variant_files_parse_or_fail_clearly() {
    for name in ["test.asf", "skeleton.asf", "iniini.asf", "modelTemplate.asf"] {
        match parse_asf(&read(&format!("variants/{name}")), name) {
            Ok(sk) => assert!(!sk.bones.is_empty(), "{name}"),
            Err(Error::Parse { line, expected, .. }) => {
                assert!(line > 0 && !expected.is_empty(), "{name}")
            }
            Err(e) => panic!("{name}: {e}"),
        }
    }
    let sk = parse_asf(&read("variants/test.asf"), "test.asf");
    if let Ok(sk) = sk {
        match parse_amc(&read("variants/test.amc"), "test.amc", &sk) {
            Ok(m) => assert!(m.frames > 0),
            Err(e) => assert!(matches!(e, Error::Parse { .. }), "{e}"),
        }
    }
}

#[test]
fn broken_files_name_the_line() {
    let asf = read("07-walk.asf");
    let truncated = &asf[..asf.len() / 2];
    let e = parse_asf(truncated, "t.asf").unwrap_err();
    assert!(matches!(e, Error::Parse { .. }), "{e}");
    let sk = parse_asf(&asf, "07-walk.asf").unwrap();
    let e = parse_amc("1\nroot 0 0 0 0 0 0\nnosuchbone 1 2\n", "x.amc", &sk).unwrap_err();
    assert!(e.to_string().contains("x.amc:3") && e.to_string().contains("nosuchbone"), "{e}");
    let e = parse_amc("1\nroot 0 0 0 0 0\n", "x.amc", &sk).unwrap_err();
    assert!(e.to_string().contains("x.amc:2") && e.to_string().contains("6 values"), "{e}");
    let e = parse_amc("1\nroot 0 0 0 0 0 nan\n", "x.amc", &sk).unwrap_err();
    assert!(e.to_string().contains("finite number"), "{e}");
    let cyclic = ONE_BONE
        .replace("AXIS", "0 0 0")
        .replace("DOF", "rz")
        .replace("    root arm\n", "    arm arm\n");
    let e = parse_asf(&cyclic, "c.asf").unwrap_err();
    assert!(e.to_string().contains("hierarchy"), "{e}");
    let e = parse_amc(":DEGREES\n", "empty.amc", &sk).unwrap_err();
    assert!(e.to_string().contains("at least one frame"), "{e}");
}

fn assert_same_skeleton(a: &Skeleton, b: &Skeleton) {
    assert_eq!(a.joint_names(), b.joint_names());
    assert_eq!(
        (a.length_unit, a.degrees, &a.root_order),
        (b.length_unit, b.degrees, &b.root_order)
    );
    for (x, y) in a.bones.iter().zip(&b.bones) {
        assert_eq!(
            (x.parent, &x.dofs, x.length, &x.axis_as_read),
            (y.parent, &y.dofs, y.length, &y.axis_as_read)
        );
        assert!((x.direction - y.direction).length() < 1e-15);
        for (l, m) in x.limits.iter().zip(&y.limits) {
            assert!((l.0 - m.0).abs() < 1e-12 && (l.1 - m.1).abs() < 1e-12);
        }
    }
}

#[test]
fn read_write_read_is_the_identity_on_every_cmu_clip() {
    for (asf, amc, _) in CMU {
        let sk = parse_asf(&read(asf), asf).unwrap();
        let again = parse_asf(&kinema::mocap::write_asf(&sk), "written.asf").unwrap();
        assert_same_skeleton(&sk, &again);
        let m = parse_amc(&read(amc), amc, &sk).unwrap();
        let text = kinema::mocap::write_amc(&sk, &m).unwrap();
        let m2 = parse_amc(&text, "written.amc", &again).unwrap();
        assert_eq!((m.frames, m.stride), (m2.frames, m2.stride));
        let worst = m
            .values
            .iter()
            .zip(&m2.values)
            .map(|(a, b)| (a - b).abs() / a.abs().max(1.0))
            .fold(0.0, f64::max);
        assert!(worst < 1e-14, "{amc}: {worst}");
    }
}

#[test]
fn limits_are_checked_per_frame() {
    let asf = ONE_BONE.replace("AXIS", "0 0 0").replace("DOF", "rz");
    let sk = parse_asf(&asf, "one.asf").unwrap();
    let m = parse_amc("1\nroot 0 0 0 0 0 0\narm 90\n2\nroot 0 0 0 0 0 0\narm 200\n", "l.amc", &sk)
        .unwrap();
    assert_eq!(sk.within_limits(&m).unwrap(), vec![true, false]);
    assert_eq!(m.slice(1, 2).unwrap().frames, 1);
    assert!(m.slice(1, 1).is_err());
}

#[test]
fn resampling_keeps_the_motion() {
    let sk = parse_asf(&read("07-walk.asf"), "07-walk.asf").unwrap();
    let m = parse_amc(&read("07_05-walk.amc"), "07_05-walk.amc", &sk).unwrap();
    // Same rate: the identity on FK (slerp at s = 0 returns the key rotation).
    let same = sk.resample(&m, 120.0, 120.0).unwrap();
    assert_eq!(same.frames, m.frames);
    let (p0, _) = fk(&sk, &m);
    let (p1, _) = fk(&sk, &same);
    assert!(p0.iter().zip(&p1).all(|(a, b)| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-9)));
    // Down to 30 Hz: every 4th frame, same poses.
    let slow = sk.resample(&m, 120.0, 30.0).unwrap();
    assert_eq!(slow.frames, (m.frames - 1) / 4 + 1);
    let (p2, _) = fk(&sk, &slow);
    let joints = 1 + sk.bones.len();
    for f in 0..slow.frames {
        for j in 0..joints {
            let (a, b) = (p2[f * joints + j], p0[4 * f * joints + j]);
            assert!(a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-9), "frame {f} joint {j}");
        }
    }
    // Up to 240 Hz: bone lengths still hold in the new in-between frames.
    let fast = sk.resample(&m, 120.0, 240.0).unwrap();
    assert_eq!(fast.frames, 2 * (m.frames - 1) + 1);
    let (p3, _) = fk(&sk, &fast);
    for (b, bone) in sk.bones.iter().enumerate() {
        let parent = bone.parent.map_or(0, |q| q + 1);
        let (a, c) = (p3[joints + parent], p3[joints + b + 1]);
        let d = ((a[0] - c[0]).powi(2) + (a[1] - c[1]).powi(2) + (a[2] - c[2]).powi(2)).sqrt();
        assert!((d - bone.length).abs() < 1e-9);
    }
    assert!(sk.resample(&m, 0.0, 30.0).is_err());
}

/// Every Acclaim bone has a length: a bone without one is a parse error naming the file, the
/// bone's line and the bone (not a silent length 0); a negative one too. An explicit
/// `length 0` (as the iniini variant writes for its hand bones) stays legal.
#[test]
fn asf_bone_without_length_is_a_parse_error() {
    let asf = ONE_BONE.replace("AXIS", "0 0 0").replace("DOF", "rz");
    let e = parse_asf(&asf.replace("    length 2\n", ""), "nolength.asf").unwrap_err();
    let Error::Parse { file, line, expected } = &e else { panic!("{e:?}") };
    assert_eq!((file.as_str(), *line), ("nolength.asf", 12), "{e}");
    assert!(expected.contains("\"arm\"") && expected.contains("missing"), "{e}");
    let e = parse_asf(&asf.replace("length 2", "length -2"), "neg.asf").unwrap_err();
    assert!(e.to_string().contains("neg.asf:12") && e.to_string().contains("negative"), "{e}");
    let zero = parse_asf(&asf.replace("length 2", "length 0"), "zero.asf").unwrap();
    assert_eq!(zero.bones[0].length, 0.0);
}

/// A skeleton built by hand or restored from bytes is checked before use: a parent index at
/// or after its bone, a non-unit axis or direction, a bad dof axis or a negative length are
/// refused by `validate` (which the Python unpickling calls) naming the bone; a parsed one
/// passes.
#[test]
fn skeleton_validate_refuses_bad_parents_and_values() {
    use kinema::mocap::Dof;
    let sk = parse_asf(&read("07-walk.asf"), "07-walk.asf").unwrap();
    sk.validate().unwrap();
    let bad: [(&str, fn(&mut Skeleton)); 6] = [
        ("parent", |s| s.bones[3].parent = Some(3)),
        ("parent", |s| s.bones[0].parent = Some(99)),
        ("direction", |s| s.bones[2].direction.x = f64::NAN),
        ("length", |s| s.bones[2].length = -1.0),
        ("axis", |s| s.bones[2].axis.w *= 2.0),
        ("dofs", |s| s.bones[2].dofs[0] = Dof::Rotation(7)),
    ];
    for (what, spoil) in bad {
        let mut s = sk.clone();
        spoil(&mut s);
        let e = s.validate().unwrap_err();
        assert!(matches!(e, Error::InvalidInput { .. }), "{e}");
        assert!(e.to_string().contains(what), "{what}: {e}");
    }
    let mut motion_ok = parse_amc(&read("07_05-walk.amc"), "07_05-walk.amc", &sk).unwrap();
    motion_ok.validate().unwrap();
    motion_ok.values.pop();
    assert!(motion_ok.validate().is_err());
}
