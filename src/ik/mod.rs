//! Inverse kinematics on a motion-capture [`Skeleton`]: joint values that bring one or several
//! end effectors (joints) to target positions and, optionally, orientations.
//!
//! The unknowns are the rotational dofs of the ASF bones (1 to 3 per bone, with their limits)
//! and, with [`Options::free_root`], the root's translation and rotation; a pose is one frame
//! of values as in [`crate::mocap::Motion`] (root values, then each bone's dofs in file order;
//! radians and skeleton length units). Only the variables of bones on the path from the root to
//! an end effector move; every other value is returned as given.
//!
//! Methods ([`Method`]):
//! - **two-bone** (analytic limb IK): the hinge of the effector's bone is set in closed form so
//!   that the distance from the upper joint to the effector equals the distance to the target
//!   (or its closest reachable value), then the upper 3-dof joint turns the limb onto the
//!   target by the minimal rotation (the swivel plane is kept). Exact in one step.
//! - **CCD**, cyclic coordinate descent (Wang & Chen, "A combined optimization method for
//!   solving the inverse kinematics problem of mechanical manipulators", IEEE Trans. Robotics
//!   and Automation 7(4), 1991): each dof in turn, from the effector towards the root, takes
//!   the angle that minimises the summed squared position and orientation error of the
//!   effectors below it, `θ = atan2(k₃, k₂ - k₁)`, clamped to its limits.
//! - **Jacobian transpose** (Wolovich & Elliott 1984; step length of Buss, "Introduction to
//!   inverse kinematics with Jacobian transpose, pseudoinverse and damped least squares
//!   methods", 2004): `Δθ = α Jᵀ e` with `α = ⟨e, JJᵀe⟩ / |JJᵀe|²`.
//! - **pseudo-inverse**: `Δθ = J⁺ e` from the SVD of `J` (singular values below `1e-9 σ_max`
//!   are treated as zero).
//! - **damped least squares** (Wampler 1986; Nakamura & Hanafusa, "Inverse kinematic
//!   solutions with singularity robustness for robot manipulator control", ASME J. Dyn. Syst.
//!   Meas. Control 108, 1986): `Δθ = Jᵀ(JJᵀ + λ²I)⁻¹ e = Σ σᵢ/(σᵢ² + λ²) uᵢ vᵢᵀ e`, with the
//!   damping adapted to the smallest singular value as in Chiaverini, "Singularity-robust
//!   task-priority redundancy resolution for real-time kinematic control of robot
//!   manipulators", IEEE Trans. Robotics and Automation 13(3), 1997:
//!   `λ² = (1 - (σ_min/ε)²) λ_max²` when `σ_min < ε`, else 0, with `ε = λ_max = 0.03 L`
//!   (`L` the reach of the chain), so away from singularities DLS is the pseudo-inverse and at
//!   a fully stretched arm the step stays bounded.
//!
//! With pseudo-inverse and DLS a secondary objective moves in the null space of the task
//! (Liégeois, "Automatic supervisory control of the configuration and behavior of multibody
//! mechanisms", IEEE Trans. SMC 7(12), 1977): `Δθ += (I - J⁺J) z` with
//! `z = -rest_weight (θ - θ_rest) - limit_weight ∇H`, `H = ½ Σ ((θ - mid)/half_range)²`, so
//! the pose stays near a rest pose and away from joint limits without disturbing the
//! effectors (to first order).
//!
//! Errors: position error `t - p` in skeleton length units; orientation error the rotation
//! vector of `q_target q⁻¹` (radians, world axes), weighted by the effector's reach `L` in the
//! task vector so that both are lengths. A solve converges when every effector is within `tol`
//! of its target position (length units) and `tol` radians of its target orientation.
//!
//! Joint limits are honoured always (unless switched off): the start pose is clamped, CCD and
//! two-bone clamp each angle, and the Jacobian methods clamp a dof that would cross a limit to
//! it, remove its column and re-solve the rest of the task with the remaining dofs (the
//! "clamping loop" of Baerlocher & Boulic, "An inverse kinematics architecture enforcing an
//! arbitrary number of strict priority levels", The Visual Computer 20, 2004). Jacobian steps
//! are capped at 0.5 rad per dof and halved (up to 10 times) until the error decreases; a
//! solve stops when converged, at `max_iters`, or when no step decreases the error any more
//! (an unreachable target or a local minimum): it then ends at the closest point it reached
//! and says `converged = false`.
//!
//! A [`Solver`] owns every buffer, so iterations allocate nothing (a test counts).

mod model;
mod solver;

pub use solver::Solver;

use crate::error::{Error, Result};
use crate::mocap::{Bone, Dof, Skeleton};
use crate::rotation::EulerSequence;
use glam::{DQuat, DVec3};

