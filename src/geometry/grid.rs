//! Neighbour search on a uniform grid of cell size = the kernel's support radius `h`, so the
//! neighbours of a point lie in its own and the 26 adjacent cells (Ihmsen et al. 2011,
//! "A parallel SPH implementation on multi-core CPUs"; Green 2008, "Particle simulation using
//! CUDA", for the sort by cell).
//!
//! Cells are hashed into a power-of-two table of about twice the number of points (so a
//! particle far from the others costs nothing), and points are sorted by bucket with a
//! counting sort (stable: within a bucket, by index); their positions and cells are copied in
//! that order, so the candidates of a cell are read from contiguous memory. A candidate counts
//! only if it lies closer than `h` and its cell is the cell being visited (two cells sharing a
//! bucket give no duplicates). The lists are found in one parallel pass over chunks of query
//! points, each chunk appending to its own buffer (Ihmsen et al.'s compact storage, one pass
//! instead of count-then-fill), so lists and their order do not depend on the thread count.
//! Points all in one layer of cells along z (crowds and 2-D flocks, lifted to `z = 0`) visit
//! only the 9 cells of their layer: the other 18 hold none of them but hash to buckets that
//! may hold other points.
//! Buffers only grow: a rebuild of the same size allocates nothing.

use glam::DVec3;
use rayon::prelude::*;

/// Query points per parallel task and per list buffer: the lists of query points
/// `c CHUNK .. (c + 1) CHUNK` lie in buffer `c` (see [`Grid::span`]).
pub const CHUNK: usize = 512;

/// The grid and the neighbour lists of the query points (see the module docs).
#[derive(Clone, Debug, Default)]
pub struct Grid {
    /// Cell of each point.
    cell: Vec<[i64; 3]>,
    /// Bucket of each point.
    bucket: Vec<u32>,
    /// Start of each bucket in `sorted` (`buckets + 1` entries).
    start: Vec<u32>,
    /// Point indices sorted by bucket.
    sorted: Vec<u32>,
    /// Positions of the points in `sorted`'s order.
    sorted_points: Vec<DVec3>,
    /// Cells of the points in `sorted`'s order.
    sorted_cells: Vec<[i64; 3]>,
    /// End of each query point's list in its chunk's buffer (`queries` entries; a list starts
    /// where the previous point's ends, or at 0 for a chunk's first point).
    ends: Vec<u32>,
    /// The neighbours of every chunk of `CHUNK` query points, concatenated per chunk.
    lists: Vec<Vec<u32>>,
    /// Every point lies in one layer of cells along z (points on a plane `z = const`, as
    /// crowds and 2-D flocks): the layers above and below are not visited.
    planar: bool,
    /// `1 / cell size` (1/m) and the bucket mask of the last build.
    inv_h: f64,
    mask: u64,
}

/// The cell of point `p` (m) in a grid of cells of size `1 / inv_h` (m) with a corner at the
/// origin (also the flock's cells, `flock/cells.rs`).
pub(crate) fn cell_of(p: DVec3, inv_h: f64) -> [i64; 3] {
    [floor(p.x * inv_h), floor(p.y * inv_h), floor(p.z * inv_h)]
}

/// `x.floor() as i64` without a call to libm's `floor` (baseline x86-64 has no rounding
/// instruction, and the call was 2 % of a flock step): truncate, then step down where that
/// rounded up. The same integer for every `x`: `as` saturates (so absurd positions give wrong
/// cells, never a panic), and NaN gives 0, as `floor` then `as` do.
#[inline]
fn floor(x: f64) -> i64 {
    let t = x as i64;
    if t as f64 > x {
        t.saturating_sub(1)
    } else {
        t
    }
}

/// The counting pass of a counting sort of the items `0..bucket.len()` by their `bucket` (of
/// `buckets`): `start[b]` gets the first slot of bucket `b` in the sorted order (`buckets + 1`
/// entries, the last `bucket.len()`). Also the flock's cells (`flock/cells.rs`), whose
/// scatter copies the boids. The buffer only grows.
pub(crate) fn bucket_starts(bucket: &[u32], buckets: usize, start: &mut Vec<u32>) {
    start.clear();
    start.resize(buckets + 1, 0);
    for &b in bucket {
        start[b as usize + 1] += 1;
    }
    for k in 0..buckets {
        start[k + 1] += start[k];
    }
}

