//! Fixed-step integration with preallocated workspaces.

// Numeric kernels index several arrays in step; index loops read closest to the formulas.
#![allow(clippy::needless_range_loop)]

use super::sparse::SparseNewton;
use super::{History, Method, OdeSystem};
use crate::error::{filled, Error, Result};
use nalgebra::DMatrix;

/// Newton corrections that shrink by less than this factor per iteration trigger a Jacobian
/// update (the simplified iteration contracts too slowly).
const NEWTON_CONTRACTION: f64 = 0.5;

/// Smallest fraction of a Newton update kept when backtracking.
const MIN_FRACTION: f64 = 1.0 / 64.0;

/// A step whose Newton iteration fails is retried as 2, 4, … up to `2^MAX_SPLITS` substeps.
const MAX_SPLITS: u32 = 4;

/// The workspaces of fixed-step integration: advances an [`OdeSystem`] by one step of the
/// method of a [`History`], allocating nothing per step once sized (at the first step of a
/// dimension). It carries nothing that a later step reads: one workspace can advance any
/// number of histories and states, in any interleaving, bitwise as if each had its own.
///
/// A step either completes or returns an error and leaves `y` untouched. Implicit methods
/// solve their equations by Newton iterations from the start of the step: the Jacobian is
/// evaluated once per step (simplified Newton) and again at the current iterate when the
/// corrections shrink by less than half (the update is then recomputed there); an update
/// after which the correction, computed with the same matrix, does not shrink at all is taken
/// back by halves down to 1/64 (Deuflhard's natural monotonicity test, *Newton Methods for
/// Nonlinear Problems*, 2004, §3.3). This keeps strongly nonlinear steps (a stiff chain that
/// swings, k = 1e9 at dt = 1/60) converging, but it is no guarantee: on a stiff 2-D spring net
/// (h² k / m = 280 on 30 x 30 particles) it stalls. A step whose Newton iteration fails is
/// then retried as 2, 4, 8 and 16 equal substeps of the method (BDF2 restarting, so its
/// substeps are implicit Euler steps), which shrink `γ h` until Newton converges; only when 16
/// substeps fail does the step fail.
///
/// When the system offers a sparse Jacobian ([`OdeSystem::sparse_jacobian`]) the iteration
/// matrix `I - γ h J` is assembled in its pattern and factorised by faer's sparse LU (symbolic
/// analysis kept per pattern, which is bitwise-neutral; numeric factorisation per Jacobian
/// update, kept while the matrix is bitwise the same, as for linear forces at a constant
/// step, which is bitwise-neutral too). A system whose Jacobian is constant
/// ([`OdeSystem::constant_jacobian`]) is not asked for it again while its key and `γ h` are
/// those of the factors, and with a sparse Jacobian its step is the one Newton update that
/// solves the affine equation. Otherwise the Jacobian is dense (analytic, or by forward differences over every
/// column) with a dense LU factorisation with partial pivoting, in place. The dense workspaces
/// (`n²` values) are allocated at the first dense step, so systems with a sparse Jacobian
/// never hold them.
#[derive(Clone, Debug)]
pub struct Workspace {
    n: usize,
    k: [Vec<f64>; 4],
    stage: Vec<f64>,
    y_new: Vec<f64>,
    /// The state between the substeps of a split implicit step.
    sub: Vec<f64>,
    jac: DMatrix<f64>,
    lu: Vec<f64>,
    pivots: Vec<usize>,
    /// The states of the finite-difference columns and their derivatives (`n²` values each,
    /// sized at the first difference Jacobian of a dimension).
    columns: Vec<f64>,
    derivatives: Vec<f64>,
    sparse: SparseNewton,
    /// Numeric LU factorisations of the iteration matrix so far (sparse or dense), for the
    /// callers' statistics; no step reads it.
    factorizations: usize,
}

impl Default for Workspace {
    fn default() -> Self {
        Workspace {
            n: 0,
            k: Default::default(),
            stage: Vec::new(),
            y_new: Vec::new(),
            sub: Vec::new(),
            jac: DMatrix::zeros(0, 0),
            lu: Vec::new(),
            pivots: Vec::new(),
            columns: Vec::new(),
            derivatives: Vec::new(),
            sparse: SparseNewton::default(),
            factorizations: 0,
        }
    }
}

