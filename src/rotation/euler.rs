//! Euler angles (intrinsic, upper case) and fixed angles (extrinsic, lower case) in all 12
//! axis sequences, to and from unit quaternions.
//!
//! An extrinsic sequence `ijk` with angles `(a, b, c)` rotates about the fixed world axes `i`,
//! then `j`, then `k`: `q = q_k(c) q_j(b) q_i(a)`. The intrinsic sequence `IJK` rotates about
//! the moving body axes and equals `q_i(a) q_j(b) q_k(c)`, so `XYZ` with `(a, b, c)` is `zyx`
//! with `(c, b, a)`.
//!
//! Quaternion to angles follows Bernardes & Viollet 2022 ("Quaternion to Euler angles
//! conversion: a direct, general and computationally efficient method", PLOS ONE 17(11)):
//! a Tait–Bryan sequence `ijk` is turned into the proper sequence `iji` by the change of frame
//! `q' = q_j(pi/2) q`, and for a proper sequence `q = (a, b, c, d)` rearranged so that
//! `a = cos(β/2) cos(θ+)`, `b = cos(β/2) sin(θ+)`, `c = sin(β/2) cos(θ-)`,
//! `d = sin(β/2) sin(θ-)`; then `β = 2 atan2(|(c, d)|, |(a, b)|)` and the outer angles are
//! `θ+ ∓ θ-` with `θ+ = atan2(b, a)`, `θ- = atan2(d, c)`. Only `atan2` and square roots of sums
//! of squares are used, so no input yields NaN and the accuracy is uniform up to the singularity.
//!
//! At gimbal lock (the middle angle within [`GIMBAL_LOCK_TOL`] of its singular value) only the
//! sum or the difference of the outer angles is defined; the third angle is set to 0 and the
//! first carries the rest, and the lock is reported to the caller.

use super::quat::quat_from_wxyz;
use super::trig::atan2_finite;
use crate::batch::{lanes, LaneKernel, Output, LANES};
use crate::error::{ensure_finite, Error, Result};
use crate::math::wrap_angle;
use glam::{DQuat, DVec3};
use std::f64::consts::{FRAC_PI_2, PI};

/// Distance (radians) of the middle angle from its singular value within which a
/// decomposition is treated as gimbal-locked.
///
/// Collapsing onto "third angle = 0" changes the rotation by up to about this angle, so the
/// tolerance sits just above the rounding noise of quaternions built exactly at lock (below
/// 1e-15) and no higher: every decomposition reproduces its rotation to ~1e-14 or better.
/// Farther from lock the general formula is used; its outer angles are individually
/// ill-conditioned there, but they always reproduce the rotation.
pub const GIMBAL_LOCK_TOL: f64 = 1e-14;

/// A parsed Euler-angle sequence such as `"XYZ"` (intrinsic) or `"zxz"` (extrinsic).
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub struct EulerSequence {
    /// Axis indices (0 = x, 1 = y, 2 = z) in the order written.
    pub axes: [usize; 3],
    /// Upper case: rotations about the moving body axes.
    pub intrinsic: bool,
}

fn unit(axis: usize) -> DVec3 {
    DVec3::AXES[axis]
}

fn elementary(axis: usize, angle: f64) -> DQuat {
    let (s, c) = (0.5 * angle).sin_cos();
    let v = unit(axis) * s;
    DQuat::from_xyzw(v.x, v.y, v.z, c)
}

impl EulerSequence {
    /// Parse a 3-letter sequence over `x y z`, all upper case (intrinsic) or all lower case
    /// (extrinsic), with no axis repeated next to itself: the 6 Tait–Bryan (`xyz`, ...) and
    /// 6 proper Euler (`zxz`, ...) sequences.
    ///
    /// # Errors
    /// Anything else, with the offending string in the message.
    pub fn parse(seq: &str) -> Result<Self> {
        let bad = |why: &str| Error::invalid("seq", format!("{seq:?} {why}"));
        let chars: Vec<char> = seq.chars().collect();
        if chars.len() != 3 {
            return Err(bad("must have exactly 3 letters from x, y, z"));
        }
        let intrinsic = chars.iter().all(|c| c.is_ascii_uppercase());
        if !intrinsic && !chars.iter().all(|c| c.is_ascii_lowercase()) {
            return Err(bad("mixes upper case (intrinsic) and lower case (extrinsic)"));
        }
        let mut axes = [0; 3];
        for (a, c) in axes.iter_mut().zip(&chars) {
            *a = match c.to_ascii_lowercase() {
                'x' => 0,
                'y' => 1,
                'z' => 2,
                _ => return Err(bad("must have exactly 3 letters from x, y, z")),
            };
        }
        if axes[0] == axes[1] || axes[1] == axes[2] {
            return Err(bad("repeats an axis in consecutive positions"));
        }
        Ok(EulerSequence { axes, intrinsic })
    }

