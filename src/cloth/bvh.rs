//! The bounding volume hierarchy of self-collision's broad phase: a binary tree of axis-aligned
//! boxes over the triangles, built once from the mesh (median splits along the longest axis of
//! the triangles' centres in the initial shape) and refit every step bottom-up from the boxes
//! of the triangles' swept motion (Bridson, Fedkiw & Anderson 2002, §6.1: refitting keeps the
//! tree valid as the cloth deforms, at a fraction of a rebuild's cost). The self-query walks
//! the tree against itself and reports each pair of triangles whose boxes overlap once; the
//! cross-query does the same between the cloth's tree and the mesh colliders' one, and the
//! ray query lists the triangles whose boxes a ray along `+x` meets (the mesh colliders'
//! inside test).

use glam::DVec3;

/// A node: its box (m) and either one triangle (a leaf) or two children.
#[derive(Clone, Copy, Debug)]
struct Node {
    lo: DVec3,
    hi: DVec3,
    /// A leaf's triangle, or `usize::MAX` for an inner node.
    triangle: usize,
    /// An inner node's children (indices into the node list, both after the node).
    children: [usize; 2],
}

/// The tree (see the module documentation). Refitting, rebuilding and querying allocate
/// nothing once the buffers have grown to the largest mesh and result.
#[derive(Debug, Default)]
pub(super) struct Bvh {
    /// Nodes, each after its parent (so a reverse pass refits children before parents).
    nodes: Vec<Node>,
    /// The traversal stack of the queries.
    stack: Vec<(usize, usize)>,
    /// The triangles' centres and order, the work of a build.
    centres: Vec<DVec3>,
    order: Vec<usize>,
}

impl Bvh {
    /// The tree of `triangles` (at least one) on the vertex `positions` (m) of the initial
    /// shape.
    pub(super) fn new(positions: &[DVec3], triangles: &[[usize; 3]]) -> Bvh {
        let mut bvh = Bvh { stack: Vec::with_capacity(256), ..Bvh::default() };
        bvh.build(positions, triangles);
        bvh
    }

    /// Build the tree anew for `triangles` (at least one) on `positions` (m), reusing the
    /// buffers (the mesh colliders' tree is rebuilt every step: their triangles may be
    /// deformed by any animation, and a tree built from the state alone keeps a step
    /// independent of the steps before it).
    pub(super) fn build(&mut self, positions: &[DVec3], triangles: &[[usize; 3]]) {
        self.centres.clear();
        self.centres.extend(
            triangles.iter().map(|t| (positions[t[0]] + positions[t[1]] + positions[t[2]]) / 3.0),
        );
        self.order.clear();
        self.order.extend(0..triangles.len());
        self.nodes.clear();
        split(&self.centres, &mut self.order, &mut self.nodes);
    }

    /// Refit every box to the triangles' vertices at `x0` and `x1` (the step's start and end;
    /// pass the same slice twice for a static box), grown by `margin` (m) on every side.
    pub(super) fn refit(
        &mut self,
        triangles: &[[usize; 3]],
        x0: &[DVec3],
        x1: &[DVec3],
        margin: f64,
    ) {
        let pad = DVec3::splat(margin);
        for k in (0..self.nodes.len()).rev() {
            let node = self.nodes[k];
            let (lo, hi) = if node.triangle != usize::MAX {
                let t = triangles[node.triangle];
                let mut lo = x0[t[0]].min(x1[t[0]]);
                let mut hi = x0[t[0]].max(x1[t[0]]);
                for &v in &t[1..] {
                    lo = lo.min(x0[v]).min(x1[v]);
                    hi = hi.max(x0[v]).max(x1[v]);
                }
                (lo - pad, hi + pad)
            } else {
                let [a, b] = node.children.map(|c| self.nodes[c]);
                (a.lo.min(b.lo), a.hi.max(b.hi))
            };
            self.nodes[k].lo = lo;
            self.nodes[k].hi = hi;
        }
    }

