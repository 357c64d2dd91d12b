//! Branch-free `atan2` and `sin_cos` for the batched rotation kernels, within 3 and 2 units
//! in the last place (ulp) of libm. Written as selects instead of branches, so that a loop
//! over lanes of rotations compiles to SIMD (SSE2, or AVX2 or AVX-512 where the CPU has
//! it), which libm's scalar, branching functions cannot; as plain scalar replacements they
//! are no faster than glibc's (measured), so they serve the lane kernels and the row-by-row
//! functions those must equal bitwise.
//!
//! `atan2`: the octant is folded into `t = min(|x|, |y|) / max(|x|, |y|)` in `[0, 1]`, then
//! `atan t = a_k + atan((t - c_k) / (1 + t c_k))` with `a_k = k pi/8`, `c_k = tan a_k`
//! (`k = 0, 1, 2`) leaves an argument of at most `tan(pi/16) ≈ 0.199`, where the Taylor series
//! of `atan` to `u^21` has its first omitted term below `2e-17` of the result (evaluated by
//! Estrin's scheme, whose dependency chain is half of Horner's). The constants
//! `pi/8, pi/4, pi/2, pi` are added in two parts (Dekker's head–tail); signed zeros and the
//! axes follow C99's `atan2` (arguments are finite: rotations are checked first).
//! `sin_cos`: see [`sin_cos_reduced`]. The tests check both bounds against libm on millions
//! of arguments across all scales and at the special values.

use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, FRAC_PI_8, PI};

/// Tails of the constants (`PI - f64(PI)` and so on) and `3 pi/8` as head and tail.
const PI_LO: f64 = 1.224_646_799_147_353_2e-16;
const PI_2_LO: f64 = 6.123_233_995_736_766e-17;
const PI_4_LO: f64 = 3.061_616_997_868_383e-17;
const PI_8_LO: f64 = 1.530_808_498_934_191_5e-17;
const FRAC_3PI_8: f64 = 1.178_097_245_096_172_4;
const PI_3_8_LO: f64 = 4.592_425_496_802_574e-17;
/// `tan(pi/8) = sqrt(2) - 1`, correctly rounded.
const TAN_PI_8: f64 = 0.414_213_562_373_095_03;
/// Split points of the `atan` reduction: `tan(pi/16)` and `tan(3 pi/16)`.
const TAN_PI_16: f64 = 0.198_912_367_379_658;
const TAN_3PI_16: f64 = 0.668_178_637_919_298_9;

/// `pi/2 = PIO2_1 + PIO2_2 + PIO2_3` to 170 bits; the first two have 33 significant bits.
const PIO2_1: f64 = 1.570_796_326_734_125_6;
const PIO2_2: f64 = 6.077_100_506_303_966e-11;
const PIO2_3: f64 = 2.022_266_248_795_950_6e-21;
/// Largest `|x|` that [`sin_cos_reduced`] takes (`k <= 2^20` keeps the reduction exact).
pub const SIN_COS_LIMIT: f64 = 1.0e6;

