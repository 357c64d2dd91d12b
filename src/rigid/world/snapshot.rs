//! World snapshots: the model and the state (the solver's workspaces are rebuilt), checked
//! before a decoded [`World`] is stepped.

use super::World;
use crate::error::Result;
use crate::snapshot::{Snapshot, Stamped};

impl Snapshot for World {
    const TAG: &'static str = "World";

    fn validate(&self) -> Result<()> {
        self.model.validate()?;
        self.state.validate(&self.model)
    }
}