    /// Proper Euler (`zxz`-like, first axis = last axis) rather than Tait–Bryan.
    pub fn is_proper(&self) -> bool {
        self.axes[0] == self.axes[2]
    }

    /// Unit quaternion of the rotation given by `angles` (radians) in this sequence.
    ///
    /// # Errors
    /// Non-finite angles.
    pub fn to_quat(&self, angles: &[f64; 3]) -> Result<DQuat> {
        ensure_finite("angles", angles)?;
        let [a, b, c] = *angles;
        let [i, j, k] = self.axes;
        let q = if self.intrinsic {
            elementary(i, a) * elementary(j, b) * elementary(k, c)
        } else {
            elementary(k, c) * elementary(j, b) * elementary(i, a)
        };
        Ok(q.normalize())
    }

    /// Angles (radians) of unit quaternion `q` in this sequence and whether the decomposition
    /// is gimbal-locked.
    ///
    /// Ranges: first and third angle in `(-pi, pi]`; the middle one in `[-pi/2, pi/2]` for
    /// Tait–Bryan sequences and in `[0, pi]` for proper Euler sequences.
    pub fn from_quat(&self, q: DQuat) -> ([f64; 3], bool) {
        let l = self.layout();
        let [a, b, c, d] = l.reduce(q.w, [q.x, q.y, q.z]);
        let [beta, plus, minus] = half_angles(a, b, c, d);
        let low = beta <= GIMBAL_LOCK_TOL;
        let high = beta >= PI - GIMBAL_LOCK_TOL;
        // first: angle about i (applied first); last: angle about k in the proper frame.
        let (first, last) = match (low, high, self.intrinsic) {
            (false, false, _) => return (l.angles(beta, plus - minus, plus + minus), false),
            // Locked: the output's third angle is zero. Extrinsic output is (first, β, last),
            // intrinsic output is (last, β, first).
            (true, _, false) => (2.0 * plus, 0.0),
            (_, true, false) => (-2.0 * minus, 0.0),
            (true, _, true) => (0.0, 2.0 * plus),
            (_, true, true) => (0.0, 2.0 * minus),
        };
        (l.angles(beta, first, last), true)
    }

    /// [`Self::from_quat`] of every quaternion `(w, x, y, z)` of `quats` (normalised as
    /// [`quat_from_wxyz`] does) into `out`, in parallel; returns how many are gimbal-locked.
    /// Bitwise the same as row by row: blocks of unit quaternions far from lock run the same
    /// arithmetic lane by lane, which compiles to SIMD (the branch-free `atan2` of `trig`;
    /// AVX2 or AVX-512 where the CPU has it, chosen at run time by `pulp`), any other block row by row.
    ///
    /// # Errors
    /// The lowest row that is zero or not finite, or `out` of another length.
    pub fn from_quats(
        &self,
        quats: &[[f64; 4]],
        out: &mut (impl Output<3> + ?Sized),
    ) -> Result<usize> {
        lanes(quats, out, &ToEuler { seq: self, l: self.layout() })
    }

    /// The axes of the sequence in the order the reduction needs them.
    #[inline(always)]
    fn layout(&self) -> Layout {
        // Work with the extrinsic order of application: first about i, then j, last about k.
        let [i, j, k] =
            if self.intrinsic { [self.axes[2], self.axes[1], self.axes[0]] } else { self.axes };
        Layout {
            i,
            j,
            m: 3 - i - j, // the axis that is neither i nor j
            proper: i == k,
            parity: if j == (i + 1) % 3 { 1.0 } else { -1.0 }, // e_i × e_j = parity e_m
            intrinsic: self.intrinsic,
        }
    }

    /// Whether `angles` in this sequence are at gimbal lock, where the first and third axes
    /// coincide: the middle angle at ±pi/2 (Tait–Bryan) or at 0 or pi (proper Euler), within
    /// `atol`. The distance is measured as `|cos β|` (Tait–Bryan) or `|sin β|` (proper), which
    /// equals the angular distance to the nearest singular value to first order.
    pub fn is_gimbal_locked(&self, angles: &[f64; 3], atol: f64) -> bool {
        let b = angles[1];
        let distance = if self.is_proper() { b.sin().abs() } else { b.cos().abs() };
        distance <= atol
    }
}

/// The lane kernel of [`EulerSequence::from_quats`].
struct ToEuler<'a> {
    seq: &'a EulerSequence,
    l: Layout,
}

