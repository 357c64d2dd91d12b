//! PBF's substep (Macklin & Müller 2013): predicted positions, Jacobi iterations of the
//! density constraints with the tensile-instability term `s_corr`, velocities from the
//! displacement, XSPH viscosity.

use super::{compression, Solver};
use crate::fluid::collider::confine;
use crate::fluid::model::Model;
use crate::fluid::Stats;
use glam::DVec3;
use rayon::prelude::*;

impl Solver {
    /// One PBF substep of length `h` (s) (Macklin & Müller 2013, algorithm 1): predict
    /// `v += h g`, `x* = x + h v` (walls confine `x*`), then until the mean compression is
    /// at most `tol` percent (or `max` iterations): `λ_i = -max(ρ̂_i - 1, 0) α_i` (unrelaxed Jacobi, as in the paper) and
    /// [`Solver::displace`]; then `v = (x* - x) / h`, the walls again, XSPH viscosity.
    /// The pressure stored is `κ = -Σ λ / h²` (the pressure whose DFSPH impulse over `h`
    /// gives the same displacement). Returns the iterations, the mean and the largest
    /// compression reached (percent).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn pbf(
        &mut self,
        model: &Model,
        h: f64,
        reach: f64,
        max: usize,
        tol: f64,
        tensile: f64,
        stats: &mut Stats,
    ) -> (usize, f64, f64) {
        let n = self.v.len();
        self.x0.clear();
        self.x0.extend_from_slice(&self.points[..n]);
        let g = model.settings.gravity * h;
        self.v.iter_mut().for_each(|v| *v += g);
        self.advect(model, h);
        self.search(model, reach);
        self.total.fill(0.0);
        let corr = tensile * model.lattice_factor();
        let mut iterations = 0;
        let (mean, largest) = loop {
            self.densities(model, true);
            let Solver { residual, density, .. } = self;
            residual.iter_mut().zip(&*density).for_each(|(r, d)| *r = d - 1.0);
            let (mean, largest) = compression(&self.residual);
            if mean <= tol || iterations == max {
                break (mean, largest);
            }
            let Solver { k, total, residual, alpha, .. } = self;
            for (((k, t), &r), &a) in
                k.iter_mut().zip(total.iter_mut()).zip(&*residual).zip(&*alpha)
            {
                *k = -r.max(0.0) * a;
                *t += *k;
            }
            self.displace(model, corr);
            iterations += 1;
        };
        let Solver { points, v, x0, pressure, total, colliders, .. } = self;
        for ((v, x), x0) in v.iter_mut().zip(&points[..n]).zip(&*x0) {
            *v = (*x - *x0) / h;
        }
        for (p, t) in pressure.iter_mut().zip(&*total) {
            *p = -t / (h * h);
        }
        let margin = 0.25 * model.settings.spacing;
        let colliders = &**colliders;
        points[..n].par_iter_mut().zip(v).for_each(|(x, v)| {
            for wall in &model.walls {
                wall.confine(x, v, margin);
            }
            for c in colliders {
                confine(c, x, v, margin);
            }
        });
        self.non_pressure(model, h, DVec3::ZERO, false, stats);
        (iterations, mean, largest)
    }

    /// PBF's position correction (Macklin & Müller 2013, eq. 12-14) with this iteration's
    /// `λ` (in `k`): `Δx_i = Σ_j V (λ_i + λ_j + s_corr) ∇W_ij + Σ_b V_b λ_i ∇W_ib`,
    /// `s_corr = -corr (W_ij / W(0.2 h))⁴`, added to the positions. `corr` (m²) is `k`
    /// times the lattice's `α`: the artificial pressure of a compression `k` at `r = 0.2 h`.
    fn displace(&mut self, model: &Model, corr: f64) {
        let Solver { neighbours, points, k, dv, .. } = self;
        let (sup, kernel, vol, n) = (model.support, model.settings.kernel, model.volume, k.len());
        let vb = &model.boundary_volume;
        let w_dq = kernel.value(0.2 * sup, sup);
        dv.par_iter_mut().enumerate().for_each(|(i, out)| {
            let mut sum = DVec3::ZERO;
            for &j in neighbours.neighbours(i) {
                let j = j as usize;
                let d = points[i] - points[j];
                let g = kernel.gradient(d, sup);
                sum += if j < n {
                    let q = kernel.value(d.length(), sup) / w_dq;
                    g * (vol * (k[i] + k[j] - corr * (q * q) * (q * q)))
                } else {
                    g * (vb[j - n] * k[i])
                };
            }
            *out = sum;
        });
        points[..n].par_iter_mut().zip(&*dv).for_each(|(x, d)| *x += *d);
    }
}
