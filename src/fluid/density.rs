//! The density pass: for every fluid particle `i`, `ρ̂_i = V W(0) + Σ_j V W_ij + Σ_b V_b W_ib`
//! (Akinci et al. 2012, eq. 6), each pair's `W_ij` (1/m³) and `∇W_ij` (1/m⁴) stored in the
//! neighbour lists' layout, and, for DFSPH and PBF, the factor
//! `α_i = 1 / (|Σ_j V ∇W_ij + Σ_b V_b ∇W_ib|² + Σ_j |V ∇W_ij|²)` (Bender & Koschier 2017,
//! eq. 8; 0 where the sum vanishes).
//!
//! Four particles at a time in the lanes of AVX2 registers where the CPU has AVX2 (found at
//! run time, [`pulp::x86::V3`]; else, and for a chunk's last particles, one at a time): lane
//! `l` walks particle `i + l`'s own list, so each lane does the scalar pass's operations on
//! the same pairs in the same order — square roots and divisions are correctly rounded in
//! AVX2 as in scalar code, the kernels' branches become selects and no fused multiply-add is
//! introduced — and the results are bitwise the scalar pass's (tested). A lane whose list is
//! shorter than the others' computes on its own position and keeps nothing.

use super::kernel::Kernel;
use super::neighbours::Neighbours;
use glam::DVec3;
#[cfg(target_arch = "x86_64")]
use std::arch::x86_64::__m256d;

/// Particles a group of lanes takes together.
pub(super) const LANES: usize = 4;

/// The inputs of the density pass.
pub(super) struct Pass<'a> {
    pub(super) neighbours: &'a Neighbours,
    /// Fluid then boundary points (m), the points of the lists.
    pub(super) points: &'a [DVec3],
    /// Fluid particles (the first `n` points).
    pub(super) n: usize,
    pub(super) kernel: Kernel,
    /// Support radius `h` (m).
    pub(super) h: f64,
    /// Fluid particle volume `V` (m³) and boundary volumes `V_b` (m³).
    pub(super) volume: f64,
    pub(super) boundary_volume: &'a [f64],
    /// Whether to compute DFSPH's factors.
    pub(super) factors: bool,
}

impl Pass<'_> {
    /// The volume of point `j`: `V` for fluid, `V_b` for boundary.
    #[inline(always)]
    fn volume_of(&self, j: usize) -> f64 {
        if j < self.n {
            self.volume
        } else {
            self.boundary_volume[j - self.n]
        }
    }

    /// `α` from the sums `Σ_k |V ∇W_ik|²` over fluid neighbours and `Σ_k V_k ∇W_ik` (m²).
    #[inline(always)]
    fn factor(&self, s: f64, g: DVec3) -> f64 {
        let s = s + g.length_squared();
        if s > 1e-9 / (self.h * self.h) {
            1.0 / s
        } else {
            0.0
        }
    }

    /// Particle `i` alone: its density ratio and factor (0 without `factors`) returned, its
    /// pairs' values and gradients written to its span of its chunk's buffers.
    pub(super) fn one(&self, i: usize, grads: &mut [DVec3], values: &mut [f64]) -> (f64, f64) {
        let (kernel, h) = (self.kernel, self.h);
        let (mut r, mut g, mut s) = (self.volume * kernel.value(0.0, h), DVec3::ZERO, 0.0);
        let (p, start) = (self.points[i], self.neighbours.span(i).start);
        for (k, &j) in self.neighbours.neighbours(i).iter().enumerate() {
            let j = j as usize;
            let d = p - self.points[j];
            let w = self.volume_of(j);
            let distance = d.length();
            let value = kernel.value(distance, h);
            r += w * value;
            values[start + k] = value;
            // `Kernel::gradient` without its second square root.
            let gradient = if distance == 0.0 {
                DVec3::ZERO
            } else {
                d * (kernel.derivative(distance, h) / distance)
            };
            grads[start + k] = gradient;
            if self.factors {
                let gw = gradient * w;
                g += gw;
                if j < self.n {
                    s += gw.length_squared();
                }
            }
        }
        (r, if self.factors { self.factor(s, g) } else { 0.0 })
    }
}

