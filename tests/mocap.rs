//! Acclaim ASF/AMC on the real CMU files in tests/data/mocap, on hand-made skeletons with
//! closed-form answers, and on broken input.

use kinema::mocap::{parse_amc, parse_asf, Edit, Motion, Skeleton};
use kinema::Error;
use std::path::PathBuf;

mod cmu;

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
fn every_cmu_clip_parses_with_its_frame_count() {
    for (asf, amc, frames) in CMU {
        let sk = parse_asf(&read(asf), asf).unwrap();
        assert_eq!((sk.length_unit, sk.mass_unit), (0.45, 1.0), "{asf}");
        assert_eq!(sk.bones.len(), 30, "{asf}");
        let m = parse_amc(&read(amc), amc, &sk).unwrap();
        assert_eq!(m.frames, frames, "{amc}");
    }
}

type Mat = [[f64; 3]; 3];

fn mat_mul(a: Mat, b: Mat) -> Mat {
    let mut c = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    c
}

fn mat_vec(a: Mat, v: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|i| (0..3).map(|k| a[i][k] * v[k]).sum())
}

fn transpose(a: Mat) -> Mat {
    [0, 1, 2].map(|i| [0, 1, 2].map(|j| a[j][i]))
}

/// The rotation matrix about coordinate axis `axis` (0 = x) by `t` radians.
fn elementary(axis: usize, t: f64) -> Mat {
    let (s, c) = t.sin_cos();
    let (i, j) = ((axis + 1) % 3, (axis + 2) % 3);
    let mut m = [[0.0; 3]; 3];
    m[axis][axis] = 1.0;
    (m[i][i], m[i][j], m[j][i], m[j][j]) = (c, -s, s, c);
    m
}

/// Forward kinematics written independently of kinema's (3x3 matrices instead of
/// quaternions) from the ASF/AMC text's meaning: `C` from `axis` (degrees, extrinsic in the
/// written order), `M` from the dofs in the order listed, `R = R_parent C M Cᵀ`, tip =
/// parent tip + length R direction. Root rotation from `order` values in the `axis` order.
fn fk_by_matrices(sk: &Skeleton, frame: &[f64]) -> Vec<[f64; 3]> {
    use kinema::mocap::Dof;
    let eye: Mat = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let (mut t, mut angles) = ([0.0; 3], [0.0; 3]);
    for (k, d) in sk.root_order.iter().enumerate() {
        match *d {
            Dof::Translation(a) => t[a] = frame[k],
            Dof::Rotation(a) => angles[a] = frame[k],
            Dof::Length => {}
        }
    }
    let mut root = eye;
    for a in sk.root_axis.axes {
        root = mat_mul(elementary(a, angles[a]), root);
    }
    let (mut pos, mut rot) = (vec![t], vec![root]);
    let mut k = sk.root_order.len();
    for bone in &sk.bones {
        let (deg, order) = &bone.axis_as_read;
        let mut c = eye;
        for ch in order.chars() {
            let a = "XYZ".find(ch.to_ascii_uppercase()).unwrap();
            c = mat_mul(elementary(a, deg[a].to_radians()), c);
        }
        let mut m = eye;
        for d in &bone.dofs {
            if let Dof::Rotation(a) = *d {
                m = mat_mul(elementary(a, frame[k]), m);
            }
            k += 1;
        }
        let p = bone.parent.map_or(0, |q| q + 1);
        let r = mat_mul(rot[p], mat_mul(c, mat_mul(m, transpose(c))));
        let d = mat_vec(r, bone.direction.to_array());
        pos.push([0, 1, 2].map(|i| pos[p][i] + bone.length * d[i]));
        rot.push(r);
    }
    pos
}

