//! The fluid's neighbour lists: Verlet lists (Verlet 1967; for SPH, Domínguez, Crespo,
//! Gómez-Gesteira & Marongiu 2011, "Neighbour lists in smoothed particle hydrodynamics",
//! IJNMF 67) over the shared hashed grid (`geometry/grid.rs`).
//!
//! The grid finds, for every query point, the **candidates** closer than `h + skin` (m); the
//! lists of every substep are the candidates closer than `h`. While no point has moved
//! `skin / 2` or more since the candidates were found, no pair can have come closer than `h`
//! without being a candidate, so the candidates are reused; otherwise (or when the points'
//! count changed) the grid is rebuilt. Without a skin the candidates, found by the same test,
//! are the lists (no filter; DFSPH's and PBF's substeps mostly have none). Each candidate list is sorted by index when it is
//! built, so every list holds exactly the points closer than `h` **in ascending index
//! order**, whatever the skin and whenever the candidates were found: results do not depend
//! on the history of the search, nor on the thread count. The lists use the grid's layout
//! (chunks of [`CHUNK`] query points, [`Neighbours::span`]). Buffers only grow.
//!
//! Points that never move (the walls' boundary particles, two thirds of the points of a
//! tank) have a grid of their own, of cells `h (1 + MAX_SKIN)`, built again only when they
//! or `h` change; a rebuild bins the query points and the moving points alone and adds the
//! fixed points' candidates from that grid. The candidates are the same set either way, and
//! sorted, so the lists are too.

use crate::geometry::grid::{Grid, CHUNK};
use glam::DVec3;
use rayon::prelude::*;

/// The largest skin, as a fraction of `h`: the cells of the fixed points' grid are
/// `h (1 + MAX_SKIN)`.
pub const MAX_SKIN: f64 = 0.25;

/// Verlet lists of the fluid (see the module docs).
#[derive(Clone, Debug, Default)]
pub struct Neighbours {
    /// The grid of the query points and the moving points.
    grid: Grid,
    /// Those points (m), the grid's input.
    moving: Vec<DVec3>,
    /// The grid of the fixed points, the points it was built from (m) and its cell size (m).
    fixed_grid: Grid,
    fixed: Vec<DVec3>,
    fixed_cell: f64,
    /// The points of the last grid build (m).
    anchor: Vec<DVec3>,
    /// The query points of the last build.
    queries: usize,
    /// The radius `h` (m) and skin (m) of the last build.
    radius: f64,
    skin: f64,
    /// Candidates of every chunk of query points, each point's sorted by index; a point's
    /// ends at `candidate_ends[i]` in its chunk's buffer.
    candidates: Vec<Vec<u32>>,
    candidate_ends: Vec<u32>,
    /// The lists (closer than `h`), in the same layout.
    lists: Vec<Vec<u32>>,
    ends: Vec<u32>,
}

/// Where the list of query point `i` lies in its chunk's buffer, given the chunk's ends.
fn span(ends: &[u32], i: usize) -> std::ops::Range<usize> {
    let start = if i.is_multiple_of(CHUNK) { 0 } else { ends[i - 1] as usize };
    start..ends[i] as usize
}

impl Neighbours {
    /// Find, for each of the first `queries` of `points`, every other point closer than `h`
    /// (m), in ascending index order. The `fixed` points after the queries do not move (see
    /// the module docs). If the candidates must be found again, they are found within
    /// `h + skin` (m, `0 ≤ skin ≤ MAX_SKIN h`).
    ///
    /// # Panics
    /// If `queries + fixed > points.len()` or there are 2³² points or more (callers check).
    pub fn update(&mut self, points: &[DVec3], queries: usize, fixed: usize, h: f64, skin: f64) {
        if !self.valid(points, queries, h) {
            self.rebuild(points, queries, fixed, h, skin);
            if skin == 0.0 {
                // The candidates within `h + 0` are the lists, by the same test: no filter.
                // (The next update rebuilds: no point can move less than 0.)
                std::mem::swap(&mut self.lists, &mut self.candidates);
                std::mem::swap(&mut self.ends, &mut self.candidate_ends);
                return;
            }
        }
        let (h2, candidates, candidate_ends) = (h * h, &self.candidates, &self.candidate_ends);
        self.ends.resize(queries, 0);
        self.lists.resize_with(queries.div_ceil(CHUNK), Vec::new);
        let chunks = self.ends.par_chunks_mut(CHUNK).zip(&mut self.lists);
        chunks.zip(candidates).enumerate().for_each(|(c, ((ends, list), near))| {
            // Without a branch (half the candidates are in, in no pattern): every candidate
            // is written, the end advances past the near ones. The buffer holds at least the
            // chunk's candidates and is never shortened (no fill at each update); what lies
            // past the last end is stale.
            if list.len() < near.len() {
                list.resize(near.len(), 0);
            }
            let mut len = 0;
            for (k, end) in ends.iter_mut().enumerate() {
                let i = c * CHUNK + k;
                let p = points[i];
                for &j in &near[span(candidate_ends, i)] {
                    list[len] = j;
                    len += usize::from((points[j as usize] - p).length_squared() < h2);
                }
                // At most `CHUNK` times the points (< 2³² / CHUNK in any real use).
                *end = len as u32;
            }
        });
    }

    /// The candidates of the last build still hold every pair closer than `h`: the same
    /// points, queries and radius, and no point moved `skin / 2` or more since.
    fn valid(&self, points: &[DVec3], queries: usize, h: f64) -> bool {
        let limit = 0.25 * self.skin * self.skin;
        self.queries == queries
            && self.radius == h
            && self.anchor.len() == points.len()
            && points.par_iter().zip(&self.anchor).all(|(p, a)| (*p - *a).length_squared() < limit)
    }

