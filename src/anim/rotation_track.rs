//! Orientation tracks: keys of unit quaternions interpolated by slerp (Shoemake 1985),
//! squad (Shoemake 1987, "Quaternion calculus and fast animation", SIGGRAPH course notes) or
//! the C2 rotation spline (Sander 2015; see `rotation_spline`).
//!
//! Each segment turns along the arc its keys choose: the shorter one by default, the longer
//! one (more than pi radians) where the caller asks. The choice is made once, by the sign of
//! each key relative to the one before, so every scheme follows it.

use super::rotation_spline::{nonlinear_term, right_jacobian, spline_segments};
use crate::error::{Error, Result};
use crate::rotation::{quat_from_rotvec, quat_from_wxyz, quat_to_wxyz, slerp};
use glam::{DQuat, DVec3};
use rayon::prelude::*;

/// How an orientation track interpolates between keys.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq, Eq)]
pub enum RotationInterpolation {
    /// Great-arc interpolation per segment: constant angular velocity, C0 at keys.
    Slerp,
    /// Spherical quadrangle interpolation with Shoemake's inner quadrangle points
    /// `s_i = q_i exp(-(log(q_i⁻¹ q_{i+1}) + log(q_i⁻¹ q_{i-1}))/4)`: C1 for equally spaced
    /// keys (the formula uses the segment parameter, not time).
    Squad,
    /// C2 rotation spline: the angular velocity and angular acceleration are continuous at
    /// the keys (Sander 2015, as scipy's `RotationSpline`).
    Spline,
}

impl RotationInterpolation {
    /// Parse `"slerp" | "squad" | "spline"`.
    ///
    /// # Errors
    /// Any other name.
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "slerp" => Ok(Self::Slerp),
            "squad" => Ok(Self::Squad),
            "spline" => Ok(Self::Spline),
            _ => Err(Error::invalid(
                "interpolation",
                format!("{name:?} is not one of slerp, squad, spline"),
            )),
        }
    }
}

/// A keyframed orientation (keys held outside the key range).
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub struct RotationTrack {
    times: Vec<f64>,
    keys: Vec<DQuat>,
    /// Squad's inner quadrangle points (empty for the other schemes).
    inner: Vec<DQuat>,
    /// The spline's rotation-vector cubic `[c, b, a]` per segment (empty otherwise).
    cubic: Vec<[DVec3; 3]>,
    mode: RotationInterpolation,
}

/// Rotation vector of `q` taken as given, angle `2 atan2(|u|, w)` in `[0, 2 pi]` (not
/// canonicalised, so a segment keeps the arc its keys chose).
fn rotvec_as_given(q: DQuat) -> DVec3 {
    let u = q.xyz();
    let s = u.length();
    let half = s.atan2(q.w);
    if s > 0.0 {
        u * (2.0 * half / s)
    } else if q.w < 0.0 {
        DVec3::new(2.0 * std::f64::consts::PI, 0.0, 0.0)
    } else {
        DVec3::ZERO
    }
}

fn log(q: DQuat) -> DVec3 {
    rotvec_as_given(q) * 0.5
}

fn exp(v: DVec3) -> DQuat {
    quat_from_rotvec(&(2.0 * v).to_array()).expect("finite rotation vector")
}

