//! The 2-D sweep of a flat, dense flock four boids at a time: the boids of four consecutive
//! sorted slots in one row of cells read the union of their candidate ranges once, each
//! candidate tested against the four in the lanes of AVX2 registers (where the CPU has AVX2,
//! found at run time, [`pulp::x86::V3`]; else the scalar sweep: the wheel runs on any
//! x86-64). A lane
//! keeps only its own candidates (the slots of its three cells of the row, as the scalar sweep
//! of `cells.rs` visits them, in the same order) and does the arithmetic of
//! `solver::flocking` on them in the same order, so the sums are bitwise the scalar sweep's:
//! a candidate a lane does not see adds `+0` (the scalar sweep adds `±0`, which leaves a sum
//! that started at `+0` unchanged too), and no fused multiply-add is introduced. The three
//! rules' steering from those sums (`solver::rules`: three square roots and divisions a
//! boid, and the clamps to `max_force`) is done in the same lanes ([`Rules`]), the same
//! operations in the same order with the branches as selects, so the accelerations too are
//! bitwise the scalar code's. Without steering behaviours the group's boids are then moved in
//! the lanes too ([`Group::advance`]: semi-implicit Euler, the speed cap, the new cells and
//! their bounds, [`Span`]), again the scalar operations in the same order.
//!
//! A candidate's position and velocity are read from the sorted copies (`cells.rs`) in
//! sequence, each component broadcast to the lanes.

use super::Settings;
use glam::DVec3;
#[cfg(target_arch = "x86_64")]
use std::arch::x86_64::__m256d;
use std::ops::Range;

/// Boids a group sweeps together.
pub(super) const LANES: usize = 4;

/// The inputs of one group's sweep: the boids in slots `first..first + LANES` (all in one
/// row of cells), and their candidates' slots per row of cells, `rows[row][lane]`.
pub(super) struct Group<'a> {
    /// The flock's positions (m) and velocities (m/s) in the cells' sorted order.
    pub(super) positions: &'a [DVec3],
    pub(super) velocities: &'a [DVec3],
    pub(super) first: usize,
    pub(super) rows: [[Range<usize>; LANES]; 3],
    /// Squared neighbour radius and separation distance (m²).
    pub(super) h2: f64,
    pub(super) separation2: f64,
    /// The cosine of half the field of view, and whether that is a full circle
    /// (`solver::view`).
    pub(super) cos_half: f64,
    pub(super) full_circle: bool,
}

