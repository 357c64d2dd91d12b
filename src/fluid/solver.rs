//! The fluid solver: neighbour lists, densities, DFSPH factors and every scratch buffer. It
//! carries nothing a later step's result depends on (a later step may reuse the Verlet
//! lists' candidates, but its lists are exact and in index order either way):
//! [`Solver::step`] copies the state in, steps the copy and writes it back only when every
//! substep succeeded. This file holds the step: frames, CFL substeps, emitters and the kill
//! box, the neighbour search, the density pass and advection; each pressure solver's
//! substep is in `solver/` (`dfsph.rs`, `pbf.rs`, `wcsph.rs`), the other forces in
//! `solver/forces.rs`.
//!
//! All quantities are per unit rest density (SPlisHSPlasH's formulation): `ρ̂ = ρ/ρ₀`,
//! fluid particle volume `V = m/ρ₀`, boundary volume `V_b = ψ_b/ρ₀`, and `κ = p/ρ₀`.
//!
//! - Density (Akinci et al. 2012, eq. 6): `ρ̂_i = V W(0) + Σ_j V W_ij + Σ_b V_b W_ib`.
//! - Pressure's velocity change (symmetric, with Akinci's boundary term, eq. 10):
//!   `Δv_i = -dt [Σ_j V (κ_i + κ_j) ∇W_ij + Σ_b V_b κ_i ∇W_ib]` (Bender & Koschier 2017,
//!   eq. 9 and 11), DFSPH's `κ` carrying the division by `ρ̂²`; WCSPH uses `κ = p/(ρ₀ ρ̂²)`.

mod dfsph;
mod forces;
mod pbf;
mod wcsph;

use super::collider::{confine, Collider};
use super::density::{Pass, LANES};
use super::model::{Model, Pressure};
use super::neighbours::{Neighbours, MAX_SKIN};
use super::order::{gather, Order};
use super::viscosity::Workspace;
use super::{State, Stats};
use crate::error::{reserve, Error, Result};
use crate::geometry::grid::CHUNK;
use glam::DVec3;
use rayon::prelude::*;

/// The largest `|g| dt² / spacing` of a substep. On the lattice at `h = 2 s` the discrete
/// divergence cannot see layers moving alternately, so converged solves let every other
/// layer fall freely for a substep (`solver_tests.rs`); only the compression that this
/// displacement, `g dt²` a substep, causes at second order pushes back, and it must stay
/// small against the spacing. Measured (docs/fluid.md, "Speed"): a column 25 particles deep
/// blows up at 0.049; the dam break at `L/50` (100 particles high) goes wrong at 0.02 (a
/// particle inside the column at 3.4 m/s, the mean speed 60 % above `L/10`'s) and agrees
/// with `L/10` and `L/20` at 0.01 and 0.005.
const GRAVITY_STEP: f64 = 0.01;

/// The Verlet skin (`neighbours.rs`) is chosen so that the candidates last about this many
/// substeps at the current speeds (each point may move half the skin).
const LIST_SUBSTEPS: f64 = 8.0;

