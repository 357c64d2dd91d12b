//! DFSPH's substep (Bender & Koschier 2015, 2017): densities and factors, the
//! divergence-free solve, the non-pressure forces, the constant-density solve, advection.
//! Quantities per unit rest density (see `solver.rs`).
//!
//! - DFSPH factor (Bender & Koschier 2017, eq. 8): `α_i = 1 / (|Σ_j V ∇W_ij + Σ_b V_b ∇W_ib|²
//!   + Σ_j |V ∇W_ij|²)` (0 where the sum vanishes; `density.rs`).
//! - The pressure's velocity change: `Δv_i = -dt [Σ_j V (κ_i + κ_j) ∇W_ij + Σ_b V_b κ_i ∇W_ib]`
//!   (Bender & Koschier 2017, eq. 9 and 11).
//! - Each solve is a Jacobi iteration on `κ ≥ 0` (projected, so it also relaxes the warm
//!   start): the constant-density solve drives the predicted density
//!   `ρ̂*_i = ρ̂_i + dt (Σ_j V (v_i - v_j)·∇W_ij + Σ_b V_b (v_i - v_b)·∇W_ib)` to 1 with
//!   increments `(ρ̂*_i - 1) α_i / dt²`; the divergence-free solve drives the rate `Dρ̂_i/Dt`
//!   to 0 with increments `(Dρ̂_i/Dt) α_i / dt`, ignoring particles with fewer than
//!   [`SPARSE`] neighbours (a free surface, as SPlisHSPlasH does).

use super::{compression, Solver};
use crate::fluid::model::Model;
use crate::fluid::Stats;
use glam::DVec3;
use rayon::prelude::*;

/// Neighbours below which a particle is left out of the divergence-free solve.
pub(super) const SPARSE: usize = 20;

/// Relaxation `ω` of the Jacobi iterations: the largest eigenvalue of `α A` on a column at
/// rest is 2.70, so `ω = 1` (the paper's) diverges and `ω` must stay under 0.74
/// (`solver_tests.rs`); SPlisHSPlasH 2.x and IISPH (Ihmsen et al. 2014) use 0.5 too.
pub(super) const RELAXATION: f64 = 0.5;

/// Which DFSPH solve.
#[derive(Clone, Copy, PartialEq)]
pub(super) enum Solve {
    Divergence,
    Density,
}

impl Solver {
    /// One DFSPH substep of length `h` (s) in which no particle moves much more than `reach`
    /// (m), with the solves' iteration limit and tolerances (percent).
    pub(super) fn dfsph(
        &mut self,
        model: &Model,
        h: f64,
        reach: f64,
        (max_iterations, divergence_tolerance, density_tolerance): (usize, f64, f64),
        stats: &mut Stats,
    ) {
        self.search(model, reach);
        self.densities(model, true);
        let (it, err, _) =
            self.solve(model, h, Solve::Divergence, max_iterations, divergence_tolerance);
        stats.divergence_iterations += it;
        stats.divergence_error = stats.divergence_error.max(err);
        self.non_pressure(model, h, model.settings.gravity * h, false, stats);
        let (it, err, max) =
            self.solve(model, h, Solve::Density, max_iterations, density_tolerance);
        stats.density_iterations += it;
        stats.density_error = stats.density_error.max(err);
        stats.max_density_error = stats.max_density_error.max(max);
        self.move_colliders(h);
        self.advect(model, h);
    }

    /// `Δv_i = -dt [Σ_j V (k_i + k_j) ∇W_ij + Σ_b V_b k_i ∇W_ib]` with this iteration's `k`.
    pub(super) fn apply(&mut self, model: &Model, h: f64) {
        let mut dv = std::mem::take(&mut self.dv);
        let (vol, k, vb, n) = (model.volume, &self.k, &model.boundary_volume, self.k.len());
        dv.par_iter_mut().enumerate().for_each(|(i, out)| {
            // The fluid neighbours, then the boundary points (the lists ascend).
            let (near, grads, fluid) = self.pairs(i);
            let (k_i, mut sum) = (k[i], DVec3::ZERO);
            for (&j, &g) in near[..fluid].iter().zip(grads) {
                sum += g * (vol * (k_i + k[j as usize]));
            }
            for (&j, &g) in near[fluid..].iter().zip(&grads[fluid..]) {
                sum += g * (vb[j as usize - n] * k_i);
            }
            *out = sum * -h;
        });
        self.v.par_iter_mut().zip(&dv).for_each(|(v, dv)| *v += *dv);
        self.dv = dv;
    }

