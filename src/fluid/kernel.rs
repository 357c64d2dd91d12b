//! SPH smoothing kernels in 3-D, written with the support radius `h` (the kernel is zero for
//! `r ≥ h`), as SPlisHSPlasH does: `W(r) = σ f(q)` with `q = r / h` and `σ` such that
//! `∫ W dV = 1`.
//!
//! - Cubic spline (Monaghan 1992, "Smoothed particle hydrodynamics", eq. 2.6, rescaled to the
//!   support `h`): `σ = 8 / (π h³)`, `f = 6q³ - 6q² + 1` for `q ≤ ½`, `2 (1 - q)³` for
//!   `q ≤ 1`.
//! - Wendland C2 (Wendland 1995; Dehnen & Aly 2012, table 1): `σ = 21 / (2π h³)`,
//!   `f = (1 - q)⁴ (1 + 4q)`.
//!
//! And the cohesion spline of surface tension, [`cohesion`] (Akinci, Akinci & Teschner 2013).

use glam::DVec3;
use std::f64::consts::PI;

/// The smoothing kernel of a fluid.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Kernel {
    /// The cubic B-spline (Monaghan 1992), the default.
    #[default]
    CubicSpline,
    /// Wendland's C2 kernel (Wendland 1995), without pairing instability.
    WendlandC2,
}

impl Kernel {
    /// `W(r)` (1/m³) for a distance `r ≥ 0` (m) and support radius `h` (m).
    pub fn value(self, r: f64, h: f64) -> f64 {
        let q = r / h;
        if q >= 1.0 {
            return 0.0;
        }
        match self {
            Kernel::CubicSpline => {
                let s = 8.0 / (PI * h * h * h);
                if q <= 0.5 {
                    s * (6.0 * q * q * (q - 1.0) + 1.0)
                } else {
                    let t = 1.0 - q;
                    s * 2.0 * t * t * t
                }
            }
            Kernel::WendlandC2 => {
                let t = 1.0 - q;
                21.0 / (2.0 * PI * h * h * h) * t * t * t * t * (1.0 + 4.0 * q)
            }
        }
    }

    /// `dW/dr` (1/m⁴) at distance `r ≥ 0` (m) for support radius `h` (m); 0 at `r = 0`.
    pub fn derivative(self, r: f64, h: f64) -> f64 {
        let q = r / h;
        if q >= 1.0 {
            return 0.0;
        }
        match self {
            Kernel::CubicSpline => {
                let s = 8.0 / (PI * h * h * h * h);
                if q <= 0.5 {
                    s * q * (18.0 * q - 12.0)
                } else {
                    let t = 1.0 - q;
                    -s * 6.0 * t * t
                }
            }
            Kernel::WendlandC2 => {
                let t = 1.0 - q;
                -21.0 / (2.0 * PI * h * h * h * h) * 20.0 * q * t * t * t
            }
        }
    }

    /// `∇W(d)` (1/m⁴) with respect to the first point, for `d = x_i - x_j` (m): `dW/dr d / r`,
    /// zero for coincident points.
    pub fn gradient(self, d: DVec3, h: f64) -> DVec3 {
        let r = d.length();
        if r == 0.0 {
            return DVec3::ZERO;
        }
        d * (self.derivative(r, h) / r)
    }
}

/// Akinci, Akinci & Teschner's (2013, eq. 2) cohesion spline `C(r)` (1/m³) for a distance
/// `r ≥ 0` (m) and support `h` (m): `32 / (π h⁹)` times `(h - r)³ r³` for `h/2 < r ≤ h`,
/// `2 (h - r)³ r³ - h⁶/64` for `r ≤ h/2`, 0 beyond `h`: attraction, largest at `h/2`, turning
/// to repulsion at short range.
pub fn cohesion(r: f64, h: f64) -> f64 {
    if r >= h {
        return 0.0;
    }
    let (t, r3) = ((h - r).powi(3), r.powi(3));
    let f = if 2.0 * r > h { t * r3 } else { 2.0 * t * r3 - h.powi(6) / 64.0 };
    32.0 / (PI * h.powi(9)) * f
}