    /// Call `pair(i, j)` for every pair of distinct triangles `i`, `j` whose boxes overlap,
    /// each pair once, in an order fixed by the tree.
    pub(super) fn self_pairs(&mut self, mut pair: impl FnMut(usize, usize)) {
        self.stack.clear();
        self.stack.push((0, 0));
        while let Some((a, b)) = self.stack.pop() {
            let (na, nb) = (self.nodes[a], self.nodes[b]);
            if a != b && !(na.lo.cmple(nb.hi).all() && nb.lo.cmple(na.hi).all()) {
                continue;
            }
            match (na.triangle != usize::MAX, nb.triangle != usize::MAX) {
                (true, true) => {
                    if a != b {
                        pair(na.triangle, nb.triangle);
                    }
                }
                (true, false) => self.stack.extend(nb.children.map(|c| (a, c))),
                (false, true) => self.stack.extend(na.children.map(|c| (c, b))),
                (false, false) if a == b => {
                    let [l, r] = na.children;
                    self.stack.extend([(l, l), (l, r), (r, r)]);
                }
                (false, false) => {
                    let [l, r] = na.children;
                    self.stack.extend([(l, b), (r, b)]);
                }
            }
        }
    }
}

impl Bvh {
    /// Call `pair(i, j)` for every triangle `i` of this tree and `j` of `other` whose boxes
    /// overlap, each pair once, in an order fixed by the two trees.
    pub(super) fn pairs_with(&mut self, other: &Bvh, mut pair: impl FnMut(usize, usize)) {
        self.stack.clear();
        self.stack.push((0, 0));
        while let Some((a, b)) = self.stack.pop() {
            let (na, nb) = (self.nodes[a], other.nodes[b]);
            if !(na.lo.cmple(nb.hi).all() && nb.lo.cmple(na.hi).all()) {
                continue;
            }
            match (na.triangle != usize::MAX, nb.triangle != usize::MAX) {
                (true, true) => pair(na.triangle, nb.triangle),
                (true, false) => self.stack.extend(nb.children.map(|c| (a, c))),
                (false, _) => self.stack.extend(na.children.map(|c| (c, b))),
            }
        }
    }
}

impl Bvh {
    /// Call `hit(j)` for every triangle `j` whose box (as last refit) meets the ray from `p`
    /// along `+x`, in an order fixed by the tree.
    pub(super) fn ray_x(&mut self, p: DVec3, mut hit: impl FnMut(usize)) {
        self.stack.clear();
        self.stack.push((0, 0));
        while let Some((k, _)) = self.stack.pop() {
            let node = self.nodes[k];
            let meets = p.x <= node.hi.x
                && (node.lo.y..=node.hi.y).contains(&p.y)
                && (node.lo.z..=node.hi.z).contains(&p.z);
            if !meets {
                continue;
            }
            if node.triangle != usize::MAX {
                hit(node.triangle);
            } else {
                self.stack.extend(node.children.map(|c| (c, 0)));
            }
        }
    }
}

/// Append the subtree of the triangles `order` (their `centres`) to `nodes`; returns its root.
fn split(centres: &[DVec3], order: &mut [usize], nodes: &mut Vec<Node>) -> usize {
    let k = nodes.len();
    nodes.push(Node { lo: DVec3::ZERO, hi: DVec3::ZERO, triangle: usize::MAX, children: [0, 0] });
    if order.len() == 1 {
        nodes[k].triangle = order[0];
        return k;
    }
    let (lo, hi) = order.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &t| {
        (lo.min(centres[t]), hi.max(centres[t]))
    });
    let extent = hi - lo;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let mid = order.len() / 2;
    order.select_nth_unstable_by(mid, |&i, &j| {
        centres[i][axis].total_cmp(&centres[j][axis]).then(i.cmp(&j))
    });
    let (left, right) = order.split_at_mut(mid);
    let l = split(centres, left, nodes);
    let r = split(centres, right, nodes);
    nodes[k].children = [l, r];
    k
}
