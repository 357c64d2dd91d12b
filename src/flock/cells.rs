//! The boids sorted by grid cell, for a sweep over each boid's neighbours without neighbour
//! lists. Cells have the size of the neighbour radius `h`, so a boid's neighbours lie in its
//! own and the adjacent cells (9 in one layer of cells along z, as 2-D flocks, else 27;
//! Green 2008, "Particle simulation using CUDA", for sorting particles by cell).
//!
//! A cell `c` is numbered row by row over the cells' bounding box widened by one cell on
//! each side, `x` fastest: `(c_x - o_x) + W ((c_y - o_y) + H (c_z - o_z))` (wrapping), and
//! its bucket is that number modulo a power-of-two table of at least the box's cells, at most
//! about `2N` buckets. For a flock filling its box no two cells share a bucket ("dense"); for a
//! sparse one (a boid far away) they may, and every candidate's cell is checked. The three cells of
//! a row `x - 1, x, x + 1` have consecutive buckets (modulo the table), so their boids are one
//! contiguous range (two when the row wraps round the table's end). Boids are ordered by
//! bucket, and by index within a bucket, so the order depends on the positions alone, not on
//! the thread count nor on the steps before; a boid's neighbours are then read from a few
//! contiguous ranges, and consecutive boids read nearly the same ones.
//!
//! The positions and velocities live here in that order for all the steps of one
//! [`super::Solver::step`] call ([`Cells::load`] from the state, [`Cells::store`] back): each
//! step re-sorts them from the previous step's order, which is nearly the new one (boids move
//! less than a cell a step), so the counting sort and the copy into the new order read
//! memory nearly in sequence instead of at random (Green 2008 keeps particles sorted the same
//! way). Buffers only grow.

use crate::geometry::grid::{cell_of, sort_by_bucket};
use glam::DVec3;
use rayon::prelude::*;

/// Boids sorted by cell (see the module docs).
#[derive(Clone, Debug, Default)]
pub(super) struct Cells {
    /// The boid in each sorted slot.
    pub(super) order: Vec<u32>,
    /// The sorted slot of each boid (the inverse of `order`).
    pub(super) rank: Vec<u32>,
    /// Positions in sorted order (m).
    pub(super) positions: Vec<DVec3>,
    /// Velocities in sorted order (m/s).
    pub(super) velocities: Vec<DVec3>,
    /// Cells in sorted order.
    cells: Vec<[i64; 3]>,
    /// Scratch of a sort: the cell and the bucket of each slot before it, the slot each new
    /// slot comes from, and the buffers of the new order (swapped with the ones above).
    cell: Vec<[i64; 3]>,
    bucket: Vec<u32>,
    from: Vec<u32>,
    next_order: Vec<u32>,
    next_positions: Vec<DVec3>,
    next_velocities: Vec<DVec3>,
    /// Start of each bucket in the sorted order (`buckets + 1` entries).
    start: Vec<u32>,
    /// The widened box's lowest cell.
    origin: [i64; 3],
    /// Cells of the widened box along x and along x and y (`W`, `W H`).
    stride: [u64; 2],
    /// Buckets minus one (a power of two minus one).
    mask: u64,
    /// Squared neighbour radius (m²).
    h2: f64,
    /// Every boid lies in one layer of cells along z: only that layer is visited.
    planar: bool,
    /// Every boid has the first one's `z` and a zero velocity `z` (a 2-D flock).
    flat: bool,
    /// The widened box has at most as many cells as there are buckets: one cell a bucket.
    dense: bool,
}

impl Cells {
    /// Take the boids at `positions` flying at `velocities`, in index order (not yet sorted).
    ///
    /// # Panics
    /// If the slices differ in length or hold 2³² boids or more (callers check).
    pub(super) fn load(&mut self, positions: &[DVec3], velocities: &[DVec3]) {
        let n = positions.len();
        assert!(velocities.len() == n && n < u32::MAX as usize);
        self.positions.clear();
        self.positions.extend_from_slice(positions);
        self.velocities.clear();
        self.velocities.extend_from_slice(velocities);
        self.order.clear();
        self.order.extend(0..n as u32);
        self.rank.clone_from(&self.order);
    }

    /// Write the boids back to `positions` and `velocities` in index order.
    pub(super) fn store(&self, positions: &mut [DVec3], velocities: &mut [DVec3]) {
        (positions, velocities, &self.rank).into_par_iter().for_each(|(p, v, &s)| {
            (*p, *v) = (self.positions[s as usize], self.velocities[s as usize]);
        });
    }