/// The workspaces of a fluid step (see the module docs).
#[derive(Clone, Debug, Default)]
pub struct Solver {
    neighbours: Neighbours,
    /// The particles' order in the stepped copy (`order.rs`): Z-order of their cells.
    order: Order,
    /// Fluid then boundary positions (m), the points of the neighbour lists.
    points: Vec<DVec3>,
    /// `∇W_ij` (1/m⁴) of every neighbour pair, in the lists' layout (chunk `i / CHUNK`,
    /// [`Neighbours::span`]): computed with the densities, read by every solver iteration.
    gradients: Vec<Vec<DVec3>>,
    /// `W_ij` (1/m³) of every neighbour pair, in the same layout: read by the viscosity.
    values: Vec<Vec<f64>>,
    /// The stepped copy of the state's velocities (m/s).
    v: Vec<DVec3>,
    /// The stepped copy of the state's pressures `κ` (m²/s²).
    pressure: Vec<f64>,
    /// The stepped copy of the state's divergence impulses (m²/s).
    divergence: Vec<f64>,
    /// The stepped copy of the state's implicit viscosity velocity changes (m/s).
    viscous: Vec<DVec3>,
    /// The implicit viscosity solve's workspace.
    implicit: Workspace,
    /// Density ratio `ρ̂` per particle.
    density: Vec<f64>,
    /// DFSPH factor `α` (m²) per particle.
    alpha: Vec<f64>,
    /// Residual per particle (density error, or density rate in 1/s).
    residual: Vec<f64>,
    /// The pressure increment of the current iteration (m²/s²).
    k: Vec<f64>,
    /// The pressure accumulated by the current solve (m²/s²).
    total: Vec<f64>,
    /// Surface normals `n_i = -h Σ_j V/ρ̂_j ∇W_ij` (Akinci et al. 2013, eq. 5, pointing out
    /// of the fluid), with surface tension only.
    normals: Vec<DVec3>,
    /// Velocity change scratch (m/s); PBF's position corrections (m).
    dv: Vec<DVec3>,
    /// WCSPH's pressure velocity change (m/s).
    dp: Vec<DVec3>,
    /// `V / ρ̂` per particle (m³), XSPH's weight of a neighbour.
    weight: Vec<f64>,
    /// PBF: the positions at the start of the substep (m).
    x0: Vec<DVec3>,
    /// The stepped copy of the state's emitter distances (m).
    emitted: Vec<f64>,
    /// An emitter's new layer (m).
    layer: Vec<DVec3>,
    /// The stepped copy of the state's colliders.
    colliders: Vec<Collider>,
    /// The velocity (m/s) of every boundary point: 0 on walls, a collider's on its own.
    boundary_velocity: Vec<DVec3>,
}

impl Solver {
    /// A solver for `model` (its buffers grow on the first step).
    pub fn new(_model: &Model) -> Self {
        Solver::default()
    }

