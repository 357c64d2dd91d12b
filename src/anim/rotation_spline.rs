//! The C2 rotation spline: per segment, the rotation vector relative to the first key is a
//! cubic in time, `q(t) = q_k exp(θ_k(τ))`, `θ_k(τ) = c τ + b τ² + a τ³`, `τ = t - t_k`, with
//! the angular velocity and the angular acceleration continuous at the keys (Sander 2015,
//! "Smooth attitude interpolation", the method behind scipy's `RotationSpline`).
//!
//! With `ω = J_r(θ) θ̇` the body angular velocity (`J_r` the right Jacobian of the exponential
//! map) the unknowns are the body angular rates `ω_k` at the keys. Each segment is the cubic
//! Hermite curve with `θ(0) = 0`, `θ'(0) = ω_k`, `θ(h) = φ_k = log(q_k* q_{k+1})`,
//! `θ'(h) = J_r(φ_k)⁻¹ ω_{k+1}`, which makes `ω` continuous. Continuity of
//! `ω̇ = J_r θ̈ + N(θ, θ̇)` at each interior key gives the block-tridiagonal system
//!
//! `(2/h_{k-1}) J_r(φ_{k-1}) ω_{k-1} + 4 (1/h_{k-1} + 1/h_k) ω_k + (2/h_k) J_r(φ_k)⁻¹ ω_{k+1}
//!   = 6 φ_{k-1}/h_{k-1}² + 6 φ_k/h_k² - N(φ_{k-1}, J_r(φ_{k-1})⁻¹ ω_k)`,
//!
//! solved by fixed-point iteration on the nonlinear term `N` (the linear part is factored
//! once by block Thomas elimination). The end rates are the mean rates of the end segments,
//! `ω_0 = φ_0/h_0`, `ω_{n-1} = φ_{n-2}/h_{n-2}`, as scipy chooses.

use crate::error::{Error, Result};
use crate::math::skew;
use glam::{DMat3, DVec3};

/// Largest number of fixed-point iterations on the nonlinear term.
const MAX_ITER: usize = 100;
/// Convergence: no key rate changes by more than `TOL (1 + |ω|)` in an iteration.
const TOL: f64 = 1e-13;

/// `(1 - cos θ)/θ²`, `(θ - sin θ)/θ³` and their derivatives over `θ`:
/// `c1'(θ)/θ = (θ sin θ - 2 (1 - cos θ))/θ⁴`, `c2'(θ)/θ = (3 sin θ - 2θ - θ cos θ)/θ⁵`.
/// Taylor series below `θ = 0.02` (next terms `θ⁶/40320`, relative error < 1e-15).
fn coefficients(theta: f64) -> [f64; 4] {
    let t2 = theta * theta;
    if theta < 0.02 {
        [
            0.5 - t2 / 24.0 + t2 * t2 / 720.0,
            1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0,
            -1.0 / 12.0 + t2 / 180.0 - t2 * t2 / 6720.0,
            -1.0 / 60.0 + t2 / 1260.0 - t2 * t2 / 60480.0,
        ]
    } else {
        let (s, c) = theta.sin_cos();
        let t4 = t2 * t2;
        [
            (1.0 - c) / t2,
            (theta - s) / (t2 * theta),
            (theta * s - 2.0 * (1.0 - c)) / t4,
            (3.0 * s - 2.0 * theta - theta * c) / (t4 * theta),
        ]
    }
}

/// The right Jacobian of the exponential map: body angular velocity `ω = J_r(θ) θ̇` for
/// `q = q₀ exp(θ)`.
pub(crate) fn right_jacobian(theta: DVec3) -> DMat3 {
    let [c1, c2, ..] = coefficients(theta.length());
    let s = skew(theta);
    DMat3::IDENTITY - s * c1 + s * s * c2
}

/// `d/dt(J_r(θ)) θ̇`, the part of the body angular acceleration that is quadratic in `θ̇`.
pub(crate) fn nonlinear_term(theta: DVec3, theta_dot: DVec3) -> DVec3 {
    let [_, c2, d1, d2] = coefficients(theta.length());
    let dp = theta.dot(theta_dot);
    let cp = theta.cross(theta_dot);
    -dp * d1 * cp + dp * d2 * theta.cross(cp) + c2 * theta_dot.cross(cp)
}