#[cfg(target_arch = "x86_64")]
impl Group<'_> {
    /// The flocking accelerations (m/s²) of the group's boids, lane by lane, with AVX2 (call
    /// inside [`pulp::x86::V3::vectorize`], so that it is compiled for it): the sums of the
    /// neighbours in view, then the three rules' steering ([`Rules`]).
    #[inline(always)]
    pub(super) fn accelerations(self, simd: pulp::x86::V3, set: &Settings) -> [DVec3; LANES] {
        use pulp::bytemuck::cast;
        let (x, y, _, _) = self.steering(simd, set);
        let [x, y]: [[f64; LANES]; 2] = [x, y].map(cast);
        std::array::from_fn(|l| DVec3::new(x[l], y[l], 0.0))
    }

    /// The group's boids moved by one step of `dt` (s), as `solver::Task` moves a boid
    /// without steering behaviours: semi-implicit Euler `v += a dt` with the speed capped at
    /// `max_speed` (glam's `clamp_length_max`, [`Rules::clamp`]), `p += v dt`, in the lanes,
    /// written to `p` and `v` (the group's slots), their cells (size `1 / inv_h` m) to `c`,
    /// and the cells' `x` and `y` bounds joined into `span`. `false` (cells and `span` not
    /// written) when a boid's position or velocity is not finite or a cell lies beyond ±2³¹
    /// (the caller then takes the cells and bounds one by one). The flock is flat: the third
    /// components of the scalar code are `v_z = ±0 + (+0) dt = +0` and
    /// `p_z + (+0) dt = p_z + 0`, the same for every boid (their `p_z` are equal), and the
    /// squared speed's `+0` leaves it unchanged; the cell's `z` is the caller's `cz`, that of
    /// `p_z + 0`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub(super) fn advance(
        self,
        simd: pulp::x86::V3,
        set: &Settings,
        (dt, inv_h): (f64, f64),
        cz: i64,
        p: &mut [DVec3],
        v: &mut [DVec3],
        c: &mut [[i64; 3]],
        span: &mut Span,
    ) -> bool {
        use pulp::bytemuck::cast;
        use std::arch::x86_64::{_CMP_EQ_OQ, _CMP_LT_OQ};
        let avx = simd.avx;
        let z = self.positions[self.first].z + 0.0;
        let (ax, ay, boids, rules) = self.steering(simd, set);
        let (mul, add) = (|a, b| avx._mm256_mul_pd(a, b), |a, b| avx._mm256_add_pd(a, b));
        let dt = avx._mm256_set1_pd(dt);
        let (vx, vy) = (add(boids.vx, mul(ax, dt)), add(boids.vy, mul(ay, dt)));
        let (vx, vy) = rules.clamp(vx, vy, rules.max_speed, rules.max_speed2);
        let (px, py) = (add(boids.px, mul(vx, dt)), add(boids.py, mul(vy, dt)));
        let [pxs, pys, vxs, vys]: [[f64; LANES]; 4] = [px, py, vx, vy].map(cast);
        for l in 0..LANES {
            (p[l], v[l]) = (DVec3::new(pxs[l], pys[l], z), DVec3::new(vxs[l], vys[l], 0.0));
        }
        let inv_h = avx._mm256_set1_pd(inv_h);
        let (cx, cy) = (avx._mm256_floor_pd(mul(px, inv_h)), avx._mm256_floor_pd(mul(py, inv_h)));
        // Every velocity finite (`x - x` is zero; NaN for an infinity or NaN), so every
        // position too (finite before, finite steps: an overflow to infinity makes its cell
        // leave the range), and every cell within ±2³¹ (NaN fails): exact through i32, the
        // integers `geometry::grid::floor` gives.
        let finite = |x: __m256d| {
            avx._mm256_cmp_pd::<_CMP_EQ_OQ>(avx._mm256_sub_pd(x, x), avx._mm256_setzero_pd())
        };
        let limit = avx._mm256_set1_pd(2_147_483_648.0);
        let within = |x: __m256d| {
            let x = avx._mm256_andnot_pd(avx._mm256_set1_pd(-0.0), x);
            avx._mm256_cmp_pd::<_CMP_LT_OQ>(x, limit)
        };
        let ok = avx._mm256_and_pd(
            avx._mm256_and_pd(finite(vx), finite(vy)),
            avx._mm256_and_pd(within(cx), within(cy)),
        );
        if avx._mm256_movemask_pd(ok) != 0b1111 {
            return false;
        }
        let wide = |x| -> [i64; LANES] {
            cast(simd.avx2._mm256_cvtepi32_epi64(avx._mm256_cvttpd_epi32(x)))
        };
        let (ix, iy) = (wide(cx), wide(cy));
        for l in 0..LANES {
            c[l] = [ix[l], iy[l], cz];
        }
        span.lo = (avx._mm256_min_pd(span.lo.0, cx), avx._mm256_min_pd(span.lo.1, cy));
        span.hi = (avx._mm256_max_pd(span.hi.0, cx), avx._mm256_max_pd(span.hi.1, cy));
        true
    }

    /// The group's flocking accelerations `(x, y)` (m/s², [`Group::accelerations`]), its
    /// boids in the lanes and the rules' constants.
    #[inline(always)]
    fn steering(self, simd: pulp::x86::V3, set: &Settings) -> (__m256d, __m256d, Boids, Rules) {
        use pulp::bytemuck::cast;
        use std::arch::x86_64::_CMP_EQ_OQ;
        let avx = simd.avx;
        let Group { positions, velocities, first, rows, h2, separation2, cos_half, full_circle } =
            self;
        let lane = |a: &[DVec3], k: usize| -> __m256d {
            cast::<[f64; LANES], _>(std::array::from_fn(|l| a[first + l][k]))
        };
        let zero = avx._mm256_setzero_pd();
        let (vx, vy) = (lane(velocities, 0), lane(velocities, 1));
        // `solver::view` in the lanes: `c = cos_half |v|`, `c |c|`, and whether the boid sees
        // all round (a full circle, or at rest).
        let speed = avx._mm256_sqrt_pd(
            avx._mm256_add_pd(avx._mm256_mul_pd(vx, vx), avx._mm256_mul_pd(vy, vy)),
        );
        let c = avx._mm256_mul_pd(avx._mm256_set1_pd(cos_half), speed);
        let cc = avx._mm256_mul_pd(c, avx._mm256_andnot_pd(avx._mm256_set1_pd(-0.0), c));
        let all = avx._mm256_castsi256_pd(avx._mm256_set1_epi64x(-i64::from(full_circle)));
        let sees_all = avx._mm256_or_pd(all, avx._mm256_cmp_pd::<_CMP_EQ_OQ>(speed, zero));
        // Slots are below 2³² (`cells.rs`): exact as f64.
        let slot = |s: usize| s as u32 as f64;
        let boids = Boids {
            px: lane(positions, 0),
            py: lane(positions, 1),
            vx,
            vy,
            cc,
            sees_all,
            own: cast(std::array::from_fn::<f64, LANES, _>(|l| slot(first + l))),
            h2: avx._mm256_set1_pd(h2),
            separation2: avx._mm256_set1_pd(separation2),
        };
        let mut sums =
            Sums { count: zero, ax: zero, ay: zero, ux: zero, uy: zero, ox: zero, oy: zero };
        // The row loop specialised on whether it holds the group's own boids (the middle row,
        // `dy = 0`) and whether a lane sees all round (rare: the field-of-view test is then
        // needed as well as skipped).
        let any_all = avx._mm256_movemask_pd(sees_all) != 0;
        for (r, row) in rows.iter().enumerate() {
            match (r == 1, any_all) {
                (false, false) => {
                    boids.row::<false, false>(simd, positions, velocities, row, &mut sums)
                }
                (true, false) => {
                    boids.row::<true, false>(simd, positions, velocities, row, &mut sums)
                }
                (false, true) => {
                    boids.row::<false, true>(simd, positions, velocities, row, &mut sums)
                }
                (true, true) => {
                    boids.row::<true, true>(simd, positions, velocities, row, &mut sums)
                }
            }
        }
        let Sums { count, ax, ay, ux, uy, ox, oy } = sums;
        let (vx, vy) = (boids.vx, boids.vy);
        let one = avx._mm256_set1_pd(1.0);
        let rules = Rules::new(simd, set);
        let inv = avx._mm256_div_pd(one, count);
        let weighted = |weight: f64, (x, y): (__m256d, __m256d)| {
            let weight = avx._mm256_set1_pd(weight);
            (avx._mm256_mul_pd(weight, x), avx._mm256_mul_pd(weight, y))
        };
        let (sx, sy) = weighted(set.separation, rules.steer(ax, ay, vx, vy));
        let (mul, add) = (|a, b| avx._mm256_mul_pd(a, b), |a, b| avx._mm256_add_pd(a, b));
        let (x, y) = weighted(set.alignment, rules.steer(mul(ux, inv), mul(uy, inv), vx, vy));
        let (sx, sy) = (add(sx, x), add(sy, y));
        let (x, y) = weighted(set.cohesion, rules.steer(mul(ox, inv), mul(oy, inv), vx, vy));
        let (sx, sy) = rules.clamp(add(sx, x), add(sy, y), rules.max_force, rules.max_force2);
        // No neighbour in view: no acceleration (`+0`, as `solver::rules` returns).
        let any = avx._mm256_cmp_pd::<{ std::arch::x86_64::_CMP_NEQ_OQ }>(count, zero);
        (avx._mm256_and_pd(any, sx), avx._mm256_and_pd(any, sy), boids, rules)
    }
}