/// An IK method; see the module documentation for the equations and sources.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Analytic two-bone limb IK (one position target on a bone with one rotational dof whose
    /// parent bone has three).
    TwoBone,
    /// Cyclic coordinate descent.
    Ccd,
    /// Jacobian transpose.
    Transpose,
    /// Pseudo-inverse by SVD.
    PseudoInverse,
    /// Damped least squares with adaptive damping.
    Dls,
}

impl Method {
    /// Parse `"two_bone"`, `"ccd"`, `"transpose"`, `"pseudo_inverse"` or `"dls"`.
    ///
    /// # Errors
    /// Any other name ([`Error::InvalidInput`], argument `method`).
    pub fn parse(name: &str) -> Result<Method> {
        Ok(match name {
            "two_bone" => Method::TwoBone,
            "ccd" => Method::Ccd,
            "transpose" => Method::Transpose,
            "pseudo_inverse" => Method::PseudoInverse,
            "dls" => Method::Dls,
            _ => {
                return Err(Error::invalid(
                    "method",
                    format!(
                        "{name:?} is not one of \"dls\", \"pseudo_inverse\", \"transpose\", \"ccd\", \"two_bone\""
                    ),
                ))
            }
        })
    }
}

/// A target for one end effector.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Target {
    /// Joint index: 0 the root, `b + 1` the tip of bone `b` (the order of
    /// [`Skeleton::joint_names`]).
    pub joint: usize,
    /// Target position of the joint (skeleton length units, world frame).
    pub position: DVec3,
    /// Target orientation of the joint (unit quaternion, world frame), if any.
    pub orientation: Option<DQuat>,
}

/// Settings of a solve.
#[derive(Clone, Debug, PartialEq)]
pub struct Options {
    /// The method.
    pub method: Method,
    /// Keep every moved dof within its ASF limits.
    pub joint_limits: bool,
    /// Null-space pull towards the rest pose, per iteration (a fraction of the way; 0 = off).
    /// Pseudo-inverse and DLS only.
    pub rest_weight: f64,
    /// Null-space push away from joint limits (step on `-∇H`, radians²; 0 = off).
    /// Pseudo-inverse and DLS only.
    pub limit_weight: f64,
    /// Rest pose for `rest_weight` (one frame of values); `None`: all zeros, the ASF rest pose.
    pub rest: Option<Vec<f64>>,
    /// Let the root translate and rotate (its dofs are held fixed otherwise).
    pub free_root: bool,
    /// Convergence tolerance: length units for positions, radians for orientations.
    pub tol: f64,
    /// Most iterations (Jacobian steps or CCD sweeps).
    pub max_iters: usize,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            method: Method::Dls,
            joint_limits: true,
            rest_weight: 0.0,
            limit_weight: 0.0,
            rest: None,
            free_root: false,
            tol: 1e-4,
            max_iters: 100,
        }
    }
}

/// What a solve achieved.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Report {
    /// Every effector within `tol` of its target (position and orientation).
    pub converged: bool,
    /// Largest position error over the effectors (skeleton length units).
    pub error: f64,
    /// Largest orientation error over the effectors with an orientation target (radians; 0
    /// without such targets).
    pub orientation_error: f64,
    /// Iterations made (Jacobian steps, CCD sweeps; 1 for two-bone).
    pub iterations: usize,
}

/// Solve IK for `targets`, changing `pose` (one frame of values of `skeleton`) in place.
///
/// Builds a [`Solver`] and runs it once; to solve many times for the same effectors, keep a
/// [`Solver`].
///
/// # Errors
/// [`Error::InvalidInput`]: a pose of the wrong length or with NaN, an unknown joint, a
/// non-finite target, bad options, a method that cannot serve these targets.
pub fn solve(
    skeleton: &Skeleton,
    pose: &mut [f64],
    targets: &[Target],
    options: &Options,
) -> Result<Report> {
    Solver::new(skeleton, targets, options)?.solve(pose, targets)
}