/// The kernel's constants for the lanes: `W = σ f(q)`, `dW/dr = σ' f'(q)` as
/// [`Kernel::value`] and [`Kernel::derivative`] compute them, factor by factor.
#[cfg(target_arch = "x86_64")]
struct Lanes {
    simd: pulp::x86::V3,
    kernel: Kernel,
    h: __m256d,
    /// Cubic spline: `σ`, `2σ`, `σ'`, `-6σ'`; Wendland C2: `σ`, unused, `-20 σ'`, unused.
    c: [__m256d; 4],
}

#[cfg(target_arch = "x86_64")]
impl Lanes {
    #[inline(always)]
    fn new(simd: pulp::x86::V3, kernel: Kernel, h: f64) -> Self {
        use std::f64::consts::PI;
        let c = match kernel {
            Kernel::CubicSpline => {
                let s = 8.0 / (PI * h * h * h);
                let d = 8.0 / (PI * h * h * h * h);
                [s, s * 2.0, d, -d * 6.0]
            }
            Kernel::WendlandC2 => {
                let s = 21.0 / (2.0 * PI * h * h * h);
                let d = -21.0 / (2.0 * PI * h * h * h * h) * 20.0;
                [s, 0.0, d, 0.0]
            }
        };
        let avx = simd.avx;
        let c = [
            avx._mm256_set1_pd(c[0]),
            avx._mm256_set1_pd(c[1]),
            avx._mm256_set1_pd(c[2]),
            avx._mm256_set1_pd(c[3]),
        ];
        Lanes { simd, kernel, h: avx._mm256_set1_pd(h), c }
    }

    /// `W(r)` and `dW/dr` in each lane, bitwise [`Kernel::value`] and
    /// [`Kernel::derivative`] (no closures here: they would not be compiled for AVX2).
    #[inline(always)]
    fn kernel(&self, r: __m256d) -> (__m256d, __m256d) {
        use std::arch::x86_64::{_CMP_GE_OQ, _CMP_LE_OQ};
        let avx = self.simd.avx;
        let one = avx._mm256_set1_pd(1.0);
        let q = avx._mm256_div_pd(r, self.h);
        let t = avx._mm256_sub_pd(one, q);
        let [c0, c1, c2, c3] = self.c;
        let (value, derivative) = match self.kernel {
            Kernel::CubicSpline => {
                let inner = avx._mm256_cmp_pd::<_CMP_LE_OQ>(q, avx._mm256_set1_pd(0.5));
                // σ (6q·q·(q − 1) + 1) or 2σ t t t; σ' q (18q − 12) or −6σ' t t.
                let six_qq = avx._mm256_mul_pd(avx._mm256_mul_pd(avx._mm256_set1_pd(6.0), q), q);
                let cubic = avx._mm256_mul_pd(six_qq, avx._mm256_sub_pd(q, one));
                let near = avx._mm256_mul_pd(c0, avx._mm256_add_pd(cubic, one));
                let far = avx._mm256_mul_pd(avx._mm256_mul_pd(avx._mm256_mul_pd(c1, t), t), t);
                let slope = avx._mm256_sub_pd(
                    avx._mm256_mul_pd(avx._mm256_set1_pd(18.0), q),
                    avx._mm256_set1_pd(12.0),
                );
                let dnear = avx._mm256_mul_pd(avx._mm256_mul_pd(c2, q), slope);
                let dfar = avx._mm256_mul_pd(avx._mm256_mul_pd(c3, t), t);
                (avx._mm256_blendv_pd(far, near, inner), avx._mm256_blendv_pd(dfar, dnear, inner))
            }
            Kernel::WendlandC2 => {
                // σ t t t t (1 + 4q); −20σ' q t t t.
                let t2 = avx._mm256_mul_pd(avx._mm256_mul_pd(c0, t), t);
                let t4 = avx._mm256_mul_pd(avx._mm256_mul_pd(t2, t), t);
                let rise = avx._mm256_add_pd(one, avx._mm256_mul_pd(avx._mm256_set1_pd(4.0), q));
                let dq = avx._mm256_mul_pd(avx._mm256_mul_pd(c2, q), t);
                let d = avx._mm256_mul_pd(avx._mm256_mul_pd(dq, t), t);
                (avx._mm256_mul_pd(t4, rise), d)
            }
        };
        let outside = avx._mm256_cmp_pd::<_CMP_GE_OQ>(q, one);
        (avx._mm256_andnot_pd(outside, value), avx._mm256_andnot_pd(outside, derivative))
    }
}

