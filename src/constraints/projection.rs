//! The step-and-project path and the post-stabilisation of Cline & Pai (2003): Gauss–Newton
//! projections of the positions onto `C = 0` in the mass metric, then of the velocities onto
//! `J v = 0`.

use super::multipliers::{assemble, Constrained};
use super::solver::{Particles, Solver};
use super::{curve::track_curves, evaluate, Formulation, Model, State};
use super::{PROJECTION_ITERATIONS, PROJECTION_TOL};
use crate::error::{Error, Result};
use crate::ode::OdeSystem;

/// One step of [`Solver::step_projection`] from `y = [x; v]` at `time` into `next`:
/// the free step `x̃ = x + h (v + h a_free)`, its implicit projection, `v₁ = (x₁ - x₀) / h`,
/// and with post-stabilisation the velocity projection onto `J v = 0`.
pub(super) fn projection_step(
    system: &mut Constrained<'_>,
    time: f64,
    y: &[f64],
    dt: f64,
    next: &mut [f64],
) -> Result<()> {
    let n = y.len() / 6;
    // next = [v; a_free].
    system.free.rhs(time, y, next)?;
    for k in 0..3 * n {
        next[k] = y[k] + dt * (y[3 * n + k] + dt * next[3 * n + k]);
    }
    system.implicit_projection(next, dt)?;
    for k in 0..3 * n {
        next[3 * n + k] = (next[k] - y[k]) / dt;
    }
    if system.model.stabilize {
        system.project_velocities(next)?;
    }
    Ok(())
}

impl Solver {
    /// Advance `particles` and `state` (a state of `model` on them) `steps` steps of `dt` by
    /// step and project (Goldenthal et al. 2007, "Efficient simulation of inextensible
    /// cloth", section 4): the free step `x̃ = x + h (v + h a_free)` is replaced by its
    /// closest point on `C(x) = 0` in the mass metric, and the velocity is
    /// `v₁ = (x₁ - x₀) / h`. The constraint impulse acts along the constraints' directions at
    /// the end of the step (an implicit step in the limit of infinite stiffness), so a rope
    /// of any tension is stable at any step; first order and dissipative. The projection is
    /// solved by Newton's method with the constraints' geometric stiffness (see
    /// `implicit.rs`) to [`PROJECTION_TOL`]; with post-stabilisation on
    /// ([`Model::set_stabilization`]) the velocities are then projected onto `J v = 0` at the
    /// new positions. Multiplier formulation only.
    ///
    /// # Errors
    /// A bad `dt`, the penalty formulation, a projection that does not converge (a step so
    /// large that the free motion leaves the constraints beyond the linearisation, or
    /// conflicting constraints), a solver failure, a custom constraint's failure, particles or
    /// a state of another model, or a non-finite state; the particles and `state` are left at
    /// the last good step.
    pub fn step_projection(
        &mut self,
        model: &Model,
        state: &mut State,
        particles: Particles<'_>,
        dt: f64,
        steps: usize,
    ) -> Result<()> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(Error::invalid("dt", format!("must be positive and finite, got {dt}")));
        }
        if model.formulation != Formulation::Multipliers {
            return Err(Error::invalid(
                "method",
                "projection needs the multiplier formulation, not penalty",
            ));
        }
        let n = particles.model.capacity();
        let free = self.start(model, state, particles)?;
        let mut next = std::mem::take(&mut self.work.next);
        next.resize(6 * n, 0.0);
        let (mut system, y, time) = assemble(model, state, &mut self.work, free);
        system.ks = 0.0;
        system.kd = 0.0;
        let result = projection_steps(&mut system, y, time, dt, steps, &mut next);
        self.work.next = next;
        result
    }
}

/// The steps of [`Solver::step_projection`] of `y` at `time`, with `next` (`6 n` values) for
/// the state being built.
fn projection_steps(
    system: &mut Constrained<'_>,
    y: &mut [f64],
    time: &mut f64,
    dt: f64,
    steps: usize,
    next: &mut [f64],
) -> Result<()> {
    let n = y.len() / 6;
    for s in 0..steps {
        system.save_state();
        let result = projection_step(system, *time, y, dt, next).and_then(|()| {
            match next.iter().position(|v| !v.is_finite()) {
                Some(bad) => Err(Error::Diverged {
                    step: s,
                    index: (bad % (3 * n)) / 3,
                    reason: "non-finite state in the constraint projection".into(),
                }),
                None => Ok(()),
            }
        });
        let result = result
            .and_then(|()| track_curves(&system.model.constraints, next, &mut system.state.curves));
        if let Err(e) = result {
            system.restore_state();
            return Err(e);
        }
        y.copy_from_slice(next);
        *time += dt;
    }
    Ok(())
}

