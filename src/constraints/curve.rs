//! Parametric curves `x(u)` for beads on wires: the [`crate::constraints::Constraint::OnCurve`]
//! constraint and the reduced-coordinate [`crate::constraints::ReducedBead`].
//!
//! Every curve gives its point and first two derivatives in its parameter `u`, and finds the
//! closest point to a position by Newton's method on `f(u) = x'(u) · (x(u) - p) = 0`, started
//! from a guess (the parameter tracked from the previous step).

use super::{at_particle, Constraint};
use crate::error::{Error, Result};
use crate::spline::Track;
use glam::DVec3;
use std::f64::consts::TAU;

/// Newton iterations of the closest-point search, at most.
const CLOSEST_ITERATIONS: usize = 50;

/// A parametric curve `x(u)` in world space (m).
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub enum Curve {
    /// The straight line `x(u) = point + u direction` (`u` in metres along the unit
    /// direction; the line is unbounded).
    Line {
        /// A point of the line (m).
        point: DVec3,
        /// Direction (normalised by [`Curve::checked`]).
        direction: DVec3,
    },
    /// The circle `x(u) = center + radius (cos u e₁ + sin u e₂)`, `u` the angle (rad) about
    /// `normal` from `e₁`; `e₁` is the unit projection of +X on the circle's plane (of +Y when
    /// `normal` is along X) and `e₂ = normal × e₁`. With `normal = +Z`, `u` runs from +X to +Y.
    Circle {
        /// Centre (m).
        center: DVec3,
        /// Unit normal of the plane (normalised by [`Curve::checked`]).
        normal: DVec3,
        /// Radius (m) > 0.
        radius: f64,
    },
    /// The helix `x(u) = center + radius (cos u e₁ + sin u e₂) + pitch u / (2π) axis`, `u` the
    /// angle (rad); `e₁`, `e₂` as for [`Curve::Circle`] with `axis` as the normal. One turn
    /// rises by `pitch` (m; negative turns the other way up).
    Helix {
        /// A point of the axis (m), the centre of the turn at `u = 0`.
        center: DVec3,
        /// Unit axis (normalised by [`Curve::checked`]).
        axis: DVec3,
        /// Radius (m) > 0.
        radius: f64,
        /// Rise per turn (m), non-zero.
        pitch: f64,
    },
    /// A keyframed 3-channel [`Track`] (spline), `u` its time parameter; the curve is `C¹` or
    /// smoother where the scheme is (Catmull–Rom, cubic splines, B-splines). Outside the key
    /// range it follows the track's extrapolation: use `linear` (the wire continues straight)
    /// or `cycle` (a closed loop) — `hold` stops the parameter and fails there.
    Track(Track),
}

/// Unit vectors `e₁`, `e₂` spanning the plane normal to the unit `n`.
fn plane_basis(n: DVec3) -> (DVec3, DVec3) {
    let reference = if n.x.abs() > 0.9 { DVec3::Y } else { DVec3::X };
    let e1 = (reference - reference.dot(n) * n).normalize();
    (e1, n.cross(e1))
}

impl Curve {
    /// The curve with its directions normalised, or an error for degenerate parameters.
    ///
    /// # Errors
    /// Non-finite values, zero directions, non-positive radii, a zero pitch, or a track with
    /// fewer than two keys or another width than 3.
    pub fn checked(self) -> Result<Curve> {
        let unit = |v: DVec3, arg: &str| {
            if v.is_finite() && v.length() > 0.0 {
                Ok(v.normalize())
            } else {
                Err(Error::invalid(arg, "must be a finite non-zero vector"))
            }
        };
        let point = |v: DVec3, arg: &str| {
            if v.is_finite() {
                Ok(v)
            } else {
                Err(Error::invalid(arg, "contains NaN or infinity"))
            }
        };
        let radius = |r: f64| {
            if r.is_finite() && r > 0.0 {
                Ok(r)
            } else {
                Err(Error::invalid("radius", format!("must be positive and finite, got {r}")))
            }
        };
        Ok(match self {
            Curve::Line { point: p, direction } => {
                Curve::Line { point: point(p, "point")?, direction: unit(direction, "direction")? }
            }
            Curve::Circle { center, normal, radius: r } => Curve::Circle {
                center: point(center, "center")?,
                normal: unit(normal, "normal")?,
                radius: radius(r)?,
            },
            Curve::Helix { center, axis, radius: r, pitch } => {
                if !(pitch.is_finite() && pitch != 0.0) {
                    return Err(Error::invalid(
                        "pitch",
                        format!("must be finite and non-zero, got {pitch}"),
                    ));
                }
                Curve::Helix {
                    center: point(center, "center")?,
                    axis: unit(axis, "axis")?,
                    radius: radius(r)?,
                    pitch,
                }
            }
            Curve::Track(track) => {
                if track.dim() != 3 || track.times().len() < 2 {
                    return Err(Error::invalid(
                        "curve",
                        format!(
                            "a track curve needs 3 channels and at least 2 keys, got {} and {}",
                            track.dim(),
                            track.times().len()
                        ),
                    ));
                }
                Curve::Track(track)
            }
        })
    }

