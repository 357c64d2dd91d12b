//! Smoothed aggregation algebraic multigrid on 3x3 blocks (Tamstorf, Jones & McCormick 2015,
//! "Smoothed aggregation multigrid for cloth simulation", §3–§4; after Vaněk, Mandel & Brezina
//! 1996, "Algebraic multigrid by smoothed aggregation for second and fourth order elliptic
//! problems"), the preconditioner of the prefiltered PCG ([`super::linear`]).
//!
//! The hierarchy is built for the filtered matrix `Â = S A S + I - S` (Tamstorf et al. §4.2:
//! the constraint filter inside the hierarchy, so that the preconditioner is symmetric positive
//! definite and the PCG can apply it as `S M⁻¹ S` on `range(S)`):
//! - **aggregates** (Vaněk et al. §4.1, the three passes: whole neighbourhoods, then joining a
//!   neighbouring aggregate, then the rest), on the graph of the mesh's triangles on the
//!   finest level (a coupling through a bending hinge alone is weak) and of the operator's
//!   pattern on the coarser ones: from the model alone, never from values (a strength measured
//!   on the values would make the aggregates depend on the state of the first solve, and a
//!   solver carries nothing a later step reads);
//! - the **tentative prolongator** from the near-null space of the rigid motions of each
//!   aggregate (three translations, three rotations about its centroid, Tamstorf et al. §3.2),
//!   **smoothed** by one damped Jacobi step, `P = (I - ω D⁻¹ Â) P̂` with `ω = 4/(3ρ)`
//!   (Vaněk et al. eq. 4.3) and `ρ` a power-iteration estimate of `ρ(D⁻¹ Â)`: the Gershgorin
//!   bound used before overestimates it on stiff cloth, and the too small `ω` left `P`
//!   under-smoothed (32², tol 1e-6, stretch 1e6 and shear 1e3: 234 iterations, 162 with the
//!   estimate);
//! - **Galerkin** coarse operators `Âₗ₊₁ = Pᵀ Âₗ P`, down to at most [`COARSEST`] nodes,
//!   solved by a dense Cholesky factorisation;
//! - a **V-cycle** with one forward block Gauss–Seidel sweep before the coarse correction and
//!   one backward sweep after it (a symmetric preconditioner, as the PCG needs); the forward
//!   sweep starts from zero, so it and the residual after it together read the matrix once.
//!
//! What is reused: the aggregates and the patterns of every `P`, `Pᵀ`, `Â P` and coarse
//! operator (the symbolic setup, from the model's pattern alone, built on the first solve).
//! Every solve refills the values — `Â`, the Jacobi-smoothed `P`, the Galerkin products and the
//! coarsest factorisation — from the step's matrix: they cost about 15 PCG iterations of block
//! SSOR at 64² and keep the solver free of anything a later step reads (reusing `P` from an
//! earlier step would make a step depend on which state the solver stepped before).

use super::bsr::BlockMatrix;
use crate::error::{Error, Result};
use glam::{DMat3, DVec3};

/// The largest number of nodes of the coarsest level (solved by dense Cholesky).
pub const COARSEST: usize = 48;

/// Marks a node not yet in an aggregate.
const NONE: u32 = u32::MAX;

/// Block compressed sparse rows, every block stored (square or rectangular), columns sorted
/// within a row.
#[derive(Default)]
struct Blocks {
    row_ptr: Vec<usize>,
    cols: Vec<u32>,
    blocks: Vec<DMat3>,
}

impl Blocks {
    /// The pattern of `rows` (each sorted, without repeats), zero-filled.
    fn from_rows(rows: &[Vec<u32>]) -> Blocks {
        let mut row_ptr = vec![0];
        let mut cols = Vec::new();
        for row in rows {
            cols.extend_from_slice(row);
            row_ptr.push(cols.len());
        }
        let blocks = vec![DMat3::ZERO; cols.len()];
        Blocks { row_ptr, cols, blocks }
    }

    fn n(&self) -> usize {
        self.row_ptr.len() - 1
    }

    fn row(&self, i: usize) -> std::ops::Range<usize> {
        self.row_ptr[i]..self.row_ptr[i + 1]
    }
}