/// Counting sort of the items `0..bucket.len()` by their `bucket` (of `buckets`), stable (by
/// index within a bucket): `sorted` gets the items in order and `start[b]` the first slot of
/// bucket `b` (`buckets + 1` entries). Buffers only grow.
fn sort_by_bucket(bucket: &[u32], buckets: usize, start: &mut Vec<u32>, sorted: &mut Vec<u32>) {
    bucket_starts(bucket, buckets, start);
    sorted.resize(bucket.len(), 0);
    for (i, &b) in bucket.iter().enumerate() {
        let slot = &mut start[b as usize];
        sorted[*slot as usize] = i as u32;
        *slot += 1;
    }
    // The scatter advanced each start to the next bucket's start: shift back.
    for k in (1..=buckets).rev() {
        start[k] = start[k - 1];
    }
    start[0] = 0;
}

fn hash(c: [i64; 3], mask: u64) -> u32 {
    let h = (c[0] as u64).wrapping_mul(73_856_093)
        ^ (c[1] as u64).wrapping_mul(19_349_663)
        ^ (c[2] as u64).wrapping_mul(83_492_791);
    (h.wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 32) as u32 & mask as u32
}

impl Grid {
    /// Sort `points` into the grid of cell size `h` (m) and find, for each of the first
    /// `queries` points, every other point closer than `h`.
    ///
    /// # Panics
    /// If `queries > points.len()` or there are 2³² points or more (callers check).
    pub fn build(&mut self, points: &[DVec3], queries: usize, h: f64) {
        assert!(queries <= points.len() && points.len() < u32::MAX as usize);
        let n = points.len();
        let buckets = (2 * n).next_power_of_two().max(2);
        let mask = (buckets - 1) as u64;
        let inv_h = 1.0 / h;
        (self.inv_h, self.mask) = (inv_h, mask);
        self.cell.resize(n, [0; 3]);
        self.bucket.resize(n, 0);
        self.cell.par_iter_mut().zip(&mut self.bucket).zip(points).for_each(|((c, b), p)| {
            *c = cell_of(*p, inv_h);
            *b = hash(*c, mask);
        });
        let layer = self.cell.first().map_or(0, |c| c[2]);
        self.planar = self.cell.par_iter().all(|c| c[2] == layer);
        sort_by_bucket(&self.bucket, buckets, &mut self.start, &mut self.sorted);
        self.sorted_points.resize(n, DVec3::ZERO);
        self.sorted_cells.resize(n, [0; 3]);
        let cell = &self.cell;
        self.sorted_points.par_iter_mut().zip(&mut self.sorted_cells).zip(&self.sorted).for_each(
            |((p, c), &j)| {
                *p = points[j as usize];
                *c = cell[j as usize];
            },
        );
        self.lists(points, queries, h);
    }

    /// The neighbour lists of the first `queries` points, one chunk of `CHUNK` per task.
    fn lists(&mut self, points: &[DVec3], queries: usize, h: f64) {
        let mut ends = std::mem::take(&mut self.ends);
        let mut lists = std::mem::take(&mut self.lists);
        ends.resize(queries, 0);
        lists.resize_with(queries.div_ceil(CHUNK), Vec::new);
        let this = &*self;
        ends.par_chunks_mut(CHUNK).zip(&mut lists).enumerate().for_each(|(c, (ends, list))| {
            list.clear();
            for (k, end) in ends.iter_mut().enumerate() {
                this.visit(points[c * CHUNK + k], c * CHUNK + k, h, list);
                // At most `CHUNK` times the points (< 2³² / CHUNK in any real use).
                *end = list.len() as u32;
            }
        });
        self.ends = ends;
        self.lists = lists;
    }

    /// Append to `out` every point `j ≠ i` closer than `h` to point `i` at `p`, cell by cell
    /// (z, y, x outer to inner; only the own layer when the points are planar), by index
    /// within a cell.
    fn visit(&self, p: DVec3, i: usize, h: f64, out: &mut Vec<u32>) {
        let layers = if self.planar { 0..=0 } else { -1..=1 };
        self.scan(p, self.cell[i], layers, h * h, Some(i as u32), out);
    }

    /// Append to `out` every point of the last build closer than `r` (m) to `p` (m), a point
    /// that need not be one of them, in the order of the lists (all 27 cells around `p`'s).
    /// `r` must not exceed the cell size of the last build.
    pub fn within(&self, p: DVec3, r: f64, out: &mut Vec<u32>) {
        if !self.sorted.is_empty() {
            let c = cell_of(p, self.inv_h);
            self.scan(p, c, -1..=1, r * r, None, out);
        }
    }

