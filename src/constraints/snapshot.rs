//! Constrained-system snapshots: what a decoded [`ConstrainedSystem`] must satisfy before it
//! is stepped. The particles are not part of it, so the particle indices are checked against
//! the particle system each call takes ([`ConstrainedSystem::check_particles`]).

use super::{ConstrainedSystem, Constraint, Formulation};
use crate::error::{Error, Result};
use crate::snapshot::{check, finite, Snapshot};

impl Snapshot for ConstrainedSystem {
    const TAG: &'static str = "ConstrainedSystem";

    fn validate(&self) -> Result<()> {
        check(finite([self.ks, self.kd]) && self.ks >= 0.0 && self.kd >= 0.0, "ks", || {
            "feedback gains must be finite and >= 0".into()
        })?;
        if let Formulation::Penalty { stiffness, damping } = self.formulation {
            check(
                finite([stiffness, damping]) && stiffness > 0.0 && damping >= 0.0,
                "stiffness",
                || "penalty stiffness and damping out of range".into(),
            )?;
        }
        for (k, c) in self.constraints.iter().enumerate() {
            let ok = match c {
                Constraint::Distance { i, j, length } => {
                    i != j && length.is_finite() && *length > 0.0
                }
                Constraint::OnSphere { center, radius, .. } => {
                    center.is_finite() && radius.is_finite() && *radius > 0.0
                }
                Constraint::OnPlane { point, normal, .. } => {
                    point.is_finite() && normal.is_finite() && (normal.length() - 1.0).abs() < 1e-6
                }
                Constraint::Fixed { point, .. } => point.is_finite(),
                Constraint::OnCurve { curve, .. } => curve.clone().checked().is_ok(),
                Constraint::Custom { .. } => false, // never stored
            };
            check(ok, "constraints", || format!("constraint {k} has invalid parameters"))?;
        }
        let w = &self.work;
        check(w.curves.len() == self.constraints.len(), "curves", || {
            "not one entry per constraint".into()
        })?;
        check(finite(w.curves.iter().flat_map(|(u, r)| [*u, r.x, r.y, r.z])), "curves", || {
            "non-finite curve parameters".into()
        })?;
        check(finite(w.implicit_lambda.iter().copied()), "implicit_lambda", || {
            "non-finite multipliers".into()
        })?;
        check(
            w.rows
                .rows
                .iter()
                .all(|r| r.start.checked_add(r.count).is_some_and(|e| e <= w.rows.blocks.len())),
            "rows",
            || "row blocks out of range".into(),
        )?;
        if let Some(s) = &self.stepper {
            s.validate()?;
        }
        Ok(())
    }
}

impl ConstrainedSystem {
    /// Check that every constraint's particles are among the `n` slots of the particle system
    /// it is used with, and that the per-particle workspace is of that size (a snapshot does
    /// not hold the particles). Allocates nothing: every step calls it.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] (argument `"particles"`) naming the first constraint that
    /// refers to a particle `>= n`, or a workspace of another size.
    pub fn check_particles(&self, n: usize) -> Result<()> {
        let highest = |c: &Constraint| match c {
            Constraint::Distance { i, j, .. } => *i.max(j),
            Constraint::OnSphere { i, .. }
            | Constraint::OnPlane { i, .. }
            | Constraint::Fixed { i, .. }
            | Constraint::OnCurve { i, .. } => *i,
            Constraint::Custom { particles, .. } => particles.iter().copied().max().unwrap_or(0),
        };
        if ![0, 6 * n].contains(&self.work.backup.len()) {
            return Err(Error::invalid("particles", format!("workspace not of {n} particles")));
        }
        match self.constraints.iter().position(|c| highest(c) >= n) {
            None => Ok(()),
            Some(k) => Err(Error::invalid(
                "particles",
                format!("constraint {k} refers to a particle beyond the {n} slots"),
            )),
        }
    }
}
