//! A static bounding volume hierarchy of a triangle mesh for segment queries: does a segment
//! meet the surface? (The visibility test of bone-heat weights, Baran & Popović 2007, §4.)
//!
//! A binary tree of axis-aligned boxes, built once by median splits of the triangles' centres
//! along the longest axis of their bounds (leaves of at most [`LEAF`] triangles). A query
//! descends into the boxes the segment crosses (the slab test, on boxes padded by a relative
//! [`PAD`] so that rounding cannot lose a triangle the segment touches) and decides each
//! candidate triangle exactly ([`segment_meets_triangle`]).

use super::triangle::segment_meets_triangle;
use glam::DVec3;

/// Most triangles in a leaf.
const LEAF: usize = 4;

/// Boxes are grown by this fraction of the mesh's bounding-box diagonal on every side.
const PAD: f64 = 1e-9;

/// A node: its box, and its triangles (`order[start..start + count]`, a leaf) or, when
/// `count = 0`, its children at `index + 1` and `right`.
#[derive(Clone, Copy, Debug)]
struct Node {
    lo: DVec3,
    hi: DVec3,
    start: usize,
    count: usize,
    right: usize,
}

/// The tree of a triangle mesh (see the module docs).
#[derive(Clone, Debug)]
pub struct TriangleTree {
    nodes: Vec<Node>,
    /// Triangle indices, leaf by leaf.
    order: Vec<usize>,
    /// The corners of every triangle, in the mesh's order.
    corners: Vec<[DVec3; 3]>,
}

impl TriangleTree {
    /// The tree of `triangles` (indices into `vertices`, all in range; any units).
    pub fn new(vertices: &[[f64; 3]], triangles: &[[u32; 3]]) -> TriangleTree {
        let corners: Vec<[DVec3; 3]> =
            triangles.iter().map(|t| t.map(|v| DVec3::from_array(vertices[v as usize]))).collect();
        let (lo, hi) = bounds(corners.iter().flatten().copied());
        let pad = DVec3::splat(PAD * (hi - lo).length());
        let mut tree = TriangleTree {
            nodes: Vec::with_capacity(2 * triangles.len() / LEAF + 1),
            order: (0..triangles.len()).collect(),
            corners,
        };
        let centres: Vec<DVec3> = tree.corners.iter().map(|c| (c[0] + c[1] + c[2]) / 3.0).collect();
        tree.split(&centres, 0, triangles.len(), pad);
        tree
    }

    /// Build the node of `order[start..end]` and its descendants; returns its index.
    fn split(&mut self, centres: &[DVec3], start: usize, end: usize, pad: DVec3) -> usize {
        let (lo, hi) = bounds(self.order[start..end].iter().flat_map(|&t| self.corners[t]));
        let index = self.nodes.len();
        self.nodes.push(Node { lo: lo - pad, hi: hi + pad, start, count: end - start, right: 0 });
        if end - start <= LEAF {
            return index;
        }
        let (clo, chi) = bounds(self.order[start..end].iter().map(|&t| centres[t]));
        let extent = chi - clo;
        let axis = if extent.x >= extent.y && extent.x >= extent.z {
            0
        } else if extent.y >= extent.z {
            1
        } else {
            2
        };
        let mid = (start + end) / 2;
        self.order[start..end].select_nth_unstable_by(mid - start, |&a, &b| {
            centres[a][axis].total_cmp(&centres[b][axis]).then(a.cmp(&b))
        });
        self.split(centres, start, mid, pad);
        let right = self.split(centres, mid, end, pad);
        self.nodes[index].count = 0;
        self.nodes[index].right = right;
        index
    }

    /// Whether the closed segment `[a, b]` meets a triangle `t` of the mesh for which
    /// `skip(t)` is false (e.g. the triangles at the vertex the segment starts from).
    pub fn segment_hits(&self, a: DVec3, b: DVec3, skip: impl Fn(usize) -> bool) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let mut stack = vec![0usize];
        while let Some(k) = stack.pop() {
            let node = &self.nodes[k];
            if !segment_meets_box(a, b, node.lo, node.hi) {
                continue;
            }
            if node.count == 0 {
                stack.push(node.right);
                stack.push(k + 1);
                continue;
            }
            let leaf = &self.order[node.start..node.start + node.count];
            if leaf.iter().any(|&t| !skip(t) && segment_meets_triangle(a, b, self.corners[t])) {
                return true;
            }
        }
        false
    }
}

/// The bounding box of `points` (`(+∞, −∞)` for none).
fn bounds(points: impl Iterator<Item = DVec3>) -> (DVec3, DVec3) {
    points.fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| (lo.min(p), hi.max(p)))
}

/// Whether the segment `[a, b]` meets the box `[lo, hi]` (the slab test).
fn segment_meets_box(a: DVec3, b: DVec3, lo: DVec3, hi: DVec3) -> bool {
    let d = b - a;
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for axis in 0..3 {
        if d[axis] == 0.0 {
            if a[axis] < lo[axis] || a[axis] > hi[axis] {
                return false;
            }
            continue;
        }
        let (u, v) = ((lo[axis] - a[axis]) / d[axis], (hi[axis] - a[axis]) / d[axis]);
        t0 = t0.max(u.min(v));
        t1 = t1.min(u.max(v));
        if t0 > t1 {
            return false;
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every segment between random points agrees with testing every triangle.
    #[test]
    fn the_tree_answers_as_testing_every_triangle() {
        let mut seed = 7u64;
        let mut rand = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let vertices: Vec<[f64; 3]> = (0..300).map(|_| [rand(), rand(), rand()]).collect();
        let triangles: Vec<[u32; 3]> = (0..100).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
        let tree = TriangleTree::new(&vertices, &triangles);
        let (mut hits, mut misses) = (0, 0);
        for _ in 0..2000 {
            let a = DVec3::new(rand(), rand(), rand());
            let b = a + 0.3 * (DVec3::new(rand(), rand(), rand()) - 0.5);
            let skip = |t: usize| t.is_multiple_of(7);
            let brute = (0..triangles.len())
                .any(|t| !skip(t) && segment_meets_triangle(a, b, tree.corners[t]));
            assert_eq!(tree.segment_hits(a, b, skip), brute);
            if brute {
                hits += 1;
            } else {
                misses += 1;
            }
        }
        assert!(hits > 100 && misses > 100, "{hits} hits, {misses} misses");
    }
}
