//! Weights by heat diffusion over the surface (Baran & Popović 2007, "Automatic rigging and
//! animation of 3D characters", section 4, "bone heat").
//!
//! Bone `i`'s weights `wⁱ` (one per vertex) solve the equilibrium of heat diffusing over the
//! surface from the bones, `−Δwⁱ + H wⁱ = H pⁱ` (paper, eq. 1): `Δ` is the surface's
//! Laplace–Beltrami operator, `H` is diagonal with `H_jj = c / d_j²` for the distance `d_j`
//! from vertex `j` to its nearest bone (`c = 1`, the paper's value), and `pⁱ_j = 1` when bone
//! `i` is vertex `j`'s nearest (`1/n` each for `n` equidistant bones). A vertex is held
//! towards its nearest bone with a strength that falls with the distance, and the weights
//! blend smoothly across the surface between the regions each bone holds: over a distance
//! of about `d/√c` from a joint.
//!
//! `Δ` is the cotangent Laplacian with barycentric areas (Meyer, Desbrun, Schröder & Barr
//! 2003): `(Δf)_j = (1/A_j) Σ_k ½ (cot α_jk + cot β_jk)(f_k − f_j)`, `A_j` a third of the
//! area of the triangles at `j`. Multiplied by the areas the system is
//! `(L + A H) wⁱ = A H pⁱ`, with `L` the symmetric positive semidefinite cotangent matrix and
//! `A H` a positive diagonal: symmetric positive definite, factorised once (sparse Cholesky,
//! faer) for every bone. Since `Σᵢ pⁱ = 1` and `L 1 = 0`, the weights of all bones sum to 1 at
//! every vertex before any truncation.
//!
//! "Nearest" is the paper's nearest *visible* bone (§4): a bone holds a vertex only if the
//! segment from the vertex to the bone's closest point meets no other part of the surface,
//! tested exactly against the triangles through a bounding volume hierarchy
//! ([`TriangleTree`]); a vertex that sees no bone has `H_jj = 0` and takes its weights from
//! its neighbours alone. So where two limbs touch (legs pressed together, an arm against the
//! torso) a vertex of one follows its own bone even when the other limb's is nearer.

use super::weights::check_bones;
use crate::error::{Error, Result};
use crate::geometry::segment::closest_point_on_segment;
use crate::geometry::tree::TriangleTree;
use crate::linalg::SparseCholesky;
use glam::DVec3;
use rayon::prelude::*;

/// The paper's `c` in `H_jj = c / d_j²`.
const HEAT: f64 = 1.0;

/// Bones within this relative distance of the nearest count as equidistant.
const TIE: f64 = 1e-9;

/// Distances to a bone are at least this fraction of the mesh's bounding-box diagonal (a
/// vertex on a bone would make `H_jj` infinite).
const MIN_DISTANCE: f64 = 1e-6;

/// Heat-diffusion weights of the surface `(vertices, triangles)` for the bones that own
/// `segments` (bone `bones_of[s]` owns segment `s`, as in
/// [`proximity_weights`](super::proximity_weights)): every vertex's `k` largest weights less
/// the `(k+1)`-th (continuous where bones enter or leave the `k` largest), normalised to
/// sum 1, as `(bones, weights)` with `k` per vertex, largest first (unused slots weight 0). Units are those of the positions. A vertex in no triangle takes its
/// nearest bone alone.
///
/// # Errors
/// [`Error::InvalidInput`] naming the argument: `k = 0`, no segments, non-finite points, a
/// segment's bone beyond `bones`, a triangle naming a vertex beyond the vertices or one
/// vertex twice; [`Error::SolverFailed`] if the factorisation fails.
pub fn heat_weights(
    vertices: &[[f64; 3]],
    triangles: &[[u32; 3]],
    segments: &[([f64; 3], [f64; 3])],
    bones_of: &[u32],
    bones: usize,
    k: usize,
) -> Result<(Vec<u32>, Vec<f64>)> {
    check_bones(vertices, segments, bones_of, bones, k)?;
    let n = vertices.len();
    for (t, tri) in triangles.iter().enumerate() {
        if tri.iter().any(|&v| v as usize >= n) {
            return Err(Error::invalid("triangles", "names a vertex beyond the vertices").at(t));
        }
        if tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
            return Err(Error::invalid("triangles", "repeats a vertex").at(t));
        }
    }
    let (nearest, hold) = nearest_bones(vertices, triangles, segments, bones_of);
    let (mut matrix, area) = Cotangent::assemble(vertices, triangles);
    for j in 0..n {
        matrix.add(j, j, area[j] * hold[j]);
    }
    let (col_ptr, row_idx, values) = matrix.lower_csc();
    let mut cholesky = SparseCholesky::new(n, col_ptr, row_idx)?;
    cholesky.factorize(&values)?;
    // Every bone that is some vertex's nearest: its weights over all vertices.
    let mut heated = vec![false; bones];
    nearest.iter().flatten().for_each(|&(b, _)| heated[b as usize] = true);
    let mut columns: Vec<(u32, Vec<f64>)> = Vec::new();
    for bone in (0..bones).filter(|&b| heated[b]) {
        let mut rhs = vec![0.0; n];
        for (j, near) in nearest.iter().enumerate() {
            if let Some(&(_, share)) = near.iter().find(|&&(b, _)| b as usize == bone) {
                rhs[j] = area[j] * hold[j] * share;
            }
        }
        cholesky.solve_in_place(&mut rhs);
        columns.push((bone as u32, rhs));
    }
    let k = k.min(bones);
    let mut out_bones = vec![0u32; n * k];
    let mut out_weights = vec![0.0; n * k];
    out_bones.par_chunks_mut(k).zip(out_weights.par_chunks_mut(k)).enumerate().for_each(
        |(j, (ob, ow))| {
            let candidates = columns.iter().map(|(b, w)| (*b, w[j]));
            largest(candidates, &nearest[j], ob, ow);
        },
    );
    Ok((out_bones, out_weights))
}

