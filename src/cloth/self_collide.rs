//! Self-collision of the cloth, after Bridson, Fedkiw & Anderson (2002), "Robust treatment of
//! collisions, contact and friction for cloth animation": a filter on the motion of a step
//! that the implicit solve proposes (each vertex from `x₀` to `x₁ = x₀ + d`), in three stages.
//!
//! 1. **Proximity** (§7.2): every vertex–triangle and edge–edge pair closer than the thickness
//!    `h` at `x₀` gets an inelastic impulse that stops its approach and a repulsion
//!    `min(Δt k (h − dist), m (0.1 (h − dist)/Δt − v_N))` (`k` the stretch stiffness), with
//!    Coulomb friction on the tangential motion (§7.2.1: the tangential relative velocity is
//!    reduced by `μ` times the normal change, at most to rest).
//! 2. **Continuous collision detection** (§6.4, §7.3): on the linear motion of the step, a
//!    pair whose four points become coplanar within `δ = h/4` of each other, or which ends the
//!    step closer than `δ` after starting farther apart, is a collision; an impulse along the
//!    normal at impact moves it to end the step `h/2` apart on the side it came from. Passes
//!    repeat until one finds no collision or `iterations` passes were made.
//! 3. **Rigid impact zones** (Provot 1997; Bridson §7.4): the vertices of the collisions that
//!    remain are merged into zones, each moved as a rigid body with the linear and angular
//!    momentum of its vertices (an exact rotation, so that distances within the zone are kept
//!    and, the motion being affine at every instant, no pair inside it can cross); zones grow
//!    until no collision between zones remains.
//!
//! Impulses act on the pair's four vertices with the weights `α` of the contact points
//! (`Σ αₖ = 0`, so linear momentum is conserved) in proportion to inverse masses; vertices
//! with a user constraint (pinned, plane, line, prescribed velocity) have infinite mass. The
//! changed displacement becomes the step's end position and its change, divided by `Δt`, is
//! added to the velocity. The broad phase is [`super::bvh::Bvh`], refit at every pass.
//!
//! **Mesh colliders** ([`super::MeshCollider`], a character's body) take part in the same
//! filter, as Bridson et al. treat kinematic objects: their vertices join the cloth's, moving
//! linearly by `velocity · h` over the step with infinite mass (no impulse moves them), and
//! the cloth's vertices and edges meet the meshes' triangles and edges, and the meshes'
//! vertices the cloth's triangles, in all three stages, with the mesh's friction. In an
//! impact zone a mesh's vertex counts [`MESH_MASS`] times the cloth's mass, so that the zone
//! moves with the mesh (exactly where the mesh moves rigidly; where it deforms, by the rigid
//! motion that fits its vertices in the zone best). The filter runs when self-collision is on
//! or the state has a mesh collider; with the meshes alone it makes the cloth–mesh pairs only,
//! with [`super::SelfCollision::default`]'s passes.
//!
//! **A cloth that starts a step inside a mesh** (a mesh teleported, or moved faster than its
//! velocities say) is pushed out before the three stages, which assume it does not: every free
//! cloth vertex inside a closed mesh (one whose every edge is shared by an even number of its
//! triangles; inside by the parity of the crossings of a ray along `+x`, decided exactly,
//! [`ray_x_crosses_triangle`]) starts the step at the mesh's nearest surface point plus the
//! thickness, with its motion relative to the mesh's there stripped of any approach
//! ([`Work::push_out`]). Open meshes have no inside and push nothing; cloth edges that cross
//! a mesh with both ends outside are not found (only vertices are tested).

use super::bvh::Bvh;
use super::strain_limit;
use super::{Model, Solver, State, StepStats};
use crate::geometry::ccd::{edge_edge, segment_weights, vertex_triangle, Impact};
use crate::geometry::segment::closest_points_of_segments;
use crate::geometry::triangle::{closest_point_on_triangle, ray_x_crosses_triangle};
use glam::{DMat3, DQuat, DVec3};

/// The closest distance the filter keeps a pair at (CCD tolerance), as a fraction of the
/// thickness.
pub const MIN_DISTANCE: f64 = 0.25;
/// The separation, as a fraction of the thickness, a collision impulse moves a pair to.
const TARGET_DISTANCE: f64 = 0.5;