/// One level of the hierarchy: its operator on blocks at points (a vertex on the finest
/// level; a translation block `2a` and a rotation block `2a + 1` at the centroid of aggregate
/// `a` on the coarser ones), and (above the coarsest) the aggregates of its points, the
/// tentative and smoothed prolongators to the next level, `Pᵀ` and `Â P`, with the V-cycle's
/// vectors.
#[derive(Default)]
struct Level {
    a: Blocks,
    /// Whether the blocks come in (translation, rotation) pairs, one pair a point.
    paired: bool,
    /// Slot of the diagonal block of each row of `a`.
    diag: Vec<usize>,
    /// The inverse diagonal blocks of `a`.
    inverse: Vec<DMat3>,
    /// The position of each point (m): the vertices', or the centroids of the aggregates.
    position: Vec<DVec3>,
    /// Points of the finer level in each point (coarse levels).
    members: Vec<u32>,
    /// The aggregate (point of the next level) of each point.
    aggregate: Vec<u32>,
    /// The tentative prolongator `P̂`: the rigid motions of each aggregate.
    tentative: Blocks,
    p: Blocks,
    /// `Pᵀ`, and the slot of `p` each of its blocks is the transpose of.
    pt: Blocks,
    pt_source: Vec<usize>,
    ap: Blocks,
    /// The level's solution, right-hand side and residual.
    x: Vec<DVec3>,
    b: Vec<DVec3>,
    r: Vec<DVec3>,
}

impl Level {
    /// The point of block `i`.
    fn point(&self, i: usize) -> usize {
        if self.paired {
            i / 2
        } else {
            i
        }
    }

    /// The blocks of point `p`.
    fn blocks_of(&self, p: usize) -> std::ops::Range<usize> {
        if self.paired {
            2 * p..2 * p + 2
        } else {
            p..p + 1
        }
    }

    /// Number of points.
    fn points(&self) -> usize {
        self.position.len()
    }
}

/// The hierarchy (see the module documentation).
pub struct Hierarchy {
    levels: Vec<Level>,
    /// For each block of the finest operator, the block of the upper-triangle matrix it is
    /// read from, and whether transposed.
    source: Vec<(usize, bool)>,
    /// The coarsest operator as a dense `3n x 3n` matrix, then its Cholesky factor.
    dense: Vec<f64>,
    /// The position of each column in the row being accumulated (a sparse accumulator).
    position: Vec<usize>,
}

impl Hierarchy {
    /// The symbolic setup on the pattern of `m` of a mesh of `triangles`: aggregates and every
    /// level's patterns.
    pub fn new(m: &BlockMatrix, triangles: &[[usize; 3]]) -> Hierarchy {
        let n = m.n();
        let mut rows: Vec<Vec<(u32, usize, bool)>> =
            (0..n).map(|i| vec![(i as u32, i, false)]).collect();
        for i in 0..n {
            for s in m.row_ptr[i]..m.row_ptr[i + 1] {
                let j = m.cols[s];
                rows[i].push((j, s, false));
                rows[j as usize].push((i as u32, s, true));
            }
        }
        let mut source = Vec::new();
        let mut pattern = Vec::with_capacity(n);
        for mut row in rows {
            row.sort_unstable_by_key(|e| e.0);
            source.extend(row.iter().map(|&(_, s, t)| (s, t)));
            pattern.push(row.iter().map(|e| e.0).collect::<Vec<_>>());
        }
        // The finest level's strong couplings: the vertices of a triangle (the membrane); a
        // coupling by a bending hinge alone is weak.
        let mut strong: Vec<Vec<u32>> = (0..n).map(|i| vec![i as u32]).collect();
        for t in triangles {
            for &a in t {
                strong[a].extend(t.iter().map(|&b| b as u32));
            }
        }
        let mut graph: Vec<Vec<u32>> = strong.into_iter().map(|r| union(r.into_iter())).collect();
        let mut levels = vec![level(&pattern, false)];
        while levels.last().expect("one level").a.n() > COARSEST {
            let fine = levels.last_mut().expect("one level");
            let (coarse, members) = coarsen(fine, &graph);
            if members.len() == fine.points() {
                break;
            }
            let mut next = level(&coarse, true);
            graph = (0..members.len())
                .map(|p| union(next.blocks_of(p).flat_map(|i| coarse[i].iter()).map(|&j| j / 2)))
                .collect();
            next.members = members;
            levels.push(next);
        }
        let nc = levels.last().expect("one level").a.n();
        let widest = levels.iter().map(|l| l.a.n()).max().unwrap_or(0);
        Hierarchy { levels, source, dense: vec![0.0; 9 * nc * nc], position: vec![0; widest] }
    }

