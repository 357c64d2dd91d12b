//! Motion editing on Acclaim and BVH motions: resampling and time warping, blending,
//! stitching with root alignment, and motion warping (Witkin & Popović 1995, "Motion
//! warping", SIGGRAPH).
//!
//! Every operation mixes frames the same way (`mix`): each group of three consecutive
//! rotation dofs of a joint (the root's, 3-dof bones', BVH joints') by slerp of the rotation
//! it makes, on the shorter arc, decomposed back in its order; one- and two-dof rotations,
//! translations and lengths linearly (exact for one dof, a first-order approximation of the
//! rotation for two). A skeleton only says how its values are laid out ([`Edit`]).

use super::{BvhSkeleton, Dof, Motion, Skeleton};
use crate::error::{filled, reserve, too_large, Error, Result};
use crate::math::wrap_angle;
use crate::rotation::EulerSequence;
use crate::spline::{Extrapolation, Interpolation, Track};
use glam::DQuat;
use rayon::prelude::*;

/// First value index and sequence of every group of three consecutive rotation dofs.
type Groups = Vec<(usize, EulerSequence)>;

fn rotation_groups<E: Edit + ?Sized>(e: &E) -> Groups {
    let mut groups = Vec::new();
    let mut k = 0;
    for (j, dofs) in e.joint_dofs().into_iter().enumerate() {
        let rot: Vec<(usize, usize)> = dofs
            .iter()
            .enumerate()
            .filter_map(|(i, d)| if let Dof::Rotation(a) = d { Some((i, *a)) } else { None })
            .collect();
        if rot.len() == 3 && rot.iter().map(|r| r.0).eq(rot[0].0..rot[0].0 + 3) {
            if let Some(seq) = e.sequence(j, [rot[0].1, rot[1].1, rot[2].1]) {
                groups.push((k + rot[0].0, seq));
            }
        }
        k += dofs.len();
    }
    groups
}

/// Where the root's translation (x, y, z) and its rotation group sit among a frame's values,
/// when the root has all three of each.
fn root_channels<E: Edit + ?Sized>(e: &E) -> Option<([usize; 3], usize, EulerSequence)> {
    let dofs = e.joint_dofs();
    let root = dofs.first()?;
    let mut t = [usize::MAX; 3];
    for (i, d) in root.iter().enumerate() {
        if let Dof::Translation(a) = d {
            t[*a] = i;
        }
    }
    let (g, seq) = rotation_groups(e).into_iter().find(|(g, _)| *g < root.len())?;
    (!t.contains(&usize::MAX)).then_some((t, g, seq))
}

/// `out = (1 - s) a + s b` for the values of one frame, rotations by slerp; exactly `a` at
/// `s = 0` and `b` at `s = 1`.
fn mix(groups: &Groups, a: &[f64], b: &[f64], s: f64, out: &mut [f64]) {
    if s == 0.0 || s == 1.0 {
        out.copy_from_slice(if s == 0.0 { a } else { b });
        return;
    }
    for c in 0..out.len() {
        out[c] = a[c] + s * (b[c] - a[c]);
    }
    for (g, seq) in groups {
        let (qa, qb) =
            (seq.to_quat(&[a[*g], a[g + 1], a[g + 2]]), seq.to_quat(&[b[*g], b[g + 1], b[g + 2]]));
        if let (Ok(qa), Ok(qb)) = (qa, qb) {
            let (angles, _) = seq.from_quat(crate::rotation::slerp(qa, qb, s, true));
            out[*g..g + 3].copy_from_slice(&angles);
        }
    }
}

fn check<E: Edit + ?Sized>(e: &E, motion: &Motion, arg: &str) -> Result<()> {
    let stride: usize = e.joint_dofs().iter().map(|d| d.len()).sum();
    if motion.stride != stride || motion.frames == 0 {
        return Err(Error::invalid(arg, "was not made for this skeleton, or has no frames"));
    }
    Ok(())
}

