//! Undoing a failed cloth step: each step first copies what it may change (state, history,
//! warm start, contact states, colliders, statistics) into reused buffers, and a failed step
//! puts it back, so the cloth is left exactly as it was; [`Cloth::restore`] puts back a whole
//! cloth in place (the state buffers that Python views point to stay).

use super::*;

impl Cloth {
    /// Become `other` (e.g. an earlier [`crate::snapshot::Snapshot`] of this cloth), copying
    /// its positions and velocities into this cloth's buffers, which stay in place so views of
    /// them stay valid (a scene undoes a failed step this way).
    ///
    /// # Errors
    /// [`Error::InvalidInput`] (argument `"data"`) if `other` has another number of vertices.
    pub fn restore(&mut self, other: Cloth) -> Result<()> {
        if other.x.len() != self.x.len() || other.v.len() != self.v.len() {
            return Err(Error::invalid("data", "is a cloth with another number of vertices"));
        }
        let (mut x, mut v) = (std::mem::take(&mut self.x), std::mem::take(&mut self.v));
        x.copy_from_slice(&other.x);
        v.copy_from_slice(&other.v);
        *self = Cloth { x, v, ..other };
        Ok(())
    }

    /// Copy what a step may change into `self.rollback` (buffers reused: no allocation after
    /// the first step).
    pub(super) fn save_rollback(&mut self) {
        let r = &mut self.rollback;
        Rollback::copy(&mut r.x, &self.x);
        Rollback::copy(&mut r.v, &self.v);
        Rollback::copy(&mut r.dv, &self.scratch.dv);
        Rollback::copy(&mut r.contact, &self.contact);
        Rollback::copy(&mut r.colliders, &self.colliders);
        Rollback::copy_history(&mut r.history, &self.history);
        r.time = self.time;
        r.stats = self.stats;
        r.evaluations = self.stepper.as_ref().map(|s| (s.history.nfev, s.history.njev));
    }

    /// Put back what [`Cloth::save_rollback`] copied (the state buffers are copied into, so
    /// Python views stay valid).
    pub(super) fn restore_rollback(&mut self) {
        let r = &mut self.rollback;
        self.x.copy_from_slice(&r.x);
        self.v.copy_from_slice(&r.v);
        Rollback::copy(&mut self.scratch.dv, &r.dv);
        Rollback::copy(&mut self.contact, &r.contact);
        Rollback::copy(&mut self.colliders, &r.colliders);
        Rollback::copy_history(&mut self.history, &r.history);
        self.time = r.time;
        self.stats = r.stats;
        match (self.stepper.as_mut(), r.evaluations) {
            (Some(s), Some((nfev, njev))) => (s.history.nfev, s.history.njev) = (nfev, njev),
            (Some(_), None) => self.stepper = None,
            _ => {}
        }
    }
}

#[derive(Default)]
pub(super) struct Rollback {
    x: Vec<DVec3>,
    v: Vec<DVec3>,
    history: History,
    /// The PCG's warm start `Δv` of the last step.
    dv: Vec<DVec3>,
    time: f64,
    contact: Vec<ContactState>,
    colliders: Vec<Collider>,
    stats: StepStats,
    /// The explicit stepper's evaluation counters.
    evaluations: Option<(usize, usize)>,
}

impl Rollback {
    /// Copy `what` into `into`, reusing its allocation.
    fn copy<T: Copy>(into: &mut Vec<T>, what: &[T]) {
        into.clear();
        into.extend_from_slice(what);
    }

    /// Copy a BDF2 history into another, reusing its buffers when it has them.
    fn copy_history(into: &mut History, what: &History) {
        match (what, into.as_mut()) {
            (None, _) => *into = None,
            (Some((wx, wv, wh)), Some((ix, iv, ih))) => {
                Rollback::copy(ix, wx);
                Rollback::copy(iv, wv);
                *ih = *wh;
            }
            (Some(h), None) => *into = Some(h.clone()),
        }
    }
}