    /// Sort the boids into cells of size `h` (m), from the order they are in.
    pub(super) fn sort(&mut self, h: f64) {
        let n = self.positions.len();
        let inv_h = 1.0 / h;
        self.h2 = h * h;
        self.cell.resize(n, [0; 3]);
        self.cell.par_iter_mut().zip(&self.positions).for_each(|(c, p)| *c = cell_of(*p, inv_h));
        let (lo, hi) = self
            .cell
            .par_iter()
            .fold_with(([i64::MAX; 3], [i64::MIN; 3]), |(lo, hi), c| {
                (std::array::from_fn(|k| lo[k].min(c[k])), std::array::from_fn(|k| hi[k].max(c[k])))
            })
            .reduce(
                || ([i64::MAX; 3], [i64::MIN; 3]),
                |a, b| {
                    (
                        std::array::from_fn(|k| a.0[k].min(b.0[k])),
                        std::array::from_fn(|k| a.1[k].max(b.1[k])),
                    )
                },
            );
        self.planar = n == 0 || lo[2] == hi[2];
        let z = self.positions.first().map_or(0.0, |p| p.z);
        self.flat = self.planar
            && (&self.positions, &self.velocities)
                .into_par_iter()
                .all(|(p, v)| p.z == z && v.z == 0.0);
        // The box widened by one cell each side; its extents in wrapping arithmetic (exact
        // for any flock whose box has fewer than 2⁶⁴ cells).
        self.origin = std::array::from_fn(|k| lo[k].wrapping_sub(1));
        let extent: [u64; 3] =
            std::array::from_fn(|k| (hi[k].wrapping_sub(lo[k]) as u64).wrapping_add(3));
        self.stride = [extent[0], extent[0].wrapping_mul(extent[1])];
        let boxed = [extent[0], extent[1], if self.planar { 1 } else { extent[2] }]
            .iter()
            .try_fold(1u64, |a, &e| a.checked_mul(e))
            .unwrap_or(u64::MAX);
        let buckets = (boxed.min(2 * n as u64).max(4) as usize).next_power_of_two();
        self.mask = buckets as u64 - 1;
        self.dense = boxed <= buckets as u64;
        let mut bucket = std::mem::take(&mut self.bucket);
        bucket.resize(n, 0);
        let this = &*self;
        bucket.par_iter_mut().zip(&this.cell).for_each(|(b, c)| *b = this.bucket_of(*c));
        self.bucket = bucket;
        // Stable by the slot before: within a bucket still in the previous order, which was by
        // index; a boid that changed bucket is moved into place by index (a few swaps).
        sort_by_bucket(&self.bucket, buckets, &mut self.start, &mut self.from, |_, _| {});
        let (order, from) = (&self.order, &self.from);
        self.next_order.resize(n, 0);
        self.next_order.par_iter_mut().zip(from).for_each(|(o, &f)| *o = order[f as usize]);
        let (next, from, bucket) = (&mut self.next_order, &mut self.from, &self.bucket);
        for k in 1..n {
            let mut j = k;
            while j > 0
                && bucket[from[j - 1] as usize] == bucket[from[j] as usize]
                && next[j - 1] > next[j]
            {
                next.swap(j - 1, j);
                from.swap(j - 1, j);
                j -= 1;
            }
        }
        self.next_positions.resize(n, DVec3::ZERO);
        self.next_velocities.resize(n, DVec3::ZERO);
        self.cells.resize(n, [0; 3]);
        let (p, v, c) = (&self.positions, &self.velocities, &self.cell);
        (&mut self.next_positions, &mut self.next_velocities, &mut self.cells)
            .into_par_iter()
            .zip(&self.from)
            .for_each(|((np, nv, nc), &f)| {
                let f = f as usize;
                (*np, *nv, *nc) = (p[f], v[f], c[f]);
            });
        std::mem::swap(&mut self.positions, &mut self.next_positions);
        std::mem::swap(&mut self.velocities, &mut self.next_velocities);
        std::mem::swap(&mut self.order, &mut self.next_order);
        for (s, &i) in self.order.iter().enumerate() {
            self.rank[i as usize] = s as u32;
        }
    }

    /// Squared neighbour radius (m²).
    pub(super) fn h2(&self) -> f64 {
        self.h2
    }

    /// Whether every boid has the first one's `z` and a zero velocity `z` (a 2-D flock).
    pub(super) fn flat(&self) -> bool {
        self.flat
    }

    /// The slots of the candidates of the boid in slot `s` in the row of cells `dy` (-1, 0
    /// or 1) next to it, if the flock is dense and planar and the row's three buckets do not
    /// wrap round the table's end: the slots [`Cells::for_each_candidate`] visits for that
    /// row, in the same order.
    pub(super) fn row(&self, s: usize, dy: i64) -> Option<std::ops::Range<usize>> {
        let c = self.cells[s];
        let first = self.bucket_of([c[0].wrapping_sub(1), c[1].wrapping_add(dy), c[2]]) as usize;
        (self.dense && self.planar && first + 3 < self.start.len())
            .then(|| self.start[first] as usize..self.start[first + 3] as usize)
    }

    /// Whether the boids in slots `a` and `b` lie in one row of cells.
    pub(super) fn same_row(&self, a: usize, b: usize) -> bool {
        self.cells[a][1..] == self.cells[b][1..]
    }

    /// The bucket of cell `c`.
    fn bucket_of(&self, c: [i64; 3]) -> u32 {
        let d: [u64; 3] = std::array::from_fn(|k| c[k].wrapping_sub(self.origin[k]) as u64);
        let number = d[0]
            .wrapping_add(d[1].wrapping_mul(self.stride[0]))
            .wrapping_add(d[2].wrapping_mul(self.stride[1]));
        (number & self.mask) as u32
    }

