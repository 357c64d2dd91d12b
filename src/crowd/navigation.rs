//! The global layer of a crowd: a visibility graph (roadmap) over the obstacles' convex
//! vertices pushed out by a clearance, searched by A* (Hart, Nilsson & Raphael 1968) so that
//! agents get preferred velocities towards their goals around walls (the global layer of
//! van den Berg et al. 2011, §7, where a roadmap gives each agent its next waypoint).
//!
//! Shortest paths among polygons bend only at convex vertices (Lozano-Pérez & Wesley 1979),
//! so the roadmap's nodes are those vertices moved out by the clearance `c`: a convex corner
//! whose outward normals `n₁, n₂` meet at 90° or less gets the miter point
//! `p + c (n₁ + n₂) / (1 + n₁·n₂)`; a sharper corner (and a wall segment's end) gets two,
//! `p + c (n₁ + e₁)` and `p + c (n₂ - e₂)` with `e₁, e₂` the directions of the incoming and
//! outgoing edges, so the inflated obstacle is the polygon offset by `c` with its sharp
//! corners cut square. Two points see each other when the segment between them keeps at
//! least `c` from every obstacle edge; a start or goal nearer than `c` to an obstacle relaxes
//! this to its own distance for its edges. Each step every agent's next waypoint is the first
//! node of its shortest path (re-planned from where it is), or its goal when it sees it.

use super::orca::segment_distance2;
use super::Model;
use glam::DVec2;

/// Relative tolerance on the clearance (a path may run exactly at `c` along an edge).
const SLACK: f64 = 1e-9;

/// A roadmap: nodes and the visible pairs between them (see the module docs).
#[derive(serde::Serialize, serde::Deserialize, Clone, Debug, PartialEq)]
pub struct Roadmap {
    /// Distance the paths keep from obstacles (m).
    clearance: f64,
    /// Node positions (m).
    nodes: Vec<DVec2>,
    /// Start of each node's neighbours in `edges` (one more entry than nodes).
    offsets: Vec<u32>,
    /// Visible neighbours `(node, distance in m)`, grouped by node.
    edges: Vec<(u32, f64)>,
}

/// The A* workspace of one query (reused, so queries allocate nothing once grown).
#[derive(Clone, Debug, Default)]
pub(super) struct Search {
    /// Cost of the best path found so far to each node, then the goal (m).
    cost: Vec<f64>,
    /// Previous node on that path (`START` for the start).
    parent: Vec<u32>,
    /// Whether the node was expanded.
    closed: Vec<bool>,
}

/// The parent of nodes reached straight from the start.
const START: u32 = u32::MAX;

/// The distance² between segments `ab` and `cd` (0 when they cross).
fn segments_distance2(a: DVec2, b: DVec2, c: DVec2, d: DVec2) -> f64 {
    let (r, s) = (b - a, d - c);
    let denom = r.perp_dot(s);
    if denom != 0.0 {
        let t = (c - a).perp_dot(s) / denom;
        let u = (c - a).perp_dot(r) / denom;
        if (0.0..=1.0).contains(&t) && (0.0..=1.0).contains(&u) {
            return 0.0;
        }
    }
    segment_distance2(a, c, d)
        .min(segment_distance2(b, c, d))
        .min(segment_distance2(c, a, b))
        .min(segment_distance2(d, a, b))
}

impl Model {
    /// The distance (m) from `p` to the nearest obstacle edge (infinite without obstacles).
    pub(super) fn obstacle_distance(&self, p: DVec2) -> f64 {
        self.vertices
            .iter()
            .map(|v| segment_distance2(p, v.point, self.vertices[v.next as usize].point))
            .fold(f64::INFINITY, f64::min)
            .sqrt()
    }

    /// Whether the segment `ab` keeps at least `clearance` (m, less the tolerance) from
    /// every obstacle edge.
    fn sees(&self, a: DVec2, b: DVec2, clearance: f64) -> bool {
        let min2 = (clearance * (1.0 - SLACK)).powi(2);
        self.vertices.iter().all(|v| {
            segments_distance2(a, b, v.point, self.vertices[v.next as usize].point) >= min2
        })
    }
}

