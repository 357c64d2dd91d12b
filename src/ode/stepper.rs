//! Fixed-step integration with preallocated workspaces.

// Numeric kernels index several arrays in step; index loops read closest to the formulas.
#![allow(clippy::needless_range_loop)]

use super::sparse::SparseNewton;
use super::{Method, OdeSystem};
use crate::error::{filled, Error, Result};
use nalgebra::DMatrix;

/// Newton corrections that shrink by less than this factor per iteration trigger a Jacobian
/// update (the simplified iteration contracts too slowly).
const NEWTON_CONTRACTION: f64 = 0.5;

/// Smallest fraction of a Newton update kept when backtracking.
const MIN_FRACTION: f64 = 1.0 / 64.0;

/// A step whose Newton iteration fails is retried as 2, 4, … up to `2^MAX_SPLITS` substeps.
const MAX_SPLITS: u32 = 4;

/// Advances an [`OdeSystem`] by fixed steps of one [`Method`], allocating nothing per step.
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
/// analysis once per pattern, numeric factorisation per Jacobian update); otherwise the
/// Jacobian is dense (analytic, or by forward differences over every column) with a dense LU
/// factorisation with partial pivoting, in place. The dense workspaces (`n²` values) are
/// allocated at the first dense step, so systems with a sparse Jacobian never hold them.
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug)]
pub struct Stepper {
    method: Method,
    n: usize,
    k: [Vec<f64>; 4],
    stage: Vec<f64>,
    y_new: Vec<f64>,
    prev: Vec<f64>,
    prev_h: Option<f64>,
    /// The state between the substeps of a split implicit step; sized at construction for
    /// the implicit methods, and after a reload at the first split.
    #[serde(skip)]
    sub: Vec<f64>,
    jac: DMatrix<f64>,
    lu: Vec<f64>,
    pivots: Vec<usize>,
    /// Scratch of the sparse factorisation, rebuilt at the next step after a reload.
    #[serde(skip)]
    sparse: SparseNewton,
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

impl Stepper {
    /// Copy what carries from step to step (the method, the previous step of the multistep
    /// methods, the settings and counters) into `saved`, reusing its buffers; the stage and
    /// Newton workspaces are not copied. A stepper of another method or size is cloned whole.
    pub fn save_into(&self, saved: &mut Stepper) {
        if saved.method != self.method || saved.n != self.n {
            *saved = self.clone();
            return;
        }
        // Destructured so that a new field cannot be forgotten here.
        let Stepper {
            method: _,
            n: _,
            k: _,
            stage: _,
            y_new: _,
            prev,
            prev_h,
            sub: _,
            jac: _,
            lu: _,
            pivots: _,
            sparse: _,
            newton_tol,
            max_newton,
            nfev,
            njev,
        } = self;
        saved.prev.clone_from(prev);
        saved.prev_h = *prev_h;
        saved.newton_tol = *newton_tol;
        saved.max_newton = *max_newton;
        saved.nfev = *nfev;
        saved.njev = *njev;
    }

    /// A stepper for systems of dimension `n`.
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
        Ok(Stepper {
            method,
            n,
            k: std::array::from_fn(|_| vec![0.0; n]),
            stage: vec![0.0; n],
            y_new: vec![0.0; n],
            prev: vec![0.0; n],
            sub: vec![0.0; if method.is_implicit() { n } else { 0 }],
            prev_h: None,
            jac: DMatrix::zeros(0, 0),
            lu: Vec::new(),
            pivots: Vec::new(),
            sparse: SparseNewton::default(),
            newton_tol: 1e-10,
            max_newton: 100,
            nfev: 0,
            njev: 0,
        })
    }

    /// The method this stepper uses.
    pub fn method(&self) -> Method {
        self.method
    }

    /// Forget the history of multistep methods (call after changing the state from outside).
    pub fn reset(&mut self) {
        self.prev_h = None;
    }

    fn eval<S: OdeSystem>(
        &mut self,
        sys: &mut S,
        t: f64,
        which: usize,
        y: Option<&[f64]>,
    ) -> Result<()> {
        self.nfev += 1;
        let input = y.unwrap_or(&self.stage);
        sys.rhs(t, input, &mut self.k[which])
    }

