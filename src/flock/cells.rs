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
//! The positions and velocities live in that order for all the steps of one
//! [`super::Solver::step`] call ([`Moved::load`] from the state, [`Moved::store`] back): a
//! step reads the sorted boids ([`Cells`]) and writes the moved ones ([`Moved`]) in the same
//! slots, with their new cells and the bounds of those cells, and the next step re-sorts them
//! from that order, which is nearly the new one (boids move less than a cell a step), so the
//! counting sort's scatter, which copies each boid into its new slot, reads and writes memory
//! nearly in sequence instead of at random (Green 2008 keeps particles sorted the same way).
//! Buffers only grow.

use crate::geometry::grid::{bucket_starts, cell_of};
use glam::DVec3;
use rayon::prelude::*;
use std::ops::Range;

/// Boids a parallel task of [`Moved::load`] measures.
const CHUNK: usize = 4096;

/// The boids as loaded or as a step moved them, in the slots of the [`Cells`] order of that
/// step (index order when loaded): what the next [`Cells::sort`] sorts.
#[derive(Clone, Debug, Default)]
pub(super) struct Moved {
    /// Positions (m).
    pub(super) positions: Vec<DVec3>,
    /// Velocities (m/s).
    pub(super) velocities: Vec<DVec3>,
    /// Cells of the positions.
    pub(super) cells: Vec<[i64; 3]>,
    /// What the next sort needs to know of them all.
    pub(super) bounds: Bounds,
}

impl Moved {
    /// Take the boids at `positions` flying at `velocities`, in index order, into cells of
    /// size `h` (m).
    ///
    /// # Panics
    /// If the slices differ in length or hold 2³² boids or more (callers check).
    pub(super) fn load(&mut self, positions: &[DVec3], velocities: &[DVec3], h: f64) {
        let n = positions.len();
        assert!(velocities.len() == n && n < u32::MAX as usize);
        self.positions.clear();
        self.positions.extend_from_slice(positions);
        self.velocities.clear();
        self.velocities.extend_from_slice(velocities);
        self.cells.resize(n, [0; 3]);
        let inv_h = 1.0 / h;
        self.bounds = (
            self.cells.par_chunks_mut(CHUNK),
            positions.par_chunks(CHUNK),
            velocities.par_chunks(CHUNK),
        )
            .into_par_iter()
            .enumerate()
            .map(|(k, (cells, p, v))| {
                let mut bounds = Bounds::EMPTY;
                for (j, (c, (p, v))) in cells.iter_mut().zip(p.iter().zip(v)).enumerate() {
                    *c = cell_of(*p, inv_h);
                    bounds.add(*c, *p, *v, (k * CHUNK + j) as u32);
                }
                bounds
            })
            .reduce(|| Bounds::EMPTY, Bounds::join);
    }

    /// Write the boids back to `positions` and `velocities` in index order; `cells` is the
    /// order they are in.
    pub(super) fn store(
        &self,
        cells: &mut Cells,
        positions: &mut [DVec3],
        velocities: &mut [DVec3],
    ) {
        let rank = cells.update_rank();
        (positions, velocities, rank).into_par_iter().for_each(|(p, v, &s)| {
            (*p, *v) = (self.positions[s as usize], self.velocities[s as usize]);
        });
    }
}

/// The bounds of the boids' cells, whether they fly in one plane of constant `z`, and the
/// lowest boid whose position or velocity is not finite: gathered boid by boid, joined in
/// any order with the same result.
#[derive(Clone, Copy, Debug)]
pub(super) struct Bounds {
    /// Lowest and highest cell along each axis.
    lo: [i64; 3],
    hi: [i64; 3],
    /// Lowest and highest position `z` (m).
    z: [f64; 2],
    /// Every velocity `z` is zero.
    still: bool,
    /// The lowest index of a boid not finite (`u32::MAX`: none).
    pub(super) bad: u32,
}

impl Default for Bounds {
    fn default() -> Self {
        Bounds::EMPTY
    }
}

impl Bounds {
    /// The bounds of no boid.
    pub(super) const EMPTY: Bounds = Bounds {
        lo: [i64::MAX; 3],
        hi: [i64::MIN; 3],
        z: [f64::INFINITY, f64::NEG_INFINITY],
        still: true,
        bad: u32::MAX,
    };

    /// Count boid `i` at `p` (m) in cell `c` flying at `v` (m/s).
    #[inline]
    pub(super) fn add(&mut self, c: [i64; 3], p: DVec3, v: DVec3, i: u32) {
        self.lo = std::array::from_fn(|k| self.lo[k].min(c[k]));
        self.hi = std::array::from_fn(|k| self.hi[k].max(c[k]));
        self.z = [self.z[0].min(p.z), self.z[1].max(p.z)];
        self.still &= v.z == 0.0;
        if !(p.is_finite() && v.is_finite()) {
            self.bad = self.bad.min(i);
        }
    }