    /// `x(u)`, `x'(u)` and `x''(u)` (m, m per unit of `u`, ...).
    pub fn eval(&self, u: f64) -> [DVec3; 3] {
        match self {
            Curve::Line { point, direction } => [*point + u * *direction, *direction, DVec3::ZERO],
            Curve::Circle { center, normal, radius } => {
                let (e1, e2) = plane_basis(*normal);
                let (s, c) = u.sin_cos();
                let r = *radius * (c * e1 + s * e2);
                let dr = *radius * (c * e2 - s * e1);
                [*center + r, dr, -r]
            }
            Curve::Helix { center, axis, radius, pitch } => {
                let (e1, e2) = plane_basis(*axis);
                let (s, c) = u.sin_cos();
                let r = *radius * (c * e1 + s * e2);
                let dr = *radius * (c * e2 - s * e1);
                let rise = *pitch / TAU * *axis;
                [*center + r + u * rise, dr + rise, -r]
            }
            Curve::Track(track) => {
                let mut out = [DVec3::ZERO; 3];
                let mut v = [0.0; 3];
                for (order, o) in out.iter_mut().enumerate() {
                    track.eval(u, order, &mut v);
                    *o = DVec3::from_array(v);
                }
                out
            }
        }
    }

    /// A world axis the tangent at `u` is far from (used to build a normal frame).
    pub(crate) fn reference(&self, u: f64) -> DVec3 {
        match self {
            Curve::Circle { normal, .. } => *normal,
            _ => {
                let t = self.eval(u)[1].abs();
                if t.x <= t.y && t.x <= t.z {
                    DVec3::X
                } else if t.y <= t.z {
                    DVec3::Y
                } else {
                    DVec3::Z
                }
            }
        }
    }

    /// A starting parameter near the closest point to `p`: exact for the line and the circle,
    /// the turn nearest in height for the helix, the best of 64 samples per key interval for a
    /// track.
    pub fn initial_parameter(&self, p: DVec3) -> f64 {
        match self {
            Curve::Line { point, direction } => (p - *point).dot(*direction),
            Curve::Circle { center, normal, .. } => {
                let (e1, e2) = plane_basis(*normal);
                let d = p - *center;
                d.dot(e2).atan2(d.dot(e1))
            }
            Curve::Helix { center, axis, pitch, .. } => {
                let (e1, e2) = plane_basis(*axis);
                let d = p - *center;
                let angle = d.dot(e2).atan2(d.dot(e1));
                let by_height = TAU * d.dot(*axis) / *pitch;
                angle + TAU * ((by_height - angle) / TAU).round()
            }
            Curve::Track(track) => {
                let times = track.times();
                let mut best = (f64::INFINITY, times[0]);
                for w in times.windows(2) {
                    for k in 0..64 {
                        let u = w[0] + (w[1] - w[0]) * k as f64 / 64.0;
                        let dist = (self.eval(u)[0] - p).length_squared();
                        if dist < best.0 {
                            best = (dist, u);
                        }
                    }
                }
                let last = times[times.len() - 1];
                if (self.eval(last)[0] - p).length_squared() < best.0 {
                    last
                } else {
                    best.1
                }
            }
        }
    }

    /// The parameter of the point of the curve closest to `p`, by Newton's method from `guess`
    /// (a gradient step where the curve bends away faster than the distance allows).
    ///
    /// # Errors
    /// [`Error::SolverFailed`] when the tangent vanishes (a `hold`-extrapolated track) or the
    /// iteration does not settle.
    pub fn closest(&self, p: DVec3, guess: f64) -> Result<f64> {
        if let Curve::Line { .. } = self {
            return Ok(self.initial_parameter(p));
        }
        let mut u = guess;
        for _ in 0..CLOSEST_ITERATIONS {
            let [x, dx, ddx] = self.eval(u);
            let speed2 = dx.length_squared();
            if !(speed2.is_finite() && speed2 > 0.0) {
                return Err(Error::SolverFailed {
                    reason: format!("the curve's tangent vanishes at u = {u}"),
                });
            }
            let f = dx.dot(x - p);
            let fp = speed2 + ddx.dot(x - p);
            let du = if fp > 0.0 { -f / fp } else { -f / speed2 };
            u += du;
            if du.abs() <= 4.0 * f64::EPSILON * (1.0 + u.abs()) {
                return Ok(u);
            }
        }
        // Rounding can leave the last correction a few ulps above the bound; accept a point
        // whose first-order condition holds to rounding.
        let [x, dx, _] = self.eval(u);
        if dx.dot(x - p).abs() <= 1e-12 * dx.length() * (1.0 + (x - p).length()) {
            Ok(u)
        } else {
            Err(Error::SolverFailed {
                reason: "the closest-point search on the curve did not converge".into(),
            })
        }
    }
}

/// Move every curve's tracked parameter to the closest point at the state `y`, and pick a new
/// frame reference where the tangent came near the old one.
pub(super) fn track_curves(
    constraints: &[Constraint],
    y: &[f64],
    curves: &mut [(f64, DVec3)],
) -> Result<()> {
    for (c, state) in constraints.iter().zip(curves) {
        if let Constraint::OnCurve { i, curve } = c {
            let x = DVec3::from_slice(&y[3 * i..]);
            let u = curve.closest(x, state.0).map_err(|e| at_particle(e, *i))?;
            let t = curve.eval(u)[1].normalize();
            let reference = if state.1.dot(t).abs() > 0.9 { curve.reference(u) } else { state.1 };
            *state = (u, reference);
        }
    }
    Ok(())
}