impl RotationTrack {
    /// Keys `quats` (`(w, x, y, z)` per key, normalised here) at strictly increasing `times`.
    /// Segment `k` (from key `k` to `k + 1`) takes the shorter arc unless `shortest[k]` is
    /// false; an empty `shortest` means shorter arcs everywhere.
    ///
    /// # Errors
    /// No keys, bad times (named by index), zero or non-finite quaternions, a `shortest` of
    /// the wrong length, a spline whose keys turn too far within one segment.
    pub fn new(
        times: &[f64],
        quats: &[[f64; 4]],
        mode: RotationInterpolation,
        shortest: &[bool],
    ) -> Result<Self> {
        if times.is_empty() || times.len() != quats.len() {
            return Err(Error::invalid(
                "rotations",
                "need one rotation per key time and at least one key",
            ));
        }
        let n = times.len();
        if !shortest.is_empty() && shortest.len() != n - 1 {
            return Err(Error::invalid(
                "shortest",
                format!("expected one flag per segment ({}), got {}", n - 1, shortest.len()),
            ));
        }
        crate::spline::check_times(times)?;
        let mut keys: Vec<DQuat> = Vec::with_capacity(n);
        for (i, q) in quats.iter().enumerate() {
            let mut q = quat_from_wxyz(q).map_err(|e| e.at(i))?;
            if let Some(prev) = keys.last() {
                let short = shortest.get(i - 1).copied().unwrap_or(true);
                if (q.dot(*prev) < 0.0) == short {
                    q = -q;
                }
            }
            keys.push(q);
        }
        let inner = match mode {
            RotationInterpolation::Squad => (0..n)
                .map(|i| {
                    if i == 0 || i == n - 1 {
                        return keys[i];
                    }
                    let qi = keys[i];
                    let a = log(qi.conjugate() * keys[i + 1]);
                    let b = log(qi.conjugate() * keys[i - 1]);
                    (qi * exp(-(a + b) / 4.0)).normalize()
                })
                .collect(),
            _ => Vec::new(),
        };
        let cubic = match mode {
            RotationInterpolation::Spline if n > 1 => {
                let phi: Vec<DVec3> =
                    keys.windows(2).map(|w| rotvec_as_given(w[0].conjugate() * w[1])).collect();
                let h: Vec<f64> = times.windows(2).map(|w| w[1] - w[0]).collect();
                spline_segments(&phi, &h)?
            }
            _ => Vec::new(),
        };
        Ok(RotationTrack { times: times.to_vec(), keys, inner, cubic, mode })
    }

    /// Segment index and local time `τ = t - t_k` of a time inside the key range.
    fn segment(&self, t: f64) -> (usize, f64) {
        let n = self.times.len();
        let k = (self.times.partition_point(|&x| x <= t).max(1) - 1).min(n - 2);
        (k, t - self.times[k])
    }

    /// Segment, local time and segment duration of a time within the keys (none outside
    /// them or for a single key, where the orientation is held).
    fn inside(&self, t: f64) -> Option<(usize, f64, f64)> {
        let n = self.times.len();
        if n == 1 || t < self.times[0] || t > self.times[n - 1] {
            return None;
        }
        let (k, tau) = self.segment(t);
        Some((k, tau, self.times[k + 1] - self.times[k]))
    }

    /// The spline's rotation vector and its first two derivatives on segment `k` at `τ`.
    fn spline_at(&self, k: usize, tau: f64) -> [DVec3; 3] {
        let [c, b, a] = self.cubic[k];
        [
            ((a * tau + b) * tau + c) * tau,
            (3.0 * a * tau + 2.0 * b) * tau + c,
            6.0 * a * tau + 2.0 * b,
        ]
    }

    /// Key times (s).
    pub fn times(&self) -> &[f64] {
        &self.times
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
        let (k, tau) = self.segment(t);
        let s = tau / (self.times[k + 1] - self.times[k]);
        let (q0, q1) = (self.keys[k], self.keys[k + 1]);
        match self.mode {
            RotationInterpolation::Slerp => slerp(q0, q1, s, false),
            RotationInterpolation::Squad => {
                let a = slerp(q0, q1, s, false);
                let b = slerp(self.inner[k], self.inner[k + 1], s, false);
                slerp(a, b, 2.0 * s * (1.0 - s), false)
            }
            RotationInterpolation::Spline => {
                (q0 * exp(0.5 * self.spline_at(k, tau)[0])).normalize()
            }
        }
    }

    /// Angular velocity (rad/s, world frame) at time `t`, exact (differentiated in closed
    /// form through the exponential map's right Jacobian for the spline and squad). Zero
    /// outside the keys.
    pub fn angular_velocity(&self, t: f64) -> DVec3 {
        let Some((k, tau, h)) = self.inside(t) else {
            return DVec3::ZERO;
        };
        match self.mode {
            RotationInterpolation::Slerp => {
                let rel = self.keys[k].conjugate() * self.keys[k + 1];
                self.eval(t) * (rotvec_as_given(rel) / h)
            }
            RotationInterpolation::Squad => {
                // q = slerp(a, b, u) = a Exp(u λ), a = q_k Exp(s φ_a), b = s_k Exp(s φ_b),
                // λ = Log(a* b), u = 2s(1 - s), s = τ/h. Body rates per unit s:
                // Ω = R_Eᵀ φ_a + J_r(uλ) (u' λ + u λ'), λ' = J_r(λ)⁻¹ (φ_b − R_Cᵀ φ_a).
                let s = tau / h;
                let (q0, q1) = (self.keys[k], self.keys[k + 1]);
                let (p0, p1) = (self.inner[k], self.inner[k + 1]);
                let (phi_a, phi_b) =
                    (rotvec_as_given(q0.conjugate() * q1), rotvec_as_given(p0.conjugate() * p1));
                let c = slerp(q0, q1, s, false).conjugate() * slerp(p0, p1, s, false);
                let lambda = rotvec_as_given(c);
                let lambda_dot = right_jacobian(lambda).inverse() * (phi_b - c.conjugate() * phi_a);
                let (u, du) = (2.0 * s * (1.0 - s), 2.0 - 4.0 * s);
                let e = exp(0.5 * u * lambda);
                let body = e.conjugate() * phi_a
                    + right_jacobian(u * lambda) * (du * lambda + u * lambda_dot);
                self.eval(t) * (body / h)
            }
            RotationInterpolation::Spline => {
                let [theta, theta_dot, _] = self.spline_at(k, tau);
                self.eval(t) * (right_jacobian(theta) * theta_dot)
            }
        }
    }

