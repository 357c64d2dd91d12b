//! An Acclaim skeleton and motion as a BVH hierarchy and motion (the conversion the CMU BVH
//! releases made with their own tools), so that kinema's BVH writer can store an ASF/AMC clip.

use super::{BvhJoint, BvhSkeleton};
use crate::error::{Error, Result};
use crate::mocap::{Dof, Motion, Skeleton};
use crate::rotation::{quat_from_wxyz, EulerSequence};
use glam::DVec3;

/// The BVH hierarchy and motion that pose every joint as `skeleton` poses its bones under
/// `motion`.
///
/// A joint `root` (position channels, then `Zrotation Yrotation Xrotation`) and one joint per
/// bone, depth first (BVH's order; children in the skeleton's order), named as the bone, at the bone's base: its `OFFSET` is the
/// parent bone's rest vector `length · direction` (zero under the root), its rotation is the
/// bone's, `R_parent⁻¹ R_bone = C M C⁻¹` (three channels `Zrotation Yrotation Xrotation`,
/// BVH's intrinsic `Rz Ry Rx`, for a bone with rotation dofs; none for a bone without), and
/// a bone without children ends in an `End Site` at its own rest vector. BVH's rest pose has
/// every joint at the world's axes, as ASF's rest pose has every bone. So the BVH joint of a
/// bone is at the bone's base and turned as the bone, frame by frame (forward kinematics
/// agree to rounding), lengths in the skeleton's units, at the motion's frame rate.
///
/// # Errors
/// A motion made for another skeleton (`motion`); a bone with translation or length dofs,
/// which BVH joints of this form cannot hold (`skeleton`).
pub fn asf_to_bvh(skeleton: &Skeleton, motion: &Motion) -> Result<(BvhSkeleton, Motion)> {
    if skeleton.bones.iter().any(|b| b.dofs.iter().any(|d| !matches!(d, Dof::Rotation(_)))) {
        return Err(Error::invalid("skeleton", "a bone with translation or length dofs"));
    }
    let bones = 1 + skeleton.bones.len();
    let mut positions = vec![[0.0; 3]; motion.frames * bones];
    let mut orientations = vec![[0.0; 4]; motion.frames * bones];
    skeleton.forward_kinematics(motion, &mut positions, &mut orientations)?;
    let zyx = [Dof::Rotation(2), Dof::Rotation(1), Dof::Rotation(0)];
    let mut joints = vec![BvhJoint {
        name: "root".into(),
        parent: None,
        offset: skeleton.root_position,
        channels: [Dof::Translation(0), Dof::Translation(1), Dof::Translation(2)]
            .into_iter()
            .chain(zyx)
            .collect(),
        end_site: None,
    }];
    // The bones depth first (BVH's file order), children in the skeleton's order; `index[b]`
    // is bone b's joint.
    let children = |p: Option<usize>| {
        let mut c: Vec<usize> =
            (0..skeleton.bones.len()).filter(|&b| skeleton.bones[b].parent == p).collect();
        c.reverse();
        c
    };
    let (mut order, mut stack, mut index) = (vec![], children(None), vec![0; bones - 1]);
    while let Some(b) = stack.pop() {
        order.push(b);
        index[b] = order.len();
        stack.extend(children(Some(b)));
    }
    let rest = |b: usize| skeleton.bones[b].length * skeleton.bones[b].direction;
    for &b in &order {
        let bone = &skeleton.bones[b];
        let leaf = !skeleton.bones.iter().any(|c| c.parent == Some(b));
        joints.push(BvhJoint {
            name: bone.name.clone(),
            parent: Some(bone.parent.map_or(0, |p| index[p])),
            offset: bone.parent.map_or(DVec3::ZERO, rest),
            channels: if bone.dofs.is_empty() { vec![] } else { zyx.to_vec() },
            end_site: leaf.then(|| rest(b)),
        });
    }
    let sequence = EulerSequence::parse("ZYX")?;
    let stride = joints.iter().map(|j| j.channels.len()).sum();
    let mut values = Vec::with_capacity(motion.frames * stride);
    for f in 0..motion.frames {
        // The orientation of bone b (row b + 1 of the forward kinematics; the root row 0).
        let at = |row: usize| quat_from_wxyz(&orientations[f * bones + row]);
        values.extend_from_slice(&positions[f * bones]);
        values.extend_from_slice(&sequence.from_quat(at(0)?).0);
        for &b in order.iter().filter(|&&b| !skeleton.bones[b].dofs.is_empty()) {
            let parent = skeleton.bones[b].parent.map_or(0, |p| p + 1);
            let local = at(parent)?.inverse() * at(b + 1)?;
            values.extend_from_slice(&sequence.from_quat(local).0);
        }
    }
    let frame_time = 1.0 / motion.frame_rate;
    let out = Motion { values, stride, frames: motion.frames, frame_rate: motion.frame_rate };
    Ok((BvhSkeleton { joints, frame_time }, out))
}