impl LaneKernel<4, 3> for ToEuler<'_> {
    #[inline(always)]
    fn block<S: pulp::Simd>(
        &self,
        _: S,
        first: usize,
        qs: &[[f64; 4]],
        os: &mut [[f64; 3]],
    ) -> Result<usize> {
        let mut locked = 0;
        let mut fast = qs.len() == LANES;
        let mut h = [[0.0; LANES]; 3];
        if fast {
            // Lanes: unit quaternions (as quat_from_wxyz takes them unchanged) far from
            // lock. The reduction gathers by axis; the half angles are pure arithmetic
            // over contiguous lanes, the part that vectorises.
            let (mut r, mut n2) = ([[0.0; LANES]; 4], [0.0; LANES]);
            for (k, q) in qs.iter().enumerate() {
                n2[k] = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
                [r[0][k], r[1][k], r[2][k], r[3][k]] = self.l.reduce(q[0], [q[1], q[2], q[3]]);
            }
            for k in 0..LANES {
                [h[0][k], h[1][k], h[2][k]] = half_angles(r[0][k], r[1][k], r[2][k], r[3][k]);
            }
            fast = (0..LANES).all(|k| {
                (n2[k] - 1.0).abs() <= 4.0 * f64::EPSILON
                    && h[0][k] > GIMBAL_LOCK_TOL
                    && h[0][k] < PI - GIMBAL_LOCK_TOL
            });
        }
        if fast {
            for (k, o) in os.iter_mut().enumerate() {
                let (beta, plus, minus) = (h[0][k], h[1][k], h[2][k]);
                *o = self.l.angles(beta, plus - minus, plus + minus);
            }
        } else {
            for (k, (q, o)) in qs.iter().zip(os.iter_mut()).enumerate() {
                let q = quat_from_wxyz(q).map_err(|e| e.at(first + k))?;
                let (angles, lock) = self.seq.from_quat(q);
                *o = angles;
                locked += usize::from(lock);
            }
        }
        Ok(locked)
    }
}

/// A sequence's axes as the reduction of Bernardes & Viollet uses them.
#[derive(Clone, Copy)]
struct Layout {
    i: usize,
    j: usize,
    m: usize,
    proper: bool,
    parity: f64,
    intrinsic: bool,
}

impl Layout {
    /// `(a, b, c, d)` of the equivalent proper sequence `iji` from the quaternion `w, v`.
    #[inline(always)]
    fn reduce(&self, w: f64, v: [f64; 3]) -> [f64; 4] {
        let (i, j, m, p) = (self.i, self.j, self.m, self.parity);
        if self.proper {
            [w, v[i], v[j], p * v[m]]
        } else {
            // q' = (1 + e_j) q ∝ q_j(pi/2) q turns ijk into the proper sequence iji.
            [w - v[j], v[i] + p * v[m], v[j] + w, p * v[m] - v[i]]
        }
    }

    /// The output angles from the middle angle and the first and last of the proper frame.
    #[inline(always)]
    fn angles(&self, beta: f64, first: f64, last: f64) -> [f64; 3] {
        let (last, beta) =
            if self.proper { (last, beta) } else { (self.parity * last, beta - FRAC_PI_2) };
        let (first, last) = (wrap_angle(first), wrap_angle(last));
        if self.intrinsic {
            [last, beta, first]
        } else {
            [first, beta, last]
        }
    }
}

/// `β`, `θ₊ = atan2(b, a)` and `θ₋ = atan2(d, c)` of the reduced quaternion.
#[inline(always)]
fn half_angles(a: f64, b: f64, c: f64, d: f64) -> [f64; 3] {
    // |q| <= sqrt(2) here, so the plain norms cannot overflow; an underflow to 0 changes β
    // by less than 1e-150.
    let beta = 2.0 * atan2_finite((c * c + d * d).sqrt(), (a * a + b * b).sqrt());
    [beta, atan2_finite(b, a), atan2_finite(d, c)]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_accepts_the_24_sequences_only() {
        let mut n = 0;
        for s in ["x", "y", "z"].iter().flat_map(|a| {
            ["x", "y", "z"]
                .iter()
                .flat_map(move |b| ["x", "y", "z"].iter().map(move |c| format!("{a}{b}{c}")))
        }) {
            let ok = EulerSequence::parse(&s).is_ok();
            assert_eq!(ok, EulerSequence::parse(&s.to_uppercase()).is_ok());
            n += usize::from(ok);
        }
        assert_eq!(n, 12);
        assert!(EulerSequence::parse("xYz").is_err());
        assert!(EulerSequence::parse("xyzx").is_err());
        assert!(EulerSequence::parse("abc").is_err());
    }
}