    /// The numeric setup for the matrix `m` (the hierarchy's pattern), the filter and the
    /// vertex positions `x` (m; the rigid motions of the aggregates).
    ///
    /// # Errors
    /// [`Error::SolverFailed`] when a diagonal block or the coarsest operator is not positive
    /// definite.
    pub fn update(&mut self, m: &BlockMatrix, filter: &[DMat3], x: &[DVec3]) -> Result<()> {
        let fine = &mut self.levels[0];
        fine.position.copy_from_slice(x);
        for i in 0..fine.a.n() {
            for s in fine.a.row(i) {
                let (slot, transposed) = self.source[s];
                let block = if transposed { m.blocks[slot].transpose() } else { m.blocks[slot] };
                let (fi, fj) = (filter[i], filter[fine.a.cols[s] as usize]);
                fine.a.blocks[s] = if fi == DMat3::IDENTITY && fj == DMat3::IDENTITY {
                    block
                } else {
                    fi * block * fj
                };
            }
            fine.a.blocks[fine.diag[i]] += DMat3::IDENTITY - filter[i];
        }
        for l in 0..self.levels.len() - 1 {
            let (fine, coarse) = self.levels.split_at_mut(l + 1);
            let (fine, coarse) = (&mut fine[l], &mut coarse[0]);
            invert_diagonal(fine)?;
            tentative(fine, coarse);
            smooth_prolongator(fine, &mut self.position);
            galerkin(fine, coarse, &mut self.position);
        }
        let last = self.levels.last_mut().expect("one level");
        invert_diagonal(last)?;
        dense_cholesky(&last.a, &mut self.dense)
    }

    /// `out = S M⁻¹ S r`: one V-cycle on the filtered `r` (`r` in `range(S)` already).
    pub fn apply(&mut self, filter: &[DMat3], r: &[DVec3], out: &mut [DVec3]) {
        self.levels[0].b.copy_from_slice(r);
        let last = self.levels.len() - 1;
        for l in 0..last {
            let (fine, coarse) = self.levels.split_at_mut(l + 1);
            let (fine, coarse) = (&mut fine[l], &mut coarse[0]);
            presmooth(fine);
            for c in 0..coarse.b.len() {
                coarse.b[c] = fine
                    .pt
                    .row(c)
                    .map(|t| fine.pt.blocks[t] * fine.r[fine.pt.cols[t] as usize])
                    .sum();
            }
        }
        let coarsest = &mut self.levels[last];
        coarsest.x.copy_from_slice(&coarsest.b);
        dense_solve(&self.dense, &mut coarsest.x);
        for l in (0..last).rev() {
            let (fine, coarse) = self.levels.split_at_mut(l + 1);
            let (fine, coarse) = (&mut fine[l], &coarse[0]);
            for i in 0..fine.x.len() {
                let correction: DVec3 = fine
                    .p
                    .row(i)
                    .map(|t| fine.p.blocks[t] * coarse.x[fine.p.cols[t] as usize])
                    .sum();
                fine.x[i] += correction;
            }
            postsmooth(fine);
        }
        for (i, o) in out.iter_mut().enumerate() {
            *o = filter[i] * self.levels[0].x[i];
        }
    }

    /// `out = Â x` with the finest operator of the last [`Hierarchy::update`].
    pub fn mul(&self, x: &[DVec3], out: &mut [DVec3]) {
        let a = &self.levels[0].a;
        for (i, o) in out.iter_mut().enumerate() {
            *o = a.row(i).map(|s| a.blocks[s] * x[a.cols[s] as usize]).sum();
        }
    }
}

/// A level on the pattern `rows` (each row sorted and holding its diagonal), zero-filled, its
/// blocks in (translation, rotation) pairs when `paired`.
fn level(rows: &[Vec<u32>], paired: bool) -> Level {
    let a = Blocks::from_rows(rows);
    let n = a.n();
    let diag = (0..n)
        .map(|i| a.row_ptr[i] + rows[i].binary_search(&(i as u32)).expect("diagonal in pattern"))
        .collect();
    let zero = vec![DVec3::ZERO; n];
    let points = if paired { n / 2 } else { n };
    Level {
        a,
        paired,
        diag,
        inverse: vec![DMat3::ZERO; n],
        position: vec![DVec3::ZERO; points],
        x: zero.clone(),
        b: zero.clone(),
        r: zero,
        ..Level::default()
    }
}

/// Sorted, without repeats.
fn union(parts: impl Iterator<Item = u32>) -> Vec<u32> {
    let mut row: Vec<u32> = parts.collect();
    row.sort_unstable();
    row.dedup();
    row
}

