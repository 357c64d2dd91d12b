//! The constraint state: what a later step reads besides the particles' own state — each
//! curve constraint's tracked parameter and frame axis, the multipliers that warm-start the
//! next solve (the conjugate gradient's `λ` and the implicit projection's), and the history of
//! the ODE integration of the constrained equations.

use super::{Constraint, Model};
use crate::error::{Error, Result};
use crate::ode::History;
use glam::DVec3;

/// What changes in time in a constrained system besides the particles (see the module docs):
/// one per particle state it constrains. `Clone`; `clone_from` reuses the buffers (no
/// allocation once they have the size), serde.
#[derive(serde::Serialize, serde::Deserialize, Debug, Default, PartialEq)]
pub struct State {
    /// Per constraint: the tracked curve parameter and frame reference axis (curves only;
    /// zero for the other kinds).
    pub(super) curves: Vec<(f64, DVec3)>,
    /// The multipliers (N) of the last multiplier solve, one per row: the conjugate
    /// gradient's starting guess, read by the constraint forces.
    pub(super) lambda: Vec<f64>,
    /// Conjugate-gradient iterations of the last multiplier solve (0 with Cholesky).
    pub(super) iterations: usize,
    /// The multipliers (N) of the last implicit projection, one per row, the next one's
    /// starting guess.
    pub(super) implicit_lambda: Vec<f64>,
    /// The ODE integration's history (method, BDF2's previous step, counters) over the
    /// particles' `[x; v]`; `None` before the first step and after the model changed.
    pub(super) history: Option<History>,
}

impl Clone for State {
    fn clone(&self) -> Self {
        let mut copy = State::default();
        copy.clone_from(self);
        copy
    }

    fn clone_from(&mut self, source: &Self) {
        // Destructured so that a new field cannot be forgotten here.
        let State { curves, lambda, iterations, implicit_lambda, history } = source;
        self.curves.clone_from(curves);
        self.lambda.clone_from(lambda);
        self.iterations = *iterations;
        self.implicit_lambda.clone_from(implicit_lambda);
        match (&mut self.history, history) {
            (Some(to), Some(from)) => to.clone_from(from),
            (to, from) => to.clone_from(from),
        }
    }
}

impl State {
    /// The state of `model` on the particles at `particles` (their positions): each curve's
    /// closest point as its tracked parameter, zero multipliers, no history.
    ///
    /// # Errors
    /// A constraint on a particle beyond the particle state's slots (argument `particles`), a
    /// rod between coincident particles (argument `j`), a curve whose closest point to its
    /// particle cannot be found (argument `curve`), a custom function that fails or is not
    /// finite at the positions.
    pub fn new(model: &Model, particles: &crate::particles::State) -> Result<Self> {
        model.check_particles(particles.capacity())?;
        let mut state = State::default();
        state.fit(model, particles.positions())?;
        Ok(state)
    }

    /// Take on the constraints added to `model` since this state was made, checked against
    /// the particles at `positions` (3 per particle, m): a tracked entry each, zero
    /// multipliers for their rows, and no history (the equations changed). Nothing changes
    /// when a constraint fails.
    ///
    /// # Errors
    /// As [`State::new`].
    pub fn fit(&mut self, model: &Model, positions: &[f64]) -> Result<()> {
        let known = self.curves.len();
        let added = &model.constraints[known.min(model.constraints.len())..];
        let mut entries = Vec::with_capacity(added.len());
        for c in added {
            entries.push(c.initial(positions)?);
        }
        self.curves.extend(entries);
        let m = model.rows();
        self.lambda.resize(m, 0.0);
        self.implicit_lambda.resize(m, 0.0);
        if !added.is_empty() {
            self.history = None;
        }
        Ok(())
    }

    /// Whether this state belongs to `model` and to particle states of `n` slots.
    ///
    /// # Errors
    /// As [`State::check_model`] and [`State::check_particles`].
    pub(super) fn check_fits(&self, model: &Model, n: usize) -> Result<()> {
        self.check_model(model)?;
        self.check_particles(n)
    }

    /// Whether this state has an entry per constraint and a multiplier per row of `model`.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] (argument `state`) for a state of another model.
    pub(super) fn check_model(&self, model: &Model) -> Result<()> {
        let m = model.rows();
        if self.curves.len() == model.constraints.len()
            && self.lambda.len() == m
            && self.implicit_lambda.len() == m
        {
            Ok(())
        } else {
            Err(Error::invalid(
                "state",
                "does not fit the model (another constraint count; see State::fit)",
            ))
        }
    }

    /// Whether the integration history (if any) is of particle states of `n` slots.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] (argument `particles`) when it is of another size.
    pub(super) fn check_particles(&self, n: usize) -> Result<()> {
        if self.history.as_ref().is_some_and(|h| h.dimension() != 6 * n) {
            return Err(Error::invalid(
                "particles",
                format!(
                    "the constraint state was stepped with another number of particles than {n}"
                ),
            ));
        }
        Ok(())
    }

    /// The tracked parameter `u` of constraint `k` of `model` when it is a
    /// [`Constraint::OnCurve`].
    pub fn curve_parameter(&self, model: &Model, k: usize) -> Option<f64> {
        match model.constraints.get(k) {
            Some(Constraint::OnCurve { .. }) => self.curves.get(k).map(|c| c.0),
            _ => None,
        }
    }

    /// Conjugate-gradient iterations of the last multiplier solve (0 with Cholesky).
    pub fn iterations(&self) -> usize {
        self.iterations
    }

    /// The multipliers (N) of the last multiplier solve, one per constraint row.
    pub fn multipliers(&self) -> &[f64] {
        &self.lambda
    }
}