#[cfg(test)]
mod tests {
    use super::*;

    const KERNELS: [Kernel; 2] = [Kernel::CubicSpline, Kernel::WendlandC2];

    /// `∫ W dV = 4π ∫₀ʰ W(r) r² dr` by composite Simpson's rule on 2000 intervals (exact to
    /// ~1e-13 for these piecewise polynomials, whose pieces meet at nodes).
    #[test]
    fn integral_over_support_is_one() {
        for k in KERNELS {
            let h = 0.037;
            let n = 2000;
            let dr = h / n as f64;
            let f = |r: f64| 4.0 * PI * r * r * k.value(r, h);
            let mut sum = f(0.0) + f(h);
            for i in 1..n {
                sum += f(i as f64 * dr) * if i % 2 == 1 { 4.0 } else { 2.0 };
            }
            let integral = sum * dr / 3.0;
            assert!((integral - 1.0).abs() < 1e-10, "{k:?}: {integral}");
        }
    }

    #[test]
    fn gradient_matches_central_differences() {
        let h = 0.1;
        for k in KERNELS {
            for d in [
                DVec3::new(0.01, 0.02, -0.03),
                DVec3::new(0.04, -0.01, 0.02),
                DVec3::new(-0.06, 0.05, 0.04),
                DVec3::new(0.02, 0.0, 0.0),
            ] {
                let e = 1e-6;
                let fd = DVec3::new(
                    k.value((d + DVec3::X * e).length(), h)
                        - k.value((d - DVec3::X * e).length(), h),
                    k.value((d + DVec3::Y * e).length(), h)
                        - k.value((d - DVec3::Y * e).length(), h),
                    k.value((d + DVec3::Z * e).length(), h)
                        - k.value((d - DVec3::Z * e).length(), h),
                ) / (2.0 * e);
                let g = k.gradient(d, h);
                assert!((g - fd).length() <= 1e-6 * g.length().max(1.0), "{k:?} {d}: {g} vs {fd}");
            }
            assert_eq!(k.gradient(DVec3::ZERO, h), DVec3::ZERO);
        }
    }

    #[test]
    fn compact_support_and_continuity() {
        let h = 0.2;
        for k in KERNELS {
            for r in [h, 1.0000001 * h, 2.0 * h, 1e300] {
                assert_eq!(k.value(r, h), 0.0);
                assert_eq!(k.derivative(r, h), 0.0);
            }
            // Continuous at the support's edge and (cubic spline) at q = 1/2.
            assert!(k.value(0.999999 * h, h) < 1e-12 * k.value(0.0, h));
            let (a, b) = (k.value(0.4999999 * h, h), k.value(0.5000001 * h, h));
            assert!((a - b).abs() < 1e-5 * a, "{k:?}");
            // Positive and decreasing inside the support.
            let mut last = f64::INFINITY;
            for i in 0..100 {
                let w = k.value(i as f64 / 100.0 * h, h);
                assert!(w > 0.0 && w < last);
                last = w;
            }
        }
    }

    #[test]
    fn cohesion_spline() {
        let h = 0.2;
        assert_eq!(cohesion(h, h), 0.0);
        assert_eq!(cohesion(2.0 * h, h), 0.0);
        // Continuous at h/2, where it peaks at 1 / (2π h³); repulsive near 0.
        let peak = cohesion(0.5 * h, h);
        assert!((peak * 2.0 * PI * h.powi(3) - 1.0).abs() < 1e-12, "{peak}");
        assert!((cohesion(0.4999999 * h, h) / peak - 1.0).abs() < 1e-5);
        assert!((cohesion(0.5000001 * h, h) / peak - 1.0).abs() < 1e-5);
        assert!(cohesion(0.0, h) < 0.0 && cohesion(0.3 * h, h) > 0.0);
        for i in 1..100 {
            assert!(cohesion(i as f64 / 100.0 * h, h) <= peak);
        }
    }
}
