//! Orientation tracks: keys of unit quaternions interpolated by slerp (Shoemake 1985) or
//! squad (Shoemake 1987, "Quaternion calculus and fast animation", SIGGRAPH course notes).

use crate::error::{Error, Result};
use crate::rotation::{quat_from_rotvec, quat_from_wxyz, quat_to_rotvec, quat_to_wxyz, slerp};
use glam::{DQuat, DVec3};
use rayon::prelude::*;

/// How an orientation track interpolates between keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RotationInterpolation {
    /// Great-arc interpolation per segment: constant angular velocity, C0 at keys.
    Slerp,
    /// Spherical quadrangle interpolation with Shoemake's inner quadrangle points
    /// `s_i = q_i exp(-(log(q_i⁻¹ q_{i+1}) + log(q_i⁻¹ q_{i-1}))/4)`: C1 for equally spaced
    /// keys (the formula uses the segment parameter, not time).
    Squad,
}

/// A keyframed orientation (keys held outside the key range).
#[derive(Clone, Debug)]
pub struct RotationTrack {
    times: Vec<f64>,
    keys: Vec<DQuat>,
    inner: Vec<DQuat>,
    mode: RotationInterpolation,
}

fn log(q: DQuat) -> DVec3 {
    DVec3::from_array(quat_to_rotvec(q)) * 0.5
}

fn exp(v: DVec3) -> DQuat {
    quat_from_rotvec(&(2.0 * v).to_array()).expect("finite rotation vector")
}

impl RotationTrack {
    /// Keys `quats` (`(w, x, y, z)` per key, normalised here) at strictly increasing `times`.
    /// Consecutive keys are sign-aligned so every segment takes the shorter arc.
    ///
    /// # Errors
    /// No keys, bad times (named by index), zero or non-finite quaternions.
    pub fn new(times: &[f64], quats: &[[f64; 4]], mode: RotationInterpolation) -> Result<Self> {
        if times.is_empty() || times.len() != quats.len() {
            return Err(Error::invalid(
                "rotations",
                "need one rotation per key time and at least one key",
            ));
        }
        super::track::check_times(times)?;
        let mut keys = Vec::with_capacity(quats.len());
        for (i, q) in quats.iter().enumerate() {
            let mut q = quat_from_wxyz(q).map_err(|e| e.at(i))?;
            if let Some(prev) = keys.last() {
                if q.dot(*prev) < 0.0 {
                    q = -q;
                }
            }
            keys.push(q);
        }
        let n = keys.len();
        let inner = (0..n)
            .map(|i| {
                if i == 0 || i == n - 1 {
                    return keys[i];
                }
                let qi = keys[i];
                let a = log(qi.conjugate() * keys[i + 1]);
                let b = log(qi.conjugate() * keys[i - 1]);
                (qi * exp(-(a + b) / 4.0)).normalize()
            })
            .collect();
        Ok(RotationTrack { times: times.to_vec(), keys, inner, mode })
    }

    /// The orientation at time `t`.
    pub fn eval(&self, t: f64) -> DQuat {
        let n = self.times.len();
        if n == 1 || t <= self.times[0] {
            return self.keys[0];
        }
        if t >= self.times[n - 1] {
            return self.keys[n - 1];
        }
        let k = (self.times.partition_point(|&x| x <= t) - 1).min(n - 2);
        let s = (t - self.times[k]) / (self.times[k + 1] - self.times[k]);
        let (q0, q1) = (self.keys[k], self.keys[k + 1]);
        match self.mode {
            RotationInterpolation::Slerp => slerp(q0, q1, s, true),
            RotationInterpolation::Squad => {
                let a = slerp(q0, q1, s, false);
                let b = slerp(self.inner[k], self.inner[k + 1], s, false);
                slerp(a, b, 2.0 * s * (1.0 - s), false)
            }
        }
    }

    /// Angular velocity (rad/s, world frame) at time `t`: exact per segment for slerp, by a
    /// central difference of step `1e-6` of the segment for squad.
    pub fn angular_velocity(&self, t: f64) -> DVec3 {
        let n = self.times.len();
        if n == 1 || t < self.times[0] || t > self.times[n - 1] {
            return DVec3::ZERO;
        }
        let k = (self.times.partition_point(|&x| x <= t).max(1) - 1).min(n - 2);
        let h = self.times[k + 1] - self.times[k];
        match self.mode {
            RotationInterpolation::Slerp => {
                let rel = self.keys[k].conjugate() * self.keys[k + 1];
                let body = DVec3::from_array(quat_to_rotvec(rel)) / h;
                self.eval(t) * body
            }
            RotationInterpolation::Squad => {
                let e = 1e-6 * h;
                let (a, b) = ((t - e).max(self.times[k]), (t + e).min(self.times[k + 1]));
                let rel = self.eval(b) * self.eval(a).conjugate();
                DVec3::from_array(quat_to_rotvec(rel)) / (b - a)
            }
        }
    }

    /// Orientations `(w, x, y, z)` at every time of `ts`, in parallel.
    ///
    /// # Errors
    /// A non-finite time, named by its index.
    pub fn eval_many(&self, ts: &[f64], out: &mut [[f64; 4]]) -> Result<()> {
        if let Some(i) = ts.iter().position(|t| !t.is_finite()) {
            return Err(Error::InvalidInput {
                arg: "t".into(),
                index: Some(i),
                reason: "is NaN or infinite".into(),
            });
        }
        out.par_iter_mut().zip(ts.par_iter()).for_each(|(o, &t)| *o = quat_to_wxyz(self.eval(t)));
        Ok(())
    }
}
