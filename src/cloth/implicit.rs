//! The implicit step of the cloth (Baraff & Witkin 1998, §4–§5): implicit Euler or the
//! variable-step BDF2 of Choi & Ko (2002) share one assembly of `(M − γh ∂f/∂v − (γh)² ∂f/∂x)`
//! with history terms, solved by the modified PCG with the constraint filter (§5.3) or by
//! sparse Cholesky ([`super::linear`]), with Newton iterations where the one linearised solve
//! adds energy; a step that strains the cloth too much is refused here and redone as two half
//! steps by [`Solver::step`].

use super::elements::Accumulator;
use super::solver::Implicit;
use super::{pcg, StepStats, VertexConstraint};
use super::{ContactState, Elasticity, LinearSolver, Model, SolveOptions, Solver, State};
use crate::error::{Error, Result};
use crate::ode::bdf2_weights;
use glam::{DMat3, DVec3};
use std::time::Instant;

impl Solver {
    /// One linearised implicit step of `h` (BDF2 when `how.bdf2` and the state has a history).
    /// With `check = Some(ceiling)` a step whose largest change of a stretch ratio exceeds
    /// `max_strain_change` but not `ceiling` is refused: no step is taken and its change is
    /// returned (see [`Solver::adaptive`]); otherwise the step is taken and `None` returned.
    /// The numbers of the step are added to `stats`.
    pub(super) fn step_implicit(
        &mut self,
        how: Implicit,
        state: &mut State,
        stats: &mut StepStats,
        h: f64,
        check: Option<f64>,
    ) -> Result<Option<f64>> {
        let Implicit { model, bdf2, options } = how;
        // Variable-step BDF2 (Choi & Ko 2002, eq. 12, at a constant step): with (c, γ) of
        // `bdf2_weights`, x₊ = x + c (x - x₋) + γh v₊, v₊ = v + c (v - v₋) + γh M⁻¹ f₊.
        let previous = if bdf2 { state.previous_dt } else { None };
        let h_eff = self.history_terms(state, h, previous);
        // A contact only pushes: one whose constraint impulse pulls the vertex towards the
        // collider in the solve is released and the step solved again, once (see
        // `Solver::release_pulling`).
        let mut resolved = false;
        let mut collide_time = 0.0;
        let (residual, converged, start_elastic) = loop {
            let t0 = Instant::now();
            self.build_constraints(model, state, h, h_eff);
            collide_time += t0.elapsed().as_secs_f64();

            let t1 = Instant::now();
            let start_elastic = self.assemble(model, state, h_eff, false);
            stats.assemble_seconds += t1.elapsed().as_secs_f64();
            self.check_overflow(h)?;

            let t2 = Instant::now();
            let (iterations, residual, converged) = self.solve(model, state, options)?;
            stats.iterations += iterations;
            stats.solve_seconds += t2.elapsed().as_secs_f64();
            if resolved || !self.release_pulling(state) {
                break (residual, converged, start_elastic);
            }
            resolved = true;
        };
        let start = kinetic_and_gravity(model, &state.x, &state.v) + start_elastic;
        let (residual, converged) =
            self.newton(how, state, stats, h, h_eff, start)?.unwrap_or((residual, converged));

        let t3 = Instant::now();
        self.motion(model, state, h, h_eff);
        // The change is measured on the positions the step would commit, after the strain
        // limit: a stretch the limiter takes back is no change of the cloth's shape (before,
        // a cloth hanging at the limit had every step halved: the unlimited solve overshoots
        // the limit by more than `max_strain_change` at the pinned corners).
        self.limit_strain(model, h_eff, options.max_strain);
        let refused = match check {
            Some(ceiling) if options.max_strain_change.is_finite() => {
                let change = strain_change(model, &state.x, &self.scratch.x_new);
                (change > options.max_strain_change && change <= ceiling).then_some(change)
            }
            _ => None,
        };
        if refused.is_none() {
            self.self_collide(model, state, h, options.max_strain, stats);
            let s = &self.scratch;
            let n = state.len();
            if let Some(i) = (0..n).find(|&i| !(s.x_new[i].is_finite() && s.v_new[i].is_finite())) {
                return Err(Error::Diverged {
                    step: 0,
                    index: i,
                    reason: "non-finite cloth state".into(),
                });
            }
            self.commit(state, h);
            stats.residual = residual;
            stats.converged &= converged;
            stats.contacts = self.scratch.contact_normal.len();
            stats.substeps += 1;
        }
        stats.collide_seconds += collide_time + t3.elapsed().as_secs_f64();
        Ok(refused)
    }

