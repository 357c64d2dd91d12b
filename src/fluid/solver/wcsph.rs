//! WCSPH's substep (Becker & Teschner 2007): densities, the Tait equation
//! `p = ρ₀ c²/7 ((ρ/ρ₀)⁷ − 1)` clamped at 0, the pressure's velocity change
//! `Δv_i = -dt [Σ_j V (κ_i + κ_j) ∇W_ij + Σ_b V_b κ_i ∇W_ib]` with `κ = p/(ρ₀ ρ̂²)` in the
//! pass of the other forces (`forces.rs`), symplectic Euler.

use super::{compression, Solver};
use crate::fluid::model::Model;
use crate::fluid::Stats;

impl Solver {
    /// One WCSPH substep of length `h` (s) in which no particle moves much more than `reach`
    /// (m), for the sound speed `c` (m/s).
    pub(super) fn wcsph(&mut self, model: &Model, h: f64, reach: f64, c: f64, stats: &mut Stats) {
        self.search(model, reach);
        self.densities(model, false);
        self.residual.iter_mut().zip(&self.density).for_each(|(e, r)| *e = r - 1.0);
        let (mean, max) = compression(&self.residual);
        stats.density_error = stats.density_error.max(mean);
        stats.max_density_error = stats.max_density_error.max(max);
        let c2 = c * c / 7.0;
        for ((p, k), &r) in self.pressure.iter_mut().zip(&mut self.k).zip(&self.density) {
            *p = (c2 * (r.powi(7) - 1.0)).max(0.0);
            *k = *p / (r * r);
        }
        self.non_pressure(model, h, model.settings.gravity * h, true, stats);
        self.move_colliders(h);
        self.advect(model, h);
    }
}