/// `(sin x, cos x)` for `|x| <= SIN_COS_LIMIT`, within 2 ulp of the platform's `sin_cos`,
/// without branches (selects only), so loops over lanes vectorise: Cody–Waite reduction
/// `x = k pi/2 + r` with pi/2 in three 33-bit parts, then the Taylor series of `sin r` to
/// `r^17` and of `cos r` to `r^16` on `|r| <= pi/4` (first omitted terms below `1e-19` and
/// `2e-18` of the result), and the quadrant `k mod 4` from the bits of the rounded `k`.
#[inline(always)]
pub fn sin_cos_reduced(x: f64) -> (f64, f64) {
    // k = round(|x| 2/pi) by the 1.5·2^52 trick: its low bits are those of k.
    const ROUND: f64 = 6_755_399_441_055_744.0;
    let a = x.abs(); // sin is odd, cos even: reduce |x| so that -0 keeps its sign
    let shifted = a * std::f64::consts::FRAC_2_PI + ROUND;
    let quadrant = shifted.to_bits() & 3;
    let k = shifted - ROUND;
    let r = ((a - k * PIO2_1) - k * PIO2_2) - k * PIO2_3;
    let z = r * r;
    // sin r = r (1 - z/3! + z²/5! - ... + z⁸/17!)
    let s = 2.811_457_254_345_520_6e-15;
    let s = s * z - 7.647_163_731_819_816e-13;
    let s = s * z + 1.605_904_383_682_161_3e-10;
    let s = s * z - 2.505_210_838_544_172e-8;
    let s = s * z + 2.755_731_922_398_589_3e-6;
    let s = s * z - 1.984_126_984_126_984e-4;
    let s = s * z + 8.333_333_333_333_333e-3;
    let s = s * z - 1.666_666_666_666_666_6e-1;
    let sin = r + r * z * s;
    // cos r = 1 - z/2! + z²/4! - ... + z⁸/16!
    let c = 4.779_477_332_387_385e-14;
    let c = c * z - 1.147_074_559_772_972_5e-11;
    let c = c * z + 2.087_675_698_786_81e-9;
    let c = c * z - 2.755_731_922_398_589e-7;
    let c = c * z + 2.480_158_730_158_73e-5;
    let c = c * z - 1.388_888_888_888_889e-3;
    let c = c * z + 4.166_666_666_666_666_4e-2;
    let cos = 1.0 - 0.5 * z + z * z * c;
    // Quadrants 1 and 3 swap sine and cosine; 1 and 2 negate the cosine, 2 and 3 the sine.
    let odd = quadrant & 1 == 1;
    let (s1, c1) = (if odd { cos } else { sin }, if odd { sin } else { cos });
    let s2 = if quadrant & 2 == 2 { -s1 } else { s1 };
    let c2 = if quadrant == 1 || quadrant == 2 { -c1 } else { c1 };
    (s2 * 1.0f64.copysign(x), c2)
}

/// `atan u` for `|u| <= tan(pi/16)`: Taylor series to `u^21`, `u + u z p(z)` with `z = u²`
/// and `p` of degree 9 evaluated by Estrin's scheme.
#[inline(always)]
fn atan_kernel(u: f64) -> f64 {
    let z = u * u;
    let z2 = z * z;
    let z4 = z2 * z2;
    let p01 = -1.0 / 3.0 + z * (1.0 / 5.0);
    let p23 = -1.0 / 7.0 + z * (1.0 / 9.0);
    let p45 = -1.0 / 11.0 + z * (1.0 / 13.0);
    let p67 = -1.0 / 15.0 + z * (1.0 / 17.0);
    let p89 = -1.0 / 19.0 + z * (1.0 / 21.0);
    let p03 = p01 + z2 * p23;
    let p47 = p45 + z2 * p67;
    let p = p03 + z4 * (p47 + z4 * p89);
    u + u * z * p
}