    /// The bounds of finite boids at `z` (m), flying at a zero velocity `z`, whose cells
    /// span `lo..=hi` along `x` and `y` in the layer `cz`.
    pub(super) fn plane(lo: [i64; 2], hi: [i64; 2], cz: i64, z: f64) -> Bounds {
        Bounds {
            lo: [lo[0], lo[1], cz],
            hi: [hi[0], hi[1], cz],
            z: [z, z],
            still: true,
            bad: u32::MAX,
        }
    }

    /// The bounds of both sets of boids.
    pub(super) fn join(self, other: Bounds) -> Bounds {
        Bounds {
            lo: std::array::from_fn(|k| self.lo[k].min(other.lo[k])),
            hi: std::array::from_fn(|k| self.hi[k].max(other.hi[k])),
            z: [self.z[0].min(other.z[0]), self.z[1].max(other.z[1])],
            still: self.still & other.still,
            bad: self.bad.min(other.bad),
        }
    }
}

/// Boids sorted by cell (see the module docs).
#[derive(Clone, Debug, Default)]
pub(super) struct Cells {
    /// The boid in each sorted slot.
    pub(super) order: Vec<u32>,
    /// The sorted slot of each boid (the inverse of `order`), as of the last
    /// [`Cells::update_rank`].
    pub(super) rank: Vec<u32>,
    /// Positions in sorted order (m).
    pub(super) positions: Vec<DVec3>,
    /// Velocities in sorted order (m/s).
    pub(super) velocities: Vec<DVec3>,
    /// Cells in sorted order.
    cells: Vec<[i64; 3]>,
    /// Scratch of a sort: the bucket of each slot before it, the next free slot of each
    /// bucket, and the order after it (swapped with `order`).
    bucket: Vec<u32>,
    end: Vec<u32>,
    next_order: Vec<u32>,
    /// Start of each bucket in the sorted order (`buckets + 1` entries).
    start: Vec<u32>,
    /// The widened box's lowest cell.
    origin: [i64; 3],
    /// Cells of the widened box along x and along x and y (`W`, `W H`).
    stride: [u64; 2],
    /// Buckets minus one (a power of two minus one).
    mask: u64,
    /// Inverse of the cells' size (1/m) and squared neighbour radius (m²).
    inv_h: f64,
    h2: f64,
    /// Every boid lies in one layer of cells along z: only that layer is visited.
    planar: bool,
    /// Every boid has the same `z` and a zero velocity `z` (a 2-D flock).
    flat: bool,
    /// The widened box has at most as many cells as there are buckets: one cell a bucket.
    dense: bool,
}

impl Cells {
    /// Start a call of `n` boids, loaded in index order ([`Moved::load`]), in cells of size
    /// `h` (m).
    pub(super) fn load(&mut self, n: usize, h: f64) {
        self.order.clear();
        self.order.extend(0..n as u32);
        (self.inv_h, self.h2) = (1.0 / h, h * h);
    }

    /// The cell of a boid at `p` (m).
    #[inline]
    pub(super) fn cell_of(&self, p: DVec3) -> [i64; 3] {
        cell_of(p, self.inv_h)
    }

    /// The sorted slot of each boid (`rank`), computed afresh.
    pub(super) fn update_rank(&mut self) -> &[u32] {
        self.rank.resize(self.order.len(), 0);
        for (s, &i) in self.order.iter().enumerate() {
            self.rank[i as usize] = s as u32;
        }
        &self.rank
    }

