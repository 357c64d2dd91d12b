//! The solver's particle order: at the start of every frame the solver's copy of the fluid is
//! sorted by the Z-order (Morton 1966) of the particles' grid cells of the kernel's support,
//! so that neighbours in space are near in memory (Ihmsen et al. 2011, "A parallel SPH
//! implementation on multi-core CPUs", section 4: Z-index sort); the state keeps the user's
//! order, restored when the step writes it back.
//!
//! The order is a function of the frame's positions and the particles' order in the state
//! alone (the sort key is the cell's Z-order, then the particle's index in the state: keys are
//! unique), so it does not depend on the solver's history or on the thread count. Each solver
//! slot remembers its particle's index in the state at the start of the step (`user`); the
//! particles emitted in the step take the indices after those, in the order of emission, and
//! the removed ones leave gaps, so the write-back puts the particles in ascending `user`
//! index: the state's order, then the emitted ones, as without sorting. Buffers only grow.

use glam::DVec3;

/// Bits of a cell coordinate in the Z-order key (3 × 21 = 63 bits; cells further than 2²¹
/// from the lowest share keys, which only costs locality).
const BITS: u32 = 21;

/// The particle order of a step (see the module docs).
#[derive(Clone, Debug, Default)]
pub struct Order {
    /// The state index of the particle in each solver slot.
    pub(super) user: Vec<u32>,
    /// The state index the next emitted particle takes.
    next: u32,
    /// Sort keys: Z-order of the cell, state index, slot before the sort.
    keys: Vec<(u64, u32, u32)>,
    /// Gather scratch.
    vectors: Vec<DVec3>,
    scalars: Vec<f64>,
    /// The slot of each state index (`u32::MAX` if removed), for the write-back.
    slot_of: Vec<u32>,
    /// The slots in their new order: after a sort, the old slot of each; for the write-back,
    /// the slots in ascending state index.
    slots: Vec<u32>,
}

/// Spread the low [`BITS`] bits of `x` to every third bit.
fn spread(x: u64) -> u64 {
    let mut x = x & ((1 << BITS) - 1);
    x = (x | x << 32) & 0x001f_0000_0000_ffff;
    x = (x | x << 16) & 0x001f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    (x | x << 2) & 0x1249_2492_4924_9249
}

/// `to[k] = from[slots[k]]` for every `k` (`to` resized to `slots`).
pub fn gather<T: Copy>(slots: &[u32], from: &[T], to: &mut Vec<T>) {
    to.clear();
    to.extend(slots.iter().map(|&k| from[k as usize]));
}

impl Order {
    /// Start a step of `n` particles in the state's order.
    pub fn start(&mut self, n: usize) {
        self.user.clear();
        self.user.extend(0..n as u32);
        self.next = n as u32;
    }

    /// Give the `k` particles just appended the next state indices.
    pub fn emitted(&mut self, k: usize) {
        self.user.extend(self.next..self.next + k as u32);
        self.next += k as u32;
    }

    /// Sort `points` (m) by the Z-order of their cells of size `cell` (m), then by state
    /// index, and apply the same permutation to `user` and to every array of `vectors` and
    /// `scalars` (one entry per point).
    pub fn sort(
        &mut self,
        points: &mut [DVec3],
        cell: f64,
        vectors: &mut [&mut Vec<DVec3>],
        scalars: &mut [&mut Vec<f64>],
    ) {
        let inv = 1.0 / cell;
        let lowest = points.iter().fold(DVec3::INFINITY, |m, p| m.min(*p));
        self.keys.clear();
        self.keys.extend(points.iter().zip(&self.user).enumerate().map(|(slot, (p, &u))| {
            // `as` saturates: non-finite positions give some key, never a panic.
            let c = ((*p - lowest) * inv).floor();
            let code = spread(c.x as u64) | spread(c.y as u64) << 1 | spread(c.z as u64) << 2;
            (code, u, slot as u32)
        }));
        self.keys.sort_unstable();
        for (u, key) in self.user.iter_mut().zip(&self.keys) {
            *u = key.1;
        }
        let slots = &mut self.slots;
        slots.clear();
        slots.extend(self.keys.iter().map(|key| key.2));
        gather(slots, points, &mut self.vectors);
        points.copy_from_slice(&self.vectors);
        for a in vectors {
            gather(slots, a, &mut self.vectors);
            std::mem::swap(*a, &mut self.vectors);
        }
        for a in scalars {
            gather(slots, a, &mut self.scalars);
            std::mem::swap(*a, &mut self.scalars);
        }
    }

    /// The solver slots in the state's order (ascending state index).
    pub fn slots(&mut self) -> &[u32] {
        self.slot_of.clear();
        self.slot_of.resize(self.next as usize, u32::MAX);
        for (slot, &u) in self.user.iter().enumerate() {
            self.slot_of[u as usize] = slot as u32;
        }
        self.slots.clear();
        self.slots.extend(self.slot_of.iter().copied().filter(|&s| s != u32::MAX));
        &self.slots
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::grid::random_points;

    #[test]
    fn spread_interleaves() {
        assert_eq!(spread(0b111), 0b1001001);
        assert_eq!(spread((1 << BITS) - 1), 0x1249_2492_4924_9249);
        // Neighbouring cells 0..8 on each axis fill the 512 codes of the first octant block.
        let mut codes: Vec<u64> = (0..512)
            .map(|c: u64| spread(c & 7) | spread(c >> 3 & 7) << 1 | spread(c >> 6) << 2)
            .collect();
        codes.sort_unstable();
        assert_eq!(codes, (0..512).collect::<Vec<u64>>());
    }

    /// The sort is a permutation applied alike to every array; the write-back finds each
    /// particle's state index again, after removals and emissions too.
    #[test]
    fn sort_then_slots_restore_the_state_order() {
        let points = random_points(3000, 3, 1.0);
        let index: Vec<f64> = (0..points.len()).map(|i| i as f64).collect();
        let mut order = Order::default();
        order.start(points.len());
        let (mut p, mut copy, mut s) = (points.clone(), points.clone(), index.clone());
        order.sort(&mut p, 0.05, &mut [&mut copy], &mut [&mut s]);
        assert_ne!(p, points, "random points should move");
        assert_eq!(p, copy);
        for (slot, &u) in order.user.iter().enumerate() {
            assert_eq!(p[slot], points[u as usize]);
            assert_eq!(s[slot], u as f64);
        }
        // Neighbours in space are nearer in memory: the mean distance of consecutive slots.
        let step = |q: &[DVec3]| q.windows(2).map(|w| (w[1] - w[0]).length()).sum::<f64>();
        assert!(step(&p) < 0.2 * step(&points), "{} vs {}", step(&p), step(&points));
        // The solver removes particles by compacting `user` with its arrays.
        let kept = order.user.iter().enumerate().filter(|(slot, _)| slot % 3 != 0);
        order.user = kept.map(|(_, &u)| u).collect();
        order.emitted(2);
        let slots: Vec<u32> = order.slots().to_vec();
        assert_eq!(slots.len(), 2000 + 2);
        let users: Vec<u32> = slots.iter().map(|&k| order.user[k as usize]).collect();
        assert!(users.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(users[2000..], [3000, 3001]);
    }
}