/// A vertex's nearest visible bones, each with its share of `p`.
type Nearest = Vec<(u32, f64)>;

/// Every vertex's nearest visible bones with their shares of `p` (`1/n` for `n` equidistant),
/// and its `H_jj = c / d_j²` (0 when it sees no bone). Bone `b` is visible from vertex `j`
/// when the segment from `j` to the closest point of one of `b`'s segments meets no triangle
/// of the surface other than those at `j` (the paper's test, §4: a bone on the other side of
/// the surface, such as the other leg's, does not hold the vertex even when it is nearer).
/// A connected part of the surface where no vertex sees a bone (the system would be singular
/// there) takes the nearest bones without the test.
fn nearest_bones(
    vertices: &[[f64; 3]],
    triangles: &[[u32; 3]],
    segments: &[([f64; 3], [f64; 3])],
    bones_of: &[u32],
) -> (Vec<Nearest>, Vec<f64>) {
    let (lo, hi) = vertices
        .iter()
        .fold((DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)), |(lo, hi), v| {
            (lo.min(DVec3::from_array(*v)), hi.max(DVec3::from_array(*v)))
        });
    let floor = MIN_DISTANCE * (hi - lo).length().max(f64::MIN_POSITIVE);
    let tree = TriangleTree::new(vertices, triangles);
    let (mut nearest, mut hold): (Vec<Nearest>, Vec<f64>) = vertices
        .par_iter()
        .enumerate()
        .map(|(j, v)| {
            let x = DVec3::from_array(*v);
            let at_j = |t: usize| triangles[t].contains(&(j as u32));
            let visible = |c: DVec3| !tree.segment_hits(x, c, at_j);
            closest_visible(x, segments, bones_of, floor, visible)
        })
        .unzip();
    let part = components(vertices.len(), triangles);
    let mut seen = vec![false; vertices.len()];
    for (j, &h) in hold.iter().enumerate() {
        seen[part[j]] |= h > 0.0;
    }
    for j in (0..vertices.len()).filter(|&j| !seen[part[j]]) {
        let x = DVec3::from_array(vertices[j]);
        (nearest[j], hold[j]) = closest_visible(x, segments, bones_of, floor, |_| true);
    }
    (nearest, hold)
}

/// The bones of the segments nearest to `x` among those whose closest point `c` passes
/// `visible(c)`, within the relative [`TIE`] of the nearest, each with an equal share; and
/// `c / d²` for their distance `d` (at least `floor`). No bones and 0 if none is visible.
fn closest_visible(
    x: DVec3,
    segments: &[([f64; 3], [f64; 3])],
    bones_of: &[u32],
    floor: f64,
    visible: impl Fn(DVec3) -> bool,
) -> (Nearest, f64) {
    let mut candidates: Vec<(f64, DVec3, u32)> = segments
        .iter()
        .zip(bones_of)
        .map(|((a, b), &bone)| {
            let c = closest_point_on_segment(DVec3::from_array(*a), DVec3::from_array(*b), x);
            (x.distance(c), c, bone)
        })
        .collect();
    candidates.sort_by(|p, q| p.0.total_cmp(&q.0).then(p.2.cmp(&q.2)));
    let Some(first) = candidates.iter().position(|&(_, c, _)| visible(c)) else {
        return (Vec::new(), 0.0);
    };
    let d = candidates[first].0;
    let mut near: Vec<u32> = candidates[first..]
        .iter()
        .take_while(|&&(e, _, _)| e <= d * (1.0 + TIE))
        .filter(|&&(_, c, _)| c == candidates[first].1 || visible(c))
        .map(|&(_, _, bone)| bone)
        .collect();
    near.sort_unstable();
    near.dedup();
    let share = 1.0 / near.len() as f64;
    let d = d.max(floor);
    (near.into_iter().map(|b| (b, share)).collect(), HEAT / (d * d))
}