    /// Call `f(t, next)` for every boid in sorted slot `t` of the buckets of the cells next
    /// to the boid in slot `s` (rows of cells z then y outer, then by slot), `next` whether
    /// its cell is one of them (always, unless cells share buckets). The boid itself comes
    /// too; callers test the distance, so they can accumulate without branches.
    #[inline]
    pub(super) fn for_each_candidate(&self, s: usize, f: impl FnMut(usize, bool)) {
        if self.dense {
            self.sweep::<true>(s, f);
        } else {
            self.sweep::<false>(s, f);
        }
    }

    /// [`Cells::for_each_candidate`]; `DENSE`: no two cells share a bucket, so a candidate's
    /// cell needs no check. A row may still run past the table's end onto its start (the
    /// numbers of a layer are offset by the layers below it, `W H` for a planar flock): the
    /// second range.
    #[inline]
    fn sweep<const DENSE: bool>(&self, s: usize, mut f: impl FnMut(usize, bool)) {
        let c = self.cells[s];
        let layers = if self.planar { 0..=0 } else { -1..=1 };
        let buckets = self.start.len() - 1;
        for dz in layers {
            for dy in -1..=1 {
                let (y, z) = (c[1].wrapping_add(dy), c[2].wrapping_add(dz));
                let first = self.bucket_of([c[0].wrapping_sub(1), y, z]) as usize;
                let end = first + 3;
                let wrapped = end.saturating_sub(buckets);
                let ranges = [
                    self.start[first] as usize..self.start[end.min(buckets)] as usize,
                    0..self.start[wrapped] as usize,
                ];
                for range in ranges {
                    for t in range {
                        let next = DENSE || {
                            let q = &self.cells[t];
                            q[1] == y
                                && q[2] == z
                                && q[0].wrapping_sub(c[0]).wrapping_add(1) as u64 <= 2
                        };
                        f(t, next);
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::grid::random_points;

    /// Every pair closer than `h` once, against brute force: rows sharing buckets, 3-D,
    /// planar, with coincident and far-away points (a sparse box whose cells share buckets),
    /// and tiny flocks; and re-sorted after the points moved, the same order as sorted afresh.
    #[test]
    fn neighbours_match_brute_force() {
        let planar = |n, seed| {
            let mut p = random_points(n, seed, 1.0);
            p.iter_mut().for_each(|q| q.z = 0.25);
            p
        };
        let mut far = random_points(3000, 5, 1.0);
        far[3] = far[2];
        far[5] = DVec3::new(1e6, -3e7, 2.0);
        far[6] = DVec3::new(-1e300, 0.0, 0.0);
        // 64 points, 128 buckets, rows 129 cells wide: the row above a cell shares the
        // buckets of its row's next cells, so only the cell check keeps rows apart.
        let mut rows = planar(63, 9);
        rows.iter_mut().for_each(|q| *q = DVec3::new(q.x + 0.5, 3.0 * (q.y + 0.5), 0.0));
        rows.push(DVec3::new(126.5, 0.5, 0.0));
        for (pts, h) in [
            (rows, 1.0),
            (random_points(3000, 7, 1.0), 0.08),
            (planar(2000, 8), 0.05),
            (far, 0.1),
            (random_points(1, 1, 1.0), 0.1),
            (Vec::new(), 0.1),
        ] {
            let n = pts.len();
            let mut cells = Cells::default();
            cells.load(&pts, &pts);
            cells.sort(h);
            for i in 0..n {
                let s = cells.rank[i] as usize;
                assert_eq!(cells.order[s] as usize, i);
                let mut got = Vec::new();
                cells.for_each_candidate(s, |t, next| {
                    let j = cells.order[t] as usize;
                    assert_eq!(cells.positions[t], pts[j]);
                    let d2 = (pts[j] - pts[i]).length_squared();
                    if next && t != s && d2 < cells.h2() {
                        got.push(j);
                    }
                });
                got.sort_unstable();
                let want: Vec<usize> = (0..n)
                    .filter(|&j| j != i && (pts[j] - pts[i]).length_squared() < h * h)
                    .collect();
                assert_eq!(got, want, "point {i} of {n}");
            }
            // Move every point by up to a cell and re-sort from this order: the order is
            // the one sorting the moved points afresh gives.
            let moved: Vec<DVec3> = pts
                .iter()
                .enumerate()
                .map(|(k, p)| *p + h * DVec3::new((k % 7) as f64 / 7.0 - 0.5, 0.3, 0.0))
                .collect();
            cells.positions.iter_mut().zip(&cells.order).for_each(|(p, &i)| *p = moved[i as usize]);
            cells.sort(h);
            let mut fresh = Cells::default();
            fresh.load(&moved, &pts);
            fresh.sort(h);
            assert_eq!(cells.order, fresh.order, "{n} points");
            assert_eq!(cells.rank, fresh.rank);
            assert_eq!(cells.positions, fresh.positions);
            assert_eq!(cells.velocities, fresh.velocities);
        }
    }
}
