//! A ragdoll from an Acclaim (ASF) skeleton: one body per bone, a capsule along the bone,
//! masses from a density, joints of the bone's kind with the ASF limits.
//!
//! Rules (all lengths in metres after `scale`):
//! - the root is a free body, a sphere whose radius is the largest of its child bones';
//! - bone `b` is a body whose frame sits at its base (its parent's tip) with world axes at
//!   rest; its capsule runs from the base to the tip, radius
//!   `max(min_radius, radius_ratio × length)`;
//! - its joint follows the ASF `dof` line: no rotation dof → fixed, one → revolute about
//!   that axis of the bone's frame `C`, two or three → ball; translation and length dofs are
//!   not simulated;
//! - limits: a revolute joint gets its dof's range; a ball joint gets ranges on the rotation
//!   vector's components about the axes of `C` (the ASF ranges of `rx ry rz`, read as
//!   ranges of the rotation vector, which agrees with the Euler ranges to first order), and
//!   `(0, 0)` about an axis without a dof;
//! - joint damping: `damping` (1/s) times the capsule's moment about its own axis (its
//!   smallest principal moment about the joint: explicit steps stay stable);
//! - the whole ragdoll is lifted so that its lowest point at rest is `clearance` above y = 0.
//!
//! A BVH skeleton ([`ragdoll_bvh`]) has joints rather than bones: a joint's rotation turns
//! the segments to its children (and to its end site), so joint `j` is a body whose frame
//! sits at the joint with world axes at rest (BVH's rest pose has every rotation zero), and
//! its capsule runs from the joint to the mean of its children's offsets and its end site
//! (a sphere where they cancel), radius `max(min_radius, radius_ratio × the longest
//! segment)`. A root is a free body; other joints are fixed without rotation channels, a
//! hinge about the channel's axis with one, a ball joint with two or three. BVH has no
//! limits: the joints are unlimited. Position channels below a root are not simulated.

use super::model::{Body, Capsule, Joint, Limits, Model, Settings};
use crate::error::{Error, Result};
use crate::mocap::{BvhSkeleton, Dof, Skeleton};
use glam::{DQuat, DVec3};

/// How [`ragdoll`] sizes bodies and joints.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct RagdollOptions {
    /// Density of every capsule (kg/m³), default 1000 (water, close to the body's).
    pub density: f64,
    /// Metres per file length unit (CMU files: [`Skeleton::metres_per_unit`]).
    pub scale: f64,
    /// Capsule radius as a fraction of the bone's length (default 0.15).
    pub radius_ratio: f64,
    /// Smallest capsule radius (m, default 0.02).
    pub min_radius: f64,
    /// Joint damping rate (1/s, default 2): a bone's joint damping is this times its
    /// smallest principal moment of inertia about the joint (about the capsule's axis), so
    /// an explicit step stays stable while `dt × damping < 2` for any limb (a damping
    /// sized on the larger moments makes the twist about a thin bone's axis unstable).
    pub damping: f64,
    /// Height of the lowest point above the ground at rest (m, default 0).
    pub clearance: f64,
}

impl Default for RagdollOptions {
    fn default() -> Self {
        RagdollOptions {
            density: 1000.0,
            scale: 1.0,
            radius_ratio: 0.15,
            min_radius: 0.02,
            damping: 2.0,
            clearance: 0.0,
        }
    }
}

/// The ragdoll of `skeleton` (rules in the module documentation) with `settings`.
///
/// # Errors
/// An option not finite and > 0 (`density`, `scale`, `radius_ratio`) or not finite and
/// >= 0 (`min_radius`, `damping`, `clearance`), named.
pub fn ragdoll(skeleton: &Skeleton, options: &RagdollOptions, settings: Settings) -> Result<Model> {
    let o = options;
    check_options(o)?;
    let radius = |len: f64| (o.radius_ratio * len).max(o.min_radius);
    let tips: Vec<DVec3> =
        skeleton.bones.iter().map(|b| b.direction * b.length * o.scale).collect();
    // Rest positions of each bone's base (root at the origin), to find the lowest point.
    let mut bases = vec![DVec3::ZERO; skeleton.bones.len()];
    for (i, b) in skeleton.bones.iter().enumerate() {
        bases[i] = b.parent.map_or(DVec3::ZERO, |p| bases[p] + tips[p]);
    }
    let root_radius = skeleton
        .bones
        .iter()
        .filter(|b| b.parent.is_none())
        .map(|b| radius(b.length * o.scale))
        .fold(o.min_radius, f64::max);
    let lowest = bases
        .iter()
        .zip(&tips)
        .zip(&skeleton.bones)
        .map(|((base, tip), b)| (base.y.min(base.y + tip.y)) - radius(b.length * o.scale))
        .fold(-root_radius, f64::min);
    let mut model = Model::new(settings);
    let root = Capsule { a: DVec3::ZERO, b: DVec3::ZERO, radius: root_radius };
    let r = skeleton.root_position * o.scale;
    let offset = DVec3::new(r.x, o.clearance - lowest, r.z);
    model.add_body(body("root", None, Joint::Free, offset, root, o.density, None, 0.0))?;
    for (i, b) in skeleton.bones.iter().enumerate() {
        let shape = Capsule { a: DVec3::ZERO, b: tips[i], radius: radius(b.length * o.scale) };
        let parent = b.parent.map_or(0, |p| p + 1);
        let offset = b.parent.map_or(DVec3::ZERO, |p| tips[p]);
        let (joint, limits) = joint_of(b.axis, &b.dofs, &b.limits);
        model.add_body(body(
            &b.name,
            Some(parent),
            joint,
            offset,
            shape,
            o.density,
            limits,
            o.damping,
        ))?;
    }
    Ok(model)
}