/// The connected part of every vertex (an index of a vertex of that part): vertices joined
/// by triangles, by union–find.
fn components(n: usize, triangles: &[[u32; 3]]) -> Vec<usize> {
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for t in triangles {
        let mut a = root(&mut parent, t[0] as usize);
        for &v in &t[1..] {
            let b = root(&mut parent, v as usize);
            parent[a.max(b)] = a.min(b);
            a = a.min(b);
        }
    }
    (0..n).map(|i| root(&mut parent, i)).collect()
}

/// The `k` largest positive weights of `candidates` into `bones`/`weights`, largest first
/// (ties by bone index), less the `(k+1)`-th largest and normalised: a bone's weight then
/// falls to 0 as it leaves a vertex's `k` largest, so the truncated weights stay continuous
/// over the surface (plain truncation jumps where the `k`-th and `(k+1)`-th swap). The
/// nearest bones' shares if no weight is positive; plain truncation if the subtraction
/// leaves nothing (the `k+1` largest equal).
fn largest(
    candidates: impl Iterator<Item = (u32, f64)>,
    nearest: &[(u32, f64)],
    bones: &mut [u32],
    weights: &mut [f64],
) {
    let mut all: Vec<(u32, f64)> = candidates.filter(|&(_, w)| w > 0.0).collect();
    if all.is_empty() {
        all = nearest.to_vec();
    }
    all.sort_by(|p, q| q.1.total_cmp(&p.1).then(p.0.cmp(&q.0)));
    let k = bones.len();
    let below = all.get(k).map_or(0.0, |&(_, w)| w);
    let kept = &all[..k.min(all.len())];
    let floor = if kept.iter().any(|&(_, w)| w > below) { below } else { 0.0 };
    bones.fill(0);
    weights.fill(0.0);
    for ((slot, w), &(b, v)) in bones.iter_mut().zip(weights.iter_mut()).zip(kept) {
        *slot = b;
        *w = v - floor;
    }
    let sum: f64 = weights.iter().sum();
    weights.iter_mut().for_each(|w| *w /= sum);
}

/// The cotangent matrix `L` being assembled, as `(row, column, value)` entries of its lower
/// triangle (summed when the pattern is built).
struct Cotangent {
    n: usize,
    entries: Vec<(usize, usize, f64)>,
}

impl Cotangent {
    /// `L` of the triangles and the barycentric area of every vertex (1 for a vertex in no
    /// triangle, so that it takes its nearest bone). Triangles of zero area add nothing.
    fn assemble(vertices: &[[f64; 3]], triangles: &[[u32; 3]]) -> (Self, Vec<f64>) {
        let n = vertices.len();
        let mut matrix = Cotangent { n, entries: Vec::with_capacity(n + 6 * triangles.len()) };
        let mut area = vec![0.0; n];
        for tri in triangles {
            let idx = tri.map(|v| v as usize);
            let p = idx.map(|v| DVec3::from_array(vertices[v]));
            let twice_area = (p[1] - p[0]).cross(p[2] - p[0]).length();
            if twice_area == 0.0 || !twice_area.is_finite() {
                continue;
            }
            for c in 0..3 {
                area[idx[c]] += twice_area / 6.0;
                // The edge opposite corner c, weighted by half the cotangent of c's angle.
                let (a, b) = (idx[(c + 1) % 3], idx[(c + 2) % 3]);
                let (ea, eb) = (p[(c + 1) % 3] - p[c], p[(c + 2) % 3] - p[c]);
                let w = 0.5 * ea.dot(eb) / twice_area;
                matrix.add(a, a, w);
                matrix.add(b, b, w);
                matrix.add(a, b, -w);
            }
        }
        area.iter_mut().filter(|a| **a == 0.0).for_each(|a| *a = 1.0);
        (matrix, area)
    }

    /// Add `value` at `(i, j)` (and at `(j, i)`: the matrix is symmetric).
    fn add(&mut self, i: usize, j: usize, value: f64) {
        self.entries.push((i.max(j), i.min(j), value));
    }

    /// The lower triangle in compressed sparse columns: `(col_ptr, row_idx, values)`, rows
    /// sorted in every column, duplicates summed.
    fn lower_csc(mut self) -> (Vec<usize>, Vec<usize>, Vec<f64>) {
        self.entries.sort_by_key(|p| (p.1, p.0));
        let mut col_ptr = vec![0usize; self.n + 1];
        let (mut row_idx, mut values) = (Vec::new(), Vec::<f64>::new());
        let mut last = None;
        for (row, col, value) in self.entries {
            if last == Some((row, col)) {
                *values.last_mut().expect("an entry was pushed") += value;
                continue;
            }
            last = Some((row, col));
            row_idx.push(row);
            values.push(value);
            col_ptr[col + 1] += 1;
        }
        for c in 0..self.n {
            col_ptr[c + 1] += col_ptr[c];
        }
        (col_ptr, row_idx, values)
    }
}