    /// Advance `y` (length `n`) from `t` by one step of `h > 0`.
    ///
    /// # Errors
    /// A bad `h` or `y` length, a system error, a Newton failure ([`Error::SolverFailed`]) or a
    /// non-finite result ([`Error::Diverged`] with step 0 and the first bad component); `y` is
    /// unchanged in every case.
    pub fn step<S: OdeSystem>(&mut self, sys: &mut S, t: f64, y: &mut [f64], h: f64) -> Result<()> {
        if !(h.is_finite() && h > 0.0) {
            return Err(Error::invalid("dt", format!("must be positive and finite, got {h}")));
        }
        if y.len() != self.n || sys.dim() != self.n {
            return Err(Error::invalid(
                "y0",
                format!("has length {}, the system has dimension {}", y.len(), sys.dim()),
            ));
        }
        let n = self.n;
        match self.method {
            Method::ExplicitEuler => {
                self.eval(sys, t, 0, Some(y))?;
                for i in 0..n {
                    self.y_new[i] = y[i] + h * self.k[0][i];
                }
            }
            Method::Midpoint => {
                self.eval(sys, t, 0, Some(y))?;
                for i in 0..n {
                    self.stage[i] = y[i] + 0.5 * h * self.k[0][i];
                }
                self.eval(sys, t + 0.5 * h, 1, None)?;
                for i in 0..n {
                    self.y_new[i] = y[i] + h * self.k[1][i];
                }
            }
            Method::Heun => {
                self.eval(sys, t, 0, Some(y))?;
                for i in 0..n {
                    self.stage[i] = y[i] + h * self.k[0][i];
                }
                self.eval(sys, t + h, 1, None)?;
                for i in 0..n {
                    self.y_new[i] = y[i] + 0.5 * h * (self.k[0][i] + self.k[1][i]);
                }
            }
            Method::Rk4 => {
                self.eval(sys, t, 0, Some(y))?;
                for (s, c) in [(1, 0.5), (2, 0.5), (3, 1.0)] {
                    for i in 0..n {
                        self.stage[i] = y[i] + c * h * self.k[s - 1][i];
                    }
                    self.eval(sys, t + c * h, s, None)?;
                }
                for i in 0..n {
                    let k = &self.k;
                    self.y_new[i] =
                        y[i] + h / 6.0 * (k[0][i] + 2.0 * k[1][i] + 2.0 * k[2][i] + k[3][i]);
                }
            }
            Method::SymplecticEuler => {
                let m = n / 2;
                self.eval(sys, t, 0, Some(y))?;
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
                let m = n / 2;
                self.eval(sys, t, 0, Some(y))?;
                for i in 0..m {
                    let a0 = self.k[0][m + i];
                    self.y_new[m + i] = y[m + i] + 0.5 * h * a0;
                    self.y_new[i] = y[i] + h * self.y_new[m + i];
                    self.stage[i] = self.y_new[i];
                    self.stage[m + i] = y[m + i] + h * a0;
                }
                self.eval(sys, t + h, 1, None)?;
                for i in 0..m {
                    self.y_new[m + i] += 0.5 * h * self.k[1][m + i];
                }
            }
            Method::ImplicitEuler | Method::Trapezoidal | Method::Bdf2 => {
                self.split_implicit_step(sys, t, y, h)?
            }
        }
        if let Some(bad) = self.y_new.iter().position(|x| !x.is_finite()) {
            return Err(Error::Diverged {
                step: 0,
                index: bad,
                reason: format!("{} produced a non-finite state", self.method.name()),
            });
        }
        if self.method == Method::Bdf2 {
            self.prev.copy_from_slice(y);
            self.prev_h = Some(h);
        }
        y.copy_from_slice(&self.y_new);
        Ok(())
    }