impl Edit for Skeleton {
    fn joint_dofs(&self) -> Vec<&[Dof]> {
        std::iter::once(self.root_order.as_slice())
            .chain(self.bones.iter().map(|b| b.dofs.as_slice()))
            .collect()
    }

    /// Acclaim dofs compose about the fixed axes in the order written (extrinsic); the root's
    /// rotation order is its `axis`, which must match its dof order.
    fn sequence(&self, joint: usize, order: [usize; 3]) -> Option<EulerSequence> {
        let seq =
            EulerSequence::parse(&order.map(|a| ['x', 'y', 'z'][a]).iter().collect::<String>())
                .ok()?;
        (joint > 0 || seq == self.root_axis).then_some(seq)
    }
}

impl Edit for BvhSkeleton {
    fn joint_dofs(&self) -> Vec<&[Dof]> {
        self.joints.iter().map(|j| j.channels.as_slice()).collect()
    }

    /// BVH rotation channels compose intrinsically in the order listed.
    fn sequence(&self, _joint: usize, order: [usize; 3]) -> Option<EulerSequence> {
        EulerSequence::parse(&order.map(|a| ['X', 'Y', 'Z'][a]).iter().collect::<String>()).ok()
    }
}

/// The body of [`Edit::time_warp`]; `arg` names `at` in errors (`times`, or the `to_rate`
/// it was made from), including when the output does not fit in memory.
fn sample<E: Edit + ?Sized>(e: &E, motion: &Motion, at: &[f64], arg: &str) -> Result<Motion> {
    check(e, motion, "motion")?;
    let last = (motion.frames - 1) as f64;
    for (i, &u) in at.iter().enumerate() {
        if !(u.is_finite() && (0.0..=last).contains(&u)) || (i > 0 && u < at[i - 1]) {
            return Err(Error::InvalidInput {
                arg: arg.into(),
                index: Some(i),
                reason: format!("must be non-decreasing frame positions within [0, {last}]"),
            });
        }
    }
    let (stride, groups) = (motion.stride, rotation_groups(e));
    let count = at.len().checked_mul(stride).ok_or_else(|| too_large(arg, at.len(), 8 * stride))?;
    let mut values = filled(arg, count, 0.0)?;
    values.par_chunks_mut(stride).zip(at.par_iter()).for_each(|(out, &u)| {
        let i = (u.floor() as usize).min(motion.frames - 1);
        let j = (i + 1).min(motion.frames - 1);
        let frame = |k: usize| &motion.values[k * stride..(k + 1) * stride];
        mix(&groups, frame(i), frame(j), u - i as f64, out);
    });
    Ok(Motion { values, stride, frames: at.len(), frame_rate: motion.frame_rate })
}

/// Motion editing for a skeleton that says how its frame values are laid out; the operations
/// are provided.
pub trait Edit: Sync {
    /// The dofs of each joint in value order, the root first.
    fn joint_dofs(&self) -> Vec<&[Dof]>;

    /// The Euler sequence of joint `joint`'s three consecutive rotation dofs about the axes
    /// `order` (0 = x), or `None` when they are not to be mixed as one rotation.
    fn sequence(&self, joint: usize, order: [usize; 3]) -> Option<EulerSequence>;

    /// `motion` (sampled at `from_rate` Hz) resampled at `to_rate` Hz over the same time span.
    ///
    /// # Errors
    /// A motion of another skeleton, non-positive rates, more frames than the allocator
    /// grants (named `to_rate`).
    fn resample(&self, motion: &Motion, from_rate: f64, to_rate: f64) -> Result<Motion> {
        check(self, motion, "motion")?;
        if !(from_rate.is_finite() && to_rate.is_finite() && from_rate > 0.0 && to_rate > 0.0) {
            return Err(Error::invalid(
                "rate",
                format!("frame rates must be positive, got {from_rate} and {to_rate}"),
            ));
        }
        let duration = (motion.frames - 1) as f64 / from_rate;
        // `as` saturates: a count beyond usize fails the allocation below like any other.
        let frames = ((duration * to_rate + 1e-9).floor() as usize).saturating_add(1);
        let mut at = Vec::new();
        reserve("to_rate", &mut at, frames)?;
        let last = (motion.frames - 1) as f64;
        at.extend((0..frames).map(|f| (f as f64 / to_rate * from_rate).min(last)));
        let mut out = sample(self, motion, &at, "to_rate")?;
        out.frame_rate = to_rate;
        Ok(out)
    }

