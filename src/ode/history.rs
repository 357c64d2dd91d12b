//! What a fixed-step integration carries from one step to the next: the method, the previous
//! step of the multistep method (BDF2), the Newton settings and the evaluation counters. A
//! system keeps it in its state; the workspaces live in [`super::Workspace`], which a solver
//! owns and may share between states.

use super::Method;
use crate::error::{Error, Result};

/// Largest Newton iteration count a history read from a snapshot may carry.
const MAX_NEWTON: usize = 10_000;

/// The part of a fixed-step integration that a later step reads (see the module docs).
///
/// `Clone` copies it; `clone_from` reuses the previous step's buffer (no allocation once it
/// has the size), so a system's undo point costs no allocation after the first.
#[derive(serde::Serialize, serde::Deserialize, Debug, PartialEq)]
pub struct History {
    method: Method,
    n: usize,
    /// The state at the start of the last BDF2 step (`n` values), read by the next BDF2 step.
    pub(super) prev: Vec<f64>,
    /// The length of the last BDF2 step (s); `None` when the next BDF2 step must restart
    /// (with implicit Euler) because there is no previous step or the state was changed.
    pub(super) prev_h: Option<f64>,
    /// Newton tolerance: stop when `max|Δy| ≤ newton_tol (1 + max|y|)`. Default 1e-10.
    pub newton_tol: f64,
    /// Newton iterations before the iteration gives up on a step, which is then retried as
    /// substeps, and fails with [`Error::SolverFailed`] when they give up too. Default 100.
    pub max_newton: usize,
    /// Right-hand-side evaluations so far.
    pub nfev: usize,
    /// Jacobian evaluations (analytic or by differences) so far.
    pub njev: usize,
}

impl Clone for History {
    fn clone(&self) -> Self {
        let mut copy = History { prev: Vec::new(), ..*self };
        copy.prev.clone_from(&self.prev);
        copy
    }

    fn clone_from(&mut self, source: &Self) {
        // Destructured so that a new field cannot be forgotten here.
        let History { method, n, prev, prev_h, newton_tol, max_newton, nfev, njev } = source;
        (self.method, self.n, self.prev_h) = (*method, *n, *prev_h);
        (self.newton_tol, self.max_newton, self.nfev, self.njev) =
            (*newton_tol, *max_newton, *nfev, *njev);
        self.prev.clone_from(prev);
    }
}

impl History {
    /// The history of an integration of states of length `n` by `method`, before its first
    /// step.
    ///
    /// # Errors
    /// A second-order method with odd `n` (the state must be `[x; v]`).
    pub fn new(method: Method, n: usize) -> Result<Self> {
        if method.is_second_order() && !n.is_multiple_of(2) {
            return Err(Error::invalid(
                "y0",
                format!("{} needs a state [x; v] of even length, got {n}", method.name()),
            ));
        }
        Ok(History {
            method,
            n,
            prev: vec![0.0; n],
            prev_h: None,
            newton_tol: 1e-10,
            max_newton: 100,
            nfev: 0,
            njev: 0,
        })
    }

    /// The method of the integration.
    pub fn method(&self) -> Method {
        self.method
    }

    /// Length of the states this history belongs to.
    pub fn dimension(&self) -> usize {
        self.n
    }

    /// Forget the previous step of multistep methods (call after changing the state from
    /// outside): the next BDF2 step restarts with implicit Euler.
    pub fn reset(&mut self) {
        self.prev_h = None;
    }

    /// Check a history decoded from a snapshot: a previous step of its dimension, finite, a
    /// positive step length, Newton settings in range. The Newton iteration count is capped at
    /// 10 000 so a damaged one cannot hang a step.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] (argument `stepper`) naming the first inconsistency.
    pub fn validate(&self) -> Result<()> {
        let bad = |what: &str| Err(Error::invalid("stepper", what.to_string()));
        if self.method.is_second_order() && !self.n.is_multiple_of(2) {
            return bad("a second-order method needs a state of even length");
        }
        if self.prev.len() != self.n {
            return bad("the previous step is not of the stepper's dimension");
        }
        if !self.prev.iter().all(|v| v.is_finite())
            || self.prev_h.is_some_and(|h| !(h.is_finite() && h > 0.0))
        {
            return bad("non-finite history");
        }
        if !(self.newton_tol.is_finite() && self.newton_tol >= 0.0) || self.max_newton > MAX_NEWTON
        {
            return bad("Newton tolerance or iteration count out of range");
        }
        Ok(())
    }
}
