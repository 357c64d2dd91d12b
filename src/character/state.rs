//! The articulated state: what changes in time and what a later step reads — joint
//! coordinates `q` and rates `q̇`, the time, and the inputs of the next steps (servo targets,
//! applied joint torques, timed pushes).

use super::model::{Joint, Model};
use crate::error::{Error, Result};
use glam::DVec3;

/// A force (N, world axes) applied at a body's centre of mass for a time.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Push {
    /// Body index.
    pub body: usize,
    /// Force (N, world axes).
    pub force: DVec3,
    /// Time it still acts (s).
    pub remaining: f64,
}

/// The state of a [`Model`]'s tree. `clone_from` reuses every buffer.
#[derive(serde::Serialize, serde::Deserialize, Debug, PartialEq)]
pub struct State {
    /// Joint coordinates, `nq` (see [`Joint`]).
    pub(super) q: Vec<f64>,
    /// Joint rates, `nv`.
    pub(super) qd: Vec<f64>,
    /// Servo targets `q̄`, `nq` (same layout as `q`; only servoed joints read theirs).
    pub(super) targets: Vec<f64>,
    /// Joint torques applied during the next steps (N m; N on free joints' linear rows), `nv`.
    pub(super) torques: Vec<f64>,
    /// Pushes still acting.
    pub(super) pushes: Vec<Push>,
    /// Simulated time (s).
    pub(super) time: f64,
}

impl Clone for State {
    fn clone(&self) -> Self {
        let mut s = State {
            q: Vec::new(),
            qd: Vec::new(),
            targets: Vec::new(),
            torques: Vec::new(),
            pushes: Vec::new(),
            time: 0.0,
        };
        s.clone_from(self);
        s
    }

    /// Field by field, reusing every buffer.
    fn clone_from(&mut self, source: &Self) {
        self.q.clone_from(&source.q);
        self.qd.clone_from(&source.qd);
        self.targets.clone_from(&source.targets);
        self.torques.clone_from(&source.torques);
        self.pushes.clone_from(&source.pushes);
        self.time = source.time;
    }
}

impl State {
    /// The model at rest in its zero pose ([`Model::neutral`]), targets at that pose, at
    /// time 0.
    pub fn new(model: &Model) -> Self {
        let q = model.neutral();
        State {
            targets: q.clone(),
            q,
            qd: vec![0.0; model.nv()],
            torques: vec![0.0; model.nv()],
            pushes: Vec::new(),
            time: 0.0,
        }
    }

    /// Joint coordinates, `nq`.
    pub fn q(&self) -> &[f64] {
        &self.q
    }

    /// Joint rates, `nv`.
    pub fn qd(&self) -> &[f64] {
        &self.qd
    }

    /// Servo targets, `nq`.
    pub fn targets(&self) -> &[f64] {
        &self.targets
    }

    /// Applied joint torques, `nv`.
    pub fn torques(&self) -> &[f64] {
        &self.torques
    }

    /// Pushes still acting.
    pub fn pushes(&self) -> &[Push] {
        &self.pushes
    }

    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Set the joint coordinates (quaternions are normalised).
    ///
    /// # Errors
    /// A wrong length, a non-finite value or a zero quaternion (`q`, with index).
    pub fn set_q(&mut self, model: &Model, q: &[f64]) -> Result<()> {
        self.q.copy_from_slice(&checked_coordinates(model, q, "q")?);
        Ok(())
    }

    /// Set the servo targets (same layout as `q`; quaternions are normalised).
    ///
    /// # Errors
    /// As [`State::set_q`] (`targets`).
    pub fn set_targets(&mut self, model: &Model, targets: &[f64]) -> Result<()> {
        self.targets.copy_from_slice(&checked_coordinates(model, targets, "targets")?);
        Ok(())
    }

    /// Set the joint rates.
    ///
    /// # Errors
    /// A wrong length or a non-finite value (`qd`, with index).
    pub fn set_qd(&mut self, qd: &[f64]) -> Result<()> {
        copy_finite(&mut self.qd, qd, "qd")
    }

    /// Set the joint torques applied during the next steps.
    ///
    /// # Errors
    /// A wrong length or a non-finite value (`torques`, with index).
    pub fn set_torques(&mut self, torques: &[f64]) -> Result<()> {
        copy_finite(&mut self.torques, torques, "torques")
    }

    /// Apply `force` (N, world axes) at body `body`'s centre of mass during the next
    /// `duration` seconds.
    ///
    /// # Errors
    /// `body` out of range (`body`), a non-finite force (`force`), a duration not finite and
    /// > 0 (`duration`).
    pub fn push(&mut self, model: &Model, body: usize, force: DVec3, duration: f64) -> Result<()> {
        if body >= model.bodies().len() {
            return Err(Error::invalid("body", "beyond the last body"));
        }
        if !force.is_finite() {
            return Err(Error::invalid("force", "must be finite"));
        }
        if !(duration.is_finite() && duration > 0.0) {
            return Err(Error::invalid("duration", "must be finite and > 0"));
        }
        self.pushes.push(Push { body, force, remaining: duration });
        Ok(())
    }
}

fn copy_finite(out: &mut [f64], values: &[f64], name: &str) -> Result<()> {
    if values.len() != out.len() {
        return Err(Error::invalid(name, format!("expected {} values", out.len())));
    }
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        return Err(Error::invalid(name, "contains NaN or infinity").at(i));
    }
    out.copy_from_slice(values);
    Ok(())
}

/// `q` checked against the model's layout, quaternions normalised.
fn checked_coordinates(model: &Model, q: &[f64], name: &str) -> Result<Vec<f64>> {
    let mut out = vec![0.0; model.nq()];
    copy_finite(&mut out, q, name)?;
    for (i, b) in model.bodies().iter().enumerate() {
        let at = model.starts(i).0 + if b.joint == Joint::Free { 3 } else { 0 };
        if matches!(b.joint, Joint::Ball | Joint::Free) {
            let quat = &mut out[at..at + 4];
            let n = quat.iter().map(|v| v * v).sum::<f64>().sqrt();
            if n.is_nan() || n <= 1e-12 {
                return Err(Error::invalid(name, "a zero quaternion").at(at));
            }
            quat.iter_mut().for_each(|v| *v /= n);
        }
    }
    Ok(out)
}
