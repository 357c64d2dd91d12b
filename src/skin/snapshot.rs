//! What a decoded skin must satisfy before it deforms anything.

use super::Skin;
use crate::error::Result;
use crate::snapshot::{check, finite, Snapshot};

impl Snapshot for Skin {
    const TAG: &'static str = "Skin";

    fn validate(&self) -> Result<()> {
        let (n, k, joints) = (self.rest.len(), self.k, self.origins.len());
        check(finite(self.rest.iter().flatten().copied()), "vertices", || "non-finite".into())?;
        check(
            k > 0 && self.bones.len() == n * k && self.weights.len() == n * k,
            "weights",
            || "influences of the wrong size".into(),
        )?;
        check(self.bones.iter().all(|&b| (b as usize) < joints), "bones", || {
            "a bone beyond the joints".into()
        })?;
        check(self.origins.iter().all(|&o| o < joints), "origins", || {
            "an origin beyond the joints".into()
        })?;
        let normalised = self.weights.chunks_exact(k).all(|w| {
            w.iter().all(|x| x.is_finite() && *x >= 0.0)
                && (w.iter().sum::<f64>() - 1.0).abs() < 1e-9
        });
        check(normalised, "weights", || "not normalised non-negative weights".into())?;
        let frames = self.bind_inverse.iter().all(|t| {
            t.translation.is_finite() && t.rotation.is_finite() && t.rotation.is_normalized()
        });
        check(self.bind_inverse.len() == joints && frames, "bind", || {
            "bind frames of the wrong size or not rigid".into()
        })
    }
}
