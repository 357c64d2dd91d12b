//! Radau IIA of order 5 with step-size control, the scheme of Hairer's RADAU5 (Hairer &
//! Wanner, *Solving ODEs II*, §IV.8; the constants as in scipy's `Radau`): the three-stage
//! collocation system is solved by simplified Newton iterations, transformed by the
//! eigenvectors of `A⁻¹` into one real system `(γ/h I − J)` and one complex system
//! `((α + iβ)/h I − J)`, whose LU factors are kept while `h` and `J` are unchanged; `J` is
//! evaluated again only when Newton converged slowly (more than two iterations at a rate above
//! 1e-3). The error is estimated from the embedded formula filtered by `(I − γ₀ h J)⁻¹`
//! (IV.8.19–20), with one more filtering after a rejected step (IV.8.21); the step follows
//! Gustafsson's predictive controller (IV.8.25). The dense output is the collocation polynomial.

// Numeric kernels index several arrays in step; index loops read closest to the formulas.
#![allow(clippy::needless_range_loop)]
// The transformation matrices as published, with all their digits.
#![allow(clippy::excessive_precision, clippy::unreadable_literal)]

use super::adaptive::Tolerance;
use super::output::Output;
use super::OdeSystem;
use crate::error::{filled, Error, Result};
use nalgebra::{Complex, DMatrix, DVector, LU};

/// Newton iterations per attempt before the step is retried (with a fresh Jacobian, then half
/// the step).
const NEWTON_MAXITER: usize = 6;
/// The eigenvector matrix `T` of `A⁻¹` (`T⁻¹ A⁻¹ T` = diag(γ, α ± iβ) in real form).
const T: [[f64; 3]; 3] = [
    [0.09443876248897524, -0.14125529502095421, 0.03002919410514742],
    [0.25021312296533332, 0.20412935229379994, -0.38294211275726192],
    [1.0, 1.0, 0.0],
];
/// `T⁻¹`.
const TI: [[f64; 3]; 3] = [
    [4.17871859155190428, 0.32768282076106237, 0.52337644549944951],
    [-4.17871859155190428, -0.32768282076106237, 0.47662355450055044],
    [0.50287263494578682, -2.57192694985560522, 0.59603920482822492],
];

/// The method's constants that need square and cube roots.
struct Constants {
    /// Nodes `c = ((4 − √6)/10, (4 + √6)/10, 1)`.
    c: [f64; 3],
    /// Embedded-error weights on the stage increments `Z` (divided by `h` at use).
    e: [f64; 3],
    /// The real eigenvalue `γ = 1/γ₀` of `A⁻¹`.
    mu_real: f64,
    /// The complex eigenvalue `α + iβ` of `A⁻¹`.
    mu_complex: Complex<f64>,
    /// Collocation polynomial: `y(t + θh) = y + Σ_j (Σ_i Z_i P_ij) θ^(j+1)`.
    p: [[f64; 3]; 3],
}

impl Constants {
    fn new() -> Self {
        let s6 = 6f64.sqrt();
        let (c13, c23) = (3f64.powf(1.0 / 3.0), 3f64.powf(2.0 / 3.0));
        Constants {
            c: [(4.0 - s6) / 10.0, (4.0 + s6) / 10.0, 1.0],
            e: [(-13.0 - 7.0 * s6) / 3.0, (-13.0 + 7.0 * s6) / 3.0, -1.0 / 3.0],
            mu_real: 3.0 + c23 - c13,
            mu_complex: Complex::new(
                3.0 + 0.5 * (c13 - c23),
                -0.5 * (3f64.powf(5.0 / 6.0) + 3f64.powf(7.0 / 6.0)),
            ),
            p: [
                [13.0 / 3.0 + 7.0 * s6 / 3.0, -23.0 / 3.0 - 22.0 * s6 / 3.0, 10.0 / 3.0 + 5.0 * s6],
                [13.0 / 3.0 - 7.0 * s6 / 3.0, -23.0 / 3.0 + 22.0 * s6 / 3.0, 10.0 / 3.0 - 5.0 * s6],
                [1.0 / 3.0, -8.0 / 3.0, 10.0 / 3.0],
            ],
        }
    }
}

/// Counters of a Radau run.
#[derive(Default)]
pub(super) struct Counts {
    pub(super) steps: usize,
    pub(super) nfev: usize,
    pub(super) njev: usize,
    pub(super) nlu: usize,
    pub(super) rejected: usize,
}