#[test]
fn forward_kinematics_matches_an_independent_matrix_implementation() {
    // Joint positions, not bone lengths (those hold by construction in any FK): a wrong
    // composition order, a missing axis frame or a wrong parent moves them.
    for (asf, amc, _) in [CMU[2], CMU[5]] {
        let sk = parse_asf(&read(asf), asf).unwrap();
        let m = parse_amc(&read(amc), amc, &sk).unwrap();
        let (p, _) = fk(&sk, &m);
        let joints = 1 + sk.bones.len();
        let mut worst: f64 = 0.0;
        for f in 0..m.frames {
            let want = fk_by_matrices(&sk, &m.values[f * m.stride..(f + 1) * m.stride]);
            for (j, w) in want.iter().enumerate() {
                let got = p[f * joints + j];
                worst = worst.max((0..3).map(|i| (got[i] - w[i]).abs()).fold(0.0, f64::max));
            }
        }
        assert!(worst < 1e-9, "{amc}: {worst}");
    }
    // And by hand: a two-bone arm, the upper bone's frame turned 90° about z (local x = global
    // y), rx = 90° on it turns the arm about global y: +x to -z; the forearm (rz = 90°, its
    // frame the identity) turns from -z on by 90° about the upper bone's turned z axis.
    let asf = ":units\n  length 1\n  angle deg\n:root\n  order TX TY TZ RX RY RZ\n  axis XYZ\n  position 0 0 0\n  orientation 0 0 0\n:bonedata\n  begin\n    name upper\n    direction 1 0 0\n    length 2\n    axis 0 0 90 XYZ\n    dof rx\n  end\n  begin\n    name fore\n    direction 1 0 0\n    length 3\n    axis 0 0 0 XYZ\n    dof rz\n  end\n:hierarchy\n  begin\n    root upper\n    upper fore\n  end\n";
    let sk = parse_asf(asf, "arm.asf").unwrap();
    let m = parse_amc("1\nroot 1 2 3 0 0 0\nupper 90\nfore 90\n", "arm.amc", &sk).unwrap();
    let (p, _) = fk(&sk, &m);
    // Upper: R = Ry(90): tip (1, 2, 3) + 2 (0, 0, -1). Fore: R = Ry(90) Rz(90), direction x
    // goes to Ry(90) (0, 1, 0) = (0, 1, 0): tip + 3 (0, 1, 0).
    let want = [[1.0, 2.0, 3.0], [1.0, 2.0, 1.0], [1.0, 5.0, 1.0]];
    for (got, want) in p.iter().zip(want) {
        assert!((0..3).all(|i| (got[i] - want[i]).abs() < 1e-12), "{got:?} vs {want:?}");
    }
}

