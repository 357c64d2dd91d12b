//! Cloth snapshots (pickles, `kinema.Scene.save`): self-contained, the [`Model`] and the
//! [`State`], and the numbers of the last step ([`StepStats`], a report); the [`Solver`] is
//! rebuilt from the model (it carries nothing a later step reads). A decoded model is checked ([`Model::validate`]: every element's vertices in range
//! and its slots those of the model's pattern) before the solver is built on it, and the state
//! against the model ([`Snapshot::validate`]), so a damaged snapshot cannot make a step panic.

use super::{Cloth, Model, Solver, State, StepStats};
use crate::error::Result;
use crate::snapshot::{Snapshot, Stamped};

/// A cloth as stored.
#[derive(serde::Serialize)]
struct Stored<'a> {
    model: &'a Model,
    state: &'a State,
    stats: StepStats,
}

/// A cloth as decoded.
#[derive(serde::Deserialize)]
struct Decoded {
    model: Model,
    state: State,
    stats: StepStats,
}

impl serde::Serialize for Cloth {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        Stored { model: self.model(), state: self.state(), stats: self.stats() }.serialize(s)
    }
}

impl<'de> serde::Deserialize<'de> for Cloth {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Cloth, D::Error> {
        let Decoded { model, state, stats } = Decoded::deserialize(d)?;
        model.validate().map_err(serde::de::Error::custom)?;
        let mut solver = Solver::new(&model);
        solver.stats = stats;
        Ok(Cloth { model, state, solver })
    }
}

impl Snapshot for Cloth {
    const TAG: &'static str = "Cloth";

    /// The state against the model (the model itself is checked while decoding, before the
    /// solver is built on it).
    fn validate(&self) -> Result<()> {
        self.state().validate(self.model())
    }
}
