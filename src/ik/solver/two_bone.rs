//! The analytic two-bone method: the hinge angle from the law of cosines, then the upper
//! bone's three angles that aim the effector at the target, within the joints' limits.

use super::super::model;
use super::super::{Report, Target};
use super::Solver;
use crate::error::{Error, Result};
use crate::math::wrap_angle;
use crate::mocap::{Dof, Skeleton};
use crate::rotation::EulerSequence;
use glam::{DQuat, DVec3};
use std::f64::consts::PI;

/// The analytic two-bone plan: effector bone with a hinge, parent bone with three dofs.
#[derive(Clone, Copy, Debug)]
pub(super) struct TwoBone {
    effector: usize,
    /// Joint index of the upper bone (the effector's parent).
    upper: usize,
    /// Pose index of the hinge value.
    hinge: usize,
    hinge_limits: (f64, f64),
    /// Pose index of the first of the upper bone's three values, their sequence and limits.
    upper_first: usize,
    upper_seq: EulerSequence,
    upper_limits: [(f64, f64); 3],
}

impl Solver<'_> {
    pub(super) fn two_bone(&mut self, q: &mut [f64], targets: &[Target]) -> Report {
        let tb = self.two_bone.expect("planned in new");
        let target = targets[0].position;
        self.bend_hinge(&tb, q, target);
        self.aim_upper(&tb, q, target);
        let mut err = std::mem::take(&mut self.err);
        let (_, ep, eo) = self.errors(targets, &mut err);
        self.err = err;
        self.report(ep, eo, 1)
    }

    /// Two-bone IK, first stage: the hinge angle that puts the effector at the target's
    /// distance from the upper bone's joint (law of cosines about the hinge axis), within the
    /// hinge's limits (the nearest limit when none reaches).
    fn bend_hinge(&mut self, tb: &TwoBone, q: &mut [f64], target: DVec3) {
        self.forward(q);
        let hip = self.pos[model::parent_joint(self.sk, tb.upper)];
        let knee = self.pos[tb.upper];
        let (s, r) = (knee - hip, self.pos[tb.effector] - knee);
        let w = self.axis[tb.hinge];
        // |s + Rot(w, δ) r|² = |s|² + |r|² + 2 (A + B cos δ + C sin δ).
        let a = w.dot(r) * w.dot(s);
        let (b, c) = (s.dot(r) - a, s.dot(w.cross(r)));
        let want =
            0.5 * ((target - hip).length_squared() - s.length_squared() - r.length_squared());
        let amp = b.hypot(c);
        if amp > 1e-12 * s.length() * r.length() {
            let phi = c.atan2(b);
            let spread = ((want - a) / amp).clamp(-1.0, 1.0).acos();
            let theta = q[tb.hinge];
            let (lo, hi) = tb.hinge_limits;
            let mut best: Option<f64> = None;
            for d in [phi + spread, phi - spread] {
                for k in [-1.0, 0.0, 1.0] {
                    let x = theta + wrap_angle(d) + k * std::f64::consts::TAU;
                    if x >= lo
                        && x <= hi
                        && best.is_none_or(|b| (x - theta).abs() < (b - theta).abs())
                    {
                        best = Some(x);
                    }
                }
            }
            // No solution within the limits: the limit whose distance is closest to the goal.
            let dist = |x: f64| a + b * (x - theta).cos() + c * (x - theta).sin();
            q[tb.hinge] = best.unwrap_or_else(|| {
                if (dist(lo) - want).abs() <= (dist(hi) - want).abs() {
                    lo
                } else {
                    hi
                }
            });
            self.forward(q);
        }
    }

    /// Two-bone IK, second stage: the upper bone's three angles that swing the effector onto
    /// the target (the shortest arc), of the two Tait–Bryan solutions the one that fits the
    /// limits better.
    fn aim_upper(&mut self, tb: &TwoBone, q: &mut [f64], target: DVec3) {
        let hip = self.pos[model::parent_joint(self.sk, tb.upper)];
        let reach = self.pos[tb.effector] - hip;
        let goal = target - hip;
        if reach.length() > 0.0 && goal.length() > 0.0 {
            let turn = DQuat::from_rotation_arc(reach.normalize(), goal.normalize());
            let bone = &self.sk.bones[tb.upper - 1];
            let parent = self.rot[model::parent_joint(self.sk, tb.upper)];
            let k = tb.upper_first;
            let m = tb.upper_seq.to_quat(&[q[k], q[k + 1], q[k + 2]]).expect("finite pose");
            let frame = parent * bone.axis;
            let m2 = (frame.conjugate() * turn * frame * m).normalize();
            let (angles, _) = tb.upper_seq.from_quat(m2);
            // The other Tait–Bryan solution (a + π, π - b, c + π); keep whichever fits the
            // limits better (smallest rotation left over after clamping).
            let other = [
                wrap_angle(angles[0] + PI),
                wrap_angle(PI - angles[1]),
                wrap_angle(angles[2] + PI),
            ];
            let mut chosen = [0.0; 3];
            let mut chosen_miss = f64::INFINITY;
            for cand in [angles, other] {
                let mut fit = [0.0; 3];
                for i in 0..3 {
                    fit[i] = fit_angle(cand[i], q[k + i], tb.upper_limits[i]);
                }
                let got = tb.upper_seq.to_quat(&fit).expect("finite angles");
                let miss = crate::rotation::rotation_angle(got.conjugate() * m2);
                if miss < chosen_miss - 1e-12 {
                    (chosen, chosen_miss) = (fit, miss);
                }
            }
            q[k..k + 3].copy_from_slice(&chosen);
            self.forward(q);
        }
    }
}