#[cfg(target_arch = "x86_64")]
impl Pass<'_> {
    /// Particles `i .. i + LANES` (in one chunk, after the chunk's earlier particles), one a
    /// lane: their density ratios and factors returned, their pairs' values and gradients
    /// written to their spans of the chunk's buffers (call inside
    /// [`pulp::x86::V3::vectorize`], so that it is compiled for AVX2; no closures in the
    /// loop, as they would not be).
    #[inline(always)]
    pub(super) fn lanes(
        &self,
        simd: pulp::x86::V3,
        i: usize,
        grads: &mut [DVec3],
        values: &mut [f64],
    ) -> [(f64, f64); LANES] {
        use pulp::bytemuck::cast;
        use std::arch::x86_64::_CMP_EQ_OQ;
        let avx = simd.avx;
        let lanes = Lanes::new(simd, self.kernel, self.h);
        let mut lists: [&[u32]; LANES] = [&[]; LANES];
        let mut starts = [0usize; LANES];
        let (mut px, mut py, mut pz) = ([0.0; LANES], [0.0; LANES], [0.0; LANES]);
        for l in 0..LANES {
            lists[l] = self.neighbours.neighbours(i + l);
            starts[l] = self.neighbours.span(i + l).start;
            let p = self.points[i + l];
            (px[l], py[l], pz[l]) = (p.x, p.y, p.z);
        }
        let longest = lists.iter().map(|l| l.len()).max().unwrap_or(0);
        let (px, py, pz): (__m256d, __m256d, __m256d) = (cast(px), cast(py), cast(pz));
        let zero = avx._mm256_setzero_pd();
        let mut r = avx._mm256_set1_pd(self.volume * self.kernel.value(0.0, self.h));
        let (mut gx, mut gy, mut gz, mut s) = (zero, zero, zero, zero);
        let all = f64::from_bits(u64::MAX);
        for k in 0..longest {
            let (mut qx, mut qy, mut qz, mut w) =
                ([0.0; LANES], [0.0; LANES], [0.0; LANES], [0.0; LANES]);
            let (mut active, mut fluid) = ([0.0; LANES], [0.0; LANES]);
            for l in 0..LANES {
                // A lane past its list's end computes on its own point and keeps nothing.
                let (j, on) = match lists[l].get(k) {
                    Some(&j) => (j as usize, true),
                    None => (i + l, false),
                };
                let q = self.points[j];
                (qx[l], qy[l], qz[l], w[l]) = (q.x, q.y, q.z, self.volume_of(j));
                active[l] = if on { all } else { 0.0 };
                fluid[l] = if on && j < self.n { all } else { 0.0 };
            }
            let (w, active, fluid): (__m256d, __m256d, __m256d) =
                (cast(w), cast(active), cast(fluid));
            let dx = avx._mm256_sub_pd(px, cast(qx));
            let dy = avx._mm256_sub_pd(py, cast(qy));
            let dz = avx._mm256_sub_pd(pz, cast(qz));
            let d2 = avx._mm256_add_pd(
                avx._mm256_add_pd(avx._mm256_mul_pd(dx, dx), avx._mm256_mul_pd(dy, dy)),
                avx._mm256_mul_pd(dz, dz),
            );
            let distance = avx._mm256_sqrt_pd(d2);
            let (value, derivative) = lanes.kernel(distance);
            r = avx._mm256_blendv_pd(r, avx._mm256_add_pd(r, avx._mm256_mul_pd(w, value)), active);
            // `+0` for coincident points, as `Pass::one`.
            let coincident = avx._mm256_cmp_pd::<_CMP_EQ_OQ>(distance, zero);
            let scale = avx._mm256_div_pd(derivative, distance);
            let ax = avx._mm256_andnot_pd(coincident, avx._mm256_mul_pd(dx, scale));
            let ay = avx._mm256_andnot_pd(coincident, avx._mm256_mul_pd(dy, scale));
            let az = avx._mm256_andnot_pd(coincident, avx._mm256_mul_pd(dz, scale));
            let value: [f64; LANES] = cast(value);
            let (ax4, ay4, az4): ([f64; LANES], [f64; LANES], [f64; LANES]) =
                (cast(ax), cast(ay), cast(az));
            for l in 0..LANES {
                if k < lists[l].len() {
                    values[starts[l] + k] = value[l];
                    grads[starts[l] + k] = DVec3::new(ax4[l], ay4[l], az4[l]);
                }
            }
            if self.factors {
                let (wx, wy, wz) =
                    (avx._mm256_mul_pd(ax, w), avx._mm256_mul_pd(ay, w), avx._mm256_mul_pd(az, w));
                gx = avx._mm256_blendv_pd(gx, avx._mm256_add_pd(gx, wx), active);
                gy = avx._mm256_blendv_pd(gy, avx._mm256_add_pd(gy, wy), active);
                gz = avx._mm256_blendv_pd(gz, avx._mm256_add_pd(gz, wz), active);
                let square = avx._mm256_add_pd(
                    avx._mm256_add_pd(avx._mm256_mul_pd(wx, wx), avx._mm256_mul_pd(wy, wy)),
                    avx._mm256_mul_pd(wz, wz),
                );
                s = avx._mm256_blendv_pd(s, avx._mm256_add_pd(s, square), fluid);
            }
        }
        let (r, s): ([f64; LANES], [f64; LANES]) = (cast(r), cast(s));
        let (gx, gy, gz): ([f64; LANES], [f64; LANES], [f64; LANES]) =
            (cast(gx), cast(gy), cast(gz));
        let mut out = [(0.0, 0.0); LANES];
        for l in 0..LANES {
            let alpha =
                if self.factors { self.factor(s[l], DVec3::new(gx[l], gy[l], gz[l])) } else { 0.0 };
            out[l] = (r[l], alpha);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::grid::random_points;

    /// The lanes give bitwise the scalar pass's densities, factors, values and gradients, for
    /// both kernels, with and without factors, on a cloud of fluid and boundary points of
    /// uneven density (lists of different lengths in a group), with coincident points and
    /// pairs at the kernel's branch `q = ½`.
    #[test]
    fn lanes_match_the_scalar_pass_bitwise() {
        let Some(simd) = pulp::x86::V3::try_new() else { return };
        let (n, h) = (1200, 0.125);
        let mut points = random_points(1600, 5, 1.0);
        for p in &mut points[..n / 2] {
            *p *= 0.5; // denser: longer lists
        }
        points[7] = points[8]; // coincident fluid points
        points[11] = points[n + 3]; // a fluid point on a boundary point
        (points[12], points[13]) =
            (DVec3::new(0.125, 0.0625, 0.0), DVec3::new(0.1875, 0.0625, 0.0)); // q = ½ exactly
        let boundary_volume: Vec<f64> =
            (0..1600 - n).map(|b| 1e-4 * (1.0 + b as f64 / 400.0)).collect();
        let mut neighbours = Neighbours::default();
        neighbours.update(&points, n, 0, h, 0.0);
        let mut pairs = 0;
        for kernel in [Kernel::CubicSpline, Kernel::WendlandC2] {
            for factors in [false, true] {
                let pass = Pass {
                    neighbours: &neighbours,
                    points: &points,
                    n,
                    kernel,
                    h,
                    volume: 2e-4,
                    boundary_volume: &boundary_volume,
                    factors,
                };
                let total = neighbours.span(511).end;
                let (mut g1, mut g4) = (vec![DVec3::ZERO; total], vec![DVec3::ZERO; total]);
                let (mut v1, mut v4) = (vec![0.0; total], vec![0.0; total]);
                for first in (0..512).step_by(LANES) {
                    let got = simd.vectorize(|| pass.lanes(simd, first, &mut g4, &mut v4));
                    for (l, got) in got.into_iter().enumerate() {
                        let want = pass.one(first + l, &mut g1, &mut v1);
                        assert_eq!(got.0.to_bits(), want.0.to_bits(), "{kernel:?} {}", first + l);
                        assert_eq!(got.1.to_bits(), want.1.to_bits(), "{kernel:?} {}", first + l);
                    }
                }
                let bits = |g: &[DVec3]| {
                    g.iter().flat_map(|g| g.to_array().map(f64::to_bits)).collect::<Vec<_>>()
                };
                assert_eq!(bits(&g4), bits(&g1));
                assert_eq!(
                    v4.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                    v1.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
                );
                pairs += v1.len();
            }
        }
        assert!(pairs > 4 * 512 * 10, "too few pairs to test: {pairs}");
    }
}