    /// Sort the `moved` boids, in the slots of this order, into cells: a counting sort by
    /// bucket whose scatter copies each boid's position, velocity and cell into its sorted
    /// slot (no separate gather), and inserts it by index among the boids of its bucket
    /// already placed, so the order is by bucket, then by index. The scatter visits the boids
    /// in the last order, which was by index within a bucket, so only a boid that changed
    /// bucket ever moves others (a few shifts a step).
    pub(super) fn sort(&mut self, moved: &Moved) {
        let n = moved.positions.len();
        let Bounds { lo, hi, z, still, .. } = moved.bounds;
        self.planar = n == 0 || lo[2] == hi[2];
        self.flat = self.planar && (n == 0 || (z[0] == z[1] && still));
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
        // Each boid's bucket, each bucket's first slot `start[b]`, and `end[b]` the next free
        // slot of the scatter.
        let (mut bucket, mut start, mut end) = (
            std::mem::take(&mut self.bucket),
            std::mem::take(&mut self.start),
            std::mem::take(&mut self.end),
        );
        bucket.clear();
        bucket.extend(moved.cells.iter().map(|&c| self.bucket_of(c)));
        bucket_starts(&bucket, buckets, &mut start);
        end.clear();
        end.extend_from_slice(&start[..buckets]);
        self.next_order.resize(n, 0);
        self.positions.resize(n, DVec3::ZERO);
        self.velocities.resize(n, DVec3::ZERO);
        self.cells.resize(n, [0; 3]);
        let (order, next) = (&self.order, &mut self.next_order);
        let (positions, velocities, cells) =
            (&mut self.positions, &mut self.velocities, &mut self.cells);
        for (f, &b) in bucket.iter().enumerate() {
            let b = b as usize;
            let (first, mut s) = (start[b] as usize, end[b] as usize);
            end[b] += 1;
            let boid = order[f];
            while s > first && next[s - 1] > boid {
                next[s] = next[s - 1];
                positions[s] = positions[s - 1];
                velocities[s] = velocities[s - 1];
                cells[s] = cells[s - 1];
                s -= 1;
            }
            next[s] = boid;
            positions[s] = moved.positions[f];
            velocities[s] = moved.velocities[f];
            cells[s] = moved.cells[f];
        }
        std::mem::swap(&mut self.order, &mut self.next_order);
        (self.bucket, self.start, self.end) = (bucket, start, end);
    }

    /// Inverse of the cells' size (1/m).
    pub(super) fn inv_h(&self) -> f64 {
        self.inv_h
    }

    /// Squared neighbour radius (m²).
    pub(super) fn h2(&self) -> f64 {
        self.h2
    }

    /// Whether every boid has the same `z` and a zero velocity `z` (a 2-D flock).
    pub(super) fn flat(&self) -> bool {
        self.flat
    }

    /// The slots of the candidates of the boids in slots `first..first + L`, all in the row
    /// of cells of the first, per row of cells next to them (`dy` = -1, 0, 1) and boid, if
    /// the flock is dense and planar and none of those rows' three buckets wrap round the
    /// table's end: the slots [`Cells::for_each_candidate`] visits for each, in the same
    /// order. The buckets are the first boid's row's, offset by the cells between them
    /// (numbers are row-major, so the same bucket as the boid's own numbering).
    pub(super) fn rows<const L: usize>(&self, first: usize) -> Option<[[Range<usize>; L]; 3]> {
        if !(self.dense && self.planar) {
            return None;
        }
        let c = self.cells[first];
        let base = u64::from(self.bucket_of([c[0].wrapping_sub(1), c[1].wrapping_sub(1), c[2]]));
        // A row's first bucket beyond this runs past the table's end.
        let last = self.start.len() - 4;
        let mut rows: [[Range<usize>; L]; 3] = std::array::from_fn(|_| [(); L].map(|_| 0..0));
        for (dy, row) in (0u64..).zip(&mut rows) {
            let base = base.wrapping_add(dy.wrapping_mul(self.stride[0]));
            for (boid, r) in self.cells[first..first + L].iter().zip(row) {
                let dx = boid[0].wrapping_sub(c[0]) as u64;
                let bucket = (base.wrapping_add(dx) & self.mask) as usize;
                if bucket > last {
                    return None;
                }
                *r = self.start[bucket] as usize..self.start[bucket + 3] as usize;
            }
        }
        Some(rows)
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
            let (mut cells, mut moved) = (Cells::default(), Moved::default());
            moved.load(&pts, &pts, h);
            cells.load(n, h);
            cells.sort(&moved);
            let rank = cells.update_rank().to_vec();
            for i in 0..n {
                let s = rank[i] as usize;
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
            let shifted: Vec<DVec3> = pts
                .iter()
                .enumerate()
                .map(|(k, p)| *p + h * DVec3::new((k % 7) as f64 / 7.0 - 0.5, 0.3, 0.0))
                .collect();
            let in_order = |v: &[DVec3]| -> Vec<DVec3> {
                cells.order.iter().map(|&i| v[i as usize]).collect()
            };
            let (p, v) = (in_order(&shifted), in_order(&pts));
            let mut again = Moved::default();
            again.load(&p, &v, h);
            cells.sort(&again);
            let (mut fresh, mut loaded) = (Cells::default(), Moved::default());
            loaded.load(&shifted, &pts, h);
            fresh.load(n, h);
            fresh.sort(&loaded);
            assert_eq!(cells.order, fresh.order, "{n} points");
            assert_eq!(cells.update_rank(), fresh.update_rank());
            assert_eq!(cells.positions, fresh.positions);
            assert_eq!(cells.velocities, fresh.velocities);
        }
    }
}