impl Roadmap {
    /// The roadmap of `model`'s obstacles for paths keeping `clearance` (m) from them.
    pub(super) fn new(model: &Model, clearance: f64) -> Self {
        let c = clearance;
        let right = |d: DVec2| DVec2::new(d.y, -d.x);
        let mut nodes = Vec::new();
        for v in model.vertices.iter().filter(|v| v.convex) {
            let (e1, e2) = (model.vertices[v.previous as usize].direction, v.direction);
            let (n1, n2) = (right(e1), right(e2));
            let cos = n1.dot(n2);
            if cos >= 0.0 {
                nodes.push(v.point + c * (n1 + n2) / (1.0 + cos));
            } else {
                nodes.push(v.point + c * (n1 + e1));
                nodes.push(v.point + c * (n2 - e2));
            }
        }
        nodes.retain(|&p| model.obstacle_distance(p) >= c * (1.0 - SLACK));
        let mut offsets = vec![0];
        let mut edges = Vec::new();
        for (i, &a) in nodes.iter().enumerate() {
            for (j, &b) in nodes.iter().enumerate() {
                if i != j && model.sees(a, b, c) {
                    edges.push((j as u32, (b - a).length()));
                }
            }
            offsets.push(edges.len() as u32);
        }
        Roadmap { clearance, nodes, offsets, edges }
    }

    /// The clearance (m).
    pub fn clearance(&self) -> f64 {
        self.clearance
    }

    /// The node positions (m).
    pub fn nodes(&self) -> &[DVec2] {
        &self.nodes
    }

    /// The shortest path from `from` to `to` (m): its nodes after `from`, ending with `to`,
    /// or `None` when the roadmap does not connect them.
    pub fn path(&self, model: &Model, from: DVec2, to: DVec2) -> Option<Vec<DVec2>> {
        let mut search = Search::default();
        let last = self.search(model, from, to, &mut search)?;
        let mut path = vec![to];
        let mut k = last;
        while k != START {
            path.push(self.nodes[k as usize]);
            k = search.parent[k as usize];
        }
        path.reverse();
        Some(path)
    }

    /// The next waypoint of an agent at `from` walking to `to` (m): the first node of its
    /// shortest path not yet reached (closer than half the clearance), or `to` itself when
    /// it sees it or when no path connects them (the agent then walks straight to its goal,
    /// as without navigation).
    pub(super) fn waypoint(
        &self,
        model: &Model,
        from: DVec2,
        to: DVec2,
        search: &mut Search,
    ) -> DVec2 {
        let Some(mut k) = self.search(model, from, to, search) else { return to };
        let mut after = to;
        if k == START {
            return to;
        }
        while search.parent[k as usize] != START {
            after = self.nodes[k as usize];
            k = search.parent[k as usize];
        }
        let first = self.nodes[k as usize];
        if (first - from).length() < 0.5 * self.clearance {
            after
        } else {
            first
        }
    }

    /// A* from `from` to `to`: the last node before `to` on the shortest path (`START` when
    /// `to` is seen directly), its predecessors in `search.parent`; `None` if unreachable.
    fn search(&self, model: &Model, from: DVec2, to: DVec2, search: &mut Search) -> Option<u32> {
        let c = self.clearance;
        let (c_from, c_to) =
            (c.min(model.obstacle_distance(from)), c.min(model.obstacle_distance(to)));
        if model.sees(from, to, c_from.min(c_to)) {
            return Some(START);
        }
        let n = self.nodes.len();
        let goal = n;
        search.cost.clear();
        search.cost.resize(n + 1, f64::INFINITY);
        search.parent.clear();
        search.parent.resize(n + 1, START);
        search.closed.clear();
        search.closed.resize(n + 1, false);
        for (k, &p) in self.nodes.iter().enumerate() {
            if model.sees(from, p, c_from) {
                search.cost[k] = (p - from).length();
            }
        }
        let estimate = |k: usize| if k == goal { 0.0 } else { (to - self.nodes[k]).length() };
        loop {
            // The open node of least estimated total cost (ties: the lowest index).
            let mut best: Option<(f64, usize)> = None;
            for k in 0..=n {
                if !search.closed[k] && search.cost[k].is_finite() {
                    let f = search.cost[k] + estimate(k);
                    if best.is_none_or(|(bf, _)| f < bf) {
                        best = Some((f, k));
                    }
                }
            }
            let (_, u) = best?;
            if u == goal {
                return Some(search.parent[goal]);
            }
            search.closed[u] = true;
            let (p, g) = (self.nodes[u], search.cost[u]);
            let range = self.offsets[u] as usize..self.offsets[u + 1] as usize;
            for &(v, w) in &self.edges[range] {
                let v = v as usize;
                if !search.closed[v] && g + w < search.cost[v] {
                    search.cost[v] = g + w;
                    search.parent[v] = u as u32;
                }
            }
            let through = g + (to - p).length();
            if through < search.cost[goal] && model.sees(p, to, c_to) {
                search.cost[goal] = through;
                search.parent[goal] = u as u32;
            }
        }
    }
}
