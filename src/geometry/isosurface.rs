//! The zero level set of a function sampled on a grid, as a closed triangle mesh: marching
//! cubes in its tetrahedral form (each cube cut into six tetrahedra around its main diagonal,
//! the Kuhn–Freudenthal split; Doi & Koide 1991, "An efficient method of triangulating
//! equi-valued surfaces by using tetrahedral cells").
//!
//! The split is the same in every cube, so neighbouring cubes cut their shared face along the
//! same diagonal and a tetrahedron has no ambiguous case: the surface is watertight and
//! manifold (every edge in two triangles) wherever the function is negative inside a box whose
//! border samples are all non-negative. A vertex lies on each grid or diagonal edge whose ends
//! have opposite signs (`f < 0` inside, `f ≥ 0` outside), at the linear interpolation of the
//! samples, and is shared by every triangle that crosses that edge. Triangles face outwards
//! (from `f < 0` to `f ≥ 0`).

use glam::DVec3;
use rayon::prelude::*;
use std::collections::HashMap;

/// The six tetrahedra of a unit cube, by cube corner (`bit 0` = x, `bit 1` = y, `bit 2` = z):
/// each walks from corner 0 to corner 7 along three different axes.
const TETRAHEDRA: [[usize; 4]; 6] =
    [[0, 1, 3, 7], [0, 1, 5, 7], [0, 2, 3, 7], [0, 2, 6, 7], [0, 4, 5, 7], [0, 4, 6, 7]];

/// A grid edge crossed by the surface: its inside sample, its outside sample.
type Edge = (usize, usize);

/// A triangle mesh: vertex positions and outward-facing triangles (indices into them).
pub type Mesh = (Vec<[f64; 3]>, Vec<[u32; 3]>);

/// The surface `f = 0` of samples `values` on the grid of `counts = [nx, ny, nz]` points
/// `origin + cell (i, j, k)` (x fastest: `values[i + nx (j + ny k)]`), inside where `f < 0`.
///
/// The caller makes `values` finite, and non-negative on the grid's border for a closed
/// surface. A grid less than two samples wide has no cube: no surface.
///
/// # Panics
/// If `values` does not hold `nx ny nz` samples.
pub fn polygonise(values: &[f64], counts: [usize; 3], origin: DVec3, cell: f64) -> Mesh {
    let [nx, ny, nz] = counts;
    assert_eq!(values.len(), nx * ny * nz, "polygonise: values do not fill the grid");
    if counts.iter().any(|&n| n < 2) {
        return (Vec::new(), Vec::new());
    }
    let index = |i: usize, j: usize, k: usize| i + nx * (j + ny * k);
    // Crossing edges per slab of cubes (parallel), then shared vertices (serial, in order).
    let slabs: Vec<Vec<[Edge; 3]>> = (0..nz.saturating_sub(1))
        .into_par_iter()
        .map(|k| {
            let mut out = Vec::new();
            for j in 0..ny - 1 {
                for i in 0..nx - 1 {
                    let corner = |c: usize| index(i + (c & 1), j + (c >> 1 & 1), k + (c >> 2));
                    for tet in &TETRAHEDRA {
                        cut(values, tet.map(corner), nx, ny, &mut out);
                    }
                }
            }
            out
        })
        .collect();
    let point = |p: usize| DVec3::from_array(lattice(p, nx, ny).map(|x| x as f64));
    let mut ids: HashMap<Edge, u32> = HashMap::new();
    let mut vertices: Vec<[f64; 3]> = Vec::new();
    let mut triangles = Vec::new();
    for triangle in slabs.iter().flatten() {
        triangles.push(triangle.map(|(a, b)| {
            *ids.entry((a, b)).or_insert_with(|| {
                let (fa, fb) = (values[a], values[b]);
                let t = (fa / (fa - fb)).clamp(0.0, 1.0);
                vertices.push((origin + cell * point(a).lerp(point(b), t)).to_array());
                (vertices.len() - 1) as u32
            })
        }));
    }
    (vertices, triangles)
}

/// Lattice coordinates `(i, j, k)` of sample `p` on a grid of `nx × ny × …` points.
fn lattice(p: usize, nx: usize, ny: usize) -> [i64; 3] {
    [(p % nx) as i64, (p / nx % ny) as i64, (p / (nx * ny)) as i64]
}

/// Append the triangles of the surface inside tetrahedron `tet` (sample indices on a grid `nx`
/// by `ny` wide), each as its three crossing edges `(inside sample, outside sample)`, ordered
/// to face outwards.
fn cut(values: &[f64], tet: [usize; 4], nx: usize, ny: usize, out: &mut Vec<[Edge; 3]>) {
    let (ins, outs): (Vec<usize>, Vec<usize>) = tet.iter().partition(|&&p| values[p] < 0.0);
    let mut push = |edges: [Edge; 3]| out.push(facing(edges, nx, ny));
    match (ins.as_slice(), outs.as_slice()) {
        (&[a], &[b, c, d]) => push([(a, b), (a, c), (a, d)]),
        (&[a, b, c], &[d]) => push([(a, d), (b, d), (c, d)]),
        (&[a, b], &[c, d]) => {
            // The crossing edges a–c, a–d, b–d, b–c go round a quadrilateral.
            push([(a, c), (a, d), (b, d)]);
            push([(a, c), (b, d), (b, c)]);
        }
        _ => {}
    }
}

/// The triangle on crossing `edges` wound to face away from the inside: its normal
/// `(p1 - p0) × (p2 - p0)` points away from the first edge's inside end `q`, i.e.
/// `det(p0 - q, p1 - q, p2 - q) > 0`. The vertices move along their edges with the samples,
/// but this sign does not (it is a product of the edge fractions and a fixed determinant of
/// the tetrahedron), so it is decided exactly on the edges' midpoints in doubled lattice
/// coordinates.
fn facing(edges: [Edge; 3], nx: usize, ny: usize) -> [Edge; 3] {
    let q = lattice(edges[0].0, nx, ny).map(|x| 2 * x);
    let mid = |(a, b): Edge| {
        let (a, b) = (lattice(a, nx, ny), lattice(b, nx, ny));
        [0, 1, 2].map(|i| a[i] + b[i] - q[i])
    };
    let [u, v, w] = edges.map(mid);
    let det = u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
        + u[2] * (v[0] * w[1] - v[1] * w[0]);
    if det > 0 {
        edges
    } else {
        [edges[0], edges[2], edges[1]]
    }
}
