//! World snapshots: what a decoded [`World`] must satisfy before it is stepped.

use super::{World, SLOTS};
use crate::error::Result;
use crate::geometry::{Material, Shape};
use crate::snapshot::{check, finite, Snapshot};
use glam::{DQuat, DVec3};

/// Largest iteration or substep count a world read from a snapshot may carry, so that a
/// damaged count cannot hang a step.
const MAX_ITERATIONS: usize = 100_000;

impl Snapshot for World {
    const TAG: &'static str = "World";

    fn validate(&self) -> Result<()> {
        let n = self.x.len();
        let lengths = [
            self.mass.len(),
            self.inertia_body.len(),
            self.com_body.len(),
            self.principal.len(),
            self.moments.len(),
            self.fixed.len(),
            self.inv_mass.len(),
            self.inv_moments.len(),
            self.bound.len(),
            self.shape.len(),
            self.restitution.len(),
            self.friction.len(),
            self.linear_damping.len(),
            self.angular_damping.len(),
            self.v.len(),
            self.q.len(),
            self.pi.len(),
            self.force.len(),
            self.torque.len(),
        ];
        check(lengths.iter().all(|&l| l == n), "bodies", || {
            format!("per-body arrays of lengths {lengths:?} for {n} bodies")
        })?;
        let vec3 = |v: &[DVec3]| finite(v.iter().flat_map(|p| p.to_array()));
        let unit = |q: &[DQuat]| q.iter().all(|q| q.is_finite() && (q.length() - 1.0).abs() < 1e-6);
        check(
            vec3(&self.x)
                && vec3(&self.v)
                && vec3(&self.pi)
                && vec3(&self.force)
                && vec3(&self.torque)
                && vec3(&self.com_body)
                && vec3(&self.moments)
                && vec3(&self.inv_moments)
                && unit(&self.q)
                && unit(&self.principal),
            "state",
            || "non-finite state or non-unit orientations".into(),
        )?;
        check(
            finite(self.mass.iter().chain(&self.inv_mass).chain(&self.bound).copied())
                && self.mass.iter().all(|&m| m > 0.0)
                && finite(self.inertia_body.iter().flat_map(|m| m.to_cols_array())),
            "mass",
            || "masses must be finite and positive".into(),
        )?;
        check(
            self.linear_damping
                .iter()
                .chain(&self.angular_damping)
                .all(|c| c.is_finite() && *c >= 0.0),
            "damping",
            || "damping rates must be finite and >= 0".into(),
        )?;
        for (i, s) in self.shape.iter().enumerate() {
            s.mass_properties(1.0).map_err(|e| e.at(i))?;
            Material { restitution: self.restitution[i], friction: self.friction[i] }
                .checked()
                .map_err(|e| e.at(i))?;
        }
        for (plane, material) in &self.planes {
            Shape::Plane(*plane).checked()?;
            check((plane.normal.length() - 1.0).abs() < 1e-6, "planes", || {
                "a plane's normal is not unit".into()
            })?;
            material.checked()?;
        }
        check(self.gravity.is_finite() && self.baumgarte.is_finite(), "gravity", || {
            "non-finite gravity or Baumgarte factor".into()
        })?;
        check(
            [self.contact_iterations, self.joint_iterations, self.xpbd_substeps]
                .iter()
                .all(|&k| k <= MAX_ITERATIONS),
            "contact_iterations",
            || format!("iteration counts above {MAX_ITERATIONS}"),
        )?;
        for j in &self.joints {
            j.validate(n)?;
        }
        let slots = self.joints.len() * SLOTS;
        check(
            [
                self.rows.len(),
                self.row_mass.len(),
                self.joint_impulse.len(),
                self.joint_impulse_next.len(),
            ] == [slots; 4],
            "rows",
            || "joint rows not of the joints' size".into(),
        )?;
        check(self.jointed.iter().all(|&(a, b)| a < b && b < n), "jointed", || {
            "body index out of range".into()
        })?;
        self.multipliers.validate(&self.joints, n)?;
        check(
            self.previous.iter().all(|c| {
                c.a < n
                    && c.b.is_none_or(|b| b < n && b != c.a)
                    && c.ra.is_finite()
                    && finite(c.impulse)
            }),
            "previous",
            || "warm-start contacts out of range or non-finite".into(),
        )
    }
}
