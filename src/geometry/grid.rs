//! Neighbour search on a uniform grid of cell size = the kernel's support radius `h`, so the
//! neighbours of a point lie in its own and the 26 adjacent cells (Ihmsen et al. 2011,
//! "A parallel SPH implementation on multi-core CPUs"; Green 2008, "Particle simulation using
//! CUDA", for the sort by cell).
//!
//! Cells are hashed into a power-of-two table of about twice the number of points (so a
//! particle far from the others costs nothing), and points are sorted by bucket with a
//! counting sort (stable: within a bucket, by index). A candidate counts only if its cell is
//! the cell being visited (two cells sharing a bucket give no duplicates) and it lies closer
//! than `h`. Neighbour lists are built in two parallel passes (count, then fill the slice of
//! each point found by a prefix sum), so lists and their order do not depend on the thread
//! count. Buffers only grow: a rebuild of the same size allocates nothing.

use glam::DVec3;
use rayon::prelude::*;

/// Points per parallel task.
const CHUNK: usize = 512;

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
    /// Start of each query point's list in `list` (`queries + 1` entries).
    offsets: Vec<usize>,
    /// The neighbours of every query point, concatenated.
    list: Vec<u32>,
}

fn cell_of(p: DVec3, inv_h: f64) -> [i64; 3] {
    // `as` saturates, so absurd positions give wrong cells, never a panic.
    [(p.x * inv_h).floor() as i64, (p.y * inv_h).floor() as i64, (p.z * inv_h).floor() as i64]
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
        self.cell.resize(n, [0; 3]);
        self.bucket.resize(n, 0);
        self.cell.par_iter_mut().zip(&mut self.bucket).zip(points).for_each(|((c, b), p)| {
            *c = cell_of(*p, inv_h);
            *b = hash(*c, mask);
        });
        // Counting sort by bucket.
        self.start.clear();
        self.start.resize(buckets + 1, 0);
        for &b in &self.bucket {
            self.start[b as usize + 1] += 1;
        }
        for k in 0..buckets {
            self.start[k + 1] += self.start[k];
        }
        self.sorted.resize(n, 0);
        for (i, &b) in self.bucket.iter().enumerate() {
            let slot = &mut self.start[b as usize];
            self.sorted[*slot as usize] = i as u32;
            *slot += 1;
        }
        // The scatter advanced each start to the next bucket's start: shift back.
        for k in (1..=buckets).rev() {
            self.start[k] = self.start[k - 1];
        }
        self.start[0] = 0;
        self.lists(points, queries, h, mask);
    }

    /// Count, then fill, the neighbour lists of the first `queries` points.
    fn lists(&mut self, points: &[DVec3], queries: usize, h: f64, mask: u64) {
        let mut counts = std::mem::take(&mut self.offsets);
        let this = &*self;
        counts.resize(queries + 1, 0);
        counts[..queries].par_chunks_mut(CHUNK).enumerate().for_each(|(c, out)| {
            for (k, o) in out.iter_mut().enumerate() {
                *o = 0;
                this.visit(points, c * CHUNK + k, h, mask, |_| *o += 1);
            }
        });
        // Exclusive prefix sum in place (the last entry, left from the last build, becomes
        // the total).
        counts[queries] = 0;
        let mut total = 0;
        for c in counts.iter_mut() {
            let k = *c;
            *c = total;
            total += k;
        }
        let mut list = std::mem::take(&mut self.list);
        list.resize(total, 0);
        self.fill(points, 0, queries, &counts, &mut list, h, mask);
        self.offsets = counts;
        self.list = list;
    }

    /// Fill the lists of query points `lo..hi` into `out` (their part of the list), splitting
    /// the range in halves on the rayon pool.
    #[allow(clippy::too_many_arguments)]
    fn fill(
        &self,
        points: &[DVec3],
        lo: usize,
        hi: usize,
        offsets: &[usize],
        out: &mut [u32],
        h: f64,
        mask: u64,
    ) {
        if hi - lo <= CHUNK {
            let base = offsets[lo];
            for (k, &start) in offsets[lo..hi].iter().enumerate() {
                let mut at = start - base;
                self.visit(points, lo + k, h, mask, |j| {
                    out[at] = j;
                    at += 1;
                });
            }
            return;
        }
        let mid = lo + (hi - lo) / 2;
        let (a, b) = out.split_at_mut(offsets[mid] - offsets[lo]);
        rayon::join(
            || self.fill(points, lo, mid, offsets, a, h, mask),
            || self.fill(points, mid, hi, offsets, b, h, mask),
        );
    }

    /// Call `f(j)` for every point `j ≠ i` closer than `h` to point `i`, cell by cell
    /// (z, y, x outer to inner), by index within a cell.
    fn visit(&self, points: &[DVec3], i: usize, h: f64, mask: u64, mut f: impl FnMut(u32)) {
        let (c, p, h2) = (self.cell[i], points[i], h * h);
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let cc = [c[0].wrapping_add(dx), c[1].wrapping_add(dy), c[2].wrapping_add(dz)];
                    let b = hash(cc, mask) as usize;
                    for &j in &self.sorted[self.start[b] as usize..self.start[b + 1] as usize] {
                        let ju = j as usize;
                        if ju != i && self.cell[ju] == cc && (points[ju] - p).length_squared() < h2
                        {
                            f(j);
                        }
                    }
                }
            }
        }
    }

    /// The neighbours of query point `i` (indices into the points of the last build).
    pub fn neighbours(&self, i: usize) -> &[u32] {
        &self.list[self.offsets[i]..self.offsets[i + 1]]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn random_points(n: usize, seed: u64, scale: f64) -> Vec<DVec3> {
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
                (grid.offsets.clone(), grid.list.clone())
            })
        };
        let one = lists(1);
        assert!(one.1.len() > 4000 * 5, "too few neighbours to test: {}", one.1.len());
        assert_eq!(one, lists(2));
    }

    #[test]
    fn rebuild_reuses_buffers() {
        let pts = random_points(2000, 3, 1.0);
        let mut grid = Grid::default();
        grid.build(&pts, 2000, 0.1);
        let caps = (grid.list.capacity(), grid.sorted.capacity(), grid.start.capacity());
        let ptr = grid.list.as_ptr();
        grid.build(&pts, 2000, 0.1);
        assert_eq!(caps, (grid.list.capacity(), grid.sorted.capacity(), grid.start.capacity()));
        assert_eq!(ptr, grid.list.as_ptr());
    }
}