/// A candidate pair: vertex–triangle `[p, a, b, c]` or edge–edge `[p, q, r, s]`, and the
/// Coulomb friction between its sides.
#[derive(Clone, Copy, Debug)]
struct Pair {
    verts: [usize; 4],
    edges: bool,
    friction: f64,
}

/// The mass of a mesh collider's vertex in the rigid impact zones, relative to the cloth's
/// total mass: large enough that a zone holding one moves with the mesh (to rounding), finite
/// so that the zone's sums stay exact to a relative 10⁻⁷.
const MESH_MASS: f64 = 1e9;

/// The workspace of self-collision (in the solver; built on the first step that needs it).
///
/// Vertices are numbered the cloth's `N` first, then those of the mesh colliders in their
/// order (`N + V` in all); every per-vertex vector has that length.
#[derive(Debug)]
pub(super) struct Work {
    bvh: Bvh,
    /// Per triangle, bits 0–2: the triangle is the first holding its vertex k; bits 3–5: the
    /// first holding its edge k (`t[k]`, `t[k+1]`), so every feature pair is found once.
    owns: Vec<u8>,
    /// The mesh colliders' triangles (numbered as above), their owned features (as `owns`),
    /// their friction, their tree (rebuilt every step), and the triangles being gathered.
    mesh_tris: Vec<[usize; 3]>,
    mesh_owns: Vec<u8>,
    mesh_friction: Vec<f64>,
    mesh_bvh: Bvh,
    gathered: Vec<[usize; 3]>,
    /// Per mesh triangle: whether an edge of it is shared by an odd number of the meshes'
    /// triangles (its mesh is then not closed); the first triangle of every mesh, and their
    /// count last; whether each mesh is closed; the parity of a ray's crossings of each.
    mesh_open: Vec<bool>,
    mesh_start: Vec<usize>,
    mesh_closed: Vec<bool>,
    parity: Vec<bool>,
    /// Positions at the start of the step (m).
    x0: Vec<DVec3>,
    /// Displacements of the step (m), and as proposed by the solve (a mesh's: `velocity · h`).
    d: Vec<DVec3>,
    d_solve: Vec<DVec3>,
    /// End positions `x₀ + d` (m), for refitting.
    x1: Vec<DVec3>,
    /// Inverse masses (1/kg), 0 for constrained vertices and the meshes' vertices.
    w: Vec<f64>,
    /// Masses (kg) in the impact zones, [`MESH_MASS`] times the cloth's for a mesh's vertex.
    m: Vec<f64>,
    pairs: Vec<Pair>,
    /// Impact zones: union-find parents, the vertices in zones, per-root sums.
    parent: Vec<usize>,
    zoned: Vec<usize>,
    in_zone: Vec<bool>,
    sums: Vec<ZoneSums>,
}

/// Mass, first moment and momentum (displacement-weighted) of a zone, then its inertia and
/// angular momentum about the centre of mass.
#[derive(Clone, Copy, Debug, Default)]
struct ZoneSums {
    m: f64,
    mx: DVec3,
    md: DVec3,
    inertia: DMat3,
    angular: DVec3,
}

impl ZoneSums {
    /// The zone's displacement of a vertex at `x` (m): the translation of the centre of mass
    /// and the exact rotation by `ω = I⁻¹ L` (regularised so that a zone on a line gets no
    /// turn about it).
    fn displacement(&self, x: DVec3) -> DVec3 {
        let (c, vc) = (self.mx / self.m, self.md / self.m);
        let i = self.inertia;
        let trace = i.x_axis.x + i.y_axis.y + i.z_axis.z;
        let regular = i + DMat3::from_diagonal(DVec3::splat(1e-9 * trace + f64::MIN_POSITIVE));
        let omega = regular.inverse() * self.angular;
        let arm = x - c;
        vc + DQuat::from_scaled_axis(omega) * arm - arm
    }
}

impl Work {
    /// The workspace of `model`.
    pub(super) fn new(model: &Model) -> Work {
        let n = model.len();
        let tris = &model.triangles;
        let mut owns = Vec::new();
        ownership(tris, &mut owns);
        let zero = vec![DVec3::ZERO; n];
        Work {
            bvh: Bvh::new(&model.initial, tris),
            owns,
            mesh_tris: Vec::new(),
            mesh_owns: Vec::new(),
            mesh_friction: Vec::new(),
            mesh_bvh: Bvh::default(),
            gathered: Vec::new(),
            mesh_open: Vec::new(),
            mesh_start: Vec::new(),
            mesh_closed: Vec::new(),
            parity: Vec::new(),
            x0: zero.clone(),
            d: zero.clone(),
            d_solve: zero.clone(),
            x1: zero,
            w: vec![0.0; n],
            m: model.mass.clone(),
            // Room for the candidates of a crumpled cloth, so that steps rarely allocate.
            pairs: Vec::with_capacity(32 * tris.len()),
            parent: (0..n).collect(),
            zoned: Vec::new(),
            in_zone: vec![false; n],
            sums: vec![ZoneSums::default(); n],
        }
    }