/// The bounds of the cells a task's groups moved their boids into ([`Group::advance`]): the
/// lowest and highest cell `x` and `y` (integers below 2³¹ as f64) per lane.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub(super) struct Span {
    lo: (__m256d, __m256d),
    hi: (__m256d, __m256d),
}

#[cfg(target_arch = "x86_64")]
impl Span {
    /// No cell.
    #[inline(always)]
    pub(super) fn new(simd: pulp::x86::V3) -> Self {
        let avx = simd.avx;
        let (lo, hi) = (avx._mm256_set1_pd(f64::INFINITY), avx._mm256_set1_pd(f64::NEG_INFINITY));
        Span { lo: (lo, lo), hi: (hi, hi) }
    }

    /// The lowest and highest cell `x` and `y` over the lanes (`None`: no cell).
    pub(super) fn extent(self) -> Option<([i64; 2], [i64; 2])> {
        use pulp::bytemuck::cast;
        let fold = |a: __m256d, f: fn(f64, f64) -> f64| {
            let a: [f64; LANES] = cast(a);
            a.into_iter().reduce(f).unwrap_or(f64::NAN)
        };
        let lo = [fold(self.lo.0, f64::min), fold(self.lo.1, f64::min)];
        let hi = [fold(self.hi.0, f64::max), fold(self.hi.1, f64::max)];
        (lo[0] <= hi[0]).then(|| (lo.map(|x| x as i64), hi.map(|x| x as i64)))
    }
}