    /// The motion sampled at fractional frame positions `at` (non-decreasing, within
    /// `[0, frames - 1]`): a time warp `t → at(t)` of the motion, one output frame per entry.
    ///
    /// # Errors
    /// A motion of another skeleton; positions that are not finite, decrease, or fall
    /// outside the motion (named by index).
    fn time_warp(&self, motion: &Motion, at: &[f64]) -> Result<Motion> {
        sample(self, motion, at, "times")
    }

    /// Frame-by-frame blend of two motions of equal length: `weights` (one, or one per frame,
    /// in `[0, 1]`) is the share of `b`; a ramp of weights makes a transition window.
    ///
    /// # Errors
    /// Motions of another skeleton or of different lengths; weights of the wrong count, not
    /// finite, or outside `[0, 1]`.
    fn blend(&self, a: &Motion, b: &Motion, weights: &[f64]) -> Result<Motion> {
        check(self, a, "a")?;
        check(self, b, "b")?;
        if a.frames != b.frames {
            return Err(Error::invalid(
                "b",
                format!("has {} frames, a has {}", b.frames, a.frames),
            ));
        }
        if weights.len() != 1 && weights.len() != a.frames {
            return Err(Error::invalid(
                "weight",
                format!(
                    "expected one weight or one per frame ({}), got {}",
                    a.frames,
                    weights.len()
                ),
            ));
        }
        if let Some(i) = weights.iter().position(|w| !(0.0..=1.0).contains(w)) {
            return Err(Error::InvalidInput {
                arg: "weight".into(),
                index: Some(i),
                reason: "must be a number in [0, 1]".into(),
            });
        }
        let (stride, groups) = (a.stride, rotation_groups(self));
        let mut values = vec![0.0; a.frames * stride];
        values.par_chunks_mut(stride).enumerate().for_each(|(f, out)| {
            let w = weights[if weights.len() == 1 { 0 } else { f }];
            let (fa, fb) =
                (&a.values[f * stride..(f + 1) * stride], &b.values[f * stride..(f + 1) * stride]);
            mix(&groups, fa, fb, w, out);
        });
        Ok(Motion { values, stride, frames: a.frames, frame_rate: a.frame_rate })
    }

