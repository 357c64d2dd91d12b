//! Acclaim ASF/AMC motion capture: parsing into a typed [`Skeleton`] and [`Motion`], and
//! forward kinematics of whole motions.
//!
//! The format (Acclaim, "ASF/AMC file format specification", 1994, and its CMU reading in the
//! Graphics Lab viewer): every bone has a rest `direction` (unit vector, global axes), a
//! `length`, and an `axis` (three angles and an order such as `XYZ`) that gives its local frame
//! `C` relative to the global axes; `C` is the extrinsic rotation about the global axes in the
//! order written (`XYZ`: first about x, then y, then z — kinema's lower-case sequence `xyz`).
//! A frame of the AMC gives each bone's `dof` values; the rotation `M` they make is composed
//! the same way, in the order the `dof` line lists them. The bone's global orientation is
//!
//! `R_bone = R_parent · C · M · C⁻¹`
//!
//! and its tip is at `p_parent_tip + length · R_bone · direction` (moved by the bone's
//! translation and length dofs when it has them, see [`Skeleton::forward_kinematics`]). The
//! root's translation and rotation come from the AMC in the root's `order`, its rotation order
//! from the root `axis`.
//!
//! Lengths and root translations stay in the file's units (`Skeleton::length_unit` keeps the
//! `:units length` value as read); [`Skeleton::metres_per_unit`] documents the CMU reading
//! (1 unit = 1/length_unit inches) without ever applying it silently.
//!
//! Biovision BVH files are read into a [`BvhSkeleton`] (joints with offsets and channels; the
//! conventions are in [`bvh`] and docs/mocap.md) and the same [`Motion`].

pub mod bvh;
mod edit;
mod parse;
mod snapshot;
mod write;

pub use bvh::{asf_to_bvh, parse_bvh, write_bvh, BvhJoint, BvhSkeleton};
pub use edit::Edit;
pub use parse::{parse_amc, parse_asf};
pub use write::{write_amc, write_asf};

use crate::error::{Error, Result};
use crate::rotation::EulerSequence;
use glam::{DQuat, DVec3};
use rayon::prelude::*;

/// One bone of an Acclaim skeleton, as read.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, PartialEq)]
pub struct Bone {
    /// Bone name.
    pub name: String,
    /// Index of the parent joint in [`Skeleton::bones`] (`None`: attached to the root).
    pub parent: Option<usize>,
    /// Rest direction (unit vector, global axes).
    pub direction: DVec3,
    /// Length (file units).
    pub length: f64,
    /// Local frame `C` relative to the global axes.
    pub axis: DQuat,
    /// The `axis` angles as written (file angle units) and their order, e.g. `"XYZ"`.
    pub axis_as_read: ([f64; 3], String),
    /// Degrees of freedom in file order; a frame's values for them compose as described in
    /// [`Skeleton::forward_kinematics`].
    pub dofs: Vec<Dof>,
    /// Limits per dof (lower, upper), in radians for rotations, as read.
    pub limits: Vec<(f64, f64)>,
}

/// A degree of freedom of a bone or of the root.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dof {
    /// Rotation about axis 0 (x), 1 (y) or 2 (z).
    Rotation(usize),
    /// Translation along axis 0, 1 or 2 (file length units): of the root along the global
    /// axes; of a bone along the axes of its frame `C`, moving its base (and so its tip and
    /// everything below it) away from the parent's tip.
    Translation(usize),
    /// Change of a bone's length (`l`, file length units, added to `length`: 0 is the rest
    /// length).
    Length,
}

/// An Acclaim skeleton: the root and a tree of bones, in file order (parents first).
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, PartialEq)]
pub struct Skeleton {
    /// Name from `:name`.
    pub name: String,
    /// `:units length` as read (CMU files: 0.45).
    pub length_unit: f64,
    /// `:units mass` as read (1.0 when absent; the multiplier of the file's mass unit,
    /// never applied: nothing in an ASF skeleton is a mass but `bodymass`, not read).
    pub mass_unit: f64,
    /// Angles in degrees (`:units angle deg`) rather than radians.
    pub degrees: bool,
    /// Root dofs in the order of `:root order`.
    pub root_order: Vec<Dof>,
    /// Rotation order of the root (`:root axis`).
    pub root_axis: EulerSequence,
    /// Root rest position and orientation (file units, radians).
    pub root_position: DVec3,
    /// Root rest orientation.
    pub root_orientation: DQuat,
    /// The root `orientation` angles as written (file angle units).
    pub root_orientation_as_read: [f64; 3],
    /// Bones, parents before children.
    pub bones: Vec<Bone>,
}