impl Workspace {
    /// Numeric LU factorisations of the Newton iteration matrix this workspace has made: one
    /// per Jacobian update, except sparse updates whose matrix is bitwise the one already
    /// factorised (kept; see the type's docs).
    pub fn factorizations(&self) -> usize {
        self.factorizations
    }

    fn eval<S: OdeSystem>(
        &mut self,
        hist: &mut History,
        sys: &mut S,
        t: f64,
        which: usize,
        y: Option<&[f64]>,
    ) -> Result<()> {
        hist.nfev += 1;
        let input = y.unwrap_or(&self.stage);
        sys.rhs(t, input, &mut self.k[which])
    }

    /// Advance `y` (length `n`, the history's dimension) from `t` by one step of `h > 0` with
    /// the history's method, reading and updating `hist` (the previous BDF2 step, counters).
    ///
    /// # Errors
    /// A bad `h` or `y` length, a system error, a Newton failure ([`Error::SolverFailed`]) or a
    /// non-finite result ([`Error::Diverged`] with step 0 and the first bad component); `y` and
    /// `hist`'s previous step are unchanged in every case (the counters count the attempt).
    pub fn step<S: OdeSystem>(
        &mut self,
        hist: &mut History,
        sys: &mut S,
        t: f64,
        y: &mut [f64],
        h: f64,
    ) -> Result<()> {
        if !(h.is_finite() && h > 0.0) {
            return Err(Error::invalid("dt", format!("must be positive and finite, got {h}")));
        }
        let n = hist.dimension();
        if y.len() != n || sys.dim() != n {
            return Err(Error::invalid(
                "y0",
                format!("has length {}, the system has dimension {}", y.len(), sys.dim()),
            ));
        }
        self.fit(n, hist.method().is_implicit());
        if hist.method().is_implicit() {
            self.split_implicit_step(hist, sys, t, y, h)?;
        } else {
            self.explicit_step(hist, sys, t, y, h)?;
        }
        // One pass without an early exit (it vectorises), then the first bad component.
        if self.y_new.iter().fold(false, |bad, x| bad | !x.is_finite()) {
            return Err(Error::Diverged {
                step: 0,
                index: self.y_new.iter().position(|x| !x.is_finite()).unwrap_or(0),
                reason: format!("{} produced a non-finite state", hist.method().name()),
            });
        }
        if hist.method() == Method::Bdf2 {
            hist.prev.copy_from_slice(y);
            hist.prev_h = Some(h);
        }
        y.copy_from_slice(&self.y_new);
        Ok(())
    }

    /// Size the workspaces for states of length `n` (allocating only when the size changes).
    fn fit(&mut self, n: usize, implicit: bool) {
        if self.n != n {
            for v in self.k.iter_mut().chain([&mut self.stage, &mut self.y_new]) {
                v.resize(n, 0.0);
            }
            self.n = n;
        }
        if implicit && self.sub.len() != n {
            self.sub.resize(n, 0.0);
        }
    }

