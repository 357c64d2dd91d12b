//! Strain limiting after the implicit solve (Provot 1995, "Deformation constraints in a
//! mass-spring model to describe rigid cloth behavior", §5; the velocity update as in
//! Goldenthal et al. 2007, "Efficient simulation of inextensible cloth", §4): every mesh
//! edge longer than `(1 + max_strain)` times its rest length is shortened to that length by
//! moving its ends in proportion to their inverse masses restricted to the directions their
//! filter leaves free, `Sᵢ / mᵢ` (pinned vertices do not move, vertices on a plane or touching
//! a collider slide along it), in Gauss–Seidel sweeps over the edges, and the velocities take
//! the position change divided by the step. It works on the step's new positions and
//! velocities in the scratch, so a step that fails later is rolled back with it. With
//! self-collision on, [`super::self_collide`] applies it again after its impulses.

use super::{Model, Solver};
use glam::{DMat3, DVec3};

/// Gauss–Seidel sweeps over the edges a step makes at most (the remaining excess, if any, is
/// taken up by the next steps).
const SWEEPS: usize = 32;

/// The mesh's edges and the work vector of the limiter.
pub(super) struct Edges {
    /// `(a, b, rest length (m))` of every edge, each once.
    edges: Vec<(u32, u32, f64)>,
    /// The positions before limiting.
    before: Vec<DVec3>,
}

impl Edges {
    /// The edges of `model`'s triangles with their rest lengths (from the rest `(u, v)` of the
    /// triangle, recovered from its `∂w/∂x`).
    pub(super) fn new(model: &Model) -> Edges {
        let mut edges: Vec<(u32, u32, f64)> = Vec::new();
        for t in &model.elements {
            // [Δu Δv] of corners 1, 2 from corner 0: the inverse of [[wu1 wu2] [wv1 wv2]].
            let (a, b, c, d) = (t.du[1], t.du[2], t.dv[1], t.dv[2]);
            let det = a * d - b * c;
            let uv = [(0.0, 0.0), (d / det, -b / det), (-c / det, a / det)];
            for (m, n) in [(0, 1), (1, 2), (2, 0)] {
                let (i, j) = (t.verts[m].min(t.verts[n]), t.verts[m].max(t.verts[n]));
                let rest = (uv[m].0 - uv[n].0).hypot(uv[m].1 - uv[n].1);
                edges.push((i as u32, j as u32, rest));
            }
        }
        edges.sort_unstable_by_key(|e| (e.0, e.1));
        edges.dedup_by(|p, q| (p.0, p.1) == (q.0, q.1));
        Edges { edges, before: vec![DVec3::ZERO; model.len()] }
    }
}

impl Edges {
    /// Shorten every edge of `x` (m) longer than `1 + max_strain` times its rest length, the
    /// ends moving by `W g λ` with `W = Sᵢ / mᵢ` (`filter` `S`, `mass` in kg) and `g` the
    /// edge's direction (the minimum-norm correction in the metric of the masses, restricted to
    /// the free directions), in at most [`SWEEPS`] Gauss–Seidel sweeps; returns whether any
    /// edge was too long.
    pub(super) fn shorten(
        &self,
        x: &mut [DVec3],
        filter: &[DMat3],
        mass: &[f64],
        max_strain: f64,
    ) -> bool {
        let mut any = false;
        for _ in 0..SWEEPS {
            let mut moved = false;
            for &(a, b, rest) in &self.edges {
                let (a, b) = (a as usize, b as usize);
                let d = x[b] - x[a];
                let (length, longest) = (d.length(), (1.0 + max_strain) * rest);
                if length <= longest {
                    continue;
                }
                let g = d / length;
                let (wa, wb) = (filter[a] * g / mass[a], filter[b] * g / mass[b]);
                let w = g.dot(wa + wb);
                if w > 1e-12 * (1.0 / mass[a] + 1.0 / mass[b]) {
                    let lambda = (length - longest) / w;
                    x[a] += wa * lambda;
                    x[b] -= wb * lambda;
                    moved = true;
                }
            }
            any |= moved;
            if !moved {
                break;
            }
        }
        any
    }
}

impl Solver {
    /// Limit the stretch of every edge of the step's new positions to `max_strain` (see the
    /// module documentation); `h` is the step (s).
    pub(super) fn limit_strain(&mut self, model: &Model, h: f64, max_strain: f64) {
        if !max_strain.is_finite() {
            return;
        }
        let s = &mut self.scratch;
        let limit = self.limiter.get_or_insert_with(|| Box::new(Edges::new(model)));
        limit.before.copy_from_slice(&s.x_new);
        limit.shorten(&mut s.x_new, &s.filter, &model.mass, max_strain);
        for i in 0..s.x_new.len() {
            s.v_new[i] += (s.x_new[i] - limit.before[i]) / h;
        }
    }
}