/// A motion: per frame, the dof values of the root and of every bone (radians, file units).
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, PartialEq)]
pub struct Motion {
    /// Values per frame: root values (in `root_order`) then each bone's dofs in order.
    pub values: Vec<f64>,
    /// Values per frame.
    pub stride: usize,
    /// Number of frames.
    pub frames: usize,
    /// Frames per second (Hz). AMC files do not store it: [`parse_amc`] sets the CMU
    /// database's 120 Hz; a BVH file's is `1 / Frame Time`.
    pub frame_rate: f64,
}

/// The frame rate of the CMU motion-capture database (Hz), which AMC files do not store.
pub const CMU_FRAME_RATE: f64 = 120.0;

impl Motion {
    /// Check a motion built by hand or restored from bytes (a parsed one always passes):
    /// `frames × stride` values, all finite, and a positive finite frame rate.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] (argument `"motion"`).
    pub fn validate(&self) -> Result<()> {
        if self.frames.checked_mul(self.stride) != Some(self.values.len()) {
            return Err(Error::invalid("motion", "must hold frames × stride values"));
        }
        if !(self.frame_rate.is_finite() && self.frame_rate > 0.0) {
            return Err(Error::invalid("motion", "frame rate must be positive and finite"));
        }
        if let Some(i) = self.values.iter().position(|v| !v.is_finite()) {
            return Err(Error::invalid("motion", "values must be finite").at(i));
        }
        Ok(())
    }

    /// Frames `start..end` as a new motion.
    ///
    /// # Errors
    /// An empty or out-of-range span.
    pub fn slice(&self, start: usize, end: usize) -> Result<Motion> {
        if start >= end || end > self.frames {
            return Err(Error::invalid(
                "frames",
                format!("need 0 <= start < end <= {}, got {start}..{end}", self.frames),
            ));
        }
        Ok(Motion {
            values: self.values[start * self.stride..end * self.stride].to_vec(),
            stride: self.stride,
            frames: end - start,
            frame_rate: self.frame_rate,
        })
    }
}

/// Whether `q` is a finite quaternion of unit length to `1e-9`.
fn is_unit(q: DQuat) -> bool {
    q.is_finite() && (q.length() - 1.0).abs() <= 1e-9
}

/// `dofs` are about or along axis 0, 1 or 2.
fn dofs_valid(dofs: &[Dof]) -> bool {
    dofs.iter().all(|d| match *d {
        Dof::Rotation(a) | Dof::Translation(a) => a < 3,
        Dof::Length => true,
    })
}