    /// One step of an explicit method into `y_new`.
    fn explicit_step<S: OdeSystem>(
        &mut self,
        hist: &mut History,
        sys: &mut S,
        t: f64,
        y: &[f64],
        h: f64,
    ) -> Result<()> {
        let n = self.n;
        match hist.method() {
            Method::ExplicitEuler => {
                self.eval(hist, sys, t, 0, Some(y))?;
                for i in 0..n {
                    self.y_new[i] = y[i] + h * self.k[0][i];
                }
            }
            Method::Midpoint => {
                self.eval(hist, sys, t, 0, Some(y))?;
                for i in 0..n {
                    self.stage[i] = y[i] + 0.5 * h * self.k[0][i];
                }
                self.eval(hist, sys, t + 0.5 * h, 1, None)?;
                for i in 0..n {
                    self.y_new[i] = y[i] + h * self.k[1][i];
                }
            }
            Method::Heun => {
                self.eval(hist, sys, t, 0, Some(y))?;
                for i in 0..n {
                    self.stage[i] = y[i] + h * self.k[0][i];
                }
                self.eval(hist, sys, t + h, 1, None)?;
                for i in 0..n {
                    self.y_new[i] = y[i] + 0.5 * h * (self.k[0][i] + self.k[1][i]);
                }
            }
            Method::Rk4 => {
                self.eval(hist, sys, t, 0, Some(y))?;
                for (s, c) in [(1, 0.5), (2, 0.5), (3, 1.0)] {
                    for i in 0..n {
                        self.stage[i] = y[i] + c * h * self.k[s - 1][i];
                    }
                    self.eval(hist, sys, t + c * h, s, None)?;
                }
                for i in 0..n {
                    let k = &self.k;
                    self.y_new[i] =
                        y[i] + h / 6.0 * (k[0][i] + 2.0 * k[1][i] + 2.0 * k[2][i] + k[3][i]);
                }
            }
            Method::SymplecticEuler | Method::VelocityVerlet => {
                self.second_order_step(hist, sys, t, y, h)?
            }
            Method::ImplicitEuler | Method::Trapezoidal | Method::Bdf2 => {
                unreachable!("implicit methods take split_implicit_step")
            }
        }
        Ok(())
    }

    /// One step of a second-order method (symplectic Euler, velocity Verlet) over
    /// `y = [x; v]` into `y_new`.
    fn second_order_step<S: OdeSystem>(
        &mut self,
        hist: &mut History,
        sys: &mut S,
        t: f64,
        y: &[f64],
        h: f64,
    ) -> Result<()> {
        let m = self.n / 2;
        match hist.method() {
            Method::SymplecticEuler => {
                self.eval(hist, sys, t, 0, Some(y))?;
                for i in 0..m {
                    let v1 = y[m + i] + h * self.k[0][m + i];
                    self.y_new[m + i] = v1;
                    self.y_new[i] = y[i] + h * v1;
                }
            }
            Method::VelocityVerlet => {
                // Kick–drift–kick; the closing kick evaluates a(x₁, v₀ + h a₀), which equals the
                // textbook a(x₁) for conservative forces and keeps second order when the force
                // depends on the velocity (damping, drag).
                self.eval(hist, sys, t, 0, Some(y))?;
                for i in 0..m {
                    let a0 = self.k[0][m + i];
                    self.y_new[m + i] = y[m + i] + 0.5 * h * a0;
                    self.y_new[i] = y[i] + h * self.y_new[m + i];
                    self.stage[i] = self.y_new[i];
                    self.stage[m + i] = y[m + i] + h * a0;
                }
                self.eval(hist, sys, t + h, 1, None)?;
                for i in 0..m {
                    self.y_new[m + i] += 0.5 * h * self.k[1][m + i];
                }
            }
            _ => unreachable!("second-order methods only"),
        }
        Ok(())
    }

    /// One implicit step of `h` into `y_new`; when Newton fails, the same step as 2, 4, … up to
    /// `2^MAX_SPLITS` equal substeps, each a step of the method (BDF2 restarts, so its substeps
    /// are implicit Euler steps), which brings `γ h` down until Newton converges.
    fn split_implicit_step<S: OdeSystem>(
        &mut self,
        hist: &mut History,
        sys: &mut S,
        t: f64,
        y: &[f64],
        h: f64,
    ) -> Result<()> {
        // A singular iteration matrix is retried too (a smaller `γ h` moves it towards I).
        let converged = |r: Result<bool>| match r {
            Err(Error::SolverFailed { .. }) => Ok(false),
            other => other,
        };
        if converged(self.implicit_step(hist, sys, t, y, h))? {
            return Ok(());
        }
        let mut sub = std::mem::take(&mut self.sub);
        // No BDF2 history within the substeps (it would describe the state before `y`).
        let history = hist.prev_h.take();
        let mut result = Ok(false);
        for level in 1..=MAX_SPLITS {
            let parts = 1_u32 << level;
            let hs = h / f64::from(parts);
            sub.copy_from_slice(y);
            for p in 0..parts {
                result = converged(self.implicit_step(hist, sys, t + f64::from(p) * hs, &sub, hs));
                if !matches!(result, Ok(true)) {
                    break;
                }
                sub.copy_from_slice(&self.y_new);
            }
            if !matches!(result, Ok(false)) {
                break;
            }
        }
        self.sub = sub;
        hist.prev_h = history;
        match result {
            Ok(true) => Ok(()),
            Ok(false) => Err(Error::SolverFailed {
                reason: format!(
                    "{}: Newton did not converge in {} iterations, nor in {} substeps; reduce dt",
                    hist.method().name(),
                    hist.max_newton,
                    1 << MAX_SPLITS
                ),
            }),
            Err(e) => Err(e),
        }
    }