/// Aggregates of the points of `fine` (Vaněk et al. 1996, §4.1: whole free neighbourhoods,
/// then the rest joins a neighbouring aggregate, repeatedly, so that every aggregate holds a
/// whole neighbourhood) and the patterns of its tentative and smoothed prolongators, `Pᵀ` and
/// `Â P`; returns the coarse operator's pattern and the number of members of each aggregate.
fn coarsen(fine: &mut Level, graph: &[Vec<u32>]) -> (Vec<Vec<u32>>, Vec<u32>) {
    let a = &fine.a;
    let points = fine.points();
    let mut aggregate = vec![NONE; points];
    let mut count = 0u32;
    for row in graph.iter().take(points) {
        if row.iter().all(|&q| aggregate[q as usize] == NONE) {
            row.iter().for_each(|&q| aggregate[q as usize] = count);
            count += 1;
        }
    }
    // Every connected point ends in an aggregate: the first point of a component reached
    // made one of its whole neighbourhood.
    let mut changed = true;
    while changed {
        changed = false;
        for p in 0..points {
            if aggregate[p] == NONE {
                if let Some(&q) = graph[p].iter().find(|&&q| aggregate[q as usize] != NONE) {
                    aggregate[p] = aggregate[q as usize];
                    changed = true;
                }
            }
        }
    }
    let mut members = vec![0u32; count as usize];
    aggregate.iter().for_each(|&c| members[c as usize] += 1);
    // P̂ (i, ·): the translation and rotation blocks of the aggregate (the rotation alone for
    // a rotation block); P (i, ·): P̂'s columns of i's neighbours; Pᵀ; Â P (i, ·): P's of
    // i's neighbours; the coarse operator (c, ·): Â P's of the rows i with P (i, c).
    let tentative: Vec<Vec<u32>> = (0..a.n())
        .map(|i| {
            let c = 2 * aggregate[fine.point(i)];
            if fine.paired && i % 2 == 1 {
                vec![c + 1]
            } else {
                vec![c, c + 1]
            }
        })
        .collect();
    let neighbours = |i: usize| a.cols[a.row(i)].iter().map(|&j| j as usize);
    let p_rows: Vec<Vec<u32>> = (0..a.n())
        .map(|i| union(neighbours(i).flat_map(|j| tentative[j].iter().copied())))
        .collect();
    let nc = 2 * count as usize;
    let mut pt_rows: Vec<Vec<(u32, usize)>> = vec![Vec::new(); nc];
    let mut slot = 0;
    for (i, row) in p_rows.iter().enumerate() {
        for &c in row {
            pt_rows[c as usize].push((i as u32, slot));
            slot += 1;
        }
    }
    let ap_rows: Vec<Vec<u32>> =
        (0..a.n()).map(|i| union(neighbours(i).flat_map(|j| p_rows[j].iter().copied()))).collect();
    let coarse: Vec<Vec<u32>> = pt_rows
        .iter()
        .map(|row| union(row.iter().flat_map(|&(i, _)| ap_rows[i as usize].iter().copied())))
        .collect();
    fine.aggregate = aggregate;
    fine.tentative = Blocks::from_rows(&tentative);
    fine.p = Blocks::from_rows(&p_rows);
    let pt: Vec<Vec<u32>> = pt_rows.iter().map(|r| r.iter().map(|e| e.0).collect()).collect();
    fine.pt = Blocks::from_rows(&pt);
    fine.pt_source = pt_rows.iter().flatten().map(|e| e.1).collect();
    fine.ap = Blocks::from_rows(&ap_rows);
    (coarse, members)
}

/// The coarse points' positions (the centroids of their aggregates) and the tentative
/// prolongator: the rigid motion `(t, θ)` of an aggregate centred at `c` moves a point at `x`
/// by `t + θ × (x - c)` and turns it by `θ` (Vaněk et al. §5; Tamstorf et al. §3.2).
fn tentative(fine: &mut Level, coarse: &mut Level) {
    coarse.position.fill(DVec3::ZERO);
    for (p, &c) in fine.aggregate.iter().enumerate() {
        coarse.position[c as usize] += fine.position[p];
    }
    for (c, &m) in coarse.position.iter_mut().zip(&coarse.members) {
        *c /= f64::from(m);
    }
    for i in 0..fine.a.n() {
        let p = fine.point(i);
        let r = fine.position[p] - coarse.position[fine.aggregate[p] as usize];
        let row = fine.tentative.row(i);
        if row.len() == 2 {
            // u = θ × r = -[r]ₓ θ.
            let skew = DMat3::from_cols(
                DVec3::new(0.0, -r.z, r.y),
                DVec3::new(r.z, 0.0, -r.x),
                DVec3::new(-r.y, r.x, 0.0),
            );
            fine.tentative.blocks[row.start] = DMat3::IDENTITY;
            fine.tentative.blocks[row.start + 1] = skew;
        } else {
            fine.tentative.blocks[row.start] = DMat3::IDENTITY;
        }
    }
}