    /// Shorten the cloth's edges of the motion's end positions `x₀ + d` over `1 + max_strain`
    /// times their rest length ([`strain_limit::Edges::shorten`] with the step's filter and
    /// masses).
    fn limit_strain(
        &mut self,
        edges: &mut strain_limit::Edges,
        (filter, mass): (&[DMat3], &[f64]),
        max_strain: f64,
    ) {
        let n = mass.len();
        for ((x1, &x), &d) in self.x1.iter_mut().zip(&self.x0).zip(&self.d).take(n) {
            *x1 = x + d;
        }
        if edges.shorten(&mut self.x1[..n], filter, mass, max_strain, false) {
            for ((d, &x1), &x) in self.d.iter_mut().zip(&self.x1).zip(&self.x0).take(n) {
                *d = x1 - x;
            }
        }
    }

    /// Take the mesh colliders of `state` for a step of `h` (s): their vertices after the
    /// cloth's in every per-vertex vector (start positions, displacements `velocity · h`, no
    /// inverse mass, [`MESH_MASS`] times the cloth's mass in the zones), their triangles
    /// numbered so, and their tree built on the start positions. Allocates only when the
    /// meshes grow.
    fn take_meshes(&mut self, model: &Model, state: &State, h: f64) {
        let n = model.len();
        let heavy = MESH_MASS * model.mass.iter().sum::<f64>();
        self.gathered.clear();
        self.mesh_friction.clear();
        self.mesh_start.clear();
        self.x0.truncate(n);
        self.d.truncate(n);
        self.m.truncate(n);
        for mesh in &state.meshes {
            let offset = self.x0.len();
            self.mesh_start.push(self.gathered.len());
            self.gathered.extend(mesh.triangles.iter().map(|t| t.map(|v| v + offset)));
            self.mesh_friction.extend(mesh.triangles.iter().map(|_| mesh.friction));
            self.x0.extend_from_slice(&mesh.vertices);
            self.d.extend(mesh.velocities.iter().map(|&v| v * h));
            self.m.extend(mesh.vertices.iter().map(|_| heavy));
        }
        self.mesh_start.push(self.gathered.len());
        let total = self.x0.len();
        self.d_solve.resize(total, DVec3::ZERO);
        self.x1.resize(total, DVec3::ZERO);
        self.w.resize(total, 0.0);
        self.w[n..].iter_mut().for_each(|w| *w = 0.0);
        self.parent.truncate(n);
        self.parent.extend(n..total);
        self.in_zone.resize(total, false);
        self.sums.resize(total, ZoneSums::default());
        if self.gathered != self.mesh_tris {
            std::mem::swap(&mut self.gathered, &mut self.mesh_tris);
            ownership(&self.mesh_tris, &mut self.mesh_owns);
            open_edges(&self.mesh_tris, &mut self.mesh_open);
        }
        let (start, open) = (&self.mesh_start, &self.mesh_open);
        self.mesh_closed.clear();
        self.mesh_closed.extend(start.windows(2).map(|r| !open[r[0]..r[1]].contains(&true)));
        self.parity.resize(self.mesh_closed.len(), false);
        if !self.mesh_tris.is_empty() {
            self.mesh_bvh.build(&self.x0, &self.mesh_tris);
        }
    }
}

