//! Implicit viscosity (Weiler, Koschier, Brochard & Bender 2018, "A physically consistent
//! implicit viscosity solver for SPH fluids", Computer Graphics Forum 37(2)): the velocities
//! after a substep of `dt` solve `v = v* + dt ν ∇²v` with the paper's Laplacian (eq. 11,
//! after Monaghan 2005), for `d = 3`,
//!
//! `ν ∇²v_i = (10 ν / ρ̂_i) [Σ_j (V/ρ̂_j) (v_ij·x_ij)/(|x_ij|² + 0.01 h²) ∇W_ij
//!           + Σ_b V_b ((v_i - v_b)·x_ib)/(|x_ib|² + 0.01 h²) ∇W_ib]`
//!
//! (`2(d + 2) = 10`; the fluid term's `m_j/ρ_j = V/ρ̂_j`; the boundary term as in
//! SPlisHSPlasH's `Viscosity_Weiler2018`, Akinci volumes `V_b` and the boundary points'
//! velocities `v_b`: a no-slip wall). The `1/ρ̂_i` of `ρ Dv/Dt = μ ∇²v` makes the system
//! matrix `A = I - dt ν ∇²` symmetric: its block `(i, j)` is `10 dt ν V/(ρ̂_i ρ̂_j) G_ij`
//! with `G_ij = ∇W_ij x_ijᵀ/(|x_ij|² + 0.01 h²)` (symmetric and negative semi-definite, as
//! `∇W_ij` points along `-x_ij`), so `A` is symmetric positive definite and conjugate
//! gradients apply. The solve is matrix-free, preconditioned by the inverses of the 3 × 3
//! diagonal blocks (block Jacobi, as in the paper), warm started from the last substep's
//! velocity change, and stops when `|b - A v| ≤ tol |b|`. Its dot products are summed per
//! chunk of [`CHUNK`] particles and then in chunk order: the same bits for any thread count.
//!
//! Pairwise terms act along `x_ij`: linear and angular momentum are conserved, and a rigid
//! rotation (`v_ij·x_ij = 0`) is not damped.

use super::neighbours::Neighbours;
use crate::geometry::grid::CHUNK;
use glam::{DMat3, DVec3};
use rayon::prelude::*;

/// `|b - A v| / |b|` (percent) at which the solve stops.
pub(super) const TOLERANCE: f64 = 0.01;

/// The most conjugate-gradient iterations of one solve.
pub(super) const MAX_ITERATIONS: usize = 100;

/// The linear system of one substep, borrowing the solver's pairs.
pub(super) struct System<'a> {
    pub neighbours: &'a Neighbours,
    /// `∇W_ij` of every pair, in the lists' layout.
    pub gradients: &'a [Vec<DVec3>],
    /// Fluid then boundary points (m).
    pub points: &'a [DVec3],
    /// `ρ̂` of the fluid particles.
    pub density: &'a [f64],
    /// The boundary points' volumes `V_b` (m³) and velocities (m/s).
    pub boundary_volume: &'a [f64],
    pub boundary_velocity: &'a [DVec3],
    /// The fluid particle volume `V` (m³).
    pub volume: f64,
    /// `10 dt ν` (m²).
    pub scale: f64,
    /// `0.01 h²` (m²).
    pub epsilon: f64,
}

/// The solve's workspace (buffers only grow).
#[derive(Clone, Debug, Default)]
pub(super) struct Workspace {
    /// The right-hand side `b` (m/s).
    rhs: Vec<DVec3>,
    /// The inverses of the diagonal blocks.
    inverse: Vec<DMat3>,
    /// The solution being iterated (m/s).
    x: Vec<DVec3>,
    /// Residual, preconditioned residual, search direction and `A p`.
    r: Vec<DVec3>,
    z: Vec<DVec3>,
    p: Vec<DVec3>,
    q: Vec<DVec3>,
    /// Partial sums of a dot product, one per chunk.
    partial: Vec<f64>,
}