#[test]
fn walking_feet_touch_a_common_ground() {
    let (sk, m) = cmu::walk();
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

fn parse_error(e: Error) -> (usize, String) {
    match e {
        Error::Parse { line, expected, .. } => (line, expected),
        other => panic!("expected a parse error, got {other}"),
    }
}

#[test]
fn every_variant_file_gives_what_it_must() {
    let variant = |name: &str| read(&format!("variants/{name}"));
    // endorphin export: lower-case root order, `limits (-inf inf)`, dof-less `_dum` bones,
    // a bone of length 0; its walk lists the bones alphabetically, lines end in a space.
    let sk = parse_asf(&variant("skeleton.asf"), "skeleton.asf").unwrap();
    assert_eq!((sk.bones.len(), sk.length_unit, sk.mass_unit, sk.degrees), (33, 0.01, 1.0, true));
    assert!(sk.bones.iter().any(|b| b.limits.contains(&(f64::NEG_INFINITY, f64::INFINITY))));
    let m = parse_amc(&variant("walking.amc"), "walking.amc", &sk).unwrap();
    assert_eq!(m.frames, 1741);
    // MotionData exports: `direction 0 0 0` on bones of length 0, `4e-006` exponents; their
    // motions do not read.
    for (asf, amc) in [("iniini.asf", "iniini.amc"), ("modelTemplate.asf", "modelTemplate.amc")] {
        let sk = parse_asf(&variant(asf), asf).unwrap();
        assert_eq!((sk.bones.len(), sk.length_unit, sk.mass_unit), (32, 1.0, 1.0), "{asf}");
        let e = parse_amc(&variant(amc), amc, &sk).unwrap_err();
        // iniini.amc is a header without frames; modelTemplate.amc gives three values to
        // `_dum` bones that have no dof in its skeleton.
        let want = if amc == "iniini.amc" {
            (2, "at least one frame".to_string())
        } else {
            (8, "0 values for \"LeftUpLeg_dum\", found 3".to_string())
        };
        assert_eq!(parse_error(e), want, "{amc}");
    }
    // Units as words (`mass kg`, `length m`) are not the numbers ASF 1.10 asks for: refused at
    // the first one. With numbers in their place the rest of the file (tabs, hierarchy lines
    // not root-first) and its motion (root line 5th in every frame) read.
    let e = parse_asf(&variant("test.asf"), "test.asf").unwrap_err();
    // (Errors name the file, line and what was expected, never the text found: issue 19.)
    assert_eq!(parse_error(e), (4, "a finite number".to_string()));
    let numeric =
        variant("test.asf").replace("mass\tkg", "mass\t1").replace("length\tm", "length\t1");
    let sk = parse_asf(&numeric, "test.asf").unwrap();
    assert_eq!((sk.bones.len(), sk.degrees), (18, true));
    assert_eq!(parse_amc(&variant("test.amc"), "test.amc", &sk).unwrap().frames, 300);
    // Seven all-zero frames for a CMU skeleton: the rest pose every time.
    let sk = parse_asf(&read("07-walk.asf"), "07-walk.asf").unwrap();
    let m = parse_amc(&variant("zeros.amc"), "zeros.amc", &sk).unwrap();
    assert_eq!(m.frames, 7);
    assert!(m.values.iter().all(|v| *v == 0.0));
}

#[test]
fn broken_files_name_the_line() {
    let asf = read("07-walk.asf");
    let truncated = &asf[..asf.len() / 2];
    let e = parse_asf(truncated, "t.asf").unwrap_err();
    assert!(matches!(e, Error::Parse { .. }), "{e}");
    let sk = parse_asf(&asf, "07-walk.asf").unwrap();
    let e = parse_amc("1\nroot 0 0 0 0 0 0\nnosuchbone 1 2\n", "x.amc", &sk).unwrap_err();
    // The place and what was expected, never the text found (a file may hold secrets).
    let m = e.to_string();
    assert!(m.contains("x.amc:3: expected a bone") && !m.contains("nosuchbone"), "{e}");
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
        (a.length_unit, a.mass_unit, a.degrees, &a.root_order),
        (b.length_unit, b.mass_unit, b.degrees, &b.root_order)
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
    // One pose at a time, the same answers; a pose of the wrong length or with NaN is refused.
    assert!(sk.pose_within_limits(&m.values[..m.stride]).unwrap());
    assert!(!sk.pose_within_limits(&m.values[m.stride..]).unwrap());
    let limit = 180f64.to_radians();
    assert!(sk.pose_within_limits(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, limit]).unwrap());
    assert!(!sk.pose_within_limits(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, limit + 1e-6]).unwrap());
    assert!(sk.pose_within_limits(&[0.0; 6]).unwrap_err().to_string().contains("7 values"));
    let nan = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, f64::NAN];
    assert!(sk.pose_within_limits(&nan).unwrap_err().to_string().contains("NaN"));
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

/// An arm whose upper bone has translation and length dofs besides a rotation, and a child.
const SLIDING: &str = ":version 1.10\n:name slide\n:units\n  mass 2.5\n  length 1\n  angle deg\n:root\n  order TX TY TZ RX RY RZ\n  axis XYZ\n  position 0 0 0\n  orientation 0 0 0\n:bonedata\n  begin\n    id 1\n    name upper\n    direction 1 0 0\n    length 2\n    axis 0 0 90 XYZ\n    dof rz tx ty l\n    limits (-180 180)\n           (-5 5)\n           (-5 5)\n           (-1 1)\n  end\n  begin\n    id 2\n    name fore\n    direction 0 1 0\n    length 1\n    axis 0 0 0 XYZ\n  end\n:hierarchy\n  begin\n    root upper\n    upper fore\n  end\n";