/// A group's boids in the lanes: positions (m), velocities (m/s), the field of view
/// (`c |c|` with `c = cos_half |v|`, and whether the boid sees all round, a mask), their
/// slots, the squared radii (m²).
#[cfg(target_arch = "x86_64")]
struct Boids {
    px: __m256d,
    py: __m256d,
    vx: __m256d,
    vy: __m256d,
    cc: __m256d,
    sees_all: __m256d,
    own: __m256d,
    h2: __m256d,
    separation2: __m256d,
}

/// The sums of a sweep per lane (`solver::flocking`): the number of neighbours seen,
/// `-Σ d / |d|²` over the close ones (`ax`, `ay`), their velocities (`ux`, `uy`) and offsets
/// (`ox`, `oy`).
#[cfg(target_arch = "x86_64")]
struct Sums {
    count: __m256d,
    ax: __m256d,
    ay: __m256d,
    ux: __m256d,
    uy: __m256d,
    ox: __m256d,
    oy: __m256d,
}

#[cfg(target_arch = "x86_64")]
impl Boids {
    /// Add the candidates of one row of cells, `row[lane]` (slots), to the lanes' sums:
    /// `MINE`, the row holds the group's own boids (each lane skips its own slot); `ALL`,
    /// some lane sees all round. A seen candidate adds its velocity and offset themselves
    /// (a mask instead of the scalar sweep's product by the weight 1; an unseen one adds
    /// `+0` where the scalar sweep adds `±0`: a sum that starts at `+0` is never `-0`, so
    /// both leave it unchanged).
    #[inline(always)]
    fn row<const MINE: bool, const ALL: bool>(
        &self,
        simd: pulp::x86::V3,
        positions: &[DVec3],
        velocities: &[DVec3],
        row: &[Range<usize>; LANES],
        sums: &mut Sums,
    ) {
        use pulp::bytemuck::cast;
        use std::arch::x86_64::{_CMP_GE_OQ, _CMP_GT_OQ, _CMP_LT_OQ, _CMP_NEQ_OQ};
        let avx = simd.avx;
        let Sums { count, ax, ay, ux, uy, ox, oy } = sums;
        let (zero, one) = (avx._mm256_setzero_pd(), avx._mm256_set1_pd(1.0));
        let sign = avx._mm256_set1_pd(-0.0);
        // Slots as f64 (exact below 2⁵³): lane l keeps the candidates in row[l].
        let lo: __m256d = cast(row.clone().map(|r| r.start as u32 as f64));
        let hi: __m256d = cast(row.clone().map(|r| r.end as u32 as f64));
        let (start, end) = (row[0].start, row[LANES - 1].end);
        let mut slot = avx._mm256_set1_pd(start as f64);
        for (p, v) in positions[start..end].iter().zip(&velocities[start..end]) {
            let dx = avx._mm256_sub_pd(avx._mm256_broadcast_sd(&p.x), self.px);
            let dy = avx._mm256_sub_pd(avx._mm256_broadcast_sd(&p.y), self.py);
            let d2 = avx._mm256_add_pd(avx._mm256_mul_pd(dx, dx), avx._mm256_mul_pd(dy, dy));
            let dot =
                avx._mm256_add_pd(avx._mm256_mul_pd(dx, self.vx), avx._mm256_mul_pd(dy, self.vy));
            let mut near = avx._mm256_and_pd(
                avx._mm256_and_pd(
                    avx._mm256_cmp_pd::<_CMP_GE_OQ>(slot, lo),
                    avx._mm256_cmp_pd::<_CMP_LT_OQ>(slot, hi),
                ),
                avx._mm256_cmp_pd::<_CMP_LT_OQ>(d2, self.h2),
            );
            if MINE {
                near = avx._mm256_and_pd(near, avx._mm256_cmp_pd::<_CMP_NEQ_OQ>(slot, self.own));
            }
            let mut front = avx._mm256_cmp_pd::<_CMP_GE_OQ>(
                avx._mm256_mul_pd(dot, avx._mm256_andnot_pd(sign, dot)),
                avx._mm256_mul_pd(self.cc, d2),
            );
            if ALL {
                front = avx._mm256_or_pd(self.sees_all, front);
            }
            let seen = avx._mm256_and_pd(near, front);
            *count = avx._mm256_add_pd(*count, avx._mm256_and_pd(seen, one));
            let tvx = avx._mm256_broadcast_sd(&v.x);
            let tvy = avx._mm256_broadcast_sd(&v.y);
            *ux = avx._mm256_add_pd(*ux, avx._mm256_and_pd(seen, tvx));
            *uy = avx._mm256_add_pd(*uy, avx._mm256_and_pd(seen, tvy));
            *ox = avx._mm256_add_pd(*ox, avx._mm256_and_pd(seen, dx));
            *oy = avx._mm256_add_pd(*oy, avx._mm256_and_pd(seen, dy));
            let close = avx._mm256_and_pd(
                avx._mm256_cmp_pd::<_CMP_LT_OQ>(d2, self.separation2),
                avx._mm256_cmp_pd::<_CMP_GT_OQ>(d2, zero),
            );
            // Every candidate divides, without a branch: a branch on whether a lane has a
            // close one was taken by about a quarter of the candidates and mispredicted
            // (`perf`), while the division unit is otherwise idle. The others add `±0`,
            // which leaves the sums unchanged (never `-0`).
            let q = avx._mm256_and_pd(avx._mm256_and_pd(close, seen), avx._mm256_div_pd(one, d2));
            *ax = avx._mm256_sub_pd(*ax, avx._mm256_mul_pd(dx, q));
            *ay = avx._mm256_sub_pd(*ay, avx._mm256_mul_pd(dy, q));
            slot = avx._mm256_add_pd(slot, one);
        }
    }
}