    /// `b` appended to `a`, moved so that it continues `a`: `b`'s root is turned about the
    /// vertical (+Y) and shifted horizontally so that its first frame has the heading and the
    /// ground position of `a`'s frame where the transition starts (its last frame when
    /// `transition` is 0); then the last `transition` frames
    /// of `a` are blended into the first of the moved `b` with a smooth ramp
    /// (`3s² - 2s³`), so the result has `a.frames + b.frames - transition` frames.
    ///
    /// # Errors
    /// Motions of another skeleton, a root without three translations and three rotations, a
    /// transition longer than either motion.
    fn stitch(&self, a: &Motion, b: &Motion, transition: usize) -> Result<Motion> {
        check(self, a, "a")?;
        check(self, b, "b")?;
        let Some((t, g, seq)) = root_channels(self) else {
            return Err(Error::invalid("skeleton", "the root needs tx ty tz and three rotations"));
        };
        if transition > a.frames.min(b.frames) {
            return Err(Error::invalid(
                "transition",
                format!("at most {} frames, got {transition}", a.frames.min(b.frames)),
            ));
        }
        let stride = a.stride;
        let frame = |m: &Motion, f: usize| m.values[f * stride..(f + 1) * stride].to_vec();
        let rotation = |v: &[f64]| seq.to_quat(&[v[g], v[g + 1], v[g + 2]]);
        let heading = |q: DQuat| {
            let f = q * glam::DVec3::Z;
            f.x.atan2(f.z)
        };
        // Align b's first frame with a's frame where the transition starts.
        let (end, start) = (frame(a, a.frames - transition.max(1)), frame(b, 0));
        let turn = DQuat::from_rotation_y(heading(rotation(&end)?) - heading(rotation(&start)?));
        let origin = glam::DVec3::new(start[t[0]], 0.0, start[t[2]]);
        let target = glam::DVec3::new(end[t[0]], 0.0, end[t[2]]);
        let mut moved = b.clone();
        for row in moved.values.chunks_mut(stride) {
            let p = glam::DVec3::new(row[t[0]], row[t[1]], row[t[2]]);
            let p = target + turn * (p - origin);
            row[t[0]] = p.x;
            row[t[2]] = p.z;
            let (angles, _) = seq.from_quat(turn * rotation(row)?);
            row[g..g + 3].copy_from_slice(&angles);
        }
        let frames = a.frames + b.frames - transition;
        let mut values = Vec::with_capacity(frames * stride);
        values.extend_from_slice(&a.values[..(a.frames - transition) * stride]);
        let groups = rotation_groups(self);
        let mut out = vec![0.0; stride];
        for k in 0..transition {
            let s = (k as f64 + 1.0) / (transition as f64 + 1.0);
            let w = s * s * (3.0 - 2.0 * s);
            let fa = frame(a, a.frames - transition + k);
            mix(&groups, &fa, &moved.values[k * stride..(k + 1) * stride], w, &mut out);
            values.extend_from_slice(&out);
        }
        values.extend_from_slice(&moved.values[transition * stride..]);
        Ok(Motion { values, stride, frames, frame_rate: a.frame_rate })
    }

