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
//! bucket with a counting sort (stable: by index within a bucket), their positions,
//! velocities and cells copied in that order; a boid's neighbours are then read from a few
//! contiguous ranges, and consecutive boids read nearly the same ones. The order depends on
//! the positions alone, not on the thread count. Buffers only grow.

use crate::geometry::grid::{cell_of, sort_by_bucket};
use glam::DVec3;
use rayon::prelude::*;

/// Boids sorted by cell (see the module docs).
#[derive(Clone, Debug, Default)]
pub(super) struct Cells {
    /// Cell of each boid, in index order.
    cell: Vec<[i64; 3]>,
    /// Bucket of each boid, in index order.
    bucket: Vec<u32>,
    /// Start of each bucket in the sorted order (`buckets + 1` entries).
    start: Vec<u32>,
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
    /// The widened box has at most as many cells as there are buckets: one cell a bucket.
    dense: bool,
}

impl Cells {
    /// Sort the boids at `positions` flying at `velocities` into cells of size `h` (m).
    ///
    /// # Panics
    /// If the slices differ in length or hold 2³² boids or more (callers check).
    pub(super) fn build(&mut self, positions: &[DVec3], velocities: &[DVec3], h: f64) {
        let n = positions.len();
        assert!(velocities.len() == n && n < u32::MAX as usize);
        let inv_h = 1.0 / h;
        self.h2 = h * h;
        self.cell.resize(n, [0; 3]);
        self.cell.par_iter_mut().zip(positions).for_each(|(c, p)| *c = cell_of(*p, inv_h));
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
        self.rank.resize(n, 0);
        let rank = &mut self.rank;
        sort_by_bucket(&self.bucket, buckets, &mut self.start, &mut self.order, |i, slot| {
            rank[i] = slot;
        });
        self.positions.resize(n, DVec3::ZERO);
        self.velocities.resize(n, DVec3::ZERO);
        self.cells.resize(n, [0; 3]);
        let cell = &self.cell;
        (&mut self.positions, &mut self.velocities, &mut self.cells)
            .into_par_iter()
            .zip(&self.order)
            .for_each(|((p, v, c), &i)| {
                let i = i as usize;
                (*p, *v, *c) = (positions[i], velocities[i], cell[i]);
            });
    }

    /// The bucket of cell `c`.
    fn bucket_of(&self, c: [i64; 3]) -> u32 {
        let d: [u64; 3] = std::array::from_fn(|k| c[k].wrapping_sub(self.origin[k]) as u64);
        let number = d[0]
            .wrapping_add(d[1].wrapping_mul(self.stride[0]))
            .wrapping_add(d[2].wrapping_mul(self.stride[1]));
        (number & self.mask) as u32
    }

    /// Call `f(t, d, near)` for every boid in sorted slot `t` of the cells next to the boid in
    /// slot `s` (rows of cells z then y outer, then by slot), `d` the offset to it (m), `near`
    /// whether it is a neighbour: `t ≠ s` and closer than `h`. Candidates that are not
    /// neighbours come too (`near` false), so callers can accumulate without branches.
    #[inline]
    pub(super) fn for_each_candidate(&self, s: usize, f: impl FnMut(usize, DVec3, bool)) {
        if self.dense {
            self.sweep::<true>(s, f);
        } else {
            self.sweep::<false>(s, f);
        }
    }

    /// [`Cells::for_each_candidate`]; `DENSE`: no two cells share a bucket and no row wraps
    /// round the table, so a candidate's cell needs no check.
    #[inline]
    fn sweep<const DENSE: bool>(&self, s: usize, mut f: impl FnMut(usize, DVec3, bool)) {
        let (p, c) = (self.positions[s], self.cells[s]);
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
                        let d = self.positions[t] - p;
                        let mut near = (d.length_squared() < self.h2) & (t != s);
                        if !DENSE {
                            let q = &self.cells[t];
                            near &= q[1] == y
                                && q[2] == z
                                && q[0].wrapping_sub(c[0]).wrapping_add(1) as u64 <= 2;
                        }
                        f(t, d, near);
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
    /// and tiny flocks.
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
            cells.build(&pts, &pts, h);
            for i in 0..n {
                let s = cells.rank[i] as usize;
                assert_eq!(cells.order[s] as usize, i);
                let mut got = Vec::new();
                cells.for_each_candidate(s, |t, d, near| {
                    let j = cells.order[t] as usize;
                    assert_eq!(d, pts[j] - pts[i]);
                    if near {
                        got.push(j);
                    }
                });
                got.sort_unstable();
                let want: Vec<usize> = (0..n)
                    .filter(|&j| j != i && (pts[j] - pts[i]).length_squared() < h * h)
                    .collect();
                assert_eq!(got, want, "point {i} of {n}");
            }
        }
    }
}
