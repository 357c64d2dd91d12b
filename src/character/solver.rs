//! Time stepping of an articulated [`State`]: the forward dynamics of a step's forces
//! ([`Solver::accelerations`]: passive forces, servos, then the ABA or the stable-PD solve)
//! and the two integrators of [`Integrator`].
//!
//! Runge–Kutta 4 is the classical one on the coordinates and rates: the stages are
//! `(q + cᵢ dt ṙᵢ₋₁, q̇ + cᵢ dt aᵢ₋₁)` and the step `q + dt Σ bᵢ ṙᵢ`, `q̇ + dt Σ bᵢ aᵢ`, with
//! `ṙ` the coordinates' time derivative (quaternions: `½ q ⊗ ω`, components renormalised).
//! Moving quaternions by the exponential map of the weighted stage velocities (MuJoCo 3's
//! `mj_RungeKutta`) is only second order for rotations whose axis turns; this is fourth order
//! and agrees with MuJoCo 4's RK4 (`tests/python/test_character.py`).

use super::dynamics::Tree;
use super::forces::{ground_force, implicit, passive};
use super::joints::{advance, coordinate_rates, integrate};
use super::model::{Integrator, Model};
use super::servo::{self, ServoWork};
use super::state::State;
use crate::error::{Error, Result};

/// Workspaces of the steps. It carries nothing a later step reads: one solver advances any
/// number of states of one model, bitwise as if each had its own.
#[derive(Clone, Debug, Default)]
pub struct Solver {
    tree: Tree,
    servo: ServoWork,
    tau: Vec<f64>,
    /// RK4: stage positions and rates, and the four stages' coordinate rates (`nq`) and
    /// accelerations.
    stage_q: Vec<f64>,
    stage_qd: Vec<f64>,
    vel: [Vec<f64>; 4],
    acc: [Vec<f64>; 4],
    start: Option<State>,
}

impl Solver {
    /// A solver for `model` (workspaces are sized on first use).
    pub fn new(model: &Model) -> Self {
        let mut s = Solver::default();
        s.tree.resize(model);
        s
    }

    /// The workspace of the recursive algorithms, for [`Solver::kinematics`] results.
    pub fn tree(&self) -> &Tree {
        &self.tree
    }

    /// Run the kinematics of `state` (positions, velocities of every body) into
    /// [`Solver::tree`] and return it.
    pub fn kinematics(&mut self, model: &Model, state: &State) -> &mut Tree {
        self.tree.kinematics(model, &state.q, &state.qd);
        &mut self.tree
    }

    /// The total ground contact force (N, world) on `state`'s bodies, as a step `dt` would
    /// apply it (the penalty forces of [`super::Settings::contact_frequency`]).
    pub fn ground_force(&mut self, model: &Model, state: &State, dt: f64) -> glam::DVec3 {
        self.tree.kinematics(model, &state.q, &state.qd);
        ground_force(model, &self.tree, 0..model.bodies().len(), dt)
    }

    /// The accelerations `qdd` (`nv`) of `state`'s inputs at `(q, q̇)` and `state`'s time for
    /// a step `dt` (pushes, contacts, damping, limits, applied torques, servos, gravity).
    pub fn accelerations(
        &mut self,
        model: &Model,
        state: &State,
        q: &[f64],
        qd: &[f64],
        dt: f64,
        qdd: &mut [f64],
    ) {
        self.tree.kinematics(model, q, qd);
        self.dynamics(model, state, q, qd, state.time, dt, qdd);
    }

    /// [`Solver::accelerations`] at the kinematics of `(q, q̇)` already in the tree, at
    /// `time` (s: where the moving colliders are).
    #[allow(clippy::too_many_arguments)]
    fn dynamics(
        &mut self,
        model: &Model,
        state: &State,
        q: &[f64],
        qd: &[f64],
        time: f64,
        dt: f64,
        qdd: &mut [f64],
    ) {
        let tree = &mut self.tree;
        self.tau.resize(model.nv(), 0.0);
        let implicit = implicit(model);
        let (torques, pushes) = (&state.torques, &state.pushes);
        passive(model, q, qd, torques, pushes, time, dt, implicit, tree, &mut self.tau);
        if implicit {
            servo::stable(
                model,
                q,
                qd,
                &state.targets,
                dt,
                tree,
                &mut self.servo,
                &mut self.tau,
                qdd,
            );
        } else {
            servo::explicit(model, q, qd, &state.targets, &mut self.servo, &mut self.tau);
            tree.aba(model, &self.tau, qdd);
        }
    }

    /// Advance `state` by `steps` steps of `dt` seconds with the model's integrator.
    ///
    /// # Errors
    /// `dt` not finite and > 0 (`dt`); settings out of range (named); a state of another
    /// model (`state`); a non-finite or exploding state (`Diverged`, with the step and the
    /// first bad rate) — the state is then exactly as before the call.
    pub fn step(&mut self, model: &Model, state: &mut State, dt: f64, steps: usize) -> Result<()> {
        check(model, state, dt)?;
        let mut start = self.start.take().unwrap_or_else(|| state.clone());
        start.clone_from(state);
        let mut result = Ok(());
        for n in 0..steps {
            if let Err(e) = self.step_once(model, state, dt, false, n) {
                state.clone_from(&start);
                result = Err(e);
                break;
            }
        }
        self.start = Some(start);
        result
    }

