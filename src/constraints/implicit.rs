//! The implicit projection of the step-and-project method: the closest point of the free step
//! on `C(x) = 0` in the mass metric, found by Newton's method on its optimality (KKT)
//! conditions with the constraints' geometric stiffness.
//!
//! `min ½ (x - x̃)ᵀ M (x - x̃)` subject to `C(x) = 0` (Goldenthal et al. 2007, "Efficient
//! simulation of inextensible cloth", section 4, solved here by Newton instead of their
//! Gauss–Newton "fast projection"). With `g = M (x - x̃) - Jᵀ λ`, each iteration solves
//!
//! ```text
//! [ K   Jᵀ ] [ δx ]   [ -g ]        K = M + Σ_r max(-λ_r, 0) ∇²C_r
//! [ J  -εI ] [ μ  ] = [ -C ],       x += δx,  λ -= μ
//! ```
//!
//! `K` is the Hessian of the Lagrangian: `-λ_r ∇²C_r` is the geometric stiffness of a rod
//! under tension (`λ_r < 0`), `T/ℓ (I - d̂ d̂ᵀ)` on its two ends (Tournier et al. 2015, "Stable
//! constrained dynamics", ACM TOG 34(4), eq. 9; Andrews et al. 2017, "Geometric stiffness for
//! real-time constrained multibody dynamics", CGF 36(2)). Gauss–Newton, which leaves it out,
//! diverges once `h² T / (m ℓ) ≫ 1` (a long rope at 1/60 s): a correction along the rods of
//! the whole rope turns into transverse motion at every kink. Compression (`λ_r > 0`) would
//! make `K` indefinite and is left out. `-εI` (`ε = 1e-14 max diag(J W Jᵀ)`) keeps redundant
//! rows solvable (at `1e-10`, the multipliers' regularisation of the other solves, it matched
//! the smallest eigenvalue of a 100,000-rod chain and Newton needed up to 18 iterations
//! instead of 8); the matrix is then quasi-definite and factorised as `L D Lᵀ` on the pattern
//! analysed once. Only `Distance` and `OnSphere` rows have a geometric stiffness here; the
//! other rows are linear (`OnPlane`, `Fixed`) or enter by their gradients only (`OnCurve`,
//! `Custom`: Gauss–Newton for those rows).

use super::multipliers::Constrained;
use super::rows::{evaluate, Rows};
use super::{Constraint, PROJECTION_ITERATIONS, PROJECTION_TOL};
use crate::error::{Error, Result};
use crate::linalg::SparseCholesky;
use crate::math::outer;
use glam::DMat3;

/// The Newton iteration stops when `max |C|` is at most [`PROJECTION_TOL`] and its last step
/// moved no particle more than this (m); the error left is of the order of the square of
/// that step.
pub const NEWTON_STEP_TOL: f64 = 1e-8;

/// Unknown index of no particle (pinned, or in no constraint).
const NONE: usize = usize::MAX;

/// The KKT matrix's pattern, factorisation and vectors, built once per set of constraints and
/// pinned particles.
#[derive(Debug)]
pub(super) struct Kkt {
    /// Per particle: its first position unknown, or [`NONE`].
    dof: Vec<usize>,
    /// Number of position unknowns (3 per free constrained particle).
    nx: usize,
    /// Value index of each entry in the order [`entries`] emits them.
    slots: Vec<usize>,
    values: Vec<f64>,
    factor: SparseCholesky,
    /// The right-hand side, then the solution `[δx; μ]`.
    rhs: Vec<f64>,
    /// The free step `x̃` (positions, `3 n`).
    target: Vec<f64>,
}

impl Kkt {
    /// Analyse the pattern for the constraints on `n` particles of inverse masses `inv_mass`.
    fn new(constraints: &[Constraint], rows: &Rows, inv_mass: &[f64]) -> Result<Self> {
        let n = inv_mass.len();
        let dof = unknowns(rows, inv_mass);
        let nx = 3 * dof.iter().filter(|&&d| d != NONE).count();
        let m = rows.rows.len();
        let mut keys = Vec::new();
        entries(constraints, rows, &[], inv_mass, &dof, nx, 0.0, &mut |r, c, _| {
            keys.push((c, r));
        });
        let mut pattern = keys.clone();
        pattern.sort_unstable();
        pattern.dedup();
        let mut col_ptr = vec![0usize; nx + m + 1];
        for &(c, _) in &pattern {
            col_ptr[c + 1] += 1;
        }
        for k in 0..nx + m {
            col_ptr[k + 1] += col_ptr[k];
        }
        let row_idx: Vec<usize> = pattern.iter().map(|&(_, r)| r).collect();
        let slots = keys
            .iter()
            .map(|key| pattern.binary_search(key).expect("every key is in the pattern"))
            .collect();
        let mut signs = vec![1_i8; nx];
        signs.resize(nx + m, -1);
        Ok(Kkt {
            dof,
            nx,
            slots,
            values: vec![0.0; pattern.len()],
            factor: SparseCholesky::quasi_definite(nx + m, col_ptr, row_idx, signs)?,
            rhs: vec![0.0; nx + m],
            target: vec![0.0; 3 * n],
        })
    }