/// The inverse diagonal blocks of the level's operator.
fn invert_diagonal(level: &mut Level) -> Result<()> {
    for (inverse, &d) in level.inverse.iter_mut().zip(&level.diag) {
        let block = level.a.blocks[d];
        let det = block.determinant();
        if !(det > 0.0 && det.is_finite()) {
            return Err(not_positive());
        }
        *inverse = block.inverse();
    }
    Ok(())
}

fn not_positive() -> Error {
    Error::SolverFailed { reason: "multigrid: the system matrix is not positive definite".into() }
}

/// `P = (I - ω D⁻¹ Â) P̂` with `ω = 4/(3ρ)`, `ρ` the estimate of `ρ(D⁻¹ Â)` of
/// [`spectral_radius`]; then `Pᵀ`.
fn smooth_prolongator(fine: &mut Level, position: &mut [usize]) {
    let rho = spectral_radius(fine);
    let (a, p) = (&fine.a, &mut fine.p);
    let omega = 4.0 / (3.0 * rho);
    let tent = &fine.tentative;
    for i in 0..a.n() {
        for t in p.row(i) {
            position[p.cols[t] as usize] = t;
            p.blocks[t] = DMat3::ZERO;
        }
        for t in tent.row(i) {
            p.blocks[position[tent.cols[t] as usize]] += tent.blocks[t];
        }
        let scaled = fine.inverse[i] * omega;
        for s in a.row(i) {
            let weighted = scaled * a.blocks[s];
            let j = a.cols[s] as usize;
            for t in tent.row(j) {
                p.blocks[position[tent.cols[t] as usize]] -= weighted * tent.blocks[t];
            }
        }
    }
    for (block, &t) in fine.pt.blocks.iter_mut().zip(&fine.pt_source) {
        *block = p.blocks[t].transpose();
    }
}

/// Power iterations for the spectral radius of `D⁻¹ Â` from a fixed start (so that the
/// estimate depends on the matrix alone): `D⁻¹ Â` is self-adjoint in the `D` inner product,
/// the Rayleigh quotients `vᵀ Â v / vᵀ D v` rise to `ρ` from below. Uses the level's `x`
/// and `r` as scratch.
fn spectral_radius(level: &mut Level) -> f64 {
    const ITERATIONS: usize = 15;
    let a = &level.a;
    let (v, w) = (&mut level.x, &mut level.r);
    for (i, vi) in v.iter_mut().enumerate() {
        // A fixed start with all components and no symmetry.
        *vi = DVec3::new(1.0, 1.3, 0.7) * (1.0 + 0.5 * ((i * 7919) % 13) as f64);
    }
    let mut rho = 0.0;
    for _ in 0..ITERATIONS {
        let (mut num, mut den) = (0.0, 0.0);
        for i in 0..a.n() {
            let av: DVec3 = a.row(i).map(|s| a.blocks[s] * v[a.cols[s] as usize]).sum();
            num += v[i].dot(av);
            den += v[i].dot(a.blocks[level.diag[i]] * v[i]);
            w[i] = level.inverse[i] * av;
        }
        rho = num / den;
        let scale = 1.0 / w.iter().map(|x| x.length_squared()).sum::<f64>().sqrt();
        v.iter_mut().zip(w.iter()).for_each(|(vi, wi)| *vi = *wi * scale);
    }
    rho
}

/// `Â P`, then the coarse operator `Pᵀ (Â P)` ([`product_into`]).
fn galerkin(fine: &mut Level, coarse: &mut Level, position: &mut [usize]) {
    product_into(&fine.a, &fine.p, &mut fine.ap, position);
    let ac = &mut coarse.a;
    product_into(&fine.pt, &fine.ap, ac, position);
    // The rotation about the line of an aggregate of two points (or collinear points) is no
    // motion: its coarse row is zero up to rounding. A relative 1e-10 on the diagonal keeps
    // the coarse operator definite (the preconditioner stays SPD; that direction's
    // right-hand side is zero).
    for &d in &coarse.diag {
        let block = &mut ac.blocks[d];
        let trace = block.x_axis.x + block.y_axis.y + block.z_axis.z;
        *block += DMat3::from_diagonal(DVec3::splat(if trace > 0.0 { 1e-10 * trace } else { 1.0 }));
    }
}