    /// Solve `y₁ = base + γ h f(t + h, y₁)` for the implicit methods by Newton into `y_new`;
    /// `Ok(false)` when the iteration gives up (an error message is built by the caller only
    /// if the substeps fail too, so that a split step allocates nothing).
    fn implicit_step<S: OdeSystem>(
        &mut self,
        hist: &mut History,
        sys: &mut S,
        t: f64,
        y: &[f64],
        h: f64,
    ) -> Result<bool> {
        let n = self.n;
        let t1 = t + h;
        let gamma = self.implicit_base(hist, sys, t, y, h)?;
        // Jacobian at (t1, y) and the iteration matrix I - γ h J.
        let mut sparse = self.factorize(hist, sys, t1, y, gamma * h)?;
        let affine = sys.constant_jacobian().is_some();
        self.y_new.copy_from_slice(y);
        // `k[0]` holds the last Newton update Δ of norm `last` (infinite before the first and
        // after a Jacobian update), of which `fraction` is applied to the accepted iterate.
        let (mut last, mut fraction) = (f64::INFINITY, 1.0);
        for _ in 0..hist.max_newton {
            hist.nfev += 1;
            sys.rhs(t1, &self.y_new, &mut self.k[1])?;
            // Residual G = y - base - γ h f(y); solve (I - γhJ) Δ = -G.
            for i in 0..n {
                self.stage[i] = -(self.y_new[i] - self.k[2][i] - gamma * h * self.k[1][i]);
            }
            if sparse {
                self.sparse.solve_in_place(&mut self.stage);
                if affine {
                    // f = J y + g with the exact J: this update solves the equation.
                    for i in 0..n {
                        self.y_new[i] += self.stage[i];
                    }
                    return Ok(true);
                }
            } else {
                lu_solve(&self.lu, &self.pivots, n, &mut self.stage);
            }
            let step = self.stage.iter().fold(0.0_f64, |m, d| m.max(d.abs()));
            let size = self.y_new.iter().fold(0.0_f64, |m, d| m.max(d.abs()));
            if step <= hist.newton_tol * (1.0 + size) {
                for i in 0..n {
                    self.y_new[i] += self.stage[i];
                }
                return Ok(true);
            }
            if last.is_finite() && (step >= last || step.is_nan()) && fraction > MIN_FRACTION {
                // The update did not shrink the correction computed with the same matrix
                // (Deuflhard's natural monotonicity test): take back half of it.
                fraction *= 0.5;
                for i in 0..n {
                    self.y_new[i] -= fraction * self.k[0][i];
                }
                continue;
            }
            if !step.is_finite() {
                break;
            }
            if last.is_finite() && step > NEWTON_CONTRACTION * last {
                // Slow contraction: the matrix is too far off (a strongly nonlinear step);
                // update it at this iterate and compute the Newton update there afresh.
                let y_new = std::mem::take(&mut self.y_new);
                let result = self.factorize(hist, sys, t1, &y_new, gamma * h);
                self.y_new = y_new;
                sparse = result?;
                (last, fraction) = (f64::INFINITY, 1.0);
                continue;
            }
            for i in 0..n {
                self.y_new[i] += self.stage[i];
            }
            self.k[0].copy_from_slice(&self.stage);
            (last, fraction) = (step, 1.0);
        }
        Ok(false)
    }