    /// One implicit step of `h` into `y_new`; when Newton fails, the same step as 2, 4, … up to
    /// `2^MAX_SPLITS` equal substeps, each a step of the method (BDF2 restarts, so its substeps
    /// are implicit Euler steps), which brings `γ h` down until Newton converges.
    fn split_implicit_step<S: OdeSystem>(
        &mut self,
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
        if converged(self.implicit_step(sys, t, y, h))? {
            return Ok(());
        }
        let mut sub = std::mem::take(&mut self.sub);
        sub.resize(self.n, 0.0);
        // No BDF2 history within the substeps (it would describe the state before `y`).
        let history = self.prev_h.take();
        let mut result = Ok(false);
        for level in 1..=MAX_SPLITS {
            let parts = 1_u32 << level;
            let hs = h / f64::from(parts);
            sub.copy_from_slice(y);
            for p in 0..parts {
                result = converged(self.implicit_step(sys, t + f64::from(p) * hs, &sub, hs));
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
        self.prev_h = history;
        match result {
            Ok(true) => Ok(()),
            Ok(false) => Err(Error::SolverFailed {
                reason: format!(
                    "{}: Newton did not converge in {} iterations, nor in {} substeps; reduce dt",
                    self.method.name(),
                    self.max_newton,
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
        sys: &mut S,
        t: f64,
        y: &[f64],
        h: f64,
    ) -> Result<bool> {
        let n = self.n;
        let t1 = t + h;
        // The explicit part `base` (in k[2]) and the weight `gamma` of f(t1, y1).
        let bdf2 = match self.method {
            Method::Bdf2 => super::bdf2_weights(h, self.prev_h),
            _ => None,
        };
        let gamma = match (self.method, bdf2) {
            (Method::Trapezoidal, _) => {
                self.eval(sys, t, 0, Some(y))?;
                for i in 0..n {
                    self.k[2][i] = y[i] + 0.5 * h * self.k[0][i];
                }
                0.5
            }
            (_, Some((c, gamma))) => {
                for i in 0..n {
                    self.k[2][i] = y[i] + c * (y[i] - self.prev[i]);
                }
                gamma
            }
            _ => {
                self.k[2].copy_from_slice(y);
                1.0
            }
        };
        // Jacobian at (t1, y) and the iteration matrix I - γ h J.
        let mut sparse = self.factorize(sys, t1, y, gamma * h)?;
        self.y_new.copy_from_slice(y);
        // `k[0]` holds the last Newton update Δ of norm `last` (infinite before the first and
        // after a Jacobian update), of which `fraction` is applied to the accepted iterate.
        let (mut last, mut fraction) = (f64::INFINITY, 1.0);
        for _ in 0..self.max_newton {
            self.nfev += 1;
            sys.rhs(t1, &self.y_new, &mut self.k[1])?;
            // Residual G = y - base - γ h f(y); solve (I - γhJ) Δ = -G.
            for i in 0..n {
                self.stage[i] = -(self.y_new[i] - self.k[2][i] - gamma * h * self.k[1][i]);
            }
            if sparse {
                self.sparse.solve_in_place(&mut self.stage);
            } else {
                lu_solve(&self.lu, &self.pivots, n, &mut self.stage);
            }
            let step = self.stage.iter().fold(0.0_f64, |m, d| m.max(d.abs()));
            let size = self.y_new.iter().fold(0.0_f64, |m, d| m.max(d.abs()));
            if step <= self.newton_tol * (1.0 + size) {
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
                let result = self.factorize(sys, t1, &y_new, gamma * h);
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

    /// Evaluate ∂f/∂y at (t, y) and factorise `I - gh J`: sparse if the system offers it
    /// (returns `true`), else dense (returns `false`).
    fn factorize<S: OdeSystem>(&mut self, sys: &mut S, t: f64, y: &[f64], gh: f64) -> Result<bool> {
        self.njev += 1;
        if sys.sparse_jacobian(t, y, &mut self.sparse.jac)? {
            self.sparse.factorize(self.n, gh)?;
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
        self.dense_jacobian(sys, t, y)?;
        for c in 0..n {
            for r in 0..n {
                self.lu[r * n + c] = f64::from(u8::from(r == c)) - gh * self.jac[(r, c)];
            }
        }
        lu_factor(&mut self.lu, &mut self.pivots, n)?;
        Ok(false)
    }

    /// Fill `self.jac` with ∂f/∂y at (t, y): analytic if the system has it, else forward
    /// differences with steps `sqrt(eps) max(|y_j|, 1)`.
    fn dense_jacobian<S: OdeSystem>(&mut self, sys: &mut S, t: f64, y: &[f64]) -> Result<()> {
        if sys.jacobian(t, y, &mut self.jac)? {
            return Ok(());
        }
        let n = self.n;
        self.eval(sys, t, 3, Some(y))?;
        self.stage.copy_from_slice(y);
        for j in 0..n {
            let d = f64::EPSILON.sqrt() * y[j].abs().max(1.0);
            self.stage[j] = y[j] + d;
            self.nfev += 1;
            sys.rhs(t, &self.stage, &mut self.k[1])?;
            for i in 0..n {
                self.jac[(i, j)] = (self.k[1][i] - self.k[3][i]) / d;
            }
            self.stage[j] = y[j];
        }
        Ok(())
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

impl Stepper {
    /// Length of the states this stepper advances.
    pub fn dimension(&self) -> usize {
        self.n
    }

    /// Check a stepper decoded from a snapshot: workspaces of its dimension, a Jacobian and LU
    /// factor that agree (square, pivots in range), finite history and Newton settings. The
    /// Newton iteration count is capped at 10 000 so a damaged one cannot hang a step.
    ///
    /// # Errors
    /// [`Error::InvalidInput`] naming the first inconsistent field.
    pub fn validate(&self) -> Result<()> {
        let n = self.n;
        let bad = |field: &str, what: &str| Err(Error::invalid(field, what.to_string()));
        if self.method.is_second_order() && !n.is_multiple_of(2) {
            return bad("stepper", "a second-order method needs a state of even length");
        }
        if self.k.iter().chain([&self.stage, &self.y_new, &self.prev]).any(|v| v.len() != n) {
            return bad("stepper", "workspaces are not of the stepper's dimension");
        }
        let m = self.jac.nrows();
        if self.jac.ncols() != m
            || (m != 0 && m != n)
            || self.lu.len() != m * m
            || self.pivots.len() != m
            || self.pivots.iter().any(|&p| p >= m)
        {
            return bad("stepper", "inconsistent Jacobian or LU factor");
        }
        if !self.prev.iter().all(|v| v.is_finite())
            || self.prev_h.is_some_and(|h| !(h.is_finite() && h > 0.0))
        {
            return bad("stepper", "non-finite history");
        }
        if !(self.newton_tol.is_finite() && self.newton_tol >= 0.0) || self.max_newton > MAX_NEWTON
        {
            return bad("stepper", "Newton tolerance or iteration count out of range");
        }
        Ok(())
    }
}

/// Largest Newton iteration count a stepper read from a snapshot may carry.
const MAX_NEWTON: usize = 10_000;
