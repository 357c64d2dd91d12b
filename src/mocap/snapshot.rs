//! Motion-capture snapshots: what a decoded skeleton or motion must satisfy before forward
//! kinematics, editing or writing read it.

use super::{BvhSkeleton, Dof, Motion, Skeleton};
use crate::error::Result;
use crate::rotation::EulerSequence;
use crate::snapshot::{check, finite, Snapshot};
use glam::DQuat;

fn axis_ok(d: &Dof) -> bool {
    match *d {
        Dof::Rotation(a) | Dof::Translation(a) => a < 3,
        Dof::Length => true,
    }
}

fn unit(q: DQuat) -> bool {
    q.is_finite() && (q.length() - 1.0).abs() < 1e-6
}

fn sequence_ok(s: &EulerSequence) -> bool {
    let [i, j, k] = s.axes;
    i < 3 && j < 3 && k < 3 && i != j && j != k
}

impl Snapshot for Skeleton {
    const TAG: &'static str = "Skeleton";

    /// Bones parents first, dofs about axes 0–2 with one limit pair each (or none), finite
    /// geometry and unit rotations, a valid root Euler sequence and a positive length unit.
    fn validate(&self) -> Result<()> {
        check(
            self.length_unit.is_finite()
                && self.length_unit > 0.0
                && self.root_order.iter().all(axis_ok)
                && sequence_ok(&self.root_axis)
                && self.root_position.is_finite()
                && unit(self.root_orientation)
                && finite(self.root_orientation_as_read),
            "root",
            || "invalid root dofs, axis, position or length unit".into(),
        )?;
        for (b, bone) in self.bones.iter().enumerate() {
            let ok = bone.parent.is_none_or(|p| p < b)
                && bone.dofs.iter().all(axis_ok)
                && (bone.limits.is_empty() || bone.limits.len() == bone.dofs.len())
                && bone.limits.iter().all(|&(lo, hi)| !lo.is_nan() && !hi.is_nan())
                && bone.direction.is_finite()
                && bone.length.is_finite()
                && unit(bone.axis)
                && finite(bone.axis_as_read.0);
            check(ok, "bones", || format!("bone {b} ({}) is invalid", bone.name))?;
        }
        Ok(())
    }
}

impl Snapshot for Motion {
    const TAG: &'static str = "Motion";

    /// `frames × stride` finite values and a finite positive frame rate.
    fn validate(&self) -> Result<()> {
        check(
            self.stride.checked_mul(self.frames) == Some(self.values.len())
                && finite(self.values.iter().copied())
                && self.frame_rate.is_finite()
                && self.frame_rate > 0.0,
            "values",
            || "not frames x stride finite values at a positive frame rate".into(),
        )
    }
}

impl Snapshot for BvhSkeleton {
    const TAG: &'static str = "BvhSkeleton";

    /// Joints parents first with position and rotation channels about axes 0–2, finite
    /// offsets and end sites, a finite positive frame time.
    fn validate(&self) -> Result<()> {
        check(!self.joints.is_empty(), "joints", || "a skeleton needs a joint".into())?;
        for (i, j) in self.joints.iter().enumerate() {
            let ok = j.parent.is_none_or(|p| p < i)
                && j.channels.iter().all(|c| axis_ok(c) && *c != Dof::Length)
                && j.offset.is_finite()
                && j.end_site.is_none_or(|e| e.is_finite());
            check(ok, "joints", || format!("joint {i} ({}) is invalid", j.name))?;
        }
        check(self.frame_time.is_finite() && self.frame_time > 0.0, "frame_time", || {
            "must be finite and positive".into()
        })
    }
}