impl Work {
    /// Push the cloth's free vertices that start the step inside a closed mesh collider (by
    /// the parity of a ray's crossings, [`ray_x_crosses_triangle`]) out to the mesh's nearest
    /// surface point plus `thickness` along the direction to it, as if they had started the
    /// step there (their start `x₀` is moved; the continuous collision detection then sees no
    /// crossing), with their displacement and velocity (`v`, m/s) relative to the mesh's motion
    /// at that point stripped of any approach along that direction. Returns how many were
    /// pushed. Vertices with a user constraint stay; open meshes push nothing (no inside).
    fn push_out(&mut self, model: &Model, h: f64, v: &mut [DVec3]) -> usize {
        if !self.mesh_closed.contains(&true) {
            return 0;
        }
        let Work { mesh_bvh, mesh_tris, mesh_start, mesh_closed, parity, x0, d, w, .. } = self;
        mesh_bvh.refit(mesh_tris, x0, x0, 0.0);
        let mut pushed = 0;
        for i in 0..model.len() {
            if w[i] == 0.0 {
                continue;
            }
            let p = x0[i];
            parity.iter_mut().for_each(|b| *b = false);
            mesh_bvh.ray_x(p, |j| {
                if ray_x_crosses_triangle(p, mesh_tris[j].map(|v| x0[v])) {
                    parity[mesh_start.partition_point(|&s| s <= j) - 1] ^= true;
                }
            });
            let Some(k) = (0..parity.len()).find(|&k| parity[k] && mesh_closed[k]) else {
                continue;
            };
            let mut nearest = (f64::INFINITY, DVec3::ZERO, [0.0; 3], [0; 3]);
            for t in &mesh_tris[mesh_start[k]..mesh_start[k + 1]] {
                let [a, b, c] = t.map(|v| x0[v]);
                let (q, weights) = closest_point_on_triangle(p, a, b, c);
                if (q - p).length_squared() < nearest.0 {
                    nearest = ((q - p).length_squared(), q, weights, *t);
                }
            }
            let (_, q, weights, t) = nearest;
            let [a, b, c] = t.map(|v| x0[v]);
            let normal = (q - p)
                .try_normalize()
                .or_else(|| (b - a).cross(c - a).try_normalize())
                .unwrap_or(DVec3::Y);
            let moved = (0..3).fold(DVec3::ZERO, |s, m| s + d[t[m]] * weights[m]);
            x0[i] = q + normal * model.thickness;
            let relative = d[i] - moved;
            d[i] = moved + relative - normal * relative.dot(normal).min(0.0);
            let relative = v[i] - moved / h;
            v[i] -= normal * relative.dot(normal).min(0.0);
            pushed += 1;
        }
        pushed
    }
}

/// Per triangle of `tris`, into `open`: whether one of its edges is shared by an odd number of
/// triangles (a closed surface, over which a ray's crossings have a parity, has none).
fn open_edges(tris: &[[usize; 3]], open: &mut Vec<bool>) {
    let mut count = std::collections::HashMap::new();
    let edge = |t: &[usize; 3], c: usize| (t[c].min(t[(c + 1) % 3]), t[c].max(t[(c + 1) % 3]));
    for t in tris {
        for c in 0..3 {
            *count.entry(edge(t, c)).or_insert(0usize) += 1;
        }
    }
    open.clear();
    open.extend(tris.iter().map(|t| (0..3).any(|c| count[&edge(t, c)] % 2 == 1)));
}

/// Per triangle of `tris`, into `owns`, bits 0–2: the triangle is the first holding its vertex
/// k; bits 3–5: the first holding its edge k (`t[k]`, `t[k+1]`), so that every feature pair
/// is found once.
fn ownership(tris: &[[usize; 3]], owns: &mut Vec<u8>) {
    let mut first_vertex = std::collections::HashMap::new();
    let mut first_edge = std::collections::HashMap::new();
    owns.clear();
    owns.resize(tris.len(), 0);
    for (k, t) in tris.iter().enumerate() {
        for c in 0..3 {
            if *first_vertex.entry(t[c]).or_insert(k) == k {
                owns[k] |= 1 << c;
            }
            let (a, b) = (t[c], t[(c + 1) % 3]);
            if *first_edge.entry((a.min(b), a.max(b))).or_insert(k) == k {
                owns[k] |= 8 << c;
            }
        }
    }
}

