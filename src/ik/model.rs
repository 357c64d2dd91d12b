//! The kinematic model IK works on: the joint variables of a [`Skeleton`], forward kinematics
//! that also yields every variable's world axis, and the analytic Jacobian.
//!
//! A bone's rotation is `R = R_parent · C · M · C⁻¹` with `M = R_{a_last}(θ_last) ⋯
//! R_{a_0}(θ_0)` (dofs in file order, see [`crate::mocap`]). Differentiating,
//! `∂R/∂θ_j = [w_j]× R` with the world axis `w_j = R_parent · C · R_{last} ⋯ R_{j+1} · e_{a_j}`,
//! so a change of `θ_j` turns everything below the bone about `w_j` through the bone's base
//! (the parent's tip). Column `j` of the Jacobian of end effector `e` is therefore
//! `(w_j × (p_e - p_base), w_j)` (position rows, orientation rows) when the bone is `e` or one
//! of its ancestors, and zero otherwise; a root translation along world axis `a` gives
//! `(e_a, 0)`. The root rotation `O · (factors of the root axis sequence)` is handled the same
//! way, with the root position as the base.

use crate::mocap::{Dof, Skeleton};
use glam::{DQuat, DVec3};

/// What a joint variable does.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Kind {
    /// Rotation about its world axis through its pivot (the base of its bone, the root
    /// position for the root's).
    Rotation,
    /// Root translation along its world axis.
    Translation,
}

/// One joint variable: a value of the pose that IK may change.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Var {
    /// Index into the pose (the frame's values).
    pub index: usize,
    /// The joint (0 = root, `b + 1` = bone `b`) the variable moves, with everything below it.
    pub joint: usize,
    pub kind: Kind,
    /// Limits (radians); infinite when the bone has none or limits are off.
    pub lo: f64,
    pub hi: f64,
}

pub(crate) fn elementary(axis: usize, angle: f64) -> DQuat {
    let (s, c) = (0.5 * angle).sin_cos();
    let e = DVec3::AXES[axis] * s;
    DQuat::from_xyzw(e.x, e.y, e.z, c)
}

/// Root rotation factors from left to right: `R_root = O · Π factors`. Extrinsic `ijk` is
/// `R_k R_j R_i`, intrinsic `IJK` is `R_i R_j R_k`.
pub(crate) fn root_factors(sk: &Skeleton) -> [usize; 3] {
    let [i, j, k] = sk.root_axis.axes;
    if sk.root_axis.intrinsic {
        [i, j, k]
    } else {
        [k, j, i]
    }
}

/// Joint index of the parent of joint `j` (`j >= 1`).
pub(crate) fn parent_joint(sk: &Skeleton, j: usize) -> usize {
    sk.bones[j - 1].parent.map_or(0, |p| p + 1)
}

/// Whether joint `a` is `j` or one of its ancestors.
pub(crate) fn is_ancestor_or_self(sk: &Skeleton, a: usize, mut j: usize) -> bool {
    loop {
        if j == a {
            return true;
        }
        if j == 0 {
            return false;
        }
        j = parent_joint(sk, j);
    }
}

