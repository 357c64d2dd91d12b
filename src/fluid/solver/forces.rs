//! The forces other than pressure, one pass over the pairs: gravity, XSPH viscosity
//! (Schechter & Bridson 2012, eq. 11), surface tension (Akinci, Akinci & Teschner 2013) and,
//! for WCSPH, the pressure's velocity change in the same pass; then the implicit viscosity
//! solve (`viscosity.rs`) in XSPH's place.

use super::{fluid_count, Solver};
use crate::fluid::model::{Model, Viscosity};
use crate::fluid::viscosity::System;
use crate::fluid::Stats;
use crate::geometry::grid::CHUNK;
use glam::DVec3;
use rayon::prelude::*;

impl Solver {
    /// Gravity's velocity change `g` (m/s: `dt` times gravity), XSPH viscosity
    /// `v_i += g + ν Σ_j (V / ρ̂_j) (v_j - v_i) W_ij` (the `W_ij` of the last
    /// [`Solver::densities`]), and over `dt` (s) surface tension (Akinci et al. 2013,
    /// [`super::Settings::surface_tension`]); then, instead of XSPH, the implicit viscosity
    /// solve ([`Viscosity::Implicit`], the `viscosity` module) over `dt`. With `pressure`
    /// (WCSPH), the same pass over the pairs also finds the pressure's velocity change of
    /// [`Solver::apply`] with the pressures `k`, added last (it reads no velocity): the same
    /// bits as a separate pass, one pass over the pairs fewer.
    pub(super) fn non_pressure(
        &mut self,
        model: &Model,
        dt: f64,
        g: DVec3,
        pressure: bool,
        stats: &mut Stats,
    ) {
        let gamma = model.settings.surface_tension;
        if gamma > 0.0 {
            self.normals_now(model);
        }
        let (mut dv, mut dp) = (std::mem::take(&mut self.dv), std::mem::take(&mut self.dp));
        let n = self.v.len();
        dp.resize(n, DVec3::ZERO);
        let mut weight = std::mem::take(&mut self.weight);
        weight.resize(n, 0.0);
        let vol = model.volume;
        weight.par_iter_mut().zip(&self.density).for_each(|(w, d)| *w = vol / d);
        let Solver { neighbours, points, v, density, normals, values, gradients, k, .. } = &*self;
        let (sup, vb) = (model.support, &model.boundary_volume);
        let nu = match model.settings.viscosity {
            Viscosity::Xsph(c) => c,
            Viscosity::Implicit(_) => 0.0,
        };
        let mass = model.volume * model.settings.rest_density;
        let viscous = nu > 0.0 || gamma > 0.0;
        dv.par_iter_mut().zip(&mut dp).enumerate().for_each(|(i, (out, out_p))| {
            let (mut sum, mut tension, mut push) = (DVec3::ZERO, DVec3::ZERO, DVec3::ZERO);
            // Flags and particle `i`'s values in registers, not read through the captures.
            let (pressure, viscous, gamma, v_i, k_i) = (pressure, viscous, gamma, v[i], k[i]);
            let span = neighbours.span(i);
            let (near, values) = (neighbours.neighbours(i), &values[i / CHUNK][span.clone()]);
            let grads = &gradients[i / CHUNK][span];
            // The fluid neighbours, then the boundary points (the lists ascend): no branch on
            // the kind of a pair, the same sums in the same order.
            let fluid = fluid_count(near, n);
            let pairs = near[..fluid].iter().zip(&values[..fluid]).zip(&grads[..fluid]);
            for ((&j, &w), &gradient) in pairs.filter(|_| viscous || pressure) {
                let j = j as usize;
                if pressure {
                    push += gradient * (vol * (k_i + k[j]));
                }
                if viscous {
                    sum += (v[j] - v_i) * (weight[j] * w);
                    let d = points[i] - points[j];
                    let r = if gamma > 0.0 { d.length() } else { 0.0 };
                    if r > 0.0 {
                        let cohesion = d * (mass * crate::fluid::kernel::cohesion(r, sup) / r);
                        let k = 2.0 / (density[i] + density[j]);
                        tension += (cohesion + normals[i] - normals[j]) * k;
                    }
                }
            }
            let walls = near[fluid..].iter().zip(&grads[fluid..]);
            for (&j, &gradient) in walls.filter(|_| pressure) {
                push += gradient * (vb[j as usize - n] * k_i);
            }
            *out = g + sum * nu - tension * (gamma * dt);
            *out_p = push * -dt;
        });
        self.v.par_iter_mut().zip(&dv).for_each(|(v, dv)| *v += *dv);
        (self.dv, self.weight) = (dv, weight);
        if let Viscosity::Implicit(nu) = model.settings.viscosity {
            let (mut w, mut v, mut warm) = (
                std::mem::take(&mut self.implicit),
                std::mem::take(&mut self.v),
                std::mem::take(&mut self.viscous),
            );
            let (it, err) = self.viscosity_system(model, dt * nu).solve(&mut w, &mut v, &mut warm);
            (self.implicit, self.v, self.viscous) = (w, v, warm);
            stats.viscosity_iterations += it;
            stats.viscosity_error = stats.viscosity_error.max(err);
        }
        if pressure {
            self.v.par_iter_mut().zip(&dp).for_each(|(v, dp)| *v += *dp);
        }
        self.dp = dp;
    }

    /// The implicit-viscosity system `(I - dt ν ∇²) v = v*` (Weiler et al. 2018, eq. 11)
    /// over this substep's pairs, for `dt_nu = dt ν` (m²).
    pub(in crate::fluid) fn viscosity_system<'a>(
        &'a self,
        model: &'a Model,
        dt_nu: f64,
    ) -> System<'a> {
        System {
            neighbours: &self.neighbours,
            gradients: &self.gradients,
            points: &self.points,
            density: &self.density,
            boundary_volume: &model.boundary_volume,
            boundary_velocity: &self.boundary_velocity,
            volume: model.volume,
            scale: 10.0 * dt_nu,
            epsilon: 0.01 * model.support * model.support,
        }
    }

    /// The surface normals `n_i = -h Σ_j (V / ρ̂_j) ∇W_ij` over fluid neighbours (Akinci et
    /// al. 2013, eq. 5), from the last [`Solver::densities`]' gradients. `∇W_ij` (with
    /// respect to `x_i`) points towards the neighbours, so the sign makes `n` point out of
    /// the fluid: with `n` pointing in, the curvature term pushed a cube's corners outwards
    /// (its corner ratio in `tests/fluid_tension.rs` grew from 1.53 to 2.2 in 1 s).
    fn normals_now(&mut self, model: &Model) {
        let mut normals = std::mem::take(&mut self.normals);
        let n = self.v.len();
        normals.resize(n, DVec3::ZERO);
        let (vol, h, density) = (model.volume, model.support, &self.density);
        normals.par_iter_mut().enumerate().for_each(|(i, out)| {
            let (near, grads, fluid) = self.pairs(i);
            let mut sum = DVec3::ZERO;
            for (&j, &g) in near[..fluid].iter().zip(grads) {
                sum += g * (vol / density[j as usize]);
            }
            *out = sum * -h;
        });
        self.normals = normals;
    }
}