    /// Whether the pattern still fits: the same particles are free and constrained.
    fn fits(&self, rows: &Rows, inv_mass: &[f64]) -> bool {
        self.dof.len() == inv_mass.len()
            && self.rhs.len() == self.nx + rows.rows.len()
            && rows.blocks.iter().all(|&(p, _)| (inv_mass[p] > 0.0) == (self.dof[p] != NONE))
    }
}

/// The first position unknown of each particle that is free (finite mass) and constrained.
fn unknowns(rows: &Rows, inv_mass: &[f64]) -> Vec<usize> {
    let mut dof = vec![NONE; inv_mass.len()];
    let mut next = 0;
    for &(p, _) in &rows.blocks {
        if inv_mass[p] > 0.0 && dof[p] == NONE {
            dof[p] = next;
            next += 3;
        }
    }
    dof
}

/// Emit every entry `(row, column, value)` (row ≥ column) of the KKT matrix in a fixed order:
/// the masses, the geometric stiffness of each row with one (weighted by `max(-λ_r, 0)`;
/// `lambda` empty: zero), `J`, and `-ε` on the multipliers' diagonal.
#[allow(clippy::too_many_arguments)]
fn entries(
    constraints: &[Constraint],
    rows: &Rows,
    lambda: &[f64],
    inv_mass: &[f64],
    dof: &[usize],
    nx: usize,
    eps: f64,
    emit: &mut impl FnMut(usize, usize, f64),
) {
    for (p, &d) in dof.iter().enumerate() {
        if d != NONE {
            for a in 0..3 {
                emit(d + a, d + a, 1.0 / inv_mass[p]);
            }
        }
    }
    let mut block = |p: usize, q: usize, k: DMat3| {
        let (dp, dq) = (dof[p], dof[q]);
        if dp == NONE || dq == NONE {
            return;
        }
        for a in 0..3 {
            for b in 0..3 {
                let (r, c) = (dp + a, dq + b);
                if p != q || r >= c {
                    emit(r.max(c), r.min(c), k.col(b)[a]);
                }
            }
        }
    };
    let mut r = 0;
    for c in constraints {
        let (i, j, length) = match *c {
            Constraint::Distance { i, j, length } => (i, Some(j), length),
            Constraint::OnSphere { i, radius, .. } => (i, None, radius),
            _ => {
                r += c.rows();
                continue;
            }
        };
        let g = rows.blocks(r)[0].1;
        let tension = lambda.get(r).map_or(0.0, |&l| (-l).max(0.0));
        let k = tension / (rows.rows[r].c + length) * (DMat3::IDENTITY - outer(g, g));
        block(i, i, k);
        if let Some(j) = j {
            block(j, j, k);
            block(i, j, -k);
        }
        r += 1;
    }
    for r in 0..rows.rows.len() {
        for &(p, g) in rows.blocks(r) {
            if dof[p] != NONE {
                for a in 0..3 {
                    emit(nx + r, dof[p] + a, g[a]);
                }
            }
        }
        emit(nx + r, nx + r, -eps);
    }
}