impl System<'_> {
    /// `Σ` over the pairs of fluid particle `i` of `f(j, ∇W_ij / (|x_ij|² + ε), x_ij)`,
    /// fluid neighbours weighted by `V/ρ̂_j`, boundary ones by `V_b` and flagged.
    fn sum(&self, i: usize, mut f: impl FnMut(usize, DVec3, DVec3, bool) -> DVec3) -> DVec3 {
        let n = self.density.len();
        let near = self.neighbours.neighbours(i);
        let grads = &self.gradients[i / CHUNK][self.neighbours.span(i)];
        let mut sum = DVec3::ZERO;
        for (&j, &g) in near.iter().zip(grads) {
            let j = j as usize;
            let x = self.points[i] - self.points[j];
            let g = g / (x.length_squared() + self.epsilon);
            sum += if j < n {
                f(j, g * (self.volume / self.density[j]), x, false)
            } else {
                f(j - n, g * self.boundary_volume[j - n], x, true)
            };
        }
        sum * (self.scale / self.density[i])
    }

    /// `out = A x` (m/s).
    pub fn product(&self, x: &[DVec3], out: &mut [DVec3]) {
        out.par_iter_mut().enumerate().for_each(|(i, out)| {
            let s = self.sum(i, |j, g, d, wall| {
                let v = if wall { x[i] } else { x[i] - x[j] };
                g * d.dot(v)
            });
            *out = x[i] - s;
        });
    }

    /// Solve `A v = v* + (boundary velocities' term)` for `v` (the velocities, m/s, `v*` on
    /// entry), from `v* + warm`; `warm` becomes the change `v - v*`. Returns the iterations
    /// and the relative residual reached (percent).
    pub fn solve(&self, w: &mut Workspace, v: &mut [DVec3], warm: &mut [DVec3]) -> (usize, f64) {
        let n = v.len();
        for buffer in [&mut w.rhs, &mut w.x, &mut w.r, &mut w.z, &mut w.p, &mut w.q] {
            buffer.resize(n, DVec3::ZERO);
        }
        w.inverse.resize(n, DMat3::IDENTITY);
        let bv = self.boundary_velocity;
        let (rhs, inverse) = (&mut w.rhs, &mut w.inverse);
        rhs.par_iter_mut().zip(inverse).enumerate().for_each(|(i, (b, inv))| {
            let mut block = DMat3::ZERO;
            let drag = self.sum(i, |j, g, d, wall| {
                let outer = DMat3::from_cols(g * d.x, g * d.y, g * d.z);
                block += outer * (self.scale / self.density[i]);
                if wall {
                    g * d.dot(bv[j])
                } else {
                    DVec3::ZERO
                }
            });
            *b = v[i] - drag;
            *inv = (DMat3::IDENTITY - block).inverse();
        });
        w.x.par_iter_mut().zip(&*v).zip(&*warm).for_each(|((x, v), d)| *x = *v + *d);
        self.product(&w.x, &mut w.r);
        w.r.par_iter_mut().zip(&w.rhs).for_each(|(r, b)| *r = *b - *r);
        let bb = dot(&w.rhs, &w.rhs, &mut w.partial);
        let limit = (TOLERANCE / 100.0).powi(2) * bb;
        precondition(&w.inverse, &w.r, &mut w.z);
        w.p.copy_from_slice(&w.z);
        let mut rz = dot(&w.r, &w.z, &mut w.partial);
        let mut rr = dot(&w.r, &w.r, &mut w.partial);
        let mut iterations = 0;
        while rr > limit && iterations < MAX_ITERATIONS {
            self.product(&w.p, &mut w.q);
            let pq = dot(&w.p, &w.q, &mut w.partial);
            if pq.is_nan() || pq <= 0.0 {
                break;
            }
            let alpha = rz / pq;
            w.x.par_iter_mut().zip(&w.p).for_each(|(x, p)| *x += *p * alpha);
            w.r.par_iter_mut().zip(&w.q).for_each(|(r, q)| *r -= *q * alpha);
            precondition(&w.inverse, &w.r, &mut w.z);
            let next = dot(&w.r, &w.z, &mut w.partial);
            let beta = next / rz;
            rz = next;
            w.p.par_iter_mut().zip(&w.z).for_each(|(p, z)| *p = *z + *p * beta);
            rr = dot(&w.r, &w.r, &mut w.partial);
            iterations += 1;
        }
        warm.par_iter_mut().zip(&w.x).zip(&*v).for_each(|((d, x), v)| *d = *x - *v);
        v.copy_from_slice(&w.x);
        let error = if bb > 0.0 { 100.0 * (rr / bb).sqrt() } else { 0.0 };
        (iterations, error)
    }
}

/// `z = M⁻¹ r` with the inverted diagonal blocks.
fn precondition(inverse: &[DMat3], r: &[DVec3], z: &mut [DVec3]) {
    z.par_iter_mut().zip(inverse).zip(r).for_each(|((z, m), r)| *z = *m * *r);
}

/// `a · b` summed per chunk of [`CHUNK`] then in chunk order (deterministic).
fn dot(a: &[DVec3], b: &[DVec3], partial: &mut Vec<f64>) -> f64 {
    partial.resize(a.len().div_ceil(CHUNK), 0.0);
    partial
        .par_iter_mut()
        .zip(a.par_chunks(CHUNK).zip(b.par_chunks(CHUNK)))
        .for_each(|(s, (a, b))| *s = a.iter().zip(b).map(|(a, b)| a.dot(*b)).sum());
    partial.iter().sum()
}