/// The workspace of a run (sized once).
struct Work {
    n: usize,
    jac: DMatrix<f64>,
    lu_real: Option<LU<f64, nalgebra::Dyn, nalgebra::Dyn>>,
    lu_complex: Option<LU<Complex<f64>, nalgebra::Dyn, nalgebra::Dyn>>,
    z: [Vec<f64>; 3],
    w: [Vec<f64>; 3],
    f: [Vec<f64>; 3],
    rhs_real: DVector<f64>,
    rhs_complex: DVector<Complex<f64>>,
    stage: Vec<f64>,
    scale: Vec<f64>,
    /// The states of the finite-difference columns and their derivatives (`n²` values each,
    /// sized at the first difference Jacobian of a run).
    columns: Vec<f64>,
    derivatives: Vec<f64>,
}

impl Work {
    /// Evaluate `J = ∂f/∂y` at `(t, y)` where `f(t, y) = fy`: the system's own, or forward
    /// differences with steps `√(ε max(1e-5, |y_j|))` (RADAU5's).
    fn jacobian<S: OdeSystem>(
        &mut self,
        sys: &mut S,
        t: f64,
        y: &[f64],
        fy: &[f64],
        counts: &mut Counts,
    ) -> Result<()> {
        counts.njev += 1;
        if sys.jacobian(t, y, &mut self.jac)? {
            return Ok(());
        }
        // All the columns' states `y + d_j e_j` in one evaluation (OdeSystem::rhs_many).
        let n = self.n;
        let step = |j: usize| (f64::EPSILON * y[j].abs().max(1e-5)).sqrt();
        for buffer in [&mut self.columns, &mut self.derivatives] {
            if buffer.is_empty() {
                *buffer = filled("y0", n * n, 0.0)?;
            }
        }
        for (j, column) in self.columns.chunks_exact_mut(n).enumerate() {
            column.copy_from_slice(y);
            column[j] = y[j] + step(j);
        }
        sys.rhs_many(t, &self.columns, &mut self.derivatives)?;
        counts.nfev += n;
        for (j, fj) in self.derivatives.chunks_exact(n).enumerate() {
            let d = step(j);
            for i in 0..n {
                self.jac[(i, j)] = (fj[i] - fy[i]) / d;
            }
        }
        Ok(())
    }

    /// Factorise `γ/h I − J` and `(α + iβ)/h I − J` (unless already factorised).
    fn factorize(&mut self, k: &Constants, h: f64, counts: &mut Counts) {
        if self.lu_real.is_some() {
            return;
        }
        counts.nlu += 1;
        let n = self.n;
        let real = DMatrix::from_fn(n, n, |i, j| {
            (if i == j { k.mu_real / h } else { 0.0 }) - self.jac[(i, j)]
        });
        let complex = DMatrix::from_fn(n, n, |i, j| {
            (if i == j { k.mu_complex / h } else { Complex::new(0.0, 0.0) })
                - Complex::new(self.jac[(i, j)], 0.0)
        });
        self.lu_real = Some(LU::new(real));
        self.lu_complex = Some(LU::new(complex));
    }

    /// The simplified Newton iteration on the collocation system from the increments in
    /// `self.z`: returns `(converged, iterations, rate)` (Hairer & Wanner IV.8, the stopping
    /// rule `rate/(1 − rate) |ΔW| < tol`, giving up when the rate reaches 1 or the
    /// extrapolated error after the remaining iterations exceeds `tol`).
    #[allow(clippy::too_many_arguments)]
    fn newton<S: OdeSystem>(
        &mut self,
        sys: &mut S,
        k: &Constants,
        t: f64,
        y: &[f64],
        h: f64,
        tol: f64,
        counts: &mut Counts,
    ) -> Result<(bool, usize, f64)> {
        let n = self.n;
        let (mr, mc) = (k.mu_real / h, k.mu_complex / h);
        for i in 0..n {
            for r in 0..3 {
                self.w[r][i] = (0..3).map(|j| TI[r][j] * self.z[j][i]).sum();
            }
        }
        let (lu_real, lu_complex) = match (&self.lu_real, &self.lu_complex) {
            (Some(a), Some(b)) => (a, b),
            _ => unreachable!("factorised before Newton"),
        };
        let mut norm_old: Option<f64> = None;
        let mut rate = f64::NAN;
        for iter in 0..NEWTON_MAXITER {
            for s in 0..3 {
                for i in 0..n {
                    self.stage[i] = y[i] + self.z[s][i];
                }
                sys.rhs(t + k.c[s] * h, &self.stage, &mut self.f[s])?;
                counts.nfev += 1;
            }
            if self.f.iter().any(|f| f.iter().any(|v| !v.is_finite())) {
                return Ok((false, iter + 1, rate));
            }
            for i in 0..n {
                let fi = [self.f[0][i], self.f[1][i], self.f[2][i]];
                let tf = |r: usize| (0..3).map(|j| TI[r][j] * fi[j]).sum::<f64>();
                self.rhs_real[i] = tf(0) - mr * self.w[0][i];
                self.rhs_complex[i] =
                    Complex::new(tf(1), tf(2)) - mc * Complex::new(self.w[1][i], self.w[2][i]);
            }
            if !(lu_real.solve_mut(&mut self.rhs_real)
                && lu_complex.solve_mut(&mut self.rhs_complex))
            {
                return Ok((false, iter + 1, rate));
            }
            let mut sum = 0.0;
            for i in 0..n {
                let (a, b) = (self.rhs_real[i], self.rhs_complex[i]);
                sum += (a * a + b.re * b.re + b.im * b.im) / (self.scale[i] * self.scale[i]);
            }
            let norm = (sum / (3 * n).max(1) as f64).sqrt();
            if let Some(old) = norm_old {
                rate = norm / old;
                let remaining = (NEWTON_MAXITER - iter) as i32;
                if rate.is_nan() || rate >= 1.0 || rate.powi(remaining) / (1.0 - rate) * norm > tol
                {
                    return Ok((false, iter + 1, rate));
                }
            }
            for i in 0..n {
                self.w[0][i] += self.rhs_real[i];
                self.w[1][i] += self.rhs_complex[i].re;
                self.w[2][i] += self.rhs_complex[i].im;
                for r in 0..3 {
                    self.z[r][i] = (0..3).map(|j| T[r][j] * self.w[j][i]).sum();
                }
            }
            if norm == 0.0 || (norm_old.is_some() && rate / (1.0 - rate) * norm < tol) {
                return Ok((true, iter + 1, rate));
            }
            norm_old = Some(norm);
        }
        Ok((false, NEWTON_MAXITER, rate))
    }
}