impl Constrained<'_> {
    /// Replace the positions of `y = [x; v]` (a free step `x̃`) by their projection onto
    /// `C(x) = 0` (the module's Newton iteration), starting from the multipliers `h² λ` of the
    /// last step, and leave its multipliers (N) in the state's `implicit_lambda`; iterate
    /// until `max |C|` is at most [`PROJECTION_TOL`] and the last Newton step at most
    /// [`NEWTON_STEP_TOL`] (or 64 ulps of the largest coordinate).
    ///
    /// # Errors
    /// No convergence in [`PROJECTION_ITERATIONS`] iterations, a non-finite iterate, a solver
    /// failure or a constraint's failure. `y` and `implicit_lambda` may be left part-way (the callers
    /// restore them).
    pub(super) fn implicit_projection(&mut self, y: &mut [f64], h: f64) -> Result<()> {
        let n = y.len() / 6;
        let inv_mass = self.inv_mass;
        evaluate(&self.model.constraints, &self.state.curves, y, n, &mut self.work.rows)?;
        let w = &mut *self.work;
        if !w.kkt.as_ref().is_some_and(|k| k.fits(&w.rows, inv_mass)) {
            w.kkt = Some(Kkt::new(&self.model.constraints, &w.rows, inv_mass)?);
        }
        let mut kkt = w.kkt.take().expect("built above");
        kkt.target.copy_from_slice(&y[..3 * n]);
        let result = self.newton(&mut kkt, y, h * h);
        self.work.kkt = Some(kkt);
        result
    }

    /// The iterations of [`Self::implicit_projection`]; `implicit_lambda` holds `h² λ` meanwhile.
    fn newton(&mut self, kkt: &mut Kkt, y: &mut [f64], h2: f64) -> Result<()> {
        let n = y.len() / 6;
        let largest = y[..3 * n].iter().fold(0.0_f64, |a, &b| a.max(b.abs()));
        let tol = PROJECTION_TOL.max(64.0 * f64::EPSILON * largest);
        let step_tol = NEWTON_STEP_TOL.max(64.0 * f64::EPSILON * largest);
        let mut last_step = f64::MAX;
        self.warm_start(y, h2);
        for iteration in 0.. {
            evaluate(&self.model.constraints, &self.state.curves, y, n, &mut self.work.rows)?;
            let worst = self.residual(kkt, y);
            if !(worst.is_finite() && last_step.is_finite()) {
                return Err(Error::Diverged {
                    step: 0,
                    index: 0,
                    reason: "non-finite iterate in the implicit constraint projection".into(),
                });
            }
            if worst <= tol && last_step <= step_tol {
                break;
            }
            if iteration == PROJECTION_ITERATIONS {
                return Err(Error::SolverFailed {
                    reason: format!(
                        "the implicit projection left max |C| = {worst:.3e} m and a Newton \
                         step of {last_step:.3e} m after {PROJECTION_ITERATIONS} iterations: \
                         the constraints conflict, or the step is too large (lower dt)"
                    ),
                });
            }
            last_step = self.newton_step(kkt, y)?;
        }
        for l in &mut self.state.implicit_lambda {
            *l /= h2;
        }
        Ok(())
    }

    /// Scale the last step's multipliers to `h² λ` and start where they would put the
    /// particles, `x̃ + W Jᵀ h² λ`, so that the first iterate is near both `C = 0` and
    /// stationarity.
    fn warm_start(&mut self, y: &mut [f64], h2: f64) {
        let (rows, inv_mass, lambda) =
            (&self.work.rows, self.inv_mass, &mut self.state.implicit_lambda);
        for l in lambda.iter_mut() {
            *l *= h2;
        }
        for (r, &l) in lambda.iter().enumerate() {
            for &(p, g) in rows.blocks(r) {
                let d = inv_mass[p] * l * g;
                for a in 0..3 {
                    y[3 * p + a] += d[a];
                }
            }
        }
    }

    /// Fill the KKT right-hand side `[-g; -C]`, `g = M (x - x̃) - Jᵀ λ`, over the free
    /// constrained particles at the rows evaluated at `y`, and return `max |C|` over the rows
    /// that move a particle.
    fn residual(&self, kkt: &mut Kkt, y: &[f64]) -> f64 {
        let (rows, lambda, nx) = (&self.work.rows, &self.state.implicit_lambda, kkt.nx);
        kkt.rhs.fill(0.0);
        for (r, &l) in lambda.iter().enumerate() {
            let mut moves = false;
            for &(p, g) in rows.blocks(r) {
                if kkt.dof[p] != NONE {
                    moves = true;
                    for a in 0..3 {
                        kkt.rhs[kkt.dof[p] + a] += l * g[a];
                    }
                }
            }
            if moves {
                kkt.rhs[nx + r] = -rows.rows[r].c;
            }
        }
        let worst = kkt.rhs[nx..].iter().fold(0.0_f64, |a, c| a.max(c.abs()));
        for (p, &d) in kkt.dof.iter().enumerate() {
            if d != NONE {
                for a in 0..3 {
                    let k = 3 * p + a;
                    kkt.rhs[d + a] -= (y[k] - kkt.target[k]) / self.inv_mass[p];
                }
            }
        }
        worst
    }

    /// One Newton step: assemble and factorise the KKT matrix at the evaluated rows, solve
    /// for `[δx; μ]`, apply `x += δx`, `λ -= μ`, and return `max |δx|` (m).
    ///
    /// # Errors
    /// A failed factorisation.
    fn newton_step(&mut self, kkt: &mut Kkt, y: &mut [f64]) -> Result<f64> {
        let inv_mass = self.inv_mass;
        let (rows, lambda, nx) = (&self.work.rows, &mut self.state.implicit_lambda, kkt.nx);
        let eps = 1e-14
            * (0..rows.rows.len()).fold(1.0_f64, |a, r| {
                a.max(rows.blocks(r).iter().map(|&(p, g)| inv_mass[p] * g.length_squared()).sum())
            });
        kkt.values.fill(0.0);
        let mut k = 0;
        let (slots, values) = (&kkt.slots, &mut kkt.values);
        let constraints = &self.model.constraints;
        entries(constraints, rows, lambda, inv_mass, &kkt.dof, nx, eps, &mut |_, _, v| {
            values[slots[k]] += v;
            k += 1;
        });
        kkt.factor.factorize(&kkt.values)?;
        kkt.factor.solve_in_place(&mut kkt.rhs);
        let mut last_step = 0.0_f64;
        for (p, &d) in kkt.dof.iter().enumerate() {
            if d != NONE {
                for a in 0..3 {
                    y[3 * p + a] += kkt.rhs[d + a];
                    last_step = last_step.max(kkt.rhs[d + a].abs());
                }
            }
        }
        for (l, mu) in lambda.iter_mut().zip(&kkt.rhs[nx..]) {
            *l -= mu;
        }
        Ok(last_step)
    }
}