#[test]
fn bone_translation_and_length_dofs_move_the_bone() {
    let sk = parse_asf(SLIDING, "slide.asf").unwrap();
    // Frame 1: tx = 3 along the bone frame's x, which `axis 0 0 90` turns to global +y; the
    // length grows by 0.5. Frame 2: ty = -1 along the frame's y, which is global -x (so a move
    // of +1 in x), with rz = 90° (about z: the bone points to +y, its child to -x).
    let amc = "1\nroot 1 2 3 0 0 0\nupper 0 3 0 0.5\n2\nroot 1 2 3 0 0 0\nupper 90 0 -1 0\n";
    let m = parse_amc(amc, "slide.amc", &sk).unwrap();
    let (p, _) = fk(&sk, &m);
    let want = [
        [[1.0, 2.0, 3.0], [3.5, 5.0, 3.0], [3.5, 6.0, 3.0]],
        [[1.0, 2.0, 3.0], [2.0, 4.0, 3.0], [1.0, 4.0, 3.0]],
    ];
    for (f, rows) in want.iter().enumerate() {
        for (j, w) in rows.iter().enumerate() {
            let got = p[f * 3 + j];
            assert!((0..3).all(|i| (got[i] - w[i]).abs() < 1e-12), "frame {f} joint {j}: {got:?}");
        }
    }
    // Inverse kinematics sees the same skeleton as FK (translation and length dofs move the
    // bones, rotations turn about the moved base).
    let pose = &m.values[m.stride..];
    let (jac, cols) = kinema::ik::jacobian(&sk, pose, &[2], false, false).unwrap();
    assert_eq!(cols, vec![6]);
    // d(tip of fore)/d(rz) = z × (tip - base) = z × ((1, 4, 3) - (2, 2, 3)) = (-2, -1, 0).
    let want = [-2.0, -1.0, 0.0];
    assert!((0..3).all(|i| (jac[i] - want[i]).abs() < 1e-12), "{jac:?}");
    // Written back and read again: the dofs, limits and values survive.
    let again = parse_asf(&kinema::mocap::write_asf(&sk), "w.asf").unwrap();
    assert_same_skeleton(&sk, &again);
    let m2 = parse_amc(&kinema::mocap::write_amc(&sk, &m).unwrap(), "w.amc", &again).unwrap();
    let (p2, _) = fk(&again, &m2);
    assert!(p.iter().zip(&p2).all(|(a, b)| (0..3).all(|i| (a[i] - b[i]).abs() < 1e-12)));
}

#[test]
fn mass_unit_is_kept_and_written_back() {
    let sk = parse_asf(SLIDING, "slide.asf").unwrap();
    assert_eq!(sk.mass_unit, 2.5);
    let text = kinema::mocap::write_asf(&sk);
    assert!(text.contains("mass 2.5"), "{text}");
    assert_eq!(parse_asf(&text, "w.asf").unwrap().mass_unit, 2.5);
    // Absent: 1.0; not a number: refused with the line.
    let without = SLIDING.replace("  mass 2.5\n", "");
    assert_eq!(parse_asf(&without, "n.asf").unwrap().mass_unit, 1.0);
    let e = parse_asf(&SLIDING.replace("mass 2.5", "mass heavy"), "h.asf").unwrap_err();
    assert!(e.to_string().contains("h.asf:4") && !e.to_string().contains("heavy"), "{e}");
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
    type Spoil = fn(&mut Skeleton);
    let bad: [(&str, Spoil); 6] = [
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