/// Gustafsson's predictive step factor (Hairer & Wanner IV.8.25), before the safety factor:
/// `min(1, h/h_old (err_old/err)^¼) err^(-¼)`.
fn predict_factor(h: f64, last: Option<(f64, f64)>, err: f64) -> f64 {
    let multiplier = match last {
        Some((h_old, err_old)) if err > 0.0 => h / h_old * (err_old / err).powf(0.25),
        _ => 1.0,
    };
    multiplier.min(1.0) * err.powf(-0.25)
}

/// Integrate from `t0` to `t1` with Radau IIA (order 5), recording into `out`; the
/// arguments are checked by the caller.
#[allow(clippy::too_many_arguments)]
pub(super) fn run<S: OdeSystem>(
    sys: &mut S,
    tol: &Tolerance,
    y0: &[f64],
    t0: f64,
    t1: f64,
    max_steps: usize,
    out: &mut Output<'_>,
) -> Result<Counts> {
    let n = y0.len();
    let k = Constants::new();
    let mut counts = Counts::default();
    let zeros = || [vec![0.0; n], vec![0.0; n], vec![0.0; n]];
    let mut work = Work {
        n,
        jac: DMatrix::zeros(n, n),
        lu_real: None,
        lu_complex: None,
        z: zeros(),
        w: zeros(),
        f: zeros(),
        rhs_real: DVector::zeros(n),
        rhs_complex: DVector::zeros(n),
        stage: vec![0.0; n],
        scale: vec![0.0; n],
        columns: Vec::new(),
        derivatives: Vec::new(),
    };
    let newton_tol = (10.0 * f64::EPSILON / tol.rtol).max(tol.rtol.sqrt().min(0.03));
    let mut y = y0.to_vec();
    let mut y_new = vec![0.0; n];
    let mut fy = vec![0.0; n];
    let mut error = vec![0.0; n];
    let mut ze = vec![0.0; n];
    // The last step's collocation polynomial `Σ_j q_j θ^(j+1)` over `h_old`, for the
    // predictor of the next step's stages.
    let mut q = zeros();
    let mut dense: Option<f64> = None;
    sys.rhs(t0, &y, &mut fy)?;
    counts.nfev += 1;
    work.jacobian(sys, t0, &y, &fy, &mut counts)?;
    let mut current_jac = true;
    let mut h = tol.initial_step(&y, &fy).min(t1 - t0);
    let mut last: Option<(f64, f64)> = None;
    let mut t = t0;
    let mut steps = 0;
    while t < t1 {
        if steps >= max_steps {
            return Err(Error::SolverFailed {
                reason: format!(
                    "more than {max_steps} steps needed; loosen rtol/atol or raise max_steps"
                ),
            });
        }
        let mut rejected = false;
        let (t_new, err_norm, iterations, rate, safety) = loop {
            let min_step = 10.0 * f64::EPSILON * t.abs().max(f64::MIN_POSITIVE);
            if h < min_step {
                return Err(Error::SolverFailed {
                    reason: format!(
                        "step size underflow at t = {t} (the Newton iteration of the Radau \
                         stages does not converge or the error stays above tolerance)"
                    ),
                });
            }
            let t_new = if t + h >= t1 { t1 } else { t + h };
            if t_new - t != h {
                work.lu_real = None;
            }
            h = t_new - t;
            // Predict the stages from the last collocation polynomial (zero on the first step).
            for s in 0..3 {
                for i in 0..n {
                    work.z[s][i] = match dense {
                        Some(h_old) => {
                            let x = (t + k.c[s] * h - (t - h_old)) / h_old;
                            // The polynomial through `y` at x = 1, minus `y`.
                            x * (q[0][i] + x * (q[1][i] + x * q[2][i]))
                                - (q[0][i] + q[1][i] + q[2][i])
                        }
                        None => 0.0,
                    };
                }
            }
            for i in 0..n {
                work.scale[i] = tol.scale(y[i], y[i]);
            }
            let (converged, iterations, rate) = loop {
                work.factorize(&k, h, &mut counts);
                let (converged, iterations, rate) =
                    work.newton(sys, &k, t, &y, h, newton_tol, &mut counts)?;
                if converged || current_jac {
                    break (converged, iterations, rate);
                }
                work.jacobian(sys, t, &y, &fy, &mut counts)?;
                current_jac = true;
                work.lu_real = None;
            };
            if !converged {
                h *= 0.5;
                work.lu_real = None;
                counts.rejected += 1;
                continue;
            }
            for i in 0..n {
                y_new[i] = y[i] + work.z[2][i];
                ze[i] = (0..3).map(|j| k.e[j] * work.z[j][i]).sum::<f64>() / h;
                work.rhs_real[i] = fy[i] + ze[i];
                work.scale[i] = tol.scale(y[i], y_new[i]);
            }
            let lu_real = work.lu_real.as_ref().expect("factorised");
            lu_real.solve_mut(&mut work.rhs_real);
            error.copy_from_slice(work.rhs_real.as_slice());
            let mut err_norm = rms(&error, &work.scale);
            let safety =
                0.9 * (2 * NEWTON_MAXITER + 1) as f64 / (2 * NEWTON_MAXITER + iterations) as f64;
            if rejected && err_norm > 1.0 {
                for i in 0..n {
                    work.stage[i] = y[i] + error[i];
                }
                sys.rhs(t, &work.stage, &mut work.f[0])?;
                counts.nfev += 1;
                for i in 0..n {
                    work.rhs_real[i] = work.f[0][i] + ze[i];
                }
                lu_real.solve_mut(&mut work.rhs_real);
                error.copy_from_slice(work.rhs_real.as_slice());
                err_norm = rms(&error, &work.scale);
            }
            if !err_norm.is_finite() {
                return Err(Error::Diverged {
                    step: steps,
                    index: y_new.iter().position(|v| !v.is_finite()).unwrap_or(0),
                    reason: "non-finite error estimate in the Radau step".into(),
                });
            }
            if err_norm > 1.0 {
                h *= (safety * predict_factor(h, last, err_norm)).max(0.2);
                work.lu_real = None;
                counts.rejected += 1;
                rejected = true;
                continue;
            }
            break (t_new, err_norm, iterations, rate, safety);
        };
        // Accepted: the collocation polynomial over [t, t_new] is the dense output.
        for i in 0..n {
            for j in 0..3 {
                q[j][i] = (0..3).map(|s| work.z[s][i] * k.p[s][j]).sum();
            }
        }
        out.wants_dense(sys, t_new, &y_new)?;
        let stop = out.accept(sys, t, t_new, &y_new, |tt, buf| {
            let x = (tt - t) / h;
            for i in 0..n {
                buf[i] = y[i] + x * (q[0][i] + x * (q[1][i] + x * q[2][i]));
            }
        })?;
        if stop {
            counts.steps = steps + 1;
            return Ok(counts);
        }
        let recompute_jac = iterations > 2 && rate > 1e-3;
        let mut factor = (safety * predict_factor(h, last, err_norm)).min(10.0);
        if !recompute_jac && factor < 1.2 {
            factor = 1.0;
        } else {
            work.lu_real = None;
        }
        last = Some((h, err_norm));
        dense = Some(h);
        t = t_new;
        y.copy_from_slice(&y_new);
        steps += 1;
        if t < t1 {
            sys.rhs(t, &y, &mut fy)?;
            counts.nfev += 1;
            current_jac = recompute_jac;
            if recompute_jac {
                work.jacobian(sys, t, &y, &fy, &mut counts)?;
            }
        }
        h *= factor;
    }
    counts.steps = steps;
    Ok(counts)
}

/// The root-mean-square of `e / scale`.
fn rms(e: &[f64], scale: &[f64]) -> f64 {
    let sum: f64 = e.iter().zip(scale).map(|(e, s)| (e / s) * (e / s)).sum();
    (sum / e.len().max(1) as f64).sqrt()
}