/// The Jacobian of the given joints' positions (and, with `orientation`, orientations) with
/// respect to the skeleton's variables at `pose`.
///
/// Returns the matrix row-major, `rows x columns` with `3` rows per joint (x, y, z of its
/// position, length units per radian) followed, with `orientation`, by `3` rows of its angular
/// velocity (radians per radian), and the pose indices of the columns: every rotational bone
/// dof and, with `free_root`, the root's dofs, in pose order. Columns are
/// `w × (p - p_pivot)` and `w` (world axis `w`, pivot the base of the dof's bone), zero for dofs that do not move the joint.
///
/// # Errors
/// A pose of the wrong length or with NaN, an unknown joint.
pub fn jacobian(
    skeleton: &Skeleton,
    pose: &[f64],
    joints: &[usize],
    orientation: bool,
    free_root: bool,
) -> Result<(Vec<f64>, Vec<usize>)> {
    solver::check_pose(skeleton, pose, "pose")?;
    for &j in joints {
        solver::check_joint(skeleton, j)?;
    }
    let mut vars = model::all_vars(skeleton, free_root, false);
    vars.sort_by_key(|v| v.index);
    let joints_n = 1 + skeleton.bones.len();
    let (mut pos, mut rot) = (vec![DVec3::ZERO; joints_n], vec![DQuat::IDENTITY; joints_n]);
    let (mut axis, mut pivot) = (vec![DVec3::ZERO; pose.len()], vec![DVec3::ZERO; pose.len()]);
    model::forward(skeleton, pose, &mut pos, &mut rot, &mut axis, &mut pivot);
    let per = if orientation { 6 } else { 3 };
    let n = vars.len();
    let mut jac = vec![0.0; joints.len() * per * n];
    for (e, &j) in joints.iter().enumerate() {
        for (c, v) in vars.iter().enumerate() {
            if model::is_ancestor_or_self(skeleton, v.joint, j) {
                let (lin, ang) = model::column(v, pos[j], &pivot, &axis);
                for d in 0..3 {
                    jac[(e * per + d) * n + c] = lin[d];
                    if orientation {
                        jac[(e * per + 3 + d) * n + c] = ang[d];
                    }
                }
            }
        }
    }
    Ok((jac, vars.iter().map(|v| v.index).collect()))
}

/// A serial chain as an Acclaim skeleton, for IK problems that are not motion capture: bone
/// `i` (named `link{i+1}`) has length `lengths[i]` (metres) and rotational dofs `dofs[i]`
/// (e.g. `"xyz"`, `"z"`, `""`: composed as ASF dofs, the first letter innermost), and lies
/// along +x at rest, so the rest pose (all zeros) is the chain stretched along +x from the
/// origin. The root is fixed at the origin (it has no dofs), so a pose is just the joint
/// angles, in bone order. `limits` gives `(lo, hi)` radians for every dof in that order, or
/// `None` for unlimited joints. `length_unit` is set so that `metres_per_unit` is 1.
///
/// A 7-dof arm is `chain(&[0.3, 0.3, 0.1], &["xyz", "z", "xyz"], ...)`.
///
/// # Errors
/// Non-positive or non-finite lengths, dof strings other than distinct letters from `x y z`,
/// limits that do not match the dofs or have `lo > hi`.
pub fn chain(lengths: &[f64], dofs: &[&str], limits: Option<&[(f64, f64)]>) -> Result<Skeleton> {
    if lengths.len() != dofs.len() {
        return Err(Error::invalid(
            "dofs",
            format!("needs one entry per bone ({}), got {}", lengths.len(), dofs.len()),
        ));
    }
    let total: usize = dofs.iter().map(|d| d.len()).sum();
    if let Some(l) = limits {
        if l.len() != total {
            return Err(Error::invalid(
                "limits",
                format!("needs one (lo, hi) per dof ({total}), got {}", l.len()),
            ));
        }
        if let Some(i) = l.iter().position(|(lo, hi)| lo.is_nan() || hi.is_nan() || lo > hi) {
            return Err(Error::invalid("limits", "needs lo <= hi").at(i));
        }
    }
    let mut bones = Vec::with_capacity(lengths.len());
    let mut k = 0;
    for (i, (&length, d)) in lengths.iter().zip(dofs).enumerate() {
        if !(length.is_finite() && length > 0.0) {
            return Err(Error::invalid("lengths", "must be positive and finite").at(i));
        }
        let mut bone_dofs = Vec::new();
        for c in d.chars() {
            let a = match c {
                'x' => 0,
                'y' => 1,
                'z' => 2,
                _ => {
                    return Err(
                        Error::invalid("dofs", format!("{d:?} has {c:?}; use x, y, z")).at(i)
                    )
                }
            };
            if bone_dofs.contains(&Dof::Rotation(a)) {
                return Err(Error::invalid("dofs", format!("{d:?} repeats {c:?}")).at(i));
            }
            bone_dofs.push(Dof::Rotation(a));
        }
        let n = bone_dofs.len();
        bones.push(Bone {
            name: format!("link{}", i + 1),
            parent: i.checked_sub(1),
            direction: DVec3::X,
            length,
            axis: DQuat::IDENTITY,
            axis_as_read: ([0.0; 3], "XYZ".into()),
            dofs: bone_dofs,
            limits: limits.map_or(Vec::new(), |l| l[k..k + n].to_vec()),
        });
        k += n;
    }
    Ok(Skeleton {
        name: "chain".into(),
        length_unit: 0.0254,
        mass_unit: 1.0,
        degrees: false,
        root_order: Vec::new(),
        root_axis: EulerSequence::parse("xyz")?,
        root_position: DVec3::ZERO,
        root_orientation: DQuat::IDENTITY,
        root_orientation_as_read: [0.0; 3],
        bones,
    })
}