    /// Angular acceleration (rad/s², world frame) at time `t`: zero inside a slerp segment,
    /// exact for the spline (`J_r θ̈ + d/dt(J_r) θ̇`, rotated to the world), by a central
    /// difference of the angular velocity for squad. Zero outside the keys.
    pub fn angular_acceleration(&self, t: f64) -> DVec3 {
        let Some((k, tau, h)) = self.inside(t) else {
            return DVec3::ZERO;
        };
        match self.mode {
            RotationInterpolation::Slerp => DVec3::ZERO,
            RotationInterpolation::Squad => {
                let e = 1e-4 * h;
                let (a, b) = ((t - e).max(self.times[k]), (t + e).min(self.times[k + 1]));
                (self.angular_velocity(b) - self.angular_velocity(a)) / (b - a)
            }
            RotationInterpolation::Spline => {
                let [theta, theta_dot, theta_ddot] = self.spline_at(k, tau);
                let body = right_jacobian(theta) * theta_ddot + nonlinear_term(theta, theta_dot);
                self.eval(t) * body
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

    /// Angular velocity (`order` 1) or acceleration (`order` 2), rad/s or rad/s² in the world
    /// frame, at every time of `ts`, in parallel.
    ///
    /// # Errors
    /// A non-finite time (named by its index), an order other than 1 or 2.
    pub fn rates_many(&self, ts: &[f64], order: usize, out: &mut [[f64; 3]]) -> Result<()> {
        if !(1..=2).contains(&order) {
            return Err(Error::invalid("order", format!("expected 1 or 2, got {order}")));
        }
        if let Some(i) = ts.iter().position(|t| !t.is_finite()) {
            return Err(Error::InvalidInput {
                arg: "t".into(),
                index: Some(i),
                reason: "is NaN or infinite".into(),
            });
        }
        out.par_iter_mut().zip(ts.par_iter()).for_each(|(o, &t)| {
            let w =
                if order == 1 { self.angular_velocity(t) } else { self.angular_acceleration(t) };
            *o = w.to_array();
        });
        Ok(())
    }
}

impl crate::snapshot::Snapshot for RotationTrack {
    const TAG: &'static str = "RotationTrack";

    /// Key times finite and strictly increasing, one unit key per time, Squad's inner points
    /// (one per key) and the spline's cubics (one per segment) present exactly for their
    /// scheme, every value finite.
    fn validate(&self) -> Result<()> {
        use crate::snapshot::{check, finite};
        let n = self.times.len();
        let unit = |q: &DQuat| q.is_finite() && (q.length() - 1.0).abs() < 1e-6;
        check(n > 0 && self.keys.len() == n, "times", || "one key per time".into())?;
        check(
            finite(self.times.iter().copied()) && self.times.windows(2).all(|w| w[0] < w[1]),
            "times",
            || "must be finite and strictly increasing".into(),
        )?;
        let squad = self.mode == RotationInterpolation::Squad;
        let spline = self.mode == RotationInterpolation::Spline && n > 1;
        check(
            self.keys.iter().chain(&self.inner).all(unit)
                && self.inner.len() == if squad { n } else { 0 }
                && self.cubic.len() == if spline { n - 1 } else { 0 }
                && finite(self.cubic.iter().flatten().flat_map(|v| v.to_array())),
            "keys",
            || "keys, inner points or cubics inconsistent with the scheme".into(),
        )
    }
}
