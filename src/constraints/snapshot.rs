//! Constraint snapshots: what a decoded [`Model`] and [`State`] must satisfy before they are
//! stepped; the system's snapshot (model and state), and a state's alone, which records the
//! fingerprint of its model ([`Model::fingerprint`]) so that it is restored only onto it. The
//! particles are not part of either, so the particle indices are checked against the particle
//! system each call takes ([`Model::check_particles`]).

use super::{ConstrainedSystem, Constraint, Formulation, Model, State};
use crate::error::Result;
use crate::snapshot::{check, finite, Snapshot, Stamped};

impl Model {
    /// Check a decoded model: gains and penalty constants in range, every constraint's
    /// parameters valid, post-stabilisation only with multipliers.
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
        check(
            !self.stabilize || self.formulation == Formulation::Multipliers,
            "stabilize",
            || "post-stabilisation needs the multiplier formulation".into(),
        )?;
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
        Ok(())
    }
}

impl Stamped for State {
    const TAG: &'static str = "ConstraintState";
    type Model = Model;

    /// Check a decoded state against its model: an entry per constraint and a multiplier per
    /// row, finite values, a valid history.
    fn validate(&self, model: &Model) -> Result<()> {
        self.check_model(model)?;
        check(finite(self.curves.iter().flat_map(|(u, r)| [*u, r.x, r.y, r.z])), "curves", || {
            "non-finite curve parameters".into()
        })?;
        check(finite(self.lambda.iter().chain(&self.implicit_lambda).copied()), "lambda", || {
            "non-finite multipliers".into()
        })?;
        if let Some(h) = &self.history {
            h.validate()?;
            check(h.dimension().is_multiple_of(6), "stepper", || {
                "dimension is not 6 x particles".into()
            })?;
        }
        Ok(())
    }
}

impl Snapshot for ConstrainedSystem {
    const TAG: &'static str = "ConstrainedSystem";

    fn validate(&self) -> Result<()> {
        self.model.validate()?;
        self.state.validate(&self.model)
    }
}