    /// The explicit part `base` of an implicit step (into `k[2]`) and the weight `γ` of
    /// `f(t + h, y₁)` it returns: `y₁ = base + γ h f(t + h, y₁)` (implicit Euler: `base = y`,
    /// `γ = 1`; trapezoidal: `base = y + h/2 f(t, y)`, `γ = 1/2`; BDF2 with a previous step:
    /// the variable-step weights of [`super::bdf2_weights`]).
    fn implicit_base<S: OdeSystem>(
        &mut self,
        hist: &mut History,
        sys: &mut S,
        t: f64,
        y: &[f64],
        h: f64,
    ) -> Result<f64> {
        let n = self.n;
        let bdf2 = match hist.method() {
            Method::Bdf2 => super::bdf2_weights(h, hist.prev_h),
            _ => None,
        };
        let gamma = match (hist.method(), bdf2) {
            (Method::Trapezoidal, _) => {
                self.eval(hist, sys, t, 0, Some(y))?;
                for i in 0..n {
                    self.k[2][i] = y[i] + 0.5 * h * self.k[0][i];
                }
                0.5
            }
            (_, Some((c, gamma))) => {
                for i in 0..n {
                    self.k[2][i] = y[i] + c * (y[i] - hist.prev[i]);
                }
                gamma
            }
            _ => {
                self.k[2].copy_from_slice(y);
                1.0
            }
        };
        Ok(gamma)
    }

    /// Evaluate ∂f/∂y at (t, y) and factorise `I - gh J`: sparse if the system offers it
    /// (returns `true`), else dense (returns `false`).
    fn factorize<S: OdeSystem>(
        &mut self,
        hist: &mut History,
        sys: &mut S,
        t: f64,
        y: &[f64],
        gh: f64,
    ) -> Result<bool> {
        // A constant Jacobian already factorised at this `γ h` (see OdeSystem::constant_jacobian).
        let key = sys.constant_jacobian().map(|k| (k, gh.to_bits()));
        if key.is_some() && self.sparse.key == key {
            return Ok(true);
        }
        hist.njev += 1;
        if sys.sparse_jacobian(t, y, &mut self.sparse.jac)? {
            self.sparse.key = None;
            if self.sparse.factorize(self.n, gh)? {
                self.factorizations += 1;
            }
            self.sparse.key = key;
            return Ok(true);
        }
        if self.sparse.is_active() {
            self.sparse.clear();
        }
        let n = self.n;
        if self.jac.nrows() != n {
            // n² values twice: allocated or reported (the state's length names it), never
            // aborted on.
            let dense = || {
                Error::invalid(
                    "y0",
                    format!(
                        "a dense Jacobian of {n} x {n} values does not fit in memory; offer a \
                         sparse Jacobian or use an explicit method"
                    ),
                )
            };
            let nn = n.checked_mul(n).ok_or_else(dense)?;
            self.jac = DMatrix::from_vec(n, n, filled("y0", nn, 0.0).map_err(|_| dense())?);
            self.lu = filled("y0", nn, 0.0).map_err(|_| dense())?;
            self.pivots = vec![0; n];
        }
        self.dense_jacobian(hist, sys, t, y)?;
        for c in 0..n {
            for r in 0..n {
                self.lu[r * n + c] = f64::from(u8::from(r == c)) - gh * self.jac[(r, c)];
            }
        }
        self.factorizations += 1;
        lu_factor(&mut self.lu, &mut self.pivots, n)?;
        Ok(false)
    }

