//! The multiplier solve `(J W Jᵀ + εI) λ = -J̇ q̇ - J W Q - k_s C - k_d Ċ` (Witkin,
//! "Constrained dynamics"; Baumgarte stabilisation) by sparse Cholesky or Jacobi-preconditioned
//! CG, and the constrained equations of motion as an [`OdeSystem`].

use super::solver::Work;
use super::{evaluate, ConstraintSolver, Formulation, Model, State};
use crate::error::Result;
use crate::linalg::conjugate_gradient;
use crate::ode::OdeSystem;
use crate::particles::{Dynamics, Free};
use glam::DVec3;

/// The constrained equations of motion of `model` with `state` over the particles `free`,
/// with the workspaces `work`; and the particles' `[x; v]` and clock.
pub(super) fn assemble<'a>(
    model: &'a Model,
    state: &'a mut State,
    work: &'a mut Work,
    free: Free<'a>,
) -> (Constrained<'a>, &'a mut [f64], &'a mut f64) {
    let equations = Constrained {
        free: free.dynamics,
        inv_mass: free.inv_mass,
        model,
        ks: model.ks,
        kd: model.kd,
        state,
        work,
    };
    (equations, free.y, free.time)
}

/// The constrained equations of motion as an [`OdeSystem`].
pub(super) struct Constrained<'a> {
    pub(super) free: Dynamics<'a>,
    /// Inverse masses of the particles (1/kg, 0 pinned).
    pub(super) inv_mass: &'a [f64],
    pub(super) model: &'a Model,
    /// The drift feedback gains of this solve: the model's, or zero for a projection step.
    pub(super) ks: f64,
    pub(super) kd: f64,
    /// The curves' tracked parameters and the warm starts, updated by the solves.
    pub(super) state: &'a mut State,
    pub(super) work: &'a mut Work,
}

impl OdeSystem for Constrained<'_> {
    fn dim(&self) -> usize {
        self.free.dim()
    }

    fn rhs(&mut self, t: f64, y: &[f64], dydt: &mut [f64]) -> Result<()> {
        self.free.rhs(t, y, dydt)?;
        let n = y.len() / 6;
        let w = &mut *self.work;
        evaluate(&self.model.constraints, &self.state.curves, y, n, &mut w.rows)?;
        let (acc, inv_mass) = (&mut dydt[3 * n..], self.inv_mass);
        if let Formulation::Penalty { stiffness, damping } = self.model.formulation {
            // a += W (-k C - c Ċ) ∇C per row.
            for (r, row) in w.rows.rows.iter().enumerate() {
                let f = -(stiffness * row.c + damping * row.cdot);
                for &(p, g) in w.rows.blocks(r) {
                    let a = inv_mass[p] * f * g;
                    for k in 0..3 {
                        acc[3 * p + k] += a[k];
                    }
                }
            }
            return Ok(());
        }
        // b = -J̇q̇ - J a_free - ks C - kd Ċ.
        for (r, row) in w.rows.rows.iter().enumerate() {
            let ja: f64 = w
                .rows
                .blocks(r)
                .iter()
                .map(|&(p, g)| g.dot(DVec3::from_slice(&acc[3 * p..])))
                .sum();
            w.b[r] = -row.jdot_qdot - ja - self.ks * row.c - self.kd * row.cdot;
        }
        self.solve_multipliers()?;
        let (w, lambda) = (&*self.work, &self.state.lambda);
        // a += W Jᵀ λ.
        for (r, &l) in lambda.iter().enumerate() {
            for &(p, g) in w.rows.blocks(r) {
                let f = inv_mass[p] * l * g;
                for k in 0..3 {
                    acc[3 * p + k] += f[k];
                }
            }
        }
        Ok(())
    }
}

impl Constrained<'_> {
    /// Solve `(J W Jᵀ + εI) λ = b` for the rows and right-hand side in the workspace.
    pub(super) fn solve_multipliers(&mut self) -> Result<()> {
        let (inv_mass, state) = (self.inv_mass, &mut *self.state);
        let w = &mut *self.work;
        for r in 0..w.rows.rows.len() {
            w.diag[r] =
                w.rows.blocks(r).iter().map(|&(p, g)| inv_mass[p] * g.length_squared()).sum();
        }
        let eps = 1e-10 * w.diag.iter().fold(1.0_f64, |a, &b| a.max(b));
        match self.model.solver {
            ConstraintSolver::Cholesky => {
                w.values.fill(0.0);
                let block = |r: usize, p: usize| {
                    w.rows.blocks(r).iter().filter(|b| b.0 == p).map(|b| b.1).sum::<DVec3>()
                };
                for &(idx, r, s, p) in &w.contributions {
                    w.values[idx] += inv_mass[p] * block(r, p).dot(block(s, p));
                }
                for &k in &w.diagonal_index {
                    w.values[k] += eps;
                }
                let chol = w.chol.as_mut().expect("pattern built before stepping");
                chol.factorize(&w.values)?;
                state.lambda.copy_from_slice(&w.b);
                chol.solve_in_place(&mut state.lambda);
                state.iterations = 0;
            }
            ConstraintSolver::ConjugateGradient => {
                let (rows, scratch) = (&w.rows, &mut w.scratch);
                let mut apply = |x: &[f64], out: &mut [f64]| {
                    // out = (J W Jᵀ + εI) x, matrix-free.
                    scratch.fill(0.0);
                    for (r, xr) in x.iter().enumerate() {
                        for &(p, g) in rows.blocks(r) {
                            for k in 0..3 {
                                scratch[3 * p + k] += g[k] * xr;
                            }
                        }
                    }
                    for (r, o) in out.iter_mut().enumerate() {
                        *o = eps * x[r]
                            + rows
                                .blocks(r)
                                .iter()
                                .map(|&(p, g)| {
                                    inv_mass[p] * g.dot(DVec3::from_slice(&scratch[3 * p..]))
                                })
                                .sum::<f64>();
                    }
                };
                let result = conjugate_gradient(
                    &mut apply,
                    &w.b,
                    &w.diag,
                    &mut state.lambda,
                    1e-12,
                    10 * w.b.len() + 100,
                    &mut w.cg,
                );
                state.iterations = result?;
            }
        }
        Ok(())
    }
}