    /// Find the candidates within `h + skin` and sort each point's by index.
    fn rebuild(&mut self, points: &[DVec3], queries: usize, fixed: usize, h: f64, skin: f64) {
        debug_assert!((0.0..=MAX_SKIN * h).contains(&skin), "skin {skin} for h {h}");
        let (walls, cell) = (&points[queries..queries + fixed], h * (1.0 + MAX_SKIN));
        if self.fixed_cell != cell || self.fixed != walls {
            self.fixed_grid.build(walls, 0, cell);
            self.fixed.clear();
            self.fixed.extend_from_slice(walls);
            self.fixed_cell = cell;
        }
        self.moving.clear();
        self.moving.extend_from_slice(&points[..queries]);
        self.moving.extend_from_slice(&points[queries + fixed..]);
        self.grid.build(&self.moving, queries, h + skin);
        self.anchor.clear();
        self.anchor.extend_from_slice(points);
        (self.queries, self.radius, self.skin) = (queries, h, skin);
        self.candidate_ends.resize(queries, 0);
        self.candidates.resize_with(queries.div_ceil(CHUNK), Vec::new);
        let (grid, fixed_grid, chunks) =
            (&self.grid, &self.fixed_grid, self.candidate_ends.par_chunks_mut(CHUNK));
        // Indices in `moving` past the queries, and in `fixed`, to indices in `points`.
        let (q, f) = (queries as u32, fixed as u32);
        chunks.zip(&mut self.candidates).enumerate().for_each(|(c, (ends, list))| {
            list.clear();
            for (k, end) in ends.iter_mut().enumerate() {
                let (i, start) = (c * CHUNK + k, list.len());
                list.extend(grid.neighbours(i).iter().map(|&j| if j < q { j } else { j + f }));
                let from = list.len();
                fixed_grid.within(points[i], h + skin, list);
                list[from..].iter_mut().for_each(|j| *j += q);
                list[start..].sort_unstable();
                *end = list.len() as u32;
            }
        });
    }

    /// Where the list of query point `i` lies in the buffer of its chunk `i / CHUNK`, so
    /// callers can keep per-pair data in buffers of the same layout.
    pub fn span(&self, i: usize) -> std::ops::Range<usize> {
        span(&self.ends, i)
    }

    /// The neighbours of query point `i` (indices into the points of the last update).
    pub fn neighbours(&self, i: usize) -> &[u32] {
        &self.lists[i / CHUNK][self.span(i)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::grid::random_points;

    fn brute_force(points: &[DVec3], i: usize, h: f64) -> Vec<u32> {
        let near = |j: &usize| *j != i && (points[*j] - points[i]).length_squared() < h * h;
        (0..points.len()).filter(near).map(|j| j as u32).collect()
    }

    /// Every list is exactly the brute force's (ascending) after moves under half the skin
    /// (the candidates reused), after moves over it (found again), and after the fixed
    /// points moved too (their grid built again).
    #[test]
    fn lists_are_exact_and_ascending_with_reused_candidates() {
        let (h, skin, queries, fixed) = (0.08, 0.02, 2500, 300);
        let mut points = random_points(3000, 5, 1.0);
        let mut near = Neighbours::default();
        near.update(&points, queries, fixed, h, skin);
        let built = near.anchor.clone();
        let mut total = 0;
        // Each point moves `fraction` of the skin in a direction of its own; the fixed
        // points `queries..queries + fixed` only in the last round.
        for (round, fraction) in [0.49, 0.49, 0.9, 0.9].into_iter().enumerate() {
            let directions = random_points(points.len(), 20 + round as u64, 2.0);
            for (i, (p, d)) in points.iter_mut().zip(directions).enumerate() {
                if round == 3 || !(queries..queries + fixed).contains(&i) {
                    *p += d.normalize_or_zero() * (fraction * skin);
                }
            }
            let reused = round == 0;
            near.update(&points, queries, fixed, h, skin);
            assert_eq!(near.anchor == built, reused, "round {round}");
            assert_eq!(near.fixed, points[queries..queries + fixed], "round {round}");
            for i in 0..queries {
                assert_eq!(near.neighbours(i), brute_force(&points, i, h), "round {round}, {i}");
                total += near.neighbours(i).len();
            }
        }
        assert!(total > 4 * queries * 5, "too few neighbours to test: {total}");
    }

    /// Without a skin the candidates are taken as the lists: exact after a build with a skin
    /// or without, and a later build with a skin (or without) is exact again. Every round
    /// moves the points more than the skin, so every update builds again.
    #[test]
    fn lists_are_exact_without_a_skin() {
        let (h, queries, fixed) = (0.08, 2500, 300);
        let mut points = random_points(3000, 7, 1.0);
        let mut near = Neighbours::default();
        for (round, skin) in [0.0, 0.02, 0.0, 0.0, 0.02, 0.02].into_iter().enumerate() {
            let directions = random_points(points.len(), 40 + round as u64, 2.0);
            for (i, (p, d)) in points.iter_mut().zip(directions).enumerate() {
                if !(queries..queries + fixed).contains(&i) {
                    *p += d.normalize_or_zero() * 0.03;
                }
            }
            near.update(&points, queries, fixed, h, skin);
            for i in 0..queries {
                assert_eq!(near.neighbours(i), brute_force(&points, i, h), "round {round}, {i}");
            }
        }
    }

    #[test]
    fn same_lists_on_one_and_two_threads() {
        let points = random_points(5000, 11, 1.0);
        let lists = |threads| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| {
                let mut near = Neighbours::default();
                near.update(&points, 4000, 0, 0.07, 0.01);
                (near.ends.clone(), near.lists.clone())
            })
        };
        assert_eq!(lists(1), lists(2));
    }
}