/// The options' checks (errors as documented on [`ragdoll`]).
fn check_options(o: &RagdollOptions) -> Result<()> {
    for (name, v, zero_ok) in [
        ("density", o.density, false),
        ("scale", o.scale, false),
        ("radius_ratio", o.radius_ratio, false),
        ("min_radius", o.min_radius, true),
        ("damping", o.damping, true),
        ("clearance", o.clearance, true),
    ] {
        if !(v.is_finite() && (v > 0.0 || (zero_ok && v == 0.0))) {
            return Err(Error::invalid(
                name,
                if zero_ok { "must be finite and >= 0" } else { "must be finite and > 0" },
            ));
        }
    }
    Ok(())
}

/// The ragdoll of a BVH `skeleton` (rules in the module documentation) with `settings`;
/// `options.scale` is metres per file unit (BVH files do not say).
///
/// # Errors
/// Those of [`ragdoll`]; a skeleton that [`BvhSkeleton::validate`] refuses.
pub fn ragdoll_bvh(
    skeleton: &BvhSkeleton,
    options: &RagdollOptions,
    settings: Settings,
) -> Result<Model> {
    let o = options;
    check_options(o)?;
    skeleton.validate()?;
    let joints = &skeleton.joints;
    // Each joint's segments (m, its frame): to its children and its end site.
    let mut segments: Vec<Vec<DVec3>> =
        joints.iter().map(|j| j.end_site.map(|e| e * o.scale).into_iter().collect()).collect();
    for j in joints {
        if let Some(p) = j.parent {
            segments[p].push(j.offset * o.scale);
        }
    }
    let shapes: Vec<Capsule> = segments
        .iter()
        .map(|s| {
            let longest = s.iter().map(|v| v.length()).fold(0.0, f64::max);
            let tip = s.iter().sum::<DVec3>() / s.len().max(1) as f64;
            Capsule { a: DVec3::ZERO, b: tip, radius: (o.radius_ratio * longest).max(o.min_radius) }
        })
        .collect();
    let mut origins = vec![DVec3::ZERO; joints.len()];
    for (i, j) in joints.iter().enumerate() {
        origins[i] = j.parent.map_or(j.offset * o.scale, |p| origins[p] + j.offset * o.scale);
    }
    let lowest = origins
        .iter()
        .zip(&shapes)
        .map(|(p, c)| p.y + c.b.y.min(0.0) - c.radius)
        .fold(f64::INFINITY, f64::min);
    let mut model = Model::new(settings);
    for (i, j) in joints.iter().enumerate() {
        let rotations: Vec<Dof> =
            j.channels.iter().copied().filter(|c| matches!(c, Dof::Rotation(_))).collect();
        let joint = match (j.parent, rotations.as_slice()) {
            (None, _) => Joint::Free,
            (_, []) => Joint::Fixed,
            (_, [Dof::Rotation(a)]) => Joint::Revolute { axis: DVec3::AXES[*a] },
            _ => Joint::Ball,
        };
        let offset = match j.parent {
            None => DVec3::new(origins[i].x, origins[i].y + o.clearance - lowest, origins[i].z),
            Some(_) => j.offset * o.scale,
        };
        model.add_body(body(
            &j.name, j.parent, joint, offset, shapes[i], o.density, None, o.damping,
        ))?;
    }
    Ok(model)
}

/// A body with the mass properties of `shape` at `density`.
#[allow(clippy::too_many_arguments)]
fn body(
    name: &str,
    parent: Option<usize>,
    joint: Joint,
    offset: DVec3,
    shape: Capsule,
    density: f64,
    limits: Option<Limits>,
    damping: f64,
) -> Body {
    let (mass, com, inertia) = shape.mass_properties(density);
    // The smallest principal moment about the joint: about the capsule's axis (through the
    // joint), or a third of the trace for a sphere.
    let axis = (shape.b - shape.a).normalize_or_zero();
    let moment = if axis == DVec3::ZERO {
        (inertia.x_axis.x + inertia.y_axis.y + inertia.z_axis.z) / 3.0
    } else {
        axis.dot(inertia * axis)
    };
    let damping = if joint == Joint::Free { 0.0 } else { damping * moment };
    Body {
        name: name.to_string(),
        parent,
        joint,
        offset,
        mass,
        com,
        inertia,
        shape: Some(shape),
        limits,
        damping,
        servo: None,
    }
}

/// The joint and limits of a bone with frame `axis` (`C`), rotation dofs and their limits.
fn joint_of(axis: DQuat, dofs: &[Dof], limits: &[(f64, f64)]) -> (Joint, Option<Limits>) {
    let rotations: Vec<(usize, (f64, f64))> = dofs
        .iter()
        .zip(limits.iter().copied().chain(std::iter::repeat((f64::NEG_INFINITY, f64::INFINITY))))
        .filter_map(|(d, l)| if let Dof::Rotation(a) = d { Some((*a, l)) } else { None })
        .collect();
    match rotations.as_slice() {
        [] => (Joint::Fixed, None),
        [(a, range)] => {
            let joint = Joint::Revolute { axis: axis * DVec3::AXES[*a] };
            (
                joint,
                Some(Limits { ranges: [*range, (0.0, 0.0), (0.0, 0.0)], frame: DQuat::IDENTITY }),
            )
        }
        _ => {
            let mut ranges = [(0.0, 0.0); 3];
            for (a, range) in &rotations {
                ranges[*a] = *range;
            }
            (Joint::Ball, Some(Limits { ranges, frame: axis }))
        }
    }
}
