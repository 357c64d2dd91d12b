//! Strain limiting after the implicit solve (Provot 1995, "Deformation constraints in a
//! mass-spring model to describe rigid cloth behavior", §5; the velocity update as in
//! Goldenthal et al. 2007, "Efficient simulation of inextensible cloth", §4): every mesh
//! edge longer than `(1 + max_strain)` times its rest length is shortened to that length by
//! moving its ends in proportion to their inverse masses (constrained and touching vertices do
//! not move), in Gauss–Seidel sweeps over the edges, and the velocities take the position
//! change divided by the step. It works on the step's new positions and velocities in the
//! scratch, so a step that fails later is rolled back with it.

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

impl Solver {
    /// Limit the stretch of every edge of the step's new positions to `max_strain` (see the
    /// module documentation); `h` is the step (s).
    pub(super) fn limit_strain(&mut self, model: &Model, h: f64, max_strain: f64) {
        if !max_strain.is_finite() {
            return;
        }
        let s = &mut self.scratch;
        let limit = self.limiter.get_or_insert_with(|| Box::new(Edges::new(model)));
        let (filter, x_new, v_new) = (&s.filter, &mut s.x_new, &mut s.v_new);
        limit.before.copy_from_slice(x_new);
        let weight = |i: usize| {
            if filter[i] == DMat3::IDENTITY {
                1.0 / model.mass[i]
            } else {
                0.0
            }
        };
        for _ in 0..SWEEPS {
            let mut moved = false;
            for &(a, b, rest) in &limit.edges {
                let (a, b) = (a as usize, b as usize);
                let d = x_new[b] - x_new[a];
                let (length, longest) = (d.length(), (1.0 + max_strain) * rest);
                let (wa, wb) = (weight(a), weight(b));
                if length > longest && wa + wb > 0.0 {
                    let correction = d * ((length - longest) / (length * (wa + wb)));
                    x_new[a] += wa * correction;
                    x_new[b] -= wb * correction;
                    moved = true;
                }
            }
            if !moved {
                break;
            }
        }
        for i in 0..x_new.len() {
            v_new[i] += (x_new[i] - limit.before[i]) / h;
        }
    }
}