impl Solver {
    /// Filter the step's proposed motion (`state.x` to the scratch's `x_new`, velocities
    /// `v_new`) of a step of `h` seconds for self-collision, if the model has it on, and for
    /// the state's mesh colliders; counts into `stats`.
    pub(super) fn self_collide(
        &mut self,
        model: &Model,
        state: &State,
        h: f64,
        max_strain: f64,
        stats: &mut StepStats,
    ) {
        if model.self_collision.is_none() && state.meshes.is_empty() {
            return;
        }
        let t0 = std::time::Instant::now();
        let work = self.self_work.get_or_insert_with(|| Box::new(Work::new(model)));
        work.take_meshes(model, state, h);
        let s = &mut self.scratch;
        for i in 0..state.len() {
            work.x0[i] = state.x[i];
            work.d[i] = s.x_new[i] - state.x[i];
            work.w[i] = if state.constraints[i].is_some() { 0.0 } else { 1.0 / model.mass[i] };
        }
        work.push_out(model, h, &mut s.v_new);
        work.d_solve.copy_from_slice(&work.d);
        let settings = model.self_collision.unwrap_or_default();
        let self_friction = model.self_collision.map(|s| s.friction);
        let filter = Filter { model, h, self_friction };
        stats.proximities += filter.proximity(work);
        // The impulses stretch edges; each CCD pass checks the motion the strain limit leaves,
        // so a pass that finds nothing ends with both the limit and no collision.
        let mut limit = max_strain.is_finite().then(|| {
            &mut **self.limiter.get_or_insert_with(|| Box::new(strain_limit::Edges::new(model)))
        });
        for _ in 0..settings.iterations {
            if let Some(edges) = limit.as_deref_mut() {
                work.limit_strain(edges, (&s.filter, &model.mass), max_strain);
            }
            if filter.ccd_pass(work) == 0 {
                break;
            }
            stats.ccd_iterations += 1;
        }
        stats.impact_zones += filter.impact_zones(work);
        for i in 0..state.len() {
            s.x_new[i] = work.x0[i] + work.d[i];
            s.v_new[i] += (work.d[i] - work.d_solve[i]) / h;
        }
        stats.self_collision_seconds += t0.elapsed().as_secs_f64();
    }
}

/// What the stages of one filter share: the model, the step (s), and the friction between
/// the cloth's layers when self-collision is on (`None`: only the mesh colliders).
struct Filter<'a> {
    model: &'a Model,
    h: f64,
    self_friction: Option<f64>,
}