    /// Newton iterations of the implicit equation where the one linearised solve adds energy
    /// (issue #21, the whole-step landing): while the energy (kinetic, gravitational and
    /// elastic) at the end of the last solve exceeds `start`, the energy at the step's start,
    /// by more than [`ENERGY_SLACK`] of its magnitude, the system is linearised again about
    /// that end ([`Solver::assemble`] `at_iterate`) and solved again, at most [`NEWTON`] times,
    /// stopping early when a solve changes no velocity by more than [`NEWTON_TOL`]. The
    /// constraints and contacts stay those of the first solve. A step whose first solve does
    /// not gain energy pays one evaluation of the elastic energy at its end.
    ///
    /// Why: a stretch condition at zero tension has no stiffness across its direction, so the
    /// linearisation about the step's start lets a vertex next to one a contact stops fall on
    /// across an unstretched edge; the positions committed are stretched, and the landing of a
    /// 64² sheet on a sphere in whole steps went 7.28 → 7.50 → 10.26 → 22.2 J
    /// (`tests/cloth_landing.rs`). The iterations converge to the root of the implicit
    /// equation itself, which the linearisation only approximates. Returns the last solve's
    /// `(residual, converged)` when it iterated.
    fn newton(
        &mut self,
        how: Implicit,
        state: &mut State,
        stats: &mut StepStats,
        h: f64,
        h_eff: f64,
        start: f64,
    ) -> Result<Option<(f64, bool)>> {
        let Implicit { model, options, .. } = how;
        let mut outcome = None;
        let scale = ENERGY_SLACK * start.abs().max(f64::MIN_POSITIVE);
        for _ in 0..NEWTON {
            self.end_of_solve(state, h_eff);
            let s = &mut self.scratch;
            let elastic = model.forces_into(&s.x_new, &s.v_new, &mut s.f);
            if kinetic_and_gravity(model, &s.x_new, &s.v_new) + elastic <= start + scale {
                break;
            }
            let t1 = Instant::now();
            self.assemble(model, state, h_eff, true);
            stats.assemble_seconds += t1.elapsed().as_secs_f64();
            self.check_overflow(h)?;
            let t2 = Instant::now();
            let (iterations, residual, converged) = self.solve(model, state, options)?;
            stats.iterations += iterations;
            stats.newton_iterations += 1;
            stats.solve_seconds += t2.elapsed().as_secs_f64();
            outcome = Some((residual, converged));
            let s = &self.scratch;
            let change = (0..state.len())
                .map(|i| (state.v[i] + state.dv[i] - s.v_new[i]).abs().max_element())
                .fold(0.0, f64::max);
            if change <= NEWTON_TOL {
                break;
            }
        }
        Ok(outcome)
    }

    /// An error naming `dt` (the step `h`, s) when the assembled system has overflowed: a step
    /// so large that `h² ∂f/∂x` or `h f` overflows has no meaningful solve (at dt = 1e100 the
    /// PCG would stop at once and the step would silently do nothing).
    fn check_overflow(&self, h: f64) -> Result<()> {
        if self.scratch.b.iter().all(|b| b.is_finite())
            && self.matrix.blocks.iter().all(|b| b.is_finite())
        {
            return Ok(());
        }
        Err(Error::invalid(
            "dt",
            format!("{h} s is too large for this cloth: the implicit system overflows"),
        ))
    }

    /// Solve the assembled system for `state.dv` with the linear solver of `options`:
    /// `(iterations, residual, converged)`.
    fn solve(
        &mut self,
        model: &Model,
        state: &mut State,
        options: SolveOptions,
    ) -> Result<pcg::Outcome> {
        match options.solver {
            LinearSolver::Multigrid => self.solve_multigrid(model, state, options),
            LinearSolver::BlockSsor => self.solve_pcg(state, options),
            LinearSolver::Cholesky => self.solve_cholesky(state),
        }
    }

    /// The BDF2 history terms `c (x - x₋)`, `c (v - v₋)` into the scratch (zero for implicit
    /// Euler or a restart), with `(c, γ)` of [`bdf2_weights`] for this step `h` and the
    /// previous one (`previous`, s); returns the effective step `γh` (`h` for implicit Euler).
    fn history_terms(&mut self, state: &State, h: f64, previous: Option<f64>) -> f64 {
        let weights = previous.and_then(|hp| bdf2_weights(h, Some(hp)));
        let s = &mut self.scratch;
        for i in 0..state.len() {
            (s.hx[i], s.hv[i]) = match weights {
                Some((c, _)) => {
                    (c * (state.x[i] - state.previous_x[i]), c * (state.v[i] - state.previous_v[i]))
                }
                None => (DVec3::ZERO, DVec3::ZERO),
            };
        }
        weights.map_or(h, |(_, gamma)| gamma * h)
    }