    /// The residual of `which` solve per particle for the velocities now: the predicted
    /// density error `ρ̂* - 1`, or the density rate `Dρ̂/Dt` (1/s, 0 for sparse particles).
    pub(super) fn residuals(&mut self, model: &Model, h: f64, which: Solve) {
        let mut residual = std::mem::take(&mut self.residual);
        let (vol, n, v, density) = (model.volume, self.v.len(), &self.v, &self.density);
        let (vb, bv) = (&model.boundary_volume, &self.boundary_velocity);
        residual.par_iter_mut().enumerate().for_each(|(i, out)| {
            // The fluid neighbours, then the boundary points (the lists ascend).
            let (near, grads, fluid) = self.pairs(i);
            let (v_i, mut rate) = (v[i], 0.0);
            for (&j, &g) in near[..fluid].iter().zip(grads) {
                rate += vol * (v_i - v[j as usize]).dot(g);
            }
            for (&j, &g) in near[fluid..].iter().zip(&grads[fluid..]) {
                let b = j as usize - n;
                rate += vb[b] * (v_i - bv[b]).dot(g);
            }
            *out = match which {
                Solve::Density => density[i] + h * rate - 1.0,
                Solve::Divergence if near.len() < SPARSE => 0.0,
                Solve::Divergence => rate,
            };
        });
        self.residual = residual;
    }

    /// One DFSPH solve: warm start from the state's pressures, then Jacobi iterations on
    /// `κ ≥ 0` until the mean error (percent; the divergence's per substep) is at most `tol`.
    /// Returns the iterations, the mean and the largest error reached (percent).
    pub(super) fn solve(
        &mut self,
        model: &Model,
        h: f64,
        which: Solve,
        max: usize,
        tol: f64,
    ) -> (usize, f64, f64) {
        let density = which == Solve::Density;
        // Errors in percent per substep, increments `r α / dt²` or `r α / dt`.
        let (scale, step) = if density { (1.0, 1.0 / (h * h)) } else { (h, 1.0 / h) };
        // Warm start: the last substep's pressures (the divergence impulse over this `h`).
        let stored = if density { &self.pressure } else { &self.divergence };
        for ((k, t), &p) in self.k.iter_mut().zip(&mut self.total).zip(stored) {
            *t = if density { p } else { p / h };
            *k = *t;
        }
        self.apply(model, h);
        let mut iterations = 0;
        let (mean, largest) = loop {
            self.residuals(model, h, which);
            // The complementarity residual: compression where κ = 0, any error where κ > 0
            // (an over-pressure from the warm start is iterated away too).
            let active = self.total.iter().zip(&self.residual);
            let lcp =
                active.map(|(&t, &r)| if t > 0.0 { r.abs() } else { r.max(0.0) }).sum::<f64>();
            let (mean, largest) = compression(&self.residual);
            let lcp = 100.0 * lcp / self.residual.len() as f64;
            if lcp * scale <= tol || iterations == max {
                break (mean * scale, largest * scale);
            }
            // Projected, relaxed Jacobi: κ ← max(κ + ω r α / dt^m, 0); apply the change.
            let Solver { k, total, residual, alpha, .. } = self;
            for (((k, t), &r), &a) in
                k.iter_mut().zip(total.iter_mut()).zip(&*residual).zip(&*alpha)
            {
                let new = (*t + RELAXATION * r * a * step).max(0.0);
                *k = new - *t;
                *t = new;
            }
            self.apply(model, h);
            iterations += 1;
        };
        let stored = if density { &mut self.pressure } else { &mut self.divergence };
        for (s, &t) in stored.iter_mut().zip(&self.total) {
            *s = if density { t } else { t * h };
        }
        (iterations, mean, largest)
    }
}
