//! Rod snapshots: the rod's (model and state), and a state's alone, which records the
//! fingerprint of its model ([`Model::fingerprint`]) so that it is restored only onto it.

use super::{Frames, Hair, Model, Rod, State};
use crate::error::Result;
use crate::snapshot::{Snapshot, Stamped};

impl Stamped for State {
    const TAG: &'static str = "RodState";
    type Model = Model;

    /// Check a decoded state against its model: lengths, finite values, unit directors.
    fn validate(&self, model: &Model) -> Result<()> {
        use crate::snapshot::{check, finite};
        let (n, v) = (model.edges(), model.vertices());
        for (field, len, want) in [
            ("positions", self.positions.len(), v),
            ("velocities", self.velocities.len(), v),
            ("forces", self.forces.len(), v),
            ("twists", self.twists.len(), n),
            ("twist_rates", self.twist_rates.len(), n),
            ("reference", self.reference.len(), n),
            ("reference_twist", self.reference_twist.len(), model.stencils()),
        ] {
            check(len == want, field, || format!("{len} entries, expected {want}"))?;
        }
        let vectors = [&self.positions, &self.velocities, &self.forces, &self.reference];
        check(
            finite(vectors.iter().flat_map(|v| v.iter().flat_map(|p| p.to_array()))),
            "positions",
            || "non-finite".into(),
        )?;
        let scalars = self.twists.iter().chain(&self.twist_rates).chain(&self.reference_twist);
        check(
            finite(scalars.copied()) && self.time.is_finite() && self.seam.is_finite(),
            "twists",
            || "non-finite".into(),
        )?;
        check(model.closed || self.seam == 0.0, "seam", || "an open rod has no seam".into())?;
        check(
            self.clamp_goals.iter().flatten().all(|g| {
                g.edge < n
                    && g.positions.iter().all(|p| p.is_finite())
                    && (g.director.length() - 1.0).abs() < 1e-9
            }),
            "clamp_goals",
            || "an edge beyond the last, or non-finite or non-unit values".into(),
        )?;
        check(self.reference.iter().all(|d| (d.length() - 1.0).abs() < 1e-9), "reference", || {
            "reference directors must be unit".into()
        })?;
        let mut frames = Frames::default();
        check(self.frames_into(&mut frames, &mut Vec::new()), "positions", || {
            "an edge has zero length".into()
        })
    }
}

impl Snapshot for Rod {
    const TAG: &'static str = "Rod";

    fn validate(&self) -> Result<()> {
        self.model.validate()?;
        self.state.validate(&self.model)
    }
}

impl Snapshot for Hair {
    const TAG: &'static str = "Hair";

    fn validate(&self) -> Result<()> {
        super::hair::validate(self)
    }
}
