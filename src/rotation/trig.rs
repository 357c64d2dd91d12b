//! `sin_cos` and a branch-free `atan2` for the batched rotation conversions, faster than the
//! platform's libm and within a few units in the last place (ulp) of it.
//!
//! `as_euler` spends most of its time in `atan2` (three per rotation), `from_rotvec` in
//! `sin_cos`. Both are a range reduction followed by a truncated Taylor series whose first
//! omitted term bounds the truncation error far below half an ulp, so the total error is that
//! of the rounding in a dozen multiply-adds. The tests check the bounds against libm on
//! millions of arguments across all scales and at the special values.
//!
//! - [`sin_cos`]: Cody–Waite reduction `x = k pi/2 + r` with pi/2 split into three parts of
//!   33 bits (exact products for `|k| < 2^20`), then the Taylor series of `sin r` to `r^17`
//!   and of `cos r` to `r^16` on `|r| <= pi/4` (first omitted terms below `1e-19` and
//!   `2e-18` of the result). Beyond `|x| = 10^6` the reduction would lose bits, so the
//!   platform's `sin_cos` (with its exact Payne–Hanek reduction) takes over.
//! - [`atan2`]: the octant is folded into `t = min(|x|, |y|) / max(|x|, |y|)` in `[0, 1]`,
//!   then `atan t = a_k + atan((t - c_k) / (1 + t c_k))` with `a_k = k pi/8`,
//!   `c_k = tan a_k` (`k = 0, 1, 2`) leaves an argument of at most `tan(pi/16) ≈ 0.199`,
//!   where the Taylor series of `atan` to `u^21` has its first omitted term below `2e-17` of
//!   the result; it is evaluated by Estrin's scheme, whose dependency chain is half of
//!   Horner's. The constants `pi/8, pi/4, pi/2, pi` are added in two parts (Dekker's
//!   head–tail), and signed zeros and infinities follow C99's `atan2`. Finite arguments take a
//!   single path: the octant and the reduction interval index tables of constants instead of
//!   branching, so random angles (`as_euler` of random rotations) cost no mispredictions.

use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, FRAC_PI_8, PI};

/// `pi/2 = PIO2_1 + PIO2_2 + PIO2_3` to 170 bits; the first two have 33 significant bits.
const PIO2_1: f64 = 1.570_796_326_734_125_6;
const PIO2_2: f64 = 6.077_100_506_303_966e-11;
const PIO2_3: f64 = 2.022_266_248_795_950_6e-21;
/// Largest `|x|` reduced by Cody–Waite here (`k <= 2^20`).
const REDUCTION_LIMIT: f64 = 1.0e6;

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

/// `sin r` and `cos r` for `|r| <= pi/4`, Taylor series evaluated by Horner's rule in `r²`.
fn sin_cos_kernel(r: f64) -> (f64, f64) {
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
    (sin, cos)
}

/// `(sin x, cos x)`; within 2 ulp of the platform's `sin_cos` for `|x| <= 10^6` (that
/// function itself beyond). NaN and infinities give NaN, as libm does.
pub fn sin_cos(x: f64) -> (f64, f64) {
    if x.is_nan() || x.abs() > REDUCTION_LIMIT {
        return x.sin_cos();
    }
    // k = round(x · 2/pi) by the 1.5·2^52 trick (no libm call, exact for |k| < 2^51).
    const ROUND: f64 = 6_755_399_441_055_744.0;
    // Reduce |x| (sin is odd, cos even) so that -0 keeps its sign.
    let a = x.abs();
    let k = (a * std::f64::consts::FRAC_2_PI + ROUND) - ROUND;
    let r = ((a - k * PIO2_1) - k * PIO2_2) - k * PIO2_3;
    let (s, c) = sin_cos_kernel(r);
    let (s, c) = match (k as u64) % 4 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    };
    (s * 1.0f64.copysign(x), c)
}

/// `atan u` for `|u| <= tan(pi/16)`: Taylor series to `u^21`, `u + u z p(z)` with `z = u²`
/// and `p` of degree 9 evaluated by Estrin's scheme (pairs, then powers `z², z⁴, z⁸`), a
/// dependency chain of 5 multiply-adds instead of Horner's 10.
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

/// The angle of the point `(x, y)`, in `[-pi, pi]`, as C99's `atan2(y, x)` (signed zeros
/// and infinities included); within 3 ulp of the platform's `atan2` (the reduction's
/// division and subtraction each round once before the series; libm carries extra bits).
///
/// Finite arguments take one path without data-dependent branches (the octant and the
/// reduction interval select table entries), so random angles cost no mispredictions.
pub fn atan2(y: f64, x: f64) -> f64 {
    let (ax, ay) = (x.abs(), y.abs());
    if !(ax.is_finite() && ay.is_finite()) {
        return atan2_not_finite(y, x);
    }
    let (num, den) = (ax.min(ay), ax.max(ay));
    let t = if den == 0.0 { 0.0 } else { num / den };
    // atan t = a_k + atan((t - c_k)/(1 + t c_k)) with c_k = tan a_k, a_k = k pi/8 (for
    // k = 0 the reduction is exact: t/1).
    let k = usize::from(t > TAN_PI_16) + usize::from(t > TAN_3PI_16);
    let c = [0.0, TAN_PI_8, 1.0][k];
    let v = atan_kernel((t - c) / (1.0 + t * c));
    // angle of (|x|, |y|) = base + sign v: a_k + v, or pi/2 - a_k - v when |y| > |x|.
    let i = k + 3 * usize::from(ay > ax);
    let head = FOLD_HEAD[i] + FOLD_SIGN[i] * v;
    let tail = FOLD_TAIL[i];
    // x < 0 mirrors the angle to pi - angle (head and tail separately, then summed).
    let j = usize::from(x.is_sign_negative());
    let angle = (MIRROR_HEAD[j] + MIRROR_SIGN[j] * head) + (MIRROR_TAIL[j] + MIRROR_SIGN[j] * tail);
    angle.copysign(y)
}

