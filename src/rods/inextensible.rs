//! Inextensible rods: the edge-length projection run after each step when
//! `Settings::inextensible` is on (Goldenthal, Harmon, Fattal, Bercovier & Grinspun 2007,
//! "Efficient simulation of inextensible cloth", sec. 4, fast projection), on the rod
//! solver's degrees of freedom and workspaces.

use super::band::Band;
use super::Model;
use crate::error::{Error, Result};
use glam::DVec3;

/// Move the positions in `q` (the solver's interleaved degrees of freedom) onto the
/// edge-length constraints `C_j = (|e_j|² − l̄_j²) / (2 l̄_j) = 0` by fast projection (Goldenthal et al. 2007, sec. 4, algorithm 1): each
/// iteration solves `(∇C W ∇Cᵀ) δλ = C` (`W` the inverse masses, zero for pinned
/// vertices; tridiagonal, cyclic for a ring) and moves `x −= W ∇Cᵀ δλ`, the
/// mass-weighted least change to first order, until no edge is strained by more than
/// the Newton `tolerance`. An edge whose two vertices are held is left out.
///
/// # Errors
/// Not converged within `max_iterations` ([`Error::SolverFailed`]).
pub(super) fn project(
    model: &Model,
    q: &mut [f64],
    band: &mut Band,
    multipliers: &mut Vec<f64>,
    dir: &mut [f64],
) -> Result<()> {
    let (n, vertices) = (model.edges(), model.vertices());
    let weight = |i: usize| if model.pinned[i] { 0.0 } else { 1.0 / model.masses[i] };
    let at = |q: &[f64], i: usize| DVec3::from_slice(&q[4 * i..4 * i + 3]);
    multipliers.resize(n, 0.0);
    for _ in 0..model.settings.max_iterations {
        let mut worst: f64 = 0.0;
        if model.closed {
            band.reset_folded(n, 2, 1);
        } else {
            band.reset(n, 1);
        }
        for (j, m) in multipliers.iter_mut().enumerate() {
            let (a, b) = (j, (j + 1) % vertices);
            let l = model.rest_lengths[j];
            let e = at(q, b) - at(q, a);
            let g = e / l;
            let c = (e.length_squared() - l * l) / (2.0 * l);
            worst = worst.max(c.abs() / l);
            let diagonal = g.length_squared() * (weight(a) + weight(b));
            if diagonal == 0.0 {
                band.hold(j);
                *m = 0.0;
                continue;
            }
            band.add(j, j, diagonal);
            *m = c;
            if j + 1 < n {
                let next = (at(q, (b + 1) % vertices) - at(q, b)) / model.rest_lengths[j + 1];
                if weight(b) > 0.0 {
                    band.add(j + 1, j, -g.dot(next) * weight(b));
                }
            }
        }
        if model.closed && weight(0) > 0.0 {
            let last = (at(q, 0) - at(q, n - 1)) / model.rest_lengths[n - 1];
            let first = (at(q, 1) - at(q, 0)) / model.rest_lengths[0];
            band.add(n - 1, 0, -last.dot(first) * weight(0));
        }
        if worst <= model.settings.tolerance {
            return Ok(());
        }
        if !worst.is_finite() || band.factor().is_err() {
            break;
        }
        band.solve(multipliers);
        dir.fill(0.0);
        for (j, &m) in multipliers.iter().enumerate() {
            let (a, b) = (j, (j + 1) % vertices);
            let push = (at(q, b) - at(q, a)) * (m / model.rest_lengths[j]);
            for r in 0..3 {
                dir[4 * a + r] += weight(a) * push[r];
                dir[4 * b + r] -= weight(b) * push[r];
            }
        }
        for i in 0..vertices {
            for r in 0..3 {
                q[4 * i + r] += dir[4 * i + r];
            }
        }
    }
    Err(Error::SolverFailed {
        reason: "the edge-length projection did not converge (lower dt or raise max_iterations)"
            .into(),
    })
}