impl Skeleton {
    /// Check what forward kinematics, editing and the writer rely on, for a skeleton built
    /// by hand or restored from bytes (a parsed one always passes): every parent index
    /// before its bone, finite values, unit directions and axes (to `1e-9`), lengths `>= 0`,
    /// a positive length unit, dofs about axes 0–2 and one limit per dof (or none).
    ///
    /// # Errors
    /// [`Error::InvalidInput`] (argument `"skeleton"`) naming the first bad bone.
    pub fn validate(&self) -> Result<()> {
        let bad = |what: &str| Err(Error::invalid("skeleton", what.to_string()));
        if !(self.length_unit.is_finite() && self.length_unit > 0.0) {
            return bad("length unit must be positive and finite");
        }
        if !(self.root_position.is_finite()
            && is_unit(self.root_orientation)
            && self.root_orientation_as_read.iter().all(|a| a.is_finite())
            && dofs_valid(&self.root_order)
            && {
                let [i, j, k] = self.root_axis.axes;
                i < 3 && j < 3 && k < 3 && i != j && j != k
            })
        {
            return bad("root: needs a finite position, a unit orientation and dofs about x, y, z");
        }
        for (i, b) in self.bones.iter().enumerate() {
            let why = if b.parent.is_some_and(|p| p >= i) {
                "parent index must come before the bone"
            } else if !(b.direction.is_finite()
                && ((b.direction.length() - 1.0).abs() <= 1e-9
                    || (b.length == 0.0 && b.direction == DVec3::ZERO)))
            {
                "direction must be a unit vector (or zero for a bone of length 0)"
            } else if !(b.length.is_finite() && b.length >= 0.0) {
                "length must be finite and >= 0"
            } else if !(is_unit(b.axis) && b.axis_as_read.0.iter().all(|a| a.is_finite())) {
                "axis must be a unit quaternion"
            } else if !dofs_valid(&b.dofs) {
                "dofs must be about or along axes 0, 1, 2"
            } else if !(b.limits.is_empty() || b.limits.len() == b.dofs.len())
                || b.limits.iter().any(|(lo, hi)| lo.is_nan() || hi.is_nan())
            {
                "limits must be one (lower, upper) per dof, or none"
            } else {
                continue;
            };
            return Err(Error::invalid("skeleton", format!("bone {:?}: {why}", b.name)).at(i));
        }
        Ok(())
    }

    /// Whether each frame of `motion` keeps every bone's dofs within the ASF limits
    /// ([`Skeleton::pose_within_limits`] per frame).
    ///
    /// # Errors
    /// A motion made for another skeleton.
    pub fn within_limits(&self, motion: &Motion) -> Result<Vec<bool>> {
        if motion.stride != self.stride() {
            return Err(Error::invalid("motion", "was not made for this skeleton"));
        }
        motion.values.chunks(motion.stride.max(1)).map(|p| self.pose_within_limits(p)).collect()
    }

    /// Whether `pose` (one frame's values: root dofs, then each bone's) keeps every bone's
    /// dofs within the ASF limits (radians for rotations, file units otherwise; to `1e-9`;
    /// bones without limits are unconstrained).
    ///
    /// # Errors
    /// A pose of the wrong length or with a NaN or infinite value (argument `"pose"`).
    pub fn pose_within_limits(&self, pose: &[f64]) -> Result<bool> {
        if pose.len() != self.stride() {
            return Err(Error::invalid(
                "pose",
                format!("needs {} values, got {}", self.stride(), pose.len()),
            ));
        }
        if let Some(i) = pose.iter().position(|v| !v.is_finite()) {
            return Err(Error::InvalidInput {
                arg: "pose".into(),
                index: Some(i),
                reason: "contains NaN or infinity".into(),
            });
        }
        let mut k = self.root_order.len();
        Ok(self.bones.iter().all(|b| {
            let ok = b
                .limits
                .iter()
                .zip(&pose[k..k + b.dofs.len()])
                .all(|(l, v)| *v >= l.0 - 1e-9 && *v <= l.1 + 1e-9);
            k += b.dofs.len();
            ok
        }))
    }

    /// Joint names: `"root"` then the bones in order.
    pub fn joint_names(&self) -> Vec<String> {
        std::iter::once("root".to_string())
            .chain(self.bones.iter().map(|b| b.name.clone()))
            .collect()
    }

    /// Metres per file unit under the CMU reading of `:units length` (1 unit = 1/length
    /// inches; 0.45 gives 0.05644 m). Real files disagree with the 1995 text, so this is never
    /// applied automatically.
    pub fn metres_per_unit(&self) -> f64 {
        0.0254 / self.length_unit
    }

    /// Values per frame of a motion of this skeleton.
    pub fn stride(&self) -> usize {
        self.root_order.len() + self.bones.iter().map(|b| b.dofs.len()).sum::<usize>()
    }