/// Every variable of the skeleton, in the order cyclic coordinate descent visits them: bones
/// from the last to the first, each bone's dofs from the innermost rotation (first in the file)
/// outwards, then the root (translations, then rotations innermost first). In that order a
/// variable's change never moves the axis or base of a variable visited after it.
pub(crate) fn all_vars(sk: &Skeleton, free_root: bool, joint_limits: bool) -> Vec<Var> {
    let mut offset = vec![0; sk.bones.len()];
    let mut k = sk.root_order.len();
    for (b, bone) in sk.bones.iter().enumerate() {
        offset[b] = k;
        k += bone.dofs.len();
    }
    let mut vars = Vec::new();
    for (b, bone) in sk.bones.iter().enumerate().rev() {
        for (i, dof) in bone.dofs.iter().enumerate() {
            if let Dof::Rotation(_) = dof {
                let (lo, hi) = match bone.limits.get(i) {
                    Some(&l) if joint_limits => l,
                    _ => (f64::NEG_INFINITY, f64::INFINITY),
                };
                vars.push(Var { index: offset[b] + i, joint: b + 1, kind: Kind::Rotation, lo, hi });
            }
        }
    }
    if free_root {
        let free = (f64::NEG_INFINITY, f64::INFINITY);
        for (i, dof) in sk.root_order.iter().enumerate() {
            if let Dof::Translation(_) = dof {
                vars.push(Var {
                    index: i,
                    joint: 0,
                    kind: Kind::Translation,
                    lo: free.0,
                    hi: free.1,
                });
            }
        }
        for axis in root_factors(sk).into_iter().rev() {
            if let Some(i) = sk.root_order.iter().position(|d| *d == Dof::Rotation(axis)) {
                vars.push(Var { index: i, joint: 0, kind: Kind::Rotation, lo: free.0, hi: free.1 });
            }
        }
    }
    vars
}

/// Forward kinematics of pose `q`: joint positions and orientations (`1 + bones` each) and, in
/// `axis` and `pivot` (one slot per pose value), the world axis of every rotation and
/// translation dof and the point a rotation turns about. Bone translation and length dofs
/// move the bones as in [`Skeleton::forward_kinematics`] (they are not IK variables), with
/// which this agrees to rounding.
pub(crate) fn forward(
    sk: &Skeleton,
    q: &[f64],
    pos: &mut [DVec3],
    rot: &mut [DQuat],
    axis: &mut [DVec3],
    pivot: &mut [DVec3],
) {
    let mut t = sk.root_position;
    let mut angles = [0.0; 3];
    let mut slot = [None; 3];
    for (k, dof) in sk.root_order.iter().enumerate() {
        match *dof {
            Dof::Translation(a) => {
                t[a] = q[k];
                axis[k] = DVec3::AXES[a];
            }
            Dof::Rotation(a) => {
                angles[a] = q[k];
                slot[a] = Some(k);
            }
            Dof::Length => {}
        }
    }
    let mut r = sk.root_orientation;
    for a in root_factors(sk) {
        if let Some(k) = slot[a] {
            axis[k] = r * DVec3::AXES[a];
            pivot[k] = t;
        }
        r *= elementary(a, angles[a]);
    }
    pos[0] = t;
    rot[0] = r.normalize();
    let mut k = sk.root_order.len();
    for (b, bone) in sk.bones.iter().enumerate() {
        let parent = bone.parent.map_or(0, |p| p + 1);
        let frame = rot[parent] * bone.axis;
        let (mut shift, mut stretch) = (DVec3::ZERO, 0.0);
        for (i, dof) in bone.dofs.iter().enumerate() {
            match *dof {
                Dof::Translation(a) => shift[a] = q[k + i],
                Dof::Length => stretch = q[k + i],
                Dof::Rotation(_) => {}
            }
        }
        let base = pos[parent] + frame * shift;
        let mut r = frame;
        for (i, dof) in bone.dofs.iter().enumerate().rev() {
            if let Dof::Rotation(a) = *dof {
                axis[k + i] = r * DVec3::AXES[a];
                pivot[k + i] = base;
                r *= elementary(a, q[k + i]);
            }
        }
        k += bone.dofs.len();
        let r = (r * bone.axis.conjugate()).normalize();
        rot[b + 1] = r;
        pos[b + 1] = base + (bone.length + stretch) * (r * bone.direction);
    }
}

/// Jacobian column of variable `v` for an end effector at `p`: (position part, orientation
/// part), from the world axes and pivots of [`forward`].
pub(crate) fn column(v: &Var, p: DVec3, pivot: &[DVec3], axis: &[DVec3]) -> (DVec3, DVec3) {
    let w = axis[v.index];
    match v.kind {
        Kind::Rotation => (w.cross(p - pivot[v.index]), w),
        Kind::Translation => (w, DVec3::ZERO),
    }
}