/// `solver::rules` in the lanes, the same operations in the same order on `x` and `y` (the
/// third component of the scalar code is `+0` throughout for a flat flock with weights
/// `≥ 0`, and adds `+0` to every squared length): each rule's steering
/// `desired · (max_speed / |desired|) - v` (none where `desired` is zero), at most `max_force`
/// long, then their weighted sum, at most `max_force`. Square roots and divisions are
/// correctly rounded in AVX2 as in scalar code, and the branches become selects, so the
/// results are bitwise the scalar ones.
#[cfg(target_arch = "x86_64")]
struct Rules {
    simd: pulp::x86::V3,
    max_speed: __m256d,
    max_speed2: __m256d,
    max_force: __m256d,
    max_force2: __m256d,
}

#[cfg(target_arch = "x86_64")]
impl Rules {
    #[inline(always)]
    fn new(simd: pulp::x86::V3, set: &Settings) -> Self {
        let avx = simd.avx;
        Rules {
            simd,
            max_speed: avx._mm256_set1_pd(set.max_speed),
            max_speed2: avx._mm256_set1_pd(set.max_speed * set.max_speed),
            max_force: avx._mm256_set1_pd(set.max_force),
            max_force2: avx._mm256_set1_pd(set.max_force * set.max_force),
        }
    }

    /// `x · x + y · y`.
    #[inline(always)]
    fn length2(&self, x: __m256d, y: __m256d) -> __m256d {
        let avx = self.simd.avx;
        avx._mm256_add_pd(avx._mm256_mul_pd(x, x), avx._mm256_mul_pd(y, y))
    }

    /// Reynolds' steering towards the desired direction `(x, y)` at velocity `(vx, vy)`.
    #[inline(always)]
    fn steer(&self, x: __m256d, y: __m256d, vx: __m256d, vy: __m256d) -> (__m256d, __m256d) {
        let avx = self.simd.avx;
        let length = avx._mm256_sqrt_pd(self.length2(x, y));
        let scale = avx._mm256_div_pd(self.max_speed, length);
        let sx = avx._mm256_sub_pd(avx._mm256_mul_pd(x, scale), vx);
        let sy = avx._mm256_sub_pd(avx._mm256_mul_pd(y, scale), vy);
        let (sx, sy) = self.clamp(sx, sy, self.max_force, self.max_force2);
        let some = avx
            ._mm256_cmp_pd::<{ std::arch::x86_64::_CMP_NEQ_OQ }>(length, avx._mm256_setzero_pd());
        (avx._mm256_and_pd(some, sx), avx._mm256_and_pd(some, sy))
    }

    /// `(x, y)` at most `max` long, `max2` its square (glam's `clamp_length_max`:
    /// `max · (v / sqrt(|v|²))` where `|v|² > max²`).
    #[inline(always)]
    fn clamp(&self, x: __m256d, y: __m256d, max: __m256d, max2: __m256d) -> (__m256d, __m256d) {
        let avx = self.simd.avx;
        let length2 = self.length2(x, y);
        let length = avx._mm256_sqrt_pd(length2);
        let over = avx._mm256_cmp_pd::<{ std::arch::x86_64::_CMP_GT_OQ }>(length2, max2);
        let cx = avx._mm256_mul_pd(max, avx._mm256_div_pd(x, length));
        let cy = avx._mm256_mul_pd(max, avx._mm256_div_pd(y, length));
        (avx._mm256_blendv_pd(x, cx, over), avx._mm256_blendv_pd(y, cy, over))
    }
}