    /// Advance `state` by `steps` frames of `dt` seconds, each in substeps of the CFL
    /// condition (at most `max_dt`, at most `cfl` spacings per substep for the fastest
    /// particle or emitter, and
    /// `dt ≤ sqrt(GRAVITY_STEP spacing / |g|)`), frames split evenly into substeps.
    ///
    /// # Errors
    /// `dt` not finite and positive; a state with another number of colliders than the model
    /// (`state`); a frame needing more than `max_substeps`
    /// ([`Error::SolverFailed`]); a non-finite position or velocity ([`Error::Diverged`]);
    /// emitters making more particles than memory or the limit of 2³⁰ allow (`steps`).
    /// The state is then left as it was.
    pub fn step(
        &mut self,
        model: &Model,
        state: &mut State,
        dt: f64,
        steps: usize,
    ) -> Result<Stats> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(Error::invalid("dt", "must be finite and > 0"));
        }
        if state.colliders.len() != model.colliders.len() {
            return Err(Error::invalid("state", "one collider pose per collider of the model"));
        }
        let mut stats = Stats::default();
        self.colliders.clone_from(&state.colliders);
        self.points.clone_from(&state.positions);
        self.v.clone_from(&state.velocities);
        self.pressure.clone_from(&state.pressure);
        self.divergence.clone_from(&state.divergence);
        self.viscous.clone_from(&state.viscous);
        self.emitted.clone_from(&state.emitted);
        self.emitted.resize(model.emitters.len(), model.settings.spacing);
        self.order.start(state.len());
        for _ in 0..steps {
            if !state.is_empty() || !model.emitters.is_empty() {
                self.frame(model, dt, &mut stats)?;
            }
        }
        let n = self.v.len();
        for buffer in [&mut state.positions, &mut state.velocities] {
            reserve("steps", buffer, n.saturating_sub(buffer.len()))?;
        }
        for buffer in [&mut state.pressure, &mut state.divergence] {
            reserve("steps", buffer, n.saturating_sub(buffer.len()))?;
        }
        let more = n.saturating_sub(state.viscous.len());
        reserve("steps", &mut state.viscous, more)?;
        // Back in the state's order (`order.rs`).
        let slots = self.order.slots();
        gather(slots, &self.points, &mut state.positions);
        gather(slots, &self.v, &mut state.velocities);
        gather(slots, &self.viscous, &mut state.viscous);
        gather(slots, &self.pressure, &mut state.pressure);
        gather(slots, &self.divergence, &mut state.divergence);
        state.emitted.clone_from(&self.emitted);
        state.colliders.clone_from(&self.colliders);
        state.time += dt * steps as f64;
        Ok(stats)
    }

    /// Emit the layers every emitter owes after a substep of `h` (s), then size the
    /// per-particle buffers.
    fn emit(&mut self, model: &Model, h: f64) -> Result<()> {
        let s = model.settings.spacing;
        for (e, moved) in model.emitters.iter().zip(&mut self.emitted) {
            *moved += e.speed * h;
            while *moved >= s {
                *moved -= s;
                let n = self.v.len();
                self.layer.clear();
                e.layer(s, *moved, &self.points[..n], &mut self.layer);
                let k = self.layer.len();
                if n + k >= u32::MAX as usize / 4 {
                    return Err(Error::invalid("steps", "the emitters exceed 2^30 particles"));
                }
                self.points.truncate(n);
                reserve("steps", &mut self.points, k)?;
                reserve("steps", &mut self.v, k)?;
                reserve("steps", &mut self.pressure, k)?;
                reserve("steps", &mut self.divergence, k)?;
                reserve("steps", &mut self.viscous, k)?;
                self.points.extend_from_slice(&self.layer);
                self.v.resize(n + k, e.direction * e.speed);
                self.pressure.resize(n + k, 0.0);
                self.divergence.resize(n + k, 0.0);
                self.viscous.resize(n + k, DVec3::ZERO);
                self.order.emitted(k);
            }
        }
        let n = self.v.len();
        self.points.truncate(n);
        for buffer in
            [&mut self.density, &mut self.alpha, &mut self.residual, &mut self.k, &mut self.total]
        {
            buffer.resize(n, 0.0);
        }
        self.dv.resize(n, DVec3::ZERO);
        Ok(())
    }

    /// Remove the particles outside the kill box, keeping the others' order.
    fn kill(&mut self, model: &Model) {
        let Some((lower, upper)) = model.kill_box else { return };
        let n = self.v.len();
        let mut kept = 0;
        for i in 0..n {
            let x = self.points[i];
            if x.cmpge(lower).all() && x.cmple(upper).all() {
                self.points[kept] = x;
                self.v[kept] = self.v[i];
                self.pressure[kept] = self.pressure[i];
                self.divergence[kept] = self.divergence[i];
                self.viscous[kept] = self.viscous[i];
                self.order.user[kept] = self.order.user[i];
                kept += 1;
            }
        }
        self.points.truncate(kept);
        self.v.truncate(kept);
        self.pressure.truncate(kept);
        self.divergence.truncate(kept);
        self.viscous.truncate(kept);
        self.order.user.truncate(kept);
    }

    /// One frame of `dt` in CFL substeps, the particles first sorted by cell (`order.rs`).
    fn frame(&mut self, model: &Model, dt: f64, stats: &mut Stats) -> Result<()> {
        let n = self.v.len();
        let Solver { order, points, v, viscous, pressure, divergence, .. } = self;
        order.sort(&mut points[..n], model.support, &mut [v, viscous], &mut [pressure, divergence]);
        let mut left = dt;
        let mut taken = 0;
        while left > 0.0 {
            if taken == model.settings.max_substeps {
                return Err(Error::SolverFailed {
                    reason: format!(
                        "a frame needs more than max_substeps = {} substeps",
                        model.settings.max_substeps
                    ),
                });
            }
            let (limit, fastest) = self.substep_limit(model);
            let h = left / (left / limit).ceil().max(1.0);
            self.substep(model, h, h * fastest, stats)?;
            left = if h >= left { 0.0 } else { left - h };
            taken += 1;
        }
        Ok(())
    }

    /// The longest substep the CFL condition allows now (s), and the speed of the fastest
    /// particle, emitter or collider (m/s).
    fn substep_limit(&self, model: &Model) -> (f64, f64) {
        let s = &model.settings;
        let emitted = model.emitters.iter().map(|e| e.speed);
        let moving = self.colliders.iter().map(|c| c.velocity.length());
        let fastest =
            self.v.iter().map(|v| v.length()).chain(emitted).chain(moving).fold(0.0, f64::max);
        let mut speed = fastest;
        if let Pressure::Wcsph { sound_speed } = s.pressure {
            speed += sound_speed;
        }
        let g = s.gravity.length();
        let mut limit = s.max_dt;
        if speed > 0.0 {
            limit = limit.min(s.cfl * s.spacing / speed);
        }
        if g > 0.0 {
            limit = limit.min((GRAVITY_STEP * s.spacing / g).sqrt());
        }
        (limit, fastest)
    }

    /// One substep of length `h` (s) in which no particle moves much more than `reach` (m).
    fn substep(&mut self, model: &Model, h: f64, reach: f64, stats: &mut Stats) -> Result<()> {
        self.emit(model, h)?;
        let n = self.v.len();
        stats.substeps += 1;
        if n == 0 {
            return Ok(());
        }
        match model.settings.pressure {
            Pressure::Dfsph { max_iterations, divergence_tolerance, density_tolerance } => {
                let limits = (max_iterations, divergence_tolerance, density_tolerance);
                self.dfsph(model, h, reach, limits, stats);
            }
            Pressure::Pbf { max_iterations, density_tolerance, tensile } => {
                // PBF's constraints act on the positions at the end of the substep.
                self.move_colliders(h);
                let (it, err, max) =
                    self.pbf(model, h, reach, max_iterations, density_tolerance, tensile, stats);
                stats.density_iterations += it;
                stats.density_error = stats.density_error.max(err);
                stats.max_density_error = stats.max_density_error.max(max);
            }
            Pressure::Wcsph { sound_speed } => self.wcsph(model, h, reach, sound_speed, stats),
        }
        // The index reported is the particle's in the state (`order.rs`).
        let finite = |i: &usize| self.points[*i].is_finite() && self.v[*i].is_finite();
        let bad = (0..n).find(|i| !finite(i)).map(|i| self.order.user[i] as usize);
        self.kill(model);
        match bad {
            Some(index) => Err(Error::Diverged {
                step: stats.substeps - 1,
                index,
                reason: "non-finite position or velocity".into(),
            }),
            None => Ok(()),
        }
    }

    /// Move every collider by its velocity over a substep of `h` (s).
    fn move_colliders(&mut self, h: f64) {
        for c in &mut self.colliders {
            c.shape = c.shape.translated(c.velocity * h);
        }
    }

    /// Put the boundary particles after the fluid's (the walls', then the colliders' where
    /// they are now, with their velocities) and update the neighbour lists. `reach`
    /// (m), how far the fastest particle moves in a substep, sets the Verlet skin: candidates
    /// that last about [`LIST_SUBSTEPS`] substeps, at most `MAX_SKIN h` (half a spacing), none if
    /// that would not last two.
    fn search(&mut self, model: &Model, reach: f64) {
        let n = self.v.len();
        self.points.truncate(n);
        self.points.extend_from_slice(&model.boundary);
        model.place_colliders(&self.colliders, &mut self.points);
        self.boundary_velocity.clear();
        self.boundary_velocity.resize(model.boundary.len(), DVec3::ZERO);
        for (body, c) in model.colliders.iter().zip(&self.colliders) {
            let k = self.boundary_velocity.len() + body.points.len();
            self.boundary_velocity.resize(k, c.velocity);
        }
        // At most `MAX_SKIN h`, half a spacing: the candidates within `h + skin` grow as
        // `(1 + skin / h)³`, 1.95 times the neighbours.
        let mut skin = (2.0 * LIST_SUBSTEPS * reach).min(MAX_SKIN * model.support);
        if skin < 4.0 * reach {
            skin = 0.0;
        }
        self.neighbours.update(&self.points, n, model.boundary.len(), model.support, skin);
    }

    /// Densities `ρ̂`, the kernel values and gradients of every pair and, if `factors`,
    /// DFSPH's `α` (`density.rs`).
    fn densities(&mut self, model: &Model, factors: bool) {
        let Solver { neighbours, points, density, alpha, gradients, values, .. } = self;
        let n = density.len();
        let pass = Pass {
            neighbours,
            points,
            n,
            kernel: model.settings.kernel,
            h: model.support,
            volume: model.volume,
            boundary_volume: &model.boundary_volume,
            factors,
        };
        gradients.resize_with(n.div_ceil(CHUNK), Vec::new);
        values.resize_with(n.div_ceil(CHUNK), Vec::new);
        #[cfg(target_arch = "x86_64")]
        let avx = pulp::x86::V3::try_new();
        let chunks = density.par_chunks_mut(CHUNK).zip(alpha.par_chunks_mut(CHUNK));
        let chunks = chunks.zip(gradients.par_iter_mut().zip(values));
        chunks.enumerate().for_each(|(c, ((rho, a), (grads, values)))| {
            // Written by span; never shortened (no fill each substep), stale past the end.
            let pairs = pass.neighbours.span(c * CHUNK + rho.len() - 1).end;
            if grads.len() < pairs {
                grads.resize(pairs, DVec3::ZERO);
                values.resize(pairs, 0.0);
            }
            let mut k = 0;
            #[cfg(target_arch = "x86_64")]
            if let Some(simd) = avx {
                simd.vectorize(|| {
                    while k + LANES <= rho.len() {
                        let got = pass.lanes(simd, c * CHUNK + k, grads, values);
                        for (l, (r, f)) in got.into_iter().enumerate() {
                            (rho[k + l], a[k + l]) = (r, f);
                        }
                        k += LANES;
                    }
                });
            }
            for k in k..rho.len() {
                (rho[k], a[k]) = pass.one(c * CHUNK + k, grads, values);
            }
        });
    }

    /// The neighbours of particle `i`, their `∇W_ij` (of the last [`Solver::densities`]) and
    /// how many of them are fluid particles (the first: the lists ascend).
    fn pairs(&self, i: usize) -> (&[u32], &[DVec3], usize) {
        let near = self.neighbours.neighbours(i);
        let grads = &self.gradients[i / CHUNK][self.neighbours.span(i)];
        (near, grads, fluid_count(near, self.v.len()))
    }

    /// `x += dt v`, then every wall and collider (where it is after the substep) puts back
    /// fluid that crossed it (a quarter spacing inside).
    fn advect(&mut self, model: &Model, h: f64) {
        let margin = 0.25 * model.settings.spacing;
        let n = self.v.len();
        let colliders = &*self.colliders;
        self.points[..n].par_iter_mut().zip(&mut self.v).for_each(|(x, v)| {
            *x += *v * h;
            for wall in &model.walls {
                wall.confine(x, v, margin);
            }
            for c in colliders {
                confine(c, x, v, margin);
            }
        });
    }

    /// Densities `ρ₀ ρ̂` (kg/m³) of `state`'s particles, into `out`.
    pub fn densities_of(&mut self, model: &Model, state: &State, out: &mut Vec<f64>) {
        let n = state.len();
        self.points.clone_from(&state.positions);
        self.v.clone_from(&state.velocities);
        self.colliders.clone_from(&state.colliders);
        self.density.resize(n, 0.0);
        self.alpha.resize(n, 0.0);
        self.search(model, 0.0);
        self.densities(model, false);
        out.clear();
        out.extend(self.density.iter().map(|r| r * model.settings.rest_density));
    }
}

/// How many of the ascending indices `near` are below `n`: the fluid neighbours in a list.
fn fluid_count(near: &[u32], n: usize) -> usize {
    near.partition_point(|&j| (j as usize) < n)
}

/// Mean and largest compression `max(e, 0)` of the errors `e` (percent of 1).
fn compression(errors: &[f64]) -> (f64, f64) {
    if errors.is_empty() {
        return (0.0, 0.0);
    }
    let (sum, max) = errors.iter().fold((0.0, 0.0f64), |(s, m), &e| {
        let e = e.max(0.0);
        (s + e, m.max(e))
    });
    (100.0 * sum / errors.len() as f64, 100.0 * max)
}

#[cfg(test)]
#[path = "solver_tests.rs"]
mod tests;
