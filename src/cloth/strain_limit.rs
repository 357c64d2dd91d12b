//! Strain limiting after the implicit solve (Provot 1995, "Deformation constraints in a
//! mass-spring model to describe rigid cloth behavior", §5; the velocity update as in
//! Goldenthal et al. 2007, "Efficient simulation of inextensible cloth", §4): every mesh
//! edge longer than `(1 + max_strain)` times its rest length is shortened to that length by
//! moving its ends in proportion to their inverse masses restricted to the directions their
//! filter leaves free, `Sᵢ / mᵢ` (pinned vertices do not move, vertices on a plane or touching
//! a collider slide along it) — only the end farther from the held vertices when one is
//! nearer (long range attachments, Kim, Chentanez & Müller 2012) — in Gauss–Seidel sweeps
//! over the edges ordered outward from the held (pinned) vertices, until no edge exceeds the
//! limit by more than 10⁻⁴ (after 16 sweeps the moves of edges whose ends both move are
//! over-relaxed, Young 1954's SOR); the velocities take the position change divided by the
//! step. It
//! works on the step's new positions and velocities in the scratch, so a step that fails
//! later is rolled back with it. With self-collision on, [`super::self_collide`] applies it
//! again after its impulses.

use super::{Model, Solver};
use glam::{DMat3, DVec3};

/// Gauss–Seidel sweeps over the edges a call makes at most (see [`Edges::shorten`]); an
/// excess left after them is taken up by the next steps.
const MAX_SWEEPS: usize = 64;

/// Sweeps after which the moves of edges whose ends both move are over-relaxed by
/// [`OVER_RELAXATION`] (see [`Edges::shorten`]); a call that ends within them is unchanged by
/// it (the hanging sheets take 2–16 sweeps a call).
const PLAIN_SWEEPS: usize = 16;

/// The over-relaxation factor `ω` of successive over-relaxation (Young 1954) for the moves of
/// edges whose ends both move, after [`PLAIN_SWEEPS`]: each such edge is shortened `ω` times
/// its excess (ending `(ω − 1)` times it below its limit, which the limit allows). Plain
/// Gauss–Seidel on a cloth with no held vertex passes a correction on like a diffusion, whose
/// sweeps grow with the square of the distance it must travel: the 128² drape's landing step
/// needed 204 sweeps (session 26, on a replica of this limiter that reproduces it to 10⁻¹⁵ m);
/// with `ω = 1.8` after 16 plain sweeps, 35.
const OVER_RELAXATION: f64 = 1.8;

/// The largest excess over its limit, as a fraction of its rest length, of an edge whose move
/// is over-relaxed ([`OVER_RELAXATION`]).
const RELAXED_EXCESS: f64 = 0.1;

/// An edge counts as too long when it exceeds its limit by more than this fraction of its
/// rest length (the sweeps stop when none does): the limit is held to 10⁻⁴ in strain.
const TOLERANCE: f64 = 1e-4;

/// The mesh's edges, its vertex graph and the work vectors of the limiter.
pub(super) struct Edges {
    /// `(a, b, rest length (m))` of every edge, each once.
    edges: Vec<(u32, u32, f64)>,
    /// The vertex graph (compressed rows): the neighbours of vertex `i` are
    /// `neighbours[start[i]..start[i + 1]]`.
    start: Vec<usize>,
    neighbours: Vec<u32>,
    /// Graph distance of every vertex from the nearest held one (`u32::MAX` where none
    /// is reachable), the breadth-first queue, the sweep order of the edges (nearest the
    /// held vertices first) and the counting sort's buckets.
    distance: Vec<u32>,
    queue: Vec<u32>,
    order: Vec<u32>,
    bucket: Vec<usize>,
    /// The positions before limiting.
    before: Vec<DVec3>,
}