/// The representative of angle `a` (mod 2π) within `limits` closest to `current`, or the
/// limit nearest to it on the circle when none is within.
fn fit_angle(a: f64, current: f64, (lo, hi): (f64, f64)) -> f64 {
    let base = a + ((current - a) / std::f64::consts::TAU).round() * std::f64::consts::TAU;
    let mut best: Option<f64> = None;
    for k in [-1.0, 0.0, 1.0] {
        let x = base + k * std::f64::consts::TAU;
        if x >= lo && x <= hi && best.is_none_or(|b| (x - current).abs() < (b - current).abs()) {
            best = Some(x);
        }
    }
    best.unwrap_or_else(|| {
        let gap = |l: f64| wrap_angle(l - a).abs();
        if gap(lo) <= gap(hi) {
            lo
        } else {
            hi
        }
    })
}

pub(super) fn two_bone_plan(
    sk: &Skeleton,
    targets: &[Target],
    joint_limits: bool,
) -> Result<TwoBone> {
    let bad = |why: &str| Err(Error::invalid("method", format!("\"two_bone\" {why}")));
    if targets.len() != 1 || targets[0].orientation.is_some() {
        return bad("takes exactly one position target");
    }
    let effector = targets[0].joint;
    let rotations = |j: usize| -> Vec<(usize, usize, (f64, f64))> {
        let mut k = sk.root_order.len();
        for b in &sk.bones[..j - 1] {
            k += b.dofs.len();
        }
        let bone = &sk.bones[j - 1];
        bone.dofs
            .iter()
            .enumerate()
            .filter_map(|(i, d)| match d {
                Dof::Rotation(a) => {
                    let lim = match bone.limits.get(i) {
                        Some(&l) if joint_limits => l,
                        _ => (f64::NEG_INFINITY, f64::INFINITY),
                    };
                    Some((k + i, *a, lim))
                }
                _ => None,
            })
            .collect()
    };
    if effector == 0 {
        return bad("needs a bone, not the root, as effector");
    }
    let hinge = rotations(effector);
    if hinge.len() != 1 {
        return bad("needs an effector bone with exactly one rotational dof (the hinge)");
    }
    let upper = model::parent_joint(sk, effector);
    if upper == 0 {
        return bad("needs the effector's parent to be a bone");
    }
    let rigid = |j: usize| sk.bones[j - 1].dofs.iter().all(|d| matches!(d, Dof::Rotation(_)));
    if !rigid(effector) || !rigid(upper) {
        return bad("needs its two bones without translation or length dofs");
    }
    let up = rotations(upper);
    if up.len() != 3 || up[1].0 != up[0].0 + 1 || up[2].0 != up[1].0 + 1 {
        return bad("needs the effector's parent bone to have three consecutive rotational dofs");
    }
    let seq: String = up.iter().map(|d| ['x', 'y', 'z'][d.1]).collect();
    let upper_seq = EulerSequence::parse(&seq)
        .ok()
        .filter(|s| !s.is_proper())
        .ok_or_else(|| Error::invalid("method", "\"two_bone\" needs three different upper axes"))?;
    Ok(TwoBone {
        effector,
        upper,
        hinge: hinge[0].0,
        hinge_limits: hinge[0].2,
        upper_first: up[0].0,
        upper_seq,
        upper_limits: [up[0].2, up[1].2, up[2].2],
    })
}