    /// Assemble `A = M - h ∂f/∂v - h² ∂f/∂x` (into the matrix) and `b = M c_v + h (f + ∂f/∂x u)`,
    /// `u = c_x + h v + y`, with `h` the effective step `h_eff` and Coulomb friction at the
    /// contacts as an explicit force; returns the elastic energy (J) at the linearisation's
    /// positions.
    ///
    /// With `at_iterate`, the system is linearised about the end of the last solve instead of
    /// the start of the step (a Newton iteration, [`Solver::newton`]): `A` and `f` at
    /// `x_k = x + c_x + h v_k + y`, `v_k = v + Δv_k` (the scratch's `x_new`, `v_new`), and
    /// `b = M c_v + h f(x_k, v_k) + (A - M) Δv_k`, the right-hand side whose solution `Δv` is
    /// the next iterate (the same equation with the linearisation's point moved; friction
    /// stays the explicit force of the step's start).
    fn assemble(&mut self, model: &Model, state: &State, h_eff: f64, at_iterate: bool) -> f64 {
        let (s, air) = (&mut self.scratch, model.material.air_damping);
        let (x, v) = if at_iterate { (&s.x_new, &s.v_new) } else { (&state.x, &state.v) };
        for (i, &vi) in v.iter().enumerate() {
            s.u[i] = if at_iterate { DVec3::ZERO } else { s.hx[i] + h_eff * vi + s.y[i] };
            s.f[i] = (model.gravity - air * vi) * model.mass[i];
            s.ku[i] = DVec3::ZERO;
        }
        let blocks = &mut self.matrix.blocks;
        blocks.iter_mut().for_each(|b| *b = DMat3::ZERO);
        let diagonal = 1.0 + h_eff * air;
        for (block, m) in blocks.iter_mut().zip(&model.mass) {
            *block = DMat3::from_diagonal(DVec3::splat(m * diagonal));
        }
        let mut acc = Accumulator {
            v,
            f: &mut s.f,
            matrix: Some((blocks, h_eff, h_eff * h_eff)),
            ku: (!at_iterate).then_some((&s.u, &mut s.ku)),
            energy: 0.0,
        };
        model.add_elements(x, &mut acc);
        let elastic = acc.energy;
        // Coulomb friction as an explicit force: the tangential impulse that would bring the
        // vertex to rest on the surface within the step against its momentum and gravity,
        // `p = m (v_rel + h g)` on the tangent plane, limited to `μ jₙ` — static when the limit
        // is not reached. (The stiff elastic forces stay out of it: an explicit force built
        // from them would be an explicit step of them.)
        for &(i, normal, vc, mu, jn) in &s.contact_normal {
            let p = model.mass[i] * (state.v[i] - vc + h_eff * model.gravity);
            let jn = jn.max(-normal.dot(p));
            let pt = p - normal * normal.dot(p);
            let len = pt.length();
            if len > 0.0 {
                s.f[i] -= pt * ((mu * jn).min(len) / (len * h_eff));
            }
        }
        for i in 0..state.len() {
            s.b[i] = model.mass[i] * s.hv[i] + h_eff * (s.f[i] + s.ku[i]);
        }
        if at_iterate {
            self.matrix.mul(&state.dv, &mut s.q);
            for i in 0..state.len() {
                s.b[i] += s.q[i] - model.mass[i] * state.dv[i];
            }
        }
        elastic
    }

    /// The step's new velocities `v + Δv` and positions `x + c_x + h_eff v₊ + y` (pinned
    /// vertices at their targets) into the scratch, the contact states it leaves, and
    /// vertices dragged into a collider projected out.
    fn motion(&mut self, model: &Model, state: &State, h: f64, h_eff: f64) {
        self.end_of_solve(state, h_eff);
        self.contact_states(&state.dv);
        self.project_penetrating(model, state, h);
    }

    /// The solve's velocities `v + Δv` and positions `x + c_x + h_eff v₊ + y` (pinned vertices
    /// at their targets) into the scratch's `v_new`, `x_new`.
    fn end_of_solve(&mut self, state: &State, h_eff: f64) {
        let s = &mut self.scratch;
        for i in 0..state.len() {
            s.v_new[i] = state.v[i] + state.dv[i];
            s.x_new[i] = match state.constraints[i] {
                Some(VertexConstraint::Pinned(p)) => p,
                _ => state.x[i] + s.hx[i] + h_eff * s.v_new[i] + s.y[i],
            };
        }
    }

