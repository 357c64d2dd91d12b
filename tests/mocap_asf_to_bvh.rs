//! An ASF/AMC clip as BVH (`kinema::mocap::asf_to_bvh`): the hierarchy's forward kinematics
//! are the skeleton's, through the writer and the reader too, and the repository's
//! `07_05-walk.bvh` is what the conversion and the writer make of CMU 07_05.

use glam::{DQuat, DVec3};
use kinema::mocap::{asf_to_bvh, parse_bvh, write_bvh, Dof, Motion};

mod cmu;
use cmu::walk;

fn quat(q: [f64; 4]) -> DQuat {
    DQuat::from_xyzw(q[1], q[2], q[3], q[0])
}

/// Every frame of CMU 07_05 (517): the BVH joint of each bone is at the bone's base (the
/// parent's tip, the root's position under the root) to 1e-9 file units and turned as the
/// bone to 1e-12, before and after BVH text (write, read: the writer's numbers read back
/// exactly). Composing the channels `X Y Z` instead of `Z Y X` fails it.
#[test]
fn the_bvh_of_an_asf_clip_poses_every_joint_as_its_bone() {
    let (skeleton, motion) = walk();
    let (bvh, clip) = asf_to_bvh(&skeleton, &motion).unwrap();
    let text = write_bvh(&bvh, &clip).unwrap();
    let (read, read_clip) = parse_bvh(&text, "07_05-walk.bvh").unwrap();
    assert_eq!((read.joints.len(), read_clip.frames), (1 + skeleton.bones.len(), 517));
    assert!((read.frame_time - 1.0 / 120.0).abs() < 1e-15);
    let rows = 1 + skeleton.bones.len();
    let (mut pos, mut ori) = (vec![[0.0; 3]; 517 * rows], vec![[0.0; 4]; 517 * rows]);
    skeleton.forward_kinematics(&motion, &mut pos, &mut ori).unwrap();
    // The skeleton's forward-kinematics row of each name: the root 0, bone b at b + 1.
    let row = |name: &str| skeleton.joint_names().iter().position(|n| n == name).unwrap();
    for (b, c) in [(&bvh, &clip), (&read, &read_clip)] {
        let (mut p, mut o) = (vec![[0.0; 3]; 517 * rows], vec![[0.0; 4]; 517 * rows]);
        b.forward_kinematics(c, &mut p, &mut o).unwrap();
        let (mut far, mut turned) = (0.0f64, 0.0f64);
        for f in 0..517 {
            for (j, joint) in b.joints.iter().enumerate() {
                // A bone's base: its parent's tip (the root's row under the root).
                let base = joint.parent.map_or(0, |p| row(&b.joints[p].name));
                let at = DVec3::from_array(pos[f * rows + base]);
                far = far.max((DVec3::from_array(p[f * rows + j]) - at).length());
                let want = quat(ori[f * rows + row(&joint.name)]);
                let ours = quat(o[f * rows + j]);
                turned = turned.max((ours - want).length().min((ours + want).length()));
            }
        }
        println!("largest position gap {far:.3e} units, orientation gap {turned:.3e}");
        assert!(far < 1e-9 && turned < 1e-12, "{far} units apart, turned {turned}");
    }
}

/// A bone with a translation dof has no BVH joint of this form: refused, naming `skeleton`.
#[test]
fn a_bone_that_slides_is_refused() {
    let (mut skeleton, _) = walk();
    skeleton.bones[3].dofs.push(Dof::Translation(0));
    skeleton.bones[3].limits.push((-1.0, 1.0));
    let stride = skeleton.stride();
    let motion = Motion { values: vec![0.0; stride], stride, frames: 1, frame_rate: 120.0 };
    let e = asf_to_bvh(&skeleton, &motion).unwrap_err();
    assert!(e.to_string().contains("skeleton"), "{e}");
}

/// `tests/data/mocap/07_05-walk.bvh` is the text `write_bvh(asf_to_bvh(07-walk.asf,
/// 07_05-walk.amc))` (the data's README says so).
#[test]
fn the_repositorys_walk_bvh_is_the_converted_clip() {
    let (skeleton, motion) = walk();
    let (bvh, clip) = asf_to_bvh(&skeleton, &motion).unwrap();
    let want = write_bvh(&bvh, &clip).unwrap();
    let file = std::fs::read_to_string("tests/data/mocap/07_05-walk.bvh").unwrap();
    assert!(file == want, "07_05-walk.bvh differs from the conversion");
}