impl Edges {
    /// The edges of `model`'s triangles with their rest lengths (from the rest `(u, v)` of the
    /// triangle, recovered from its `∂w/∂x`).
    pub(super) fn new(model: &Model) -> Edges {
        let n = model.len();
        let mut edges: Vec<(u32, u32, f64)> = Vec::new();
        for t in &model.elements {
            // [Δu Δv] of corners 1, 2 from corner 0: the inverse of [[wu1 wu2] [wv1 wv2]].
            let (a, b, c, d) = (t.du[1], t.du[2], t.dv[1], t.dv[2]);
            let det = a * d - b * c;
            let uv = [(0.0, 0.0), (d / det, -b / det), (-c / det, a / det)];
            for (m, k) in [(0, 1), (1, 2), (2, 0)] {
                let (i, j) = (t.verts[m].min(t.verts[k]), t.verts[m].max(t.verts[k]));
                let rest = (uv[m].0 - uv[k].0).hypot(uv[m].1 - uv[k].1);
                edges.push((i as u32, j as u32, rest));
            }
        }
        edges.sort_unstable_by_key(|e| (e.0, e.1));
        edges.dedup_by(|p, q| (p.0, p.1) == (q.0, q.1));
        let mut start = vec![0; n + 1];
        for &(a, b, _) in &edges {
            start[a as usize + 1] += 1;
            start[b as usize + 1] += 1;
        }
        for i in 0..n {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut neighbours = vec![0; 2 * edges.len()];
        for &(a, b, _) in &edges {
            neighbours[fill[a as usize]] = b;
            fill[a as usize] += 1;
            neighbours[fill[b as usize]] = a;
            fill[b as usize] += 1;
        }
        Edges {
            order: (0..edges.len() as u32).collect(),
            edges,
            start,
            neighbours,
            distance: vec![0; n],
            queue: Vec::with_capacity(n),
            bucket: vec![0; n + 2],
            before: vec![DVec3::ZERO; n],
        }
    }

    /// Order the edges by the graph distance of their nearer end from the held vertices, those
    /// whose filter is zero (pinned or moving at a prescribed velocity), in which
    /// [`Edges::shorten`] sweeps. Breadth-first search and a counting sort (stable, so edges
    /// at one distance keep the index order): no allocation.
    fn order_from_constraints(&mut self, filter: &[DMat3]) {
        let n = filter.len();
        self.queue.clear();
        for (i, f) in filter.iter().enumerate() {
            let held = *f == DMat3::ZERO;
            self.distance[i] = if held { 0 } else { u32::MAX };
            if held {
                self.queue.push(i as u32);
            }
        }
        let mut head = 0;
        while head < self.queue.len() {
            let i = self.queue[head] as usize;
            head += 1;
            for &j in &self.neighbours[self.start[i]..self.start[i + 1]] {
                if self.distance[j as usize] == u32::MAX {
                    self.distance[j as usize] = self.distance[i] + 1;
                    self.queue.push(j);
                }
            }
        }
        // Counting sort on min(distance) (unreached edges last), stable in the index order.
        let key =
            |d: &[u32], e: &(u32, u32, f64)| (d[e.0 as usize].min(d[e.1 as usize]) as usize).min(n);
        self.bucket.iter_mut().for_each(|c| *c = 0);
        for e in &self.edges {
            self.bucket[key(&self.distance, e) + 1] += 1;
        }
        for k in 0..=n {
            self.bucket[k + 1] += self.bucket[k];
        }
        for (index, e) in self.edges.iter().enumerate() {
            let k = key(&self.distance, e);
            self.order[self.bucket[k]] = index as u32;
            self.bucket[k] += 1;
        }
    }

    /// Shorten every edge of `x` (m) longer than `1 + max_strain` times its rest length, its
    /// ends moving by `W g λ` with `W = Sᵢ / mᵢ` (`filter` `S`, `mass` in kg) and `g` the
    /// edge's direction (the minimum-norm correction in the metric of the masses, restricted to
    /// the free directions), except that an end nearer the held vertices than the other
    /// ([`Edges::order_from_constraints`]) counts as infinitely heavy: only the far end moves
    /// (both, if the far end's filter keeps it from moving along the edge),
    /// as in long range attachments (Kim, Chentanez & Müller 2012) and the mass scaling of
    /// Macklin et al. 2014 (§5.2), so that the Gauss–Seidel sweeps, in the order of that
    /// distance, carry a correction from a held vertex along a taut chain in one sweep. (With
    /// both ends moving, in the index order, each projection passed half an edge's excess back
    /// towards the held vertex — Gauss–Seidel on a chain's Laplacian, whose sweeps grow with
    /// the square of its length: 1,700–4,000 were measured at 128² in session 19, and 32 left
    /// the 128² sheet at 5.8 %.)
    /// Edges between vertices at one distance, and every edge of a cloth with no held
    /// vertex, move both ends (momentum kept). Only vertices whose filter is zero are held:
    /// held vertices touching a collider (until session 22) could not reach the limit where
    /// the cloth spans two contact regions, as they can only slide (the 128² drape between
    /// the sphere's top and the ground ended its steps at 7.6 %). The sweeps stop when no edge exceeds its limit
    /// by more than [`TOLERANCE`] of its rest length, after at most [`MAX_SWEEPS`]; returns
    /// whether any edge was too long. Without `one_sided` both ends of every edge move (as
    /// self-collision applies it between its passes: the far end moving alone there left the
    /// folding sheet of `tests/cloth_self_collision.rs` at 3.3 % after its last impulses).
    pub(super) fn shorten(
        &mut self,
        x: &mut [DVec3],
        filter: &[DMat3],
        mass: &[f64],
        max_strain: f64,
        one_sided: bool,
    ) -> bool {
        let too_long = |x: &[DVec3], &(a, b, rest): &(u32, u32, f64)| {
            (x[b as usize] - x[a as usize]).length() > (1.0 + max_strain + TOLERANCE) * rest
        };
        if !self.edges.iter().any(|e| too_long(x, e)) {
            return false;
        }
        self.order_from_constraints(filter);
        let distance = &self.distance;
        for sweep in 0..MAX_SWEEPS {
            let relax = sweep >= PLAIN_SWEEPS;
            let mut moved = false;
            for &k in &self.order {
                let (a, b, rest) = self.edges[k as usize];
                let (a, b) = (a as usize, b as usize);
                let d = x[b] - x[a];
                let (length, longest) = (d.length(), (1.0 + max_strain) * rest);
                if length <= longest {
                    continue;
                }
                let g = d / length;
                let (mut wa, mut wb) = (filter[a] * g / mass[a], filter[b] * g / mass[b]);
                let small = 1e-12 * (1.0 / mass[a] + 1.0 / mass[b]);
                // The far end alone, unless its filter keeps it from moving along the edge.
                if one_sided && distance[a] < distance[b] && g.dot(wb) > small {
                    wa = DVec3::ZERO;
                } else if one_sided && distance[b] < distance[a] && g.dot(wa) > small {
                    wb = DVec3::ZERO;
                }
                let w = g.dot(wa + wb);
                if w > small {
                    // Over-relaxed: an edge whose ends both move, after the plain sweeps, while
                    // its excess is small (far from the limit the projection is not linear
                    // and `ω` overshoots: on the 128² drape's step after its landing, with
                    // edges at 70 % over, it took them to 226 %).
                    let both = wa != DVec3::ZERO && wb != DVec3::ZERO;
                    let small_excess = length - longest < RELAXED_EXCESS * rest;
                    let omega = if relax && both && small_excess { OVER_RELAXATION } else { 1.0 };
                    let lambda = (length - longest) / w * omega;
                    x[a] += wa * lambda;
                    x[b] -= wb * lambda;
                    moved |= length > longest + TOLERANCE * rest;
                }
            }
            if !moved {
                break;
            }
        }
        true
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
        limit.shorten(&mut s.x_new, &s.filter, &model.mass, max_strain, true);
        for i in 0..s.x_new.len() {
            s.v_new[i] += (s.x_new[i] - limit.before[i]) / h;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cloth::{Elasticity, Material, Mesh, Triangulation};

    /// The edges of a strip of `nx` x `ny` vertices `length` m long (default material) and its
    /// positions stretched along its length by 10 %.
    fn stretched_strip(nx: usize, ny: usize, length: f64) -> (Model, Edges, Vec<DVec3>) {
        let mesh = Mesh::grid(nx, ny, 0.01, length, Triangulation::Alternating).unwrap();
        let model =
            Model::new(mesh, Elasticity::BaraffWitkin, Material::default(), DVec3::ZERO).unwrap();
        let edges = Edges::new(&model);
        let mut x = model.state().positions().to_vec();
        x.iter_mut().for_each(|p| p.z *= 1.1);
        (model, edges, x)
    }

    /// The largest strain of `edges` at positions `x`.
    fn largest_strain(edges: &Edges, x: &[DVec3]) -> f64 {
        edges
            .edges
            .iter()
            .map(|&(a, b, rest)| (x[b as usize] - x[a as usize]).length() / rest - 1.0)
            .fold(0.0, f64::max)
    }

    /// A strip of 2 x 200 vertices (a chain of 199 quads), stretched along its length by 10 %
    /// and held at its last two vertices (the end the edge index order reaches last): the
    /// limiter must bring every edge to within the tolerance of 3 % in one call. The limiter
    /// before session 21 (index order, both ends of every edge moving, 32 sweeps) left its
    /// largest strain at 13.4 % (seen failing: 0.1344).
    #[test]
    fn a_long_strip_held_at_its_far_end_is_limited_in_one_call() {
        let (nx, ny) = (2, 200);
        let (model, mut edges, mut x) = stretched_strip(nx, ny, 1.0);
        let mut filter = vec![DMat3::IDENTITY; model.len()];
        filter[nx * ny - 1] = DMat3::ZERO;
        filter[nx * ny - 2] = DMat3::ZERO;
        let held = [x[nx * ny - 1], x[nx * ny - 2]];
        assert!(edges.shorten(&mut x, &filter, &model.mass, 0.03, true));
        let worst = largest_strain(&edges, &x);
        assert!(worst <= 0.03 + TOLERANCE, "largest strain {worst:.4}");
        assert_eq!([x[nx * ny - 1], x[nx * ny - 2]], held, "held vertices moved");
    }

    /// A strip of 2 x 14 vertices (0.25 m) lying over a cylinder of radius 0.3 m (axis along x,
    /// as the 128² drape lies over the sphere's top), stretched along its length by 10 %,
    /// every vertex touching (filter `I − n̂n̂ᵀ`, `n̂` the cylinder's normal), none held: every
    /// edge moves both ends, and plain Gauss–Seidel passes the correction on like a diffusion.
    /// The limiter must reach 3 % in one call, and every vertex stay in its tangent plane.
    /// Plain sweeps (no over-relaxation) need 145 and leave 3.43 % after the 64 of a call (seen
    /// failing with `OVER_RELAXATION = 1`: 0.0343); with it, 36 (counts from an exact Python
    /// emulation of this limiter).
    #[test]
    fn a_strip_lying_over_a_cylinder_with_no_held_vertex_is_limited_in_one_call() {
        let (nx, ny) = (2, 14);
        let (model, mut edges, mut x) = stretched_strip(nx, ny, 0.25);
        let (radius, axis) = (0.3, DVec3::new(0.0, -0.3, 0.0));
        let mut filter = vec![DMat3::IDENTITY; model.len()];
        let mut normal = vec![DVec3::ZERO; model.len()];
        for (i, p) in x.iter_mut().enumerate() {
            // Arc length along the cylinder = the stretched z.
            let angle = p.z / radius;
            normal[i] = DVec3::new(0.0, angle.cos(), angle.sin());
            *p = DVec3::new(p.x, 0.0, 0.0) + axis + normal[i] * radius;
            filter[i] = DMat3::IDENTITY - crate::math::outer(normal[i], normal[i]);
        }
        let before = x.clone();
        assert!(largest_strain(&edges, &x) > 0.09);
        assert!(edges.shorten(&mut x, &filter, &model.mass, 0.03, true));
        let worst = largest_strain(&edges, &x);
        assert!(worst <= 0.03 + TOLERANCE, "largest strain {worst:.4}");
        for i in 0..x.len() {
            let off = (x[i] - before[i]).dot(normal[i]);
            assert!(off.abs() < 1e-12, "vertex {i} left its tangent plane by {off:e} m");
        }
    }

    /// A strip of 2 x 6 vertices stretched along its length by 10 %, its four end vertices
    /// touching the ground (filter `I - ŷŷᵀ`: they slide in the x–z plane), the others free:
    /// the limit is reachable only if the touching vertices slide. Counted as held (as until
    /// session 22) they kept the strip's length and left its largest strain at 10 %; the 128²
    /// drape, spanning the sphere's top and the ground, ended so at 7.6 %.
    #[test]
    fn vertices_touching_a_collider_slide_to_reach_the_limit() {
        let (nx, ny) = (2, 6);
        let (model, mut edges, mut x) = stretched_strip(nx, ny, 0.25);
        let before = x.clone();
        let mut filter = vec![DMat3::IDENTITY; model.len()];
        let ends = [0, 1, nx * ny - 2, nx * ny - 1];
        for &i in &ends {
            filter[i] = DMat3::IDENTITY - crate::math::outer(DVec3::Y, DVec3::Y);
        }
        assert!(edges.shorten(&mut x, &filter, &model.mass, 0.03, true));
        let worst = largest_strain(&edges, &x);
        assert!(worst <= 0.03 + TOLERANCE, "largest strain {worst:.4}");
        for &i in &ends {
            assert_eq!(x[i].y, before[i].y, "vertex {i} left the ground");
        }
    }
}