/// The angle of the point `(x, y)` in `[-pi, pi]` for finite arguments, as C99's
/// `atan2(y, x)` (signed zeros included), within 3 ulp of the platform's; without branches
/// (selects only), so loops over lanes vectorise.
#[inline(always)]
pub fn atan2_finite(y: f64, x: f64) -> f64 {
    let (ax, ay) = (x.abs(), y.abs());
    let swap = ay > ax;
    let num = if swap { ax } else { ay };
    let den = if swap { ay } else { ax };
    let ratio = num / den; // 0/0 = NaN when both are zero: replaced by 0 below
    let t = if den == 0.0 { 0.0 } else { ratio };
    let (mid, high) = (t > TAN_PI_16, t > TAN_3PI_16);
    let c = if high {
        1.0
    } else if mid {
        TAN_PI_8
    } else {
        0.0
    };
    let v = atan_kernel((t - c) / (1.0 + t * c));
    // angle of (|x|, |y|) = a_k + v, or pi/2 - a_k - v when |y| > |x|, as head + tail.
    let (a_hi, a_lo) = if high {
        (FRAC_PI_4, PI_4_LO)
    } else if mid {
        (FRAC_PI_8, PI_8_LO)
    } else {
        (0.0, 0.0)
    };
    let (r_hi, r_lo) = if high {
        (FRAC_PI_4, PI_4_LO)
    } else if mid {
        (FRAC_3PI_8, PI_3_8_LO)
    } else {
        (FRAC_PI_2, PI_2_LO)
    };
    let head = if swap { r_hi - v } else { a_hi + v };
    let tail = if swap { r_lo } else { a_lo };
    // x < 0 mirrors the angle to pi - angle (head and tail separately, then summed).
    let neg = x.is_sign_negative();
    let angle = if neg { (PI - head) + (PI_LO - tail) } else { head + tail };
    angle.copysign(y)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Distance in units in the last place of `exact`.
    fn ulps(value: f64, exact: f64) -> f64 {
        if value == exact {
            return 0.0;
        }
        let ulp = if exact == 0.0 {
            f64::from_bits(1)
        } else {
            let e = exact.abs();
            f64::from_bits(e.to_bits() + 1) - e
        };
        (value - exact).abs() / ulp
    }

    /// xorshift64*: a fixed, dependency-free stream of arguments.
    fn stream(seed: u64) -> impl FnMut() -> f64 {
        let mut s = seed;
        move || {
            s ^= s >> 12;
            s ^= s << 25;
            s ^= s >> 27;
            (s.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// The documented bounds against libm (whose results are within 1 ulp of exact).
    const SIN_COS_ULPS: f64 = 2.0;
    const ATAN2_ULPS: f64 = 3.0;

    #[test]
    fn sin_cos_agrees_with_libm_across_scales() {
        let mut rnd = stream(1);
        let mut worst: f64 = 0.0;
        for scale in [1e-300, 1e-8, 1e-3, 0.5, 1.0, 3.0, 10.0, 1e3, 1e6] {
            for _ in 0..200_000 {
                let x = scale * (2.0 * rnd() - 1.0);
                let (s, c) = sin_cos_reduced(x);
                let (s0, c0) = x.sin_cos();
                worst = worst.max(ulps(s, s0)).max(ulps(c, c0));
            }
        }
        // Near multiples of pi/4 (the reduction's edges) and exact zeros.
        for k in -40..=40 {
            for d in [-1e-12, 0.0, 1e-12] {
                let x = f64::from(k) * std::f64::consts::FRAC_PI_4 + d;
                let ((s, c), (s0, c0)) = (sin_cos_reduced(x), x.sin_cos());
                worst = worst.max(ulps(s, s0)).max(ulps(c, c0));
            }
        }
        assert!(worst <= SIN_COS_ULPS, "worst error {worst} ulp");
        assert_eq!(sin_cos_reduced(-0.0).0.to_bits(), (-0.0f64).to_bits());
        assert_eq!(sin_cos_reduced(0.0), (0.0, 1.0));
    }

    #[test]
    fn atan2_agrees_with_libm_in_every_octant_and_scale() {
        let mut rnd = stream(2);
        let mut worst: f64 = 0.0;
        for scale in [1e-315, 1e-300, 1e-5, 1.0, 1e5, 1e300, 1.7e308] {
            for _ in 0..300_000 {
                let (y, x) = (scale * (2.0 * rnd() - 1.0), scale * (2.0 * rnd() - 1.0));
                let e = ulps(atan2_finite(y, x), y.atan2(x));
                worst = worst.max(e);
                // Lopsided pairs: angles near 0, pi/2 and pi.
                let e = ulps(atan2_finite(y * 1e-9, x), (y * 1e-9).atan2(x));
                worst = worst.max(e).max(ulps(atan2_finite(y, x * 1e-9), y.atan2(x * 1e-9)));
            }
        }
        // Near each reduction split point.
        for t in [TAN_PI_16, TAN_3PI_16] {
            for k in -20..=20 {
                let y = t + f64::from(k) * f64::EPSILON;
                worst = worst.max(ulps(atan2_finite(y, 1.0), y.atan2(1.0)));
            }
        }
        assert!(worst <= ATAN2_ULPS, "worst error {worst} ulp");
    }

    #[test]
    fn atan2_signed_zeros_and_axes_follow_c99() {
        let cases = [
            (0.0, 1.0),
            (-0.0, 1.0),
            (0.0, -1.0),
            (-0.0, -1.0),
            (0.0, 0.0),
            (-0.0, 0.0),
            (0.0, -0.0),
            (-0.0, -0.0),
            (1.0, 0.0),
            (-1.0, -0.0),
            (f64::MAX, f64::MAX),
            (-f64::MIN_POSITIVE, f64::MAX),
            (1.0, 1.0),
            (1.0, -1.0),
        ];
        for (y, x) in cases {
            let (ours, libm) = (atan2_finite(y, x), y.atan2(x));
            assert!(ulps(ours, libm) <= 1.0, "atan2({y}, {x}) = {ours}, libm {libm}");
            assert_eq!(ours.is_sign_negative(), libm.is_sign_negative(), "sign of atan2({y}, {x})");
        }
    }
}