    /// One step of `dt` of `state` (checked by [`check`]), the `n`-th of its caller; with
    /// `known`, the tree already holds the kinematics of `state` (a [`Solver::kinematics`]
    /// of it, only its torques, targets and pushes changed since: the walkers', whose
    /// controllers read them first), and they are not computed again.
    ///
    /// # Errors
    /// A non-finite or exploding state (`Diverged`); the state is then not put back (the
    /// caller does).
    pub(super) fn step_once(
        &mut self,
        model: &Model,
        state: &mut State,
        dt: f64,
        known: bool,
        n: usize,
    ) -> Result<()> {
        match model.settings.integrator {
            Integrator::SymplecticEuler => self.euler(model, state, dt, known),
            Integrator::Rk4 => self.rk4(model, state, dt, known),
        }
        state.time += dt;
        for p in &mut state.pushes {
            p.remaining -= dt;
        }
        state.pushes.retain(|p| p.remaining > 0.0);
        match state.q.iter().chain(&state.qd).position(|v| v.is_nan() || v.abs() >= 1e8) {
            Some(index) => Err(Error::Diverged {
                step: n,
                index,
                reason: "non-finite or exploding joint state".into(),
            }),
            None => Ok(()),
        }
    }

    fn euler(&mut self, model: &Model, state: &mut State, dt: f64, known: bool) {
        let mut acc = std::mem::take(&mut self.acc[0]);
        let (mut sq, mut sqd) =
            (std::mem::take(&mut self.stage_q), std::mem::take(&mut self.stage_qd));
        acc.resize(model.nv(), 0.0);
        sq.clone_from(&state.q);
        sqd.clone_from(&state.qd);
        if !known {
            self.tree.kinematics(model, &sq, &sqd);
        }
        self.dynamics(model, state, &sq, &sqd, state.time, dt, &mut acc);
        for (v, a) in state.qd.iter_mut().zip(&acc) {
            *v += dt * a;
        }
        integrate(model, &sq, &state.qd, dt, &mut state.q);
        (self.acc[0], self.stage_q, self.stage_qd) = (acc, sq, sqd);
    }

    fn rk4(&mut self, model: &Model, state: &mut State, dt: f64, known: bool) {
        const C: [f64; 4] = [0.0, 0.5, 0.5, 1.0];
        const B: [f64; 4] = [1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0];
        let (nq, nv) = (model.nq(), model.nv());
        let mut vel = std::mem::take(&mut self.vel);
        let mut acc = std::mem::take(&mut self.acc);
        let (mut sq, mut sqd) =
            (std::mem::take(&mut self.stage_q), std::mem::take(&mut self.stage_qd));
        sq.resize(nq, 0.0);
        sqd.resize(nv, 0.0);
        for k in 0..4 {
            vel[k].resize(nq, 0.0);
            acc[k].resize(nv, 0.0);
            if k == 0 {
                sq.copy_from_slice(&state.q);
                sqd.copy_from_slice(&state.qd);
            } else {
                sq.copy_from_slice(&state.q);
                advance(model, &vel[k - 1], C[k] * dt, &mut sq);
                for j in 0..nv {
                    sqd[j] = state.qd[j] + C[k] * dt * acc[k - 1][j];
                }
            }
            coordinate_rates(model, &sq, &sqd, &mut vel[k]);
            if !(known && k == 0) {
                self.tree.kinematics(model, &sq, &sqd);
            }
            self.dynamics(model, state, &sq, &sqd, state.time + C[k] * dt, dt, &mut acc[k]);
        }
        for (j, v) in state.qd.iter_mut().enumerate() {
            *v += dt * (0..4).map(|k| B[k] * acc[k][j]).sum::<f64>();
        }
        for (j, r) in sq.iter_mut().enumerate() {
            *r = (0..4).map(|k| B[k] * vel[k][j]).sum();
        }
        advance(model, &sq, dt, &mut state.q);
        (self.vel, self.acc, self.stage_q, self.stage_qd) = (vel, acc, sq, sqd);
    }
}

/// Check a step of `dt` of `state` under `model`.
///
/// # Errors
/// `dt` not finite and > 0 (`dt`); settings out of range (named); a state of another model
/// (`state`).
pub(super) fn check(model: &Model, state: &State, dt: f64) -> Result<()> {
    if !(dt.is_finite() && dt > 0.0) {
        return Err(Error::invalid("dt", "must be finite and > 0"));
    }
    model.check_settings()?;
    if state.q.len() != model.nq() || state.qd.len() != model.nv() {
        return Err(Error::invalid("state", "is not a state of this model"));
    }
    Ok(())
}