impl Filter<'_> {
    /// Refit the tree to the motion (`swept`) or to the start positions, grown by `margin / 2`,
    /// and list the candidate pairs.
    fn candidates(&self, work: &mut Work, swept: bool, margin: f64) {
        let tris = &self.model.triangles;
        if swept {
            for i in 0..work.x0.len() {
                work.x1[i] = work.x0[i] + work.d[i];
            }
        }
        let Work {
            bvh, owns, pairs, x0, x1, mesh_tris, mesh_owns, mesh_friction, mesh_bvh, ..
        } = work;
        let (x0, x1) = (&x0[..], if swept { &x1[..] } else { &x0[..] });
        bvh.refit(tris, x0, x1, 0.5 * margin);
        pairs.clear();
        // The pair's own boxes (of its features' motion) must overlap too.
        let close = |a: &[usize], b: &[usize]| {
            let bounds = |v: &[usize]| {
                v.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &k| {
                    (lo.min(x0[k]).min(x1[k]), hi.max(x0[k]).max(x1[k]))
                })
            };
            let ((alo, ahi), (blo, bhi)) = (bounds(a), bounds(b));
            (alo - margin).cmple(bhi).all() && (blo - margin).cmple(ahi).all()
        };
        // The features of triangle `ta` selected by `oa` against triangle `tb`: the vertices
        // of bits 0–2 against `tb`, the edges of bits 3–5 against `tb`'s edges of `ob`'s bits
        // 3–5 (with the ownership bits, each feature pair once; pairs sharing a vertex are no
        // pairs).
        let mut features = |ta: [usize; 3], oa: u8, tb: [usize; 3], ob: u8, friction: f64| {
            for (c, &p) in ta.iter().enumerate() {
                if oa & (1 << c) != 0 && !tb.contains(&p) && close(&[p], &tb) {
                    pairs.push(Pair { verts: [p, tb[0], tb[1], tb[2]], edges: false, friction });
                }
            }
            for c in 0..3 {
                if oa & (8 << c) == 0 {
                    continue;
                }
                let (p, q) = (ta[c], ta[(c + 1) % 3]);
                for e in 0..3 {
                    let (r, s) = (tb[e], tb[(e + 1) % 3]);
                    let apart = ![r, s].iter().any(|v| *v == p || *v == q);
                    if ob & (8 << e) != 0 && apart && close(&[p, q], &[r, s]) {
                        pairs.push(Pair { verts: [p, q, r, s], edges: true, friction });
                    }
                }
            }
        };
        if let Some(friction) = self.self_friction {
            bvh.self_pairs(|i, j| {
                features(tris[i], owns[i] & 7, tris[j], 0, friction);
                features(tris[j], owns[j] & 7, tris[i], 0, friction);
                features(tris[i], owns[i] & !7, tris[j], owns[j], friction);
            });
        }
        if !mesh_tris.is_empty() {
            mesh_bvh.refit(mesh_tris, x0, x1, 0.5 * margin);
            bvh.pairs_with(mesh_bvh, |i, j| {
                let mu = mesh_friction[j];
                features(tris[i], owns[i] & 7, mesh_tris[j], 0, mu);
                features(mesh_tris[j], mesh_owns[j] & 7, tris[i], 0, mu);
                features(tris[i], owns[i] & !7, mesh_tris[j], mesh_owns[j], mu);
            });
        }
    }

    /// Stage 1: repulsion and friction impulses on the pairs closer than the thickness at the
    /// start of the step; returns their number.
    fn proximity(&self, work: &mut Work) -> usize {
        let thickness = self.model.thickness;
        self.candidates(work, false, thickness);
        let mut count = 0;
        for k in 0..work.pairs.len() {
            let pair = work.pairs[k];
            let x = pair.verts.map(|v| work.x0[v]);
            let (distance, weights, normal) = closest(pair, x);
            if distance < thickness {
                count += 1;
                self.repulse(work, pair, weights, normal, thickness - distance);
            }
        }
        count
    }

    /// The proximity impulse of one pair (see the module documentation) on the displacements.
    fn repulse(&self, work: &mut Work, pair: Pair, alpha: [f64; 4], n: DVec3, overlap: f64) {
        let verts = pair.verts;
        let w: f64 = (0..4).map(|k| alpha[k] * alpha[k] * work.w[verts[k]]).sum();
        if w <= 0.0 || w.is_nan() {
            return;
        }
        let rel = (0..4).fold(DVec3::ZERO, |s, k| s + work.d[verts[k]] * alpha[k]);
        let dn = n.dot(rel);
        // Inelastic: stop the approach; then the spring repulsion up to 0.1 overlap per step.
        let mut change = (-dn).max(0.0);
        let wanted = 0.1 * overlap - (dn + change);
        if wanted > 0.0 {
            let spring = self.h * self.h * self.model.material.stretch * overlap * w;
            change += spring.min(wanted);
        }
        if change <= 0.0 {
            return;
        }
        let tangent = rel - n * dn;
        let slide = tangent.length();
        let friction = (pair.friction * change).min(slide);
        let mut impulse = n * (change / w);
        if slide > 0.0 {
            impulse -= tangent * (friction / (slide * w));
        }
        for k in 0..4 {
            work.d[verts[k]] += impulse * (alpha[k] * work.w[verts[k]]);
        }
    }

    /// Stage 2: one pass of continuous collision detection, each collision answered by its
    /// impulse at once; returns the number of collisions.
    fn ccd_pass(&self, work: &mut Work) -> usize {
        let delta = MIN_DISTANCE * self.model.thickness;
        self.candidates(work, true, delta);
        let mut count = 0;
        for k in 0..work.pairs.len() {
            let pair = work.pairs[k];
            if let Some(impact) = self.collision(work, pair) {
                if self.push_apart(work, pair.verts, impact) {
                    count += 1;
                }
            }
        }
        count
    }

    /// The collision of a pair in the current motion, if any (see the module documentation).
    fn collision(&self, work: &Work, pair: Pair) -> Option<Impact> {
        let delta = MIN_DISTANCE * self.model.thickness;
        let x0 = pair.verts.map(|v| work.x0[v]);
        let x1 = pair.verts.map(|v| work.x0[v] + work.d[v]);
        let crossing =
            if pair.edges { edge_edge(x0, x1, delta) } else { vertex_triangle(x0, x1, delta) };
        if crossing.is_some() {
            return crossing;
        }
        let (end, weights, normal) = closest(pair, x1);
        if end >= delta || end >= closest(pair, x0).0 - 1e-6 * delta {
            return None;
        }
        Some(Impact { time: 1.0, weights, distance: end, normal })
    }

    /// The impulse that moves a colliding pair to end the step `TARGET_DISTANCE · thickness`
    /// apart along the impact's normal; `false` when it already does or cannot move.
    fn push_apart(&self, work: &mut Work, verts: [usize; 4], impact: Impact) -> bool {
        let alpha = impact.weights;
        let w: f64 = (0..4).map(|k| alpha[k] * alpha[k] * work.w[verts[k]]).sum();
        let end =
            (0..4).fold(DVec3::ZERO, |s, k| s + (work.x0[verts[k]] + work.d[verts[k]]) * alpha[k]);
        let change = TARGET_DISTANCE * self.model.thickness - impact.normal.dot(end);
        if !(w > 0.0 && change > 0.0) {
            return false;
        }
        let impulse = impact.normal * (change / w);
        for k in 0..4 {
            work.d[verts[k]] += impulse * (alpha[k] * work.w[verts[k]]);
        }
        true
    }

    /// Stage 3: rigid impact zones until no collision between zones remains (at most one
    /// merge per vertex); returns the number of zones of two or more vertices.
    fn impact_zones(&self, work: &mut Work) -> usize {
        let n = work.x0.len();
        work.zoned.clear();
        let mut merged = false;
        for _ in 0..n {
            let delta = MIN_DISTANCE * self.model.thickness;
            self.candidates(work, true, delta);
            let mut found = false;
            for k in 0..work.pairs.len() {
                let pair = work.pairs[k];
                let root = find(&mut work.parent, pair.verts[0]);
                if pair.verts[1..].iter().all(|&v| find(&mut work.parent, v) == root) {
                    continue;
                }
                if self.collision(work, pair).is_some() {
                    found = true;
                    for &v in &pair.verts {
                        if !work.in_zone[v] {
                            work.in_zone[v] = true;
                            work.zoned.push(v);
                        }
                        let r = find(&mut work.parent, v);
                        let root = find(&mut work.parent, pair.verts[0]);
                        work.parent[r] = root;
                    }
                }
            }
            if !found {
                break;
            }
            merged = true;
            self.rigidify(work);
        }
        let zones =
            if merged { work.zoned.iter().filter(|&&v| work.parent[v] == v).count() } else { 0 };
        for &v in &work.zoned {
            work.parent[v] = v;
            work.in_zone[v] = false;
        }
        zones
    }

    /// Move the free vertices of every zone rigidly with the zone's momentum (Bridson §7.4;
    /// [`ZoneSums::displacement`]).
    fn rigidify(&self, work: &mut Work) {
        let Work { parent, zoned, sums, d, w, x0, m, .. } = work;
        for &v in zoned.iter() {
            let r = find(parent, v);
            let s = &mut sums[r];
            s.m += m[v];
            s.mx += x0[v] * m[v];
            s.md += d[v] * m[v];
        }
        for &v in zoned.iter() {
            let r = find(parent, v);
            let s = &mut sums[r];
            let (c, vc) = (s.mx / s.m, s.md / s.m);
            let arm = x0[v] - c;
            s.angular += arm.cross(d[v] - vc) * m[v];
            s.inertia += (DMat3::from_diagonal(DVec3::splat(arm.length_squared()))
                - crate::math::outer(arm, arm))
                * m[v];
        }
        for &v in zoned.iter() {
            if w[v] > 0.0 {
                d[v] = sums[find(parent, v)].displacement(x0[v]);
            }
        }
        for &v in zoned.iter() {
            sums[v] = ZoneSums::default();
        }
    }
}

/// The root of `v`'s zone (with path halving).
fn find(parent: &mut [usize], mut v: usize) -> usize {
    while parent[v] != v {
        parent[v] = parent[parent[v]];
        v = parent[v];
    }
    v
}

/// Distance (m), weights `α` and unit direction of the closest points of a pair at positions
/// `x` (the triangle's normal, or the edges' cross product, where the points coincide).
fn closest(pair: Pair, x: [DVec3; 4]) -> (f64, [f64; 4], DVec3) {
    let [p, a, b, c] = x;
    let (sep, weights, fallback) = if pair.edges {
        let (c1, c2) = closest_points_of_segments(p, a, b, c);
        (c1 - c2, segment_weights(p, a, c1, b, c, c2), (a - p).cross(c - b))
    } else {
        let (q, w) = closest_point_on_triangle(p, a, b, c);
        (p - q, [1.0, -w[0], -w[1], -w[2]], (b - a).cross(c - a))
    };
    let distance = sep.length();
    let normal = sep.try_normalize().or(fallback.try_normalize()).unwrap_or(DVec3::Y);
    (distance, weights, normal)
}