/// Heads, tails and signs of `a_k` (`k = 0, 1, 2`), then of `pi/2 - a_k`.
const FOLD_HEAD: [f64; 6] = [0.0, FRAC_PI_8, FRAC_PI_4, FRAC_PI_2, FRAC_3PI_8, FRAC_PI_4];
const FOLD_TAIL: [f64; 6] = [0.0, PI_8_LO, PI_4_LO, PI_2_LO, PI_3_8_LO, PI_4_LO];
const FOLD_SIGN: [f64; 6] = [1.0, 1.0, 1.0, -1.0, -1.0, -1.0];
/// `angle` for `x >= 0`, `pi - angle` for `x < 0`.
const MIRROR_HEAD: [f64; 2] = [0.0, PI];
const MIRROR_TAIL: [f64; 2] = [0.0, PI_LO];
const MIRROR_SIGN: [f64; 2] = [1.0, -1.0];

/// `atan2` when an argument is NaN or infinite (C99 Annex F).
fn atan2_not_finite(y: f64, x: f64) -> f64 {
    if y.is_nan() || x.is_nan() {
        return f64::NAN;
    }
    let angle = match (x.is_infinite(), y.is_infinite()) {
        (true, true) => FRAC_PI_4,
        (true, false) => 0.0,
        _ => FRAC_PI_2,
    };
    let angle = if x.is_sign_negative() { PI - angle } else { angle };
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
        for scale in [1e-300, 1e-8, 1e-3, 0.5, 1.0, 3.2, 10.0, 1e3, 1e5, 9.9e5] {
            for _ in 0..200_000 {
                let x = scale * (2.0 * rnd() - 1.0);
                let ((s, c), (s0, c0)) = (sin_cos(x), x.sin_cos());
                // Near a zero of sin or cos the value is tiny and relative ulps are
                // meaningless: measure there against the size of the argument reduction.
                let floor = f64::EPSILON * 1e-3;
                let (es, ec) = (
                    if s0.abs() > floor { ulps(s, s0) } else { (s - s0).abs() / floor },
                    if c0.abs() > floor { ulps(c, c0) } else { (c - c0).abs() / floor },
                );
                worst = worst.max(es).max(ec);
            }
        }
        assert!(worst <= SIN_COS_ULPS, "worst error {worst} ulp");
    }

    #[test]
    fn sin_cos_special_values() {
        assert_eq!(sin_cos(0.0), (0.0, 1.0));
        assert!(sin_cos(-0.0).0.is_sign_negative());
        let (s, c) = sin_cos(std::f64::consts::FRAC_PI_2);
        assert!((s - 1.0).abs() <= f64::EPSILON && c.abs() < 1e-16);
        assert!(sin_cos(f64::NAN).0.is_nan() && sin_cos(f64::INFINITY).1.is_nan());
        // Beyond the reduction limit libm takes over.
        assert_eq!(sin_cos(1e300), 1e300f64.sin_cos());
        assert_eq!(sin_cos(-2e6), (-2e6f64).sin_cos());
    }

    #[test]
    fn atan2_agrees_with_libm_in_every_octant_and_scale() {
        let mut rnd = stream(2);
        let mut worst: f64 = 0.0;
        for scale in [1e-315, 1e-300, 1e-5, 1.0, 1e5, 1e300, 1.7e308] {
            for _ in 0..300_000 {
                let (y, x) = (scale * (2.0 * rnd() - 1.0), scale * (2.0 * rnd() - 1.0));
                let e = ulps(atan2(y, x), y.atan2(x));
                worst = worst.max(e);
                // Lopsided pairs: angles near 0, pi/2 and pi.
                let e = ulps(atan2(y * 1e-9, x), (y * 1e-9).atan2(x));
                worst = worst.max(e).max(ulps(atan2(y, x * 1e-9), y.atan2(x * 1e-9)));
            }
        }
        // Near each reduction split point.
        for t in [TAN_PI_16, TAN_3PI_16] {
            for k in -20..=20 {
                let y = t + f64::from(k) * f64::EPSILON;
                worst = worst.max(ulps(atan2(y, 1.0), y.atan2(1.0)));
            }
        }
        assert!(worst <= ATAN2_ULPS, "worst error {worst} ulp");
    }

    #[test]
    fn atan2_special_values_follow_c99() {
        let inf = f64::INFINITY;
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
            (inf, inf),
            (-inf, inf),
            (inf, -inf),
            (-inf, -inf),
            (1.0, inf),
            (1.0, -inf),
            (-1.0, -inf),
            (inf, 1.0),
            (-inf, -1.0),
            (1.0, 1.0),
            (1.0, -1.0),
        ];
        for (y, x) in cases {
            let (ours, libm) = (atan2(y, x), y.atan2(x));
            assert!(ulps(ours, libm) <= 1.0, "atan2({y}, {x}) = {ours}, libm {libm}");
            assert_eq!(ours.is_sign_negative(), libm.is_sign_negative(), "sign of atan2({y}, {x})");
        }
        assert!(atan2(f64::NAN, 1.0).is_nan() && atan2(1.0, f64::NAN).is_nan());
    }
}