/// The values of `out = left · right` on `out`'s pattern (which holds the product's),
/// row by row with a sparse accumulator: `position` (one slot per column of `right`) maps a
/// column to its slot in the row being built.
fn product_into(left: &Blocks, right: &Blocks, out: &mut Blocks, position: &mut [usize]) {
    for i in 0..out.n() {
        for t in out.row(i) {
            position[out.cols[t] as usize] = t;
            out.blocks[t] = DMat3::ZERO;
        }
        for s in left.row(i) {
            let k = left.cols[s] as usize;
            for t in right.row(k) {
                out.blocks[position[right.cols[t] as usize]] += left.blocks[s] * right.blocks[t];
            }
        }
    }
}

/// One forward block Gauss–Seidel sweep on `a x = b` from `x = 0`, then `r = b - a x`. From
/// zero, row `i` of the sweep meets only the rows before it (the later ones are still zero),
/// so it reads the strictly lower blocks only; and after it `(a x)ᵢ = bᵢ + Σ_{j>i} aᵢⱼ xⱼ`,
/// so `rᵢ = -Σ_{j>i} aᵢⱼ xⱼ` reads the strictly upper ones: one pass over the matrix for
/// both, where a sweep and a residual took two.
fn presmooth(level: &mut Level) {
    let a = &level.a;
    for i in 0..a.n() {
        let mut sum = level.b[i];
        for s in a.row_ptr[i]..level.diag[i] {
            sum -= a.blocks[s] * level.x[a.cols[s] as usize];
        }
        level.x[i] = level.inverse[i] * sum;
    }
    for i in 0..a.n() {
        let mut sum = DVec3::ZERO;
        for s in level.diag[i] + 1..a.row_ptr[i + 1] {
            sum -= a.blocks[s] * level.x[a.cols[s] as usize];
        }
        level.r[i] = sum;
    }
}

/// One backward block Gauss–Seidel sweep on `a x = b` (the symmetric partner of
/// [`presmooth`]'s).
fn postsmooth(level: &mut Level) {
    let a = &level.a;
    for i in (0..a.n()).rev() {
        let mut sum = level.b[i];
        for s in a.row(i) {
            let j = a.cols[s] as usize;
            if j != i {
                sum -= a.blocks[s] * level.x[j];
            }
        }
        level.x[i] = level.inverse[i] * sum;
    }
}

/// The dense lower Cholesky factor of `a` (`3n x 3n`, row-major) into `out`.
fn dense_cholesky(a: &Blocks, out: &mut [f64]) -> Result<()> {
    let m = 3 * a.n();
    out.fill(0.0);
    for i in 0..a.n() {
        for s in a.row(i) {
            let (j, b) = (a.cols[s] as usize, a.blocks[s]);
            for r in 0..3 {
                for c in 0..3 {
                    out[(3 * i + r) * m + 3 * j + c] = b.col(c)[r];
                }
            }
        }
    }
    for j in 0..m {
        let d = out[j * m + j] - (0..j).map(|k| out[j * m + k] * out[j * m + k]).sum::<f64>();
        if !(d > 0.0 && d.is_finite()) {
            return Err(not_positive());
        }
        let d = d.sqrt();
        out[j * m + j] = d;
        for i in j + 1..m {
            let s = out[i * m + j] - (0..j).map(|k| out[i * m + k] * out[j * m + k]).sum::<f64>();
            out[i * m + j] = s / d;
        }
    }
    Ok(())
}

/// Solve `L Lᵀ x = x` in place with the factor of [`dense_cholesky`].
fn dense_solve(l: &[f64], x: &mut [DVec3]) {
    let m = 3 * x.len();
    let flat: &mut [f64] = bytemuck::cast_slice_mut(x);
    for i in 0..m {
        let s = flat[i] - (0..i).map(|k| l[i * m + k] * flat[k]).sum::<f64>();
        flat[i] = s / l[i * m + i];
    }
    for i in (0..m).rev() {
        let s = flat[i] - (i + 1..m).map(|k| l[k * m + i] * flat[k]).sum::<f64>();
        flat[i] = s / l[i * m + i];
    }
}