    /// The points other than `skip` closer than `sqrt(h2)` to `p` in the cells `c + (dx, dy,
    /// dz)`, `dz` in `layers`, appended to `out`.
    fn scan(
        &self,
        p: DVec3,
        c: [i64; 3],
        layers: std::ops::RangeInclusive<i64>,
        h2: f64,
        skip: Option<u32>,
        out: &mut Vec<u32>,
    ) {
        for dz in layers {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let cc = [c[0].wrapping_add(dx), c[1].wrapping_add(dy), c[2].wrapping_add(dz)];
                    let b = hash(cc, self.mask) as usize;
                    let range = self.start[b] as usize..self.start[b + 1] as usize;
                    let candidates = self.sorted_points[range.clone()].iter();
                    for ((q, qc), &j) in
                        candidates.zip(&self.sorted_cells[range.clone()]).zip(&self.sorted[range])
                    {
                        if (*q - p).length_squared() < h2 && *qc == cc && Some(j) != skip {
                            out.push(j);
                        }
                    }
                }
            }
        }
    }

    /// Where the list of query point `i` lies in the buffer of its chunk `i / CHUNK`, so
    /// callers can keep per-pair data in buffers of the same layout.
    pub fn span(&self, i: usize) -> std::ops::Range<usize> {
        let start = if i.is_multiple_of(CHUNK) { 0 } else { self.ends[i - 1] as usize };
        start..self.ends[i] as usize
    }

    /// The neighbours of query point `i` (indices into the points of the last build).
    pub fn neighbours(&self, i: usize) -> &[u32] {
        &self.lists[i / CHUNK][self.span(i)]
    }
}

/// `n` points uniform in the cube of side `scale` around the origin, from a splitmix64
/// stream seeded by `seed` (for the tests of this module and of the flock's cells).
#[cfg(test)]
pub(crate) fn random_points(n: usize, seed: u64, scale: f64) -> Vec<DVec3> {
    let mut s = seed;
    let mut next = move || {
        s = s.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = s;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..n).map(|_| DVec3::new(next(), next(), next()) * scale - scale / 2.0).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_is_floor_then_as() {
        let xs = [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            -1.5,
            2.0_f64.powi(52) + 0.5,
            -2.0_f64.powi(53),
            1e300,
            -1e300,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            -(2.0_f64.powi(63)),
            2.0_f64.powi(63),
            -1e-300,
            7.999_999_999_999_999,
        ];
        for x in xs {
            assert_eq!(floor(x), x.floor() as i64, "{x}");
        }
    }

    #[test]
    fn matches_brute_force() {
        for (n, queries, h) in [(3000, 2000, 0.08), (500, 500, 0.3), (1, 1, 0.1), (0, 0, 0.1)] {
            let mut pts = random_points(n, 7, 1.0);
            if n > 10 {
                pts[3] = pts[2]; // coincident points are neighbours
                pts[5] = DVec3::new(1e6, -3e7, 2.0); // far away
            }
            let mut grid = Grid::default();
            grid.build(&pts, queries, h);
            for i in 0..queries {
                let mut got: Vec<u32> = grid.neighbours(i).to_vec();
                got.sort_unstable();
                let want: Vec<u32> = (0..n)
                    .filter(|&j| j != i && (pts[j] - pts[i]).length_squared() < h * h)
                    .map(|j| j as u32)
                    .collect();
                assert_eq!(got, want, "point {i}");
            }
            if n > 10 {
                assert!(grid.neighbours(2).contains(&3));
            }
        }
    }

    #[test]
    fn same_lists_on_one_and_two_threads() {
        let pts = random_points(5000, 11, 1.0);
        let lists = |threads| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| {
                let mut grid = Grid::default();
                grid.build(&pts, 4000, 0.07);
                (grid.ends.clone(), grid.lists.clone())
            })
        };
        let one = lists(1);
        let total: usize = one.1.iter().map(Vec::len).sum();
        assert!(total > 4000 * 5, "too few neighbours to test: {total}");
        assert_eq!(one, lists(2));
    }

    #[test]
    fn rebuild_reuses_buffers() {
        let pts = random_points(2000, 3, 1.0);
        let mut grid = Grid::default();
        grid.build(&pts, 2000, 0.1);
        let caps = (grid.lists[1].capacity(), grid.sorted.capacity(), grid.start.capacity());
        let ptr = grid.lists[1].as_ptr();
        grid.build(&pts, 2000, 0.1);
        assert_eq!(caps, (grid.lists[1].capacity(), grid.sorted.capacity(), grid.start.capacity()));
        assert_eq!(ptr, grid.lists[1].as_ptr());
    }
}