    /// Motion warping: the motion plus a smooth displacement of every value that makes it
    /// pass through the key poses exactly, `keys` as `(frame, pose)`. The displacement
    /// (`pose - frame`, per value; rotation dofs as angle differences in radians, wrapped to
    /// `(-π, π]` so that an edit across the ±π seam takes the shorter turn) is known at
    /// the keys, zero at the first and the last frame unless they are keyed, and interpolated
    /// in between over the frame index by the monotone cubic of Fritsch & Carlson (1980; the
    /// tangents of scipy's `PchipInterpolator`): C1, never beyond its keys, and exactly zero
    /// between consecutive keys that leave a value unchanged, so an edit stays where it was
    /// keyed (a natural spline would ring into the rest of the motion). The motion keeps its
    /// own detail and bends smoothly towards the keys.
    ///
    /// # Errors
    /// A motion of another skeleton; no keys, a key frame out of range or repeated, a pose of
    /// the wrong length or with non-finite values.
    fn warp(&self, motion: &Motion, keys: &[(usize, Vec<f64>)]) -> Result<Motion> {
        check(self, motion, "motion")?;
        let stride = motion.stride;
        if keys.is_empty() {
            return Err(Error::invalid("keys", "need at least one key pose"));
        }
        let mut keys: Vec<&(usize, Vec<f64>)> = keys.iter().collect();
        keys.sort_by_key(|k| k.0);
        for (i, (f, pose)) in keys.iter().enumerate() {
            if *f >= motion.frames || (i > 0 && keys[i - 1].0 == *f) {
                return Err(Error::invalid(
                    "keys",
                    format!("frame {f} is out of range (0..{}) or keyed twice", motion.frames),
                ));
            }
            if pose.len() != stride || pose.iter().any(|v| !v.is_finite()) {
                return Err(Error::invalid(
                    "keys",
                    format!("the pose at frame {f} needs {stride} finite values"),
                ));
            }
        }
        let rotation: Vec<bool> = self
            .joint_dofs()
            .into_iter()
            .flatten()
            .map(|d| matches!(d, Dof::Rotation(_)))
            .collect();
        let (mut times, mut offsets) = (Vec::new(), Vec::new());
        let last = motion.frames - 1;
        if keys[0].0 != 0 {
            times.push(0.0);
            offsets.extend(std::iter::repeat_n(0.0, stride));
        }
        for (f, pose) in &keys {
            times.push(*f as f64);
            let row = &motion.values[f * stride..(f + 1) * stride];
            offsets.extend(pose.iter().zip(row).zip(&rotation).map(|((p, v), &r)| {
                if r {
                    wrap_angle(p - v)
                } else {
                    p - v
                }
            }));
        }
        if keys[keys.len() - 1].0 != last {
            times.push(last as f64);
            offsets.extend(std::iter::repeat_n(0.0, stride));
        }
        let tangents = pchip_slopes(&times, &offsets, stride);
        let track = Track::new(
            &times,
            &offsets,
            stride,
            Interpolation::Hermite { tangents },
            Extrapolation::Hold,
        )?;
        let mut values = motion.values.clone();
        values.par_chunks_mut(stride).enumerate().for_each(|(f, row)| {
            let mut d = vec![0.0; stride];
            track.eval(f as f64, 0, &mut d);
            row.iter_mut().zip(&d).for_each(|(v, d)| *v += d);
        });
        // Exact at the keys (the spline passes through them up to rounding), except where a
        // rotation's displacement was wrapped: there the key's angle plus the multiple of 2π
        // that keeps the value continuous with its neighbours.
        for (f, pose) in &keys {
            let row = &mut values[f * stride..(f + 1) * stride];
            let original = &motion.values[f * stride..(f + 1) * stride];
            for c in 0..stride {
                let d = pose[c] - original[c];
                row[c] = if !rotation[c] || wrap_angle(d) == d {
                    pose[c]
                } else {
                    original[c] + wrap_angle(d)
                };
            }
        }
        Ok(Motion { values, stride, frames: motion.frames, frame_rate: motion.frame_rate })
    }
}

/// Slopes of the monotone piecewise cubic through `(t_k, y_k)` per channel (`y` is
/// `n x dim`): Fritsch & Carlson's weighted harmonic mean of the neighbouring secants inside
/// (zero where they differ in sign), the shape-preserving three-point formula at the ends.
fn pchip_slopes(t: &[f64], y: &[f64], dim: usize) -> Vec<f64> {
    let n = t.len();
    let mut m = vec![0.0; n * dim];
    if n < 2 {
        return m;
    }
    let h: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    for c in 0..dim {
        let d: Vec<f64> =
            (0..n - 1).map(|k| (y[(k + 1) * dim + c] - y[k * dim + c]) / h[k]).collect();
        if n == 2 {
            m[c] = d[0];
            m[dim + c] = d[0];
            continue;
        }
        for k in 1..n - 1 {
            m[k * dim + c] = if d[k - 1] * d[k] <= 0.0 {
                0.0
            } else {
                let (w1, w2) = (2.0 * h[k] + h[k - 1], h[k] + 2.0 * h[k - 1]);
                (w1 + w2) / (w1 / d[k - 1] + w2 / d[k])
            };
        }
        let end = |h0: f64, h1: f64, d0: f64, d1: f64| {
            let s = ((2.0 * h0 + h1) * d0 - h0 * d1) / (h0 + h1);
            if s.signum() != d0.signum() || d0 == 0.0 {
                0.0
            } else if d0.signum() != d1.signum() && s.abs() > 3.0 * d0.abs() {
                3.0 * d0
            } else {
                s
            }
        };
        m[c] = end(h[0], h[1], d[0], d[1]);
        m[(n - 1) * dim + c] = end(h[n - 2], h[n - 3], d[n - 2], d[n - 3]);
    }
    m
}