    /// Release the contacts of the step whose constraint impulse `A Δv - b` (Baraff & Witkin
    /// §5.3) pulls the vertex towards the collider, for the solve to be taken again without
    /// them; returns whether any was released. Baraff & Witkin release such a contact at the
    /// next step; within the step it pulls, and the momentum it adds towards the collider
    /// stays. At the short substeps of a landing (`h/8`–`h/16`), where the contact set changes
    /// at every substep, some contacts pulled in every one (with no bending stiffness the gain
    /// below vanished: the bending at the rim of the landed region pushes them off): a 64²
    /// sheet landing on a sphere at 1.64 m/s in 8 substeps of `h/8` gained downward momentum
    /// beyond its free fall, energy (7.98 J from 7.28 J) and a largest speed of 3.6 m/s
    /// (`tests/cloth_landing.rs`); released within the step, the landing takes energy away
    /// and the largest speed stays within 6 % of the free fall's (1.90 m/s against 1.80).
    /// Released here, a contact stays so for the rest of the step (and in the state, also
    /// when the step is refused and halved), constrained again only where the vertex would
    /// otherwise end inside the collider.
    fn release_pulling(&mut self, state: &mut State) -> bool {
        self.contact_states(&state.dv);
        let s = &self.scratch;
        let mut released = false;
        for &(i, ..) in &s.contact_normal {
            if s.states[i] == ContactState::Released {
                state.contact[i] = ContactState::Released;
                released = true;
            }
        }
        released
    }

    /// Contact states for the next step from the constraint impulse `A Δv - b` (Baraff &
    /// Witkin §5.3): a pulling impulse releases the contact.
    fn contact_states(&mut self, dv: &[DVec3]) {
        let s = &mut self.scratch;
        s.states.iter_mut().for_each(|c| *c = ContactState::Free);
        if !s.contact_normal.is_empty() {
            self.matrix.mul(dv, &mut s.q);
        }
        for &(i, normal, ..) in &s.contact_normal {
            let jn = (s.q[i] - s.b[i]).dot(normal);
            s.states[i] =
                if jn < 0.0 { ContactState::Released } else { ContactState::Touching(jn) };
        }
    }

    /// Take the step: the state before it becomes the history, the new positions and
    /// velocities are copied in (never swapped: Python views of the state buffers stay
    /// valid), the contact states are kept and the colliders moved on by `h`.
    fn commit(&mut self, state: &mut State, h: f64) {
        let s = &mut self.scratch;
        state.previous_x.copy_from_slice(&state.x);
        state.previous_v.copy_from_slice(&state.v);
        state.previous_dt = Some(h);
        state.x.copy_from_slice(&s.x_new);
        state.v.copy_from_slice(&s.v_new);
        std::mem::swap(&mut state.contact, &mut s.states);
        state.advance_colliders(h);
    }
}

/// The largest change of a stretch ratio between positions `x` and `x_new`.
fn strain_change(model: &Model, x: &[DVec3], x_new: &[DVec3]) -> f64 {
    let mut worst: f64 = 0.0;
    if model.elasticity == Elasticity::BaraffWitkin {
        for t in &model.elements {
            let (u0, v0) = t.warp(x);
            let (u1, v1) = t.warp(x_new);
            worst =
                worst.max((u1.length() - u0.length()).abs()).max((v1.length() - v0.length()).abs());
        }
    }
    for sp in &model.springs {
        let [a, b] = sp.verts;
        let change = ((x_new[b] - x_new[a]).length() - (x[b] - x[a]).length()) / sp.rest;
        worst = worst.max(change.abs());
    }
    worst
}

/// The share of the magnitude of a step's starting energy by which the end of its solve may
/// exceed it before [`Solver::newton`] iterates (rounding, not physics: a sheet at rest
/// neither gains nor loses).
const ENERGY_SLACK: f64 = 1e-9;

/// The most Newton iterations (solves beyond the first) of one step.
const NEWTON: usize = 4;

/// A Newton iteration that changes no velocity component by more than this (m/s) ends them.
const NEWTON_TOL: f64 = 1e-3;

/// Kinetic and gravitational energy (J) of positions `x` and velocities `v` of `model`, the
/// potential `-Σ m g·x` as in [`Model::energy`].
fn kinetic_and_gravity(model: &Model, x: &[DVec3], v: &[DVec3]) -> f64 {
    let mut sum = 0.0;
    for ((x, v), m) in x.iter().zip(v).zip(&model.mass) {
        sum += m * (0.5 * v.length_squared() - model.gravity.dot(*x));
    }
    sum
}
