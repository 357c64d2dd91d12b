//! The spatial hash grid that finds close pairs of particles (Teschner et al. 2003, "Optimized
//! spatial hashing for collision detection of deformable objects"), without an all-pairs loop.

use glam::DVec3;

pub(super) fn cell_key(c: [i64; 3]) -> u64 {
    let h = |v: i64| (v as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    h(c[0]) ^ h(c[1]).rotate_left(21) ^ h(c[2]).rotate_left(42)
}

/// Call `f(i, j, d, |d|)` for every pair `i < j` of live particles closer than `radius`
/// (and not coincident), `d = x_i - x_j`, found with a spatial hash grid of cell size `radius`
/// kept in `cells`; pairs come in a fixed order.
pub(super) fn for_each_close_pair(
    cells: &mut Vec<(u64, u32)>,
    n: usize,
    alive: &[bool],
    x: &[f64],
    radius: f64,
    mut f: impl FnMut(usize, usize, DVec3, f64),
) {
    let p = |i: usize| DVec3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2]);
    let cell = |q: DVec3| {
        [
            (q.x / radius).floor() as i64,
            (q.y / radius).floor() as i64,
            (q.z / radius).floor() as i64,
        ]
    };
    cells.clear();
    cells.extend((0..n).filter(|&i| alive[i]).map(|i| (cell_key(cell(p(i))), i as u32)));
    cells.sort_unstable();
    for i in (0..n).filter(|&i| alive[i]) {
        let c = cell(p(i));
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    // Wrapping: cells of positions beyond ±2⁶³ radii saturate; their keys
                    // may then be wrong but never overflow (no panic on absurd positions).
                    let key = cell_key([
                        c[0].wrapping_add(dx),
                        c[1].wrapping_add(dy),
                        c[2].wrapping_add(dz),
                    ]);
                    let start = cells.partition_point(|e| e.0 < key);
                    for &(k, j) in &cells[start..] {
                        if k != key {
                            break;
                        }
                        let j = j as usize;
                        if j <= i {
                            continue;
                        }
                        let d = p(i) - p(j);
                        let dist = d.length();
                        if dist < radius && dist > 0.0 {
                            f(i, j, d, dist);
                        }
                    }
                }
            }
        }
    }
}