    /// Forward kinematics of every frame: positions `(frames, 1 + bones, 3)` of the root and
    /// of every bone's tip (file units) and orientations `(frames, 1 + bones, 4)` (`w, x, y, z`,
    /// global), in parallel over frames.
    ///
    /// A bone's rotation dofs make `M` (composed in the order listed, about fixed axes), its
    /// translation dofs a vector `t` in its frame `C` and its `l` dof a length change `δ`
    /// (Acclaim ASF 1.10, `dof rx ry rz tx ty tz l`); with the parent's tip `p` and
    /// orientation `R_p`, the bone's orientation is `R = R_p · C · M · C⁻¹` and its tip
    /// `p + R_p · C · t + (length + δ) · R · direction`.
    ///
    /// # Errors
    /// A motion made for another skeleton (wrong stride).
    pub fn forward_kinematics(
        &self,
        motion: &Motion,
        positions: &mut [[f64; 3]],
        orientations: &mut [[f64; 4]],
    ) -> Result<()> {
        let joints = 1 + self.bones.len();
        if motion.stride != self.stride() {
            return Err(Error::invalid(
                "motion",
                format!(
                    "has {} values per frame, the skeleton needs {}",
                    motion.stride,
                    self.stride()
                ),
            ));
        }
        pose_frames(motion, joints, positions, orientations, |frame, pos, ori| {
            self.pose(frame, pos, ori);
        })
    }

    /// FK of one frame of values into `pos`/`ori` (`1 + bones` rows each).
    fn pose(&self, frame: &[f64], pos: &mut [[f64; 3]], ori: &mut [[f64; 4]]) {
        let mut k = 0;
        let mut t = self.root_position;
        let mut angles = [0.0; 3];
        for dof in &self.root_order {
            match *dof {
                Dof::Translation(a) => t[a] = frame[k],
                Dof::Rotation(a) => angles[a] = frame[k],
                Dof::Length => {}
            }
            k += 1;
        }
        let [i, j, l] = self.root_axis.axes;
        let m = self.root_axis.to_quat(&[angles[i], angles[j], angles[l]]).expect("finite angles");
        let root_rot = (self.root_orientation * m).normalize();
        pos[0] = t.to_array();
        ori[0] = crate::rotation::quat_to_wxyz(root_rot);
        for (b, bone) in self.bones.iter().enumerate() {
            let (mut m, mut shift, mut stretch) = (DQuat::IDENTITY, DVec3::ZERO, 0.0);
            for dof in &bone.dofs {
                match *dof {
                    Dof::Rotation(a) => {
                        let (s, c) = (0.5 * frame[k]).sin_cos();
                        let e = DVec3::AXES[a] * s;
                        m = DQuat::from_xyzw(e.x, e.y, e.z, c) * m;
                    }
                    Dof::Translation(a) => shift[a] = frame[k],
                    Dof::Length => stretch = frame[k],
                }
                k += 1;
            }
            // Parents come first, so their rows are already final.
            let parent = bone.parent.map_or(0, |p| p + 1);
            let [w, x, y, z] = ori[parent];
            let frame_c = DQuat::from_xyzw(x, y, z, w) * bone.axis;
            let r = (frame_c * m * bone.axis.conjugate()).normalize();
            ori[b + 1] = crate::rotation::quat_to_wxyz(r);
            let base = DVec3::from_array(pos[parent]) + frame_c * shift;
            pos[b + 1] = (base + (bone.length + stretch) * (r * bone.direction)).to_array();
        }
    }
}

/// Forward kinematics of every frame of `motion` into `joints` rows of `positions` and
/// `orientations` per frame, in parallel over frames; `pose` fills one frame's rows from its
/// values.
///
/// # Errors
/// Output slices that do not hold `frames x joints` rows.
fn pose_frames(
    motion: &Motion,
    joints: usize,
    positions: &mut [[f64; 3]],
    orientations: &mut [[f64; 4]],
    pose: impl Fn(&[f64], &mut [[f64; 3]], &mut [[f64; 4]]) + Sync,
) -> Result<()> {
    if positions.len() != motion.frames * joints || orientations.len() != motion.frames * joints {
        return Err(Error::invalid("out", "needs frames x joints rows"));
    }
    if joints == 0 {
        return Ok(());
    }
    positions.par_chunks_mut(joints).zip(orientations.par_chunks_mut(joints)).enumerate().for_each(
        |(f, (pos, ori))| {
            pose(&motion.values[f * motion.stride..(f + 1) * motion.stride], pos, ori)
        },
    );
    Ok(())
}