impl Constrained<'_> {
    /// Post-stabilisation of `y = [x; v]` (Cline & Pai 2003): Gauss–Newton projections of the
    /// positions onto `C(x) = 0` in the mass metric, `(J W Jᵀ + εI) δ = -C`, `x += W Jᵀ δ`,
    /// until `max |C| ≤` [`PROJECTION_TOL`] (or, far from the origin, 64 ulps of the largest
    /// coordinate) over the rows that act on a particle of finite mass, then the velocities onto `J v = 0` at the projected positions,
    /// `(J W Jᵀ + εI) μ = -J v`, `v += W Jᵀ μ`. `y` may be left part-way on failure (the
    /// callers restore it).
    ///
    /// # Errors
    /// No convergence in [`PROJECTION_ITERATIONS`] projections (conflicting constraints, which
    /// have no point with `C = 0`, or a step too large for the linearisation), a solver failure
    /// or a constraint's failure.
    pub(super) fn project_positions(&mut self, y: &mut [f64]) -> Result<()> {
        let n = y.len() / 6;
        let largest = y[..3 * n].iter().fold(0.0_f64, |a, &b| a.max(b.abs()));
        let tol = PROJECTION_TOL.max(64.0 * f64::EPSILON * largest);
        let inv_mass = self.inv_mass;
        for iteration in 0.. {
            evaluate(&self.model.constraints, &self.state.curves, y, n, &mut self.work.rows)?;
            let w = &mut *self.work;
            // Rows on pinned particles only cannot be moved, so they are not waited for.
            let worst = (0..w.rows.rows.len())
                .filter(|&r| w.rows.blocks(r).iter().any(|&(p, _)| inv_mass[p] > 0.0))
                .fold(0.0_f64, |a, r| a.max(w.rows.rows[r].c.abs()));
            if worst <= tol {
                break;
            }
            if iteration == PROJECTION_ITERATIONS {
                return Err(Error::SolverFailed {
                    reason: format!(
                        "the position projection left max |C| = {worst:.3e} after \
                         {PROJECTION_ITERATIONS} iterations: the constraints conflict, or \
                         the step is too large (lower dt)"
                    ),
                });
            }
            for (b, row) in w.b.iter_mut().zip(&w.rows.rows) {
                *b = -row.c;
            }
            self.apply_correction(y, 0)?;
        }
        Ok(())
    }

    /// Post-stabilisation of the velocities of `y = [x; v]` (Cline & Pai 2003): onto
    /// `J v = 0` at the positions of `y`, `(J W Jᵀ + εI) μ = -J v`, `v += W Jᵀ μ`.
    ///
    /// # Errors
    /// A solver failure or a constraint's failure.
    pub(super) fn project_velocities(&mut self, y: &mut [f64]) -> Result<()> {
        let n = y.len() / 6;
        evaluate(&self.model.constraints, &self.state.curves, y, n, &mut self.work.rows)?;
        let w = &mut *self.work;
        for (b, row) in w.b.iter_mut().zip(&w.rows.rows) {
            *b = -row.cdot;
        }
        self.apply_correction(y, 3 * n)
    }

    /// Solve for the multipliers of the right-hand side in the workspace and add `W Jᵀ λ` to
    /// the block of `y` at `offset` (0: positions, `3 n`: velocities).
    pub(super) fn apply_correction(&mut self, y: &mut [f64], offset: usize) -> Result<()> {
        self.solve_multipliers()?;
        let (w, inv_mass, lambda) = (&*self.work, self.inv_mass, &self.state.lambda);
        for (r, &l) in lambda.iter().enumerate() {
            for &(p, g) in w.rows.blocks(r) {
                let d = inv_mass[p] * l * g;
                for k in 0..3 {
                    y[offset + 3 * p + k] += d[k];
                }
            }
        }
        Ok(())
    }
}