    /// Fill `self.jac` with ∂f/∂y at (t, y): analytic if the system has it, else forward
    /// differences with steps `sqrt(eps) max(|y_j|, 1)`.
    fn dense_jacobian<S: OdeSystem>(
        &mut self,
        hist: &mut History,
        sys: &mut S,
        t: f64,
        y: &[f64],
    ) -> Result<()> {
        if sys.jacobian(t, y, &mut self.jac)? {
            return Ok(());
        }
        let n = self.n;
        self.eval(hist, sys, t, 3, Some(y))?;
        // All the columns' states `y + d_j e_j` in one evaluation (OdeSystem::rhs_many).
        let step = |j: usize| f64::EPSILON.sqrt() * y[j].abs().max(1.0);
        for buffer in [&mut self.columns, &mut self.derivatives] {
            if buffer.len() != n * n {
                *buffer = filled("y0", n * n, 0.0)?;
            }
        }
        for (j, column) in self.columns.chunks_exact_mut(n).enumerate() {
            column.copy_from_slice(y);
            column[j] = y[j] + step(j);
        }
        hist.nfev += n;
        sys.rhs_many(t, &self.columns, &mut self.derivatives)?;
        for (j, fj) in self.derivatives.chunks_exact(n).enumerate() {
            let d = step(j);
            for i in 0..n {
                self.jac[(i, j)] = (fj[i] - self.k[3][i]) / d;
            }
        }
        Ok(())
    }
}

/// A [`History`] with a [`Workspace`] of its own, for callers that keep the two together (a
/// one-off solve, a system without a separate solver). A snapshot of it holds the history only
/// (the workspace is sized again at the next step).
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub struct Stepper {
    /// What carries from step to step: method, previous BDF2 step, Newton settings, counters.
    pub history: History,
    #[serde(skip)]
    work: Workspace,
}

impl Stepper {
    /// A stepper for systems of dimension `n` ([`History::new`]).
    ///
    /// # Errors
    /// A second-order method with odd `n` (the state must be `[x; v]`).
    pub fn new(method: Method, n: usize) -> Result<Self> {
        Ok(Stepper { history: History::new(method, n)?, work: Workspace::default() })
    }

    /// The method this stepper uses.
    pub fn method(&self) -> Method {
        self.history.method()
    }

    /// Length of the states this stepper advances.
    pub fn dimension(&self) -> usize {
        self.history.dimension()
    }

    /// Forget the history of multistep methods ([`History::reset`]).
    pub fn reset(&mut self) {
        self.history.reset();
    }

    /// Check a stepper decoded from a snapshot ([`History::validate`]).
    ///
    /// # Errors
    /// As [`History::validate`].
    pub fn validate(&self) -> Result<()> {
        self.history.validate()
    }

    /// Advance `y` by one step of `h` ([`Workspace::step`]).
    ///
    /// # Errors
    /// As [`Workspace::step`].
    pub fn step<S: OdeSystem>(&mut self, sys: &mut S, t: f64, y: &mut [f64], h: f64) -> Result<()> {
        self.work.step(&mut self.history, sys, t, y, h)
    }
}

/// In-place LU factorisation with partial pivoting of the row-major `n x n` matrix `a`.
fn lu_factor(a: &mut [f64], pivots: &mut [usize], n: usize) -> Result<()> {
    for col in 0..n {
        let p = (col..n)
            .max_by(|&i, &j| a[i * n + col].abs().total_cmp(&a[j * n + col].abs()))
            .unwrap_or(col);
        let pivot = a[p * n + col];
        if pivot == 0.0 || !pivot.is_finite() {
            return Err(Error::SolverFailed {
                reason: "the Newton iteration matrix is singular".into(),
            });
        }
        pivots[col] = p;
        if p != col {
            for c in 0..n {
                a.swap(col * n + c, p * n + c);
            }
        }
        for r in col + 1..n {
            let f = a[r * n + col] / pivot;
            a[r * n + col] = f;
            for c in col + 1..n {
                a[r * n + c] -= f * a[col * n + c];
            }
        }
    }
    Ok(())
}

/// Solve `A x = b` in place from the factors of [`lu_factor`].
fn lu_solve(a: &[f64], pivots: &[usize], n: usize, b: &mut [f64]) {
    for (col, &p) in pivots.iter().enumerate().take(n) {
        b.swap(col, p);
    }
    for r in 0..n {
        let s: f64 = (0..r).map(|c| a[r * n + c] * b[c]).sum();
        b[r] -= s;
    }
    for r in (0..n).rev() {
        let s: f64 = (r + 1..n).map(|c| a[r * n + c] * b[c]).sum();
        b[r] = (b[r] - s) / a[r * n + r];
    }
}