/// Per-segment cubic coefficients `[c, b, a]` of the C2 spline through the relative rotation
/// vectors `phi` (one per segment) over the segment durations `h`.
///
/// # Errors
/// The fixed-point iteration did not converge (keys that turn by nearly a full turn or more
/// within one segment).
pub(crate) fn spline_segments(phi: &[DVec3], h: &[f64]) -> Result<Vec<[DVec3; 3]>> {
    let m = phi.len();
    let n = m + 1; // keys
    let jr: Vec<DMat3> = phi.iter().map(|&p| right_jacobian(p)).collect();
    let jr_inv: Vec<DMat3> = jr.iter().map(|j| j.inverse()).collect();
    let mut w: Vec<DVec3> = (0..n).map(|k| phi[k.min(m - 1)] / h[k.min(m - 1)]).collect();
    if n > 2 {
        let blocks = Blocks { jr: &jr, jr_inv: &jr_inv, h };
        let dinv = blocks.pivot_inverses()?;
        blocks.interior_rates(phi, &dinv, &mut w)?;
    }
    Ok((0..m)
        .map(|k| {
            let (p, hk) = (phi[k], h[k]);
            let m1 = jr_inv[k] * w[k + 1];
            let b = 3.0 * p / (hk * hk) - (2.0 * w[k] + m1) / hk;
            let a = -2.0 * p / (hk * hk * hk) + (w[k] + m1) / (hk * hk);
            [w[k], b, a]
        })
        .collect())
}

/// The block tridiagonal system of the interior keys' angular rates, row `j` (keys 1..n-1):
/// `L_j ω_{j-1} + D_j ω_j + U_j ω_{j+1} = r_j`, solved by block Thomas elimination.
struct Blocks<'a> {
    jr: &'a [DMat3],
    jr_inv: &'a [DMat3],
    h: &'a [f64],
}

impl Blocks<'_> {
    fn lower(&self, j: usize) -> DMat3 {
        self.jr[j - 1] * (2.0 / self.h[j - 1])
    }

    fn upper(&self, j: usize) -> DMat3 {
        self.jr_inv[j] * (2.0 / self.h[j])
    }

    fn diag(&self, j: usize) -> f64 {
        4.0 * (1.0 / self.h[j - 1] + 1.0 / self.h[j])
    }

    /// The inverses of the modified diagonals `D'_j = D_j - L_j D'_{j-1}⁻¹ U_{j-1}`.
    fn pivot_inverses(&self) -> Result<Vec<DMat3>> {
        let rows = self.h.len() - 1;
        let mut dinv: Vec<DMat3> = Vec::with_capacity(rows);
        for r in 0..rows {
            let j = r + 1;
            let mut d = DMat3::from_diagonal(DVec3::splat(self.diag(j)));
            if r > 0 {
                d -= self.lower(j) * dinv[r - 1] * self.upper(j - 1);
            }
            let det = d.determinant();
            if !(det.is_finite() && det.abs() > 0.0) {
                return Err(Error::invalid(
                    "rotations",
                    "the rotation spline's system is singular (keys turn too far within one segment)",
                ));
            }
            dinv.push(d.inverse());
        }
        Ok(dinv)
    }

    /// The interior rates `w[1..n-1]` (the end rates `w[0]`, `w[n-1]` given), by fixed-point
    /// iteration on the nonlinear term with one Thomas sweep per iteration, until the largest
    /// relative change is under `TOL`.
    fn interior_rates(&self, phi: &[DVec3], dinv: &[DMat3], w: &mut [DVec3]) -> Result<()> {
        let (h, rows, n) = (self.h, dinv.len(), w.len());
        let base: Vec<DVec3> = (0..rows)
            .map(|r| {
                let j = r + 1;
                6.0 * phi[j - 1] / (h[j - 1] * h[j - 1]) + 6.0 * phi[j] / (h[j] * h[j])
            })
            .collect();
        let mut y = vec![DVec3::ZERO; rows];
        for _ in 0..MAX_ITER {
            for r in 0..rows {
                let j = r + 1;
                let mut rhs = base[r] - nonlinear_term(phi[j - 1], self.jr_inv[j - 1] * w[j]);
                if r == 0 {
                    rhs -= self.lower(j) * w[0];
                } else {
                    rhs -= self.lower(j) * dinv[r - 1] * y[r - 1];
                }
                if r == rows - 1 {
                    rhs -= self.upper(j) * w[n - 1];
                }
                y[r] = rhs;
            }
            let mut change: f64 = 0.0;
            let mut next = DVec3::ZERO;
            for r in (0..rows).rev() {
                let j = r + 1;
                let rhs = if r == rows - 1 { y[r] } else { y[r] - self.upper(j) * next };
                let wj = dinv[r] * rhs;
                change = change.max(((wj - w[j]).abs() / (DVec3::ONE + wj.abs())).max_element());
                w[j] = wj;
                next = wj;
            }
            if !change.is_finite() {
                break;
            }
            if change <= TOL {
                return Ok(());
            }
        }
        Err(Error::invalid(
            "rotations",
            "the rotation spline's angular rates did not converge (keys turn too far within \
             one segment; use squad or add keys)",
        ))
    }
}
