//! The fluid's surface as a closed triangle mesh: the level `½` of the smoothed colour field
//! `c(x) = Σ_j V W(x - x_j)` (Müller, Charypar & Gross 2003, "Particle-based fluid simulation
//! for interactive applications", §4.4; the same kernel and particle volume as the solver),
//! sampled on a grid and polygonised by the shared marching tetrahedra
//! ([`crate::geometry::isosurface`]).
//!
//! Why `½`: the particle volume makes `c = 1` on the rest lattice, and a lattice face is a
//! mirror plane of the lattice, so on the face of a block at rest `c` is exactly half of 1:
//! the mesh passes through the block's faces (half a spacing beyond its outer particles)
//! and rounds its edges and corners within the kernel's support. Not Zhu & Bridson (2005)
//! or Yu & Turk (2013): their fields need a radius or anisotropy tuned to do the same.

use super::{Model, State};
use crate::error::{Error, Result};
use crate::geometry::isosurface::{polygonise, Mesh};
use glam::DVec3;
use rayon::prelude::*;

/// Most grid samples a surface may take (2²⁶, 512 MiB of samples).
const MAX_SAMPLES: usize = 1 << 26;

/// The surface of `state`'s fluid sampled every `resolution` metres (see the module docs):
/// vertices (m) and outward-facing triangles, closed and manifold. No fluid: no surface.
///
/// # Errors
/// `resolution` not finite and positive, or so fine that the grid over the fluid would
/// take more than 2²⁶ samples (`resolution`).
pub fn surface_mesh(model: &Model, state: &State, resolution: f64) -> Result<Mesh> {
    if !(resolution.is_finite() && resolution > 0.0) {
        return Err(Error::invalid("resolution", "must be finite and > 0"));
    }
    let x = &state.positions;
    if x.is_empty() {
        return Ok((Vec::new(), Vec::new()));
    }
    let h = model.support;
    let lower = x.iter().fold(DVec3::INFINITY, |a, &p| a.min(p)) - DVec3::splat(h + resolution);
    let upper = x.iter().fold(DVec3::NEG_INFINITY, |a, &p| a.max(p)) + DVec3::splat(h + resolution);
    let span = ((upper - lower) / resolution).ceil() + 1.0;
    if !span.is_finite() || span.x * span.y * span.z > MAX_SAMPLES as f64 {
        return Err(Error::invalid(
            "resolution",
            "too fine: the grid needs more than 2^26 samples",
        ));
    }
    let counts = span.to_array().map(|c| c as usize);
    let values = colour(model, x, lower, resolution, counts);
    Ok(polygonise(&values, counts, lower, resolution))
}

/// `½ - c` at the grid samples `lower + resolution (i, j, k)` (x fastest), each z-slab of
/// samples summing the particles whose support reaches it (in particle order: the same
/// bits on any number of threads).
fn colour(model: &Model, x: &[DVec3], lower: DVec3, cell: f64, counts: [usize; 3]) -> Vec<f64> {
    let (h, kernel, vol) = (model.support, model.settings.kernel, model.volume);
    let [nx, ny, nz] = counts;
    let index = |p: f64, lo: f64, n: usize| {
        let r = (p - lo) / cell;
        (((r - h / cell).ceil().max(0.0)) as usize, ((r + h / cell).floor() as usize).min(n - 1))
    };
    let mut values = vec![0.5; nx * ny * nz];
    values.par_chunks_mut(nx * ny).enumerate().for_each(|(k, slab)| {
        let z = lower.z + cell * k as f64;
        for p in x.iter().filter(|p| (p.z - z).abs() < h) {
            let (i0, i1) = index(p.x, lower.x, nx);
            let (j0, j1) = index(p.y, lower.y, ny);
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let at = lower + DVec3::new(i as f64, j as f64, k as f64) * cell;
                    slab[i + nx * j] -= vol * kernel.value((at - *p).length(), h);
                }
            }
        }
    });
    values
}
