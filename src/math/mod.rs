//! Small math helpers shared by every system: outer products, cross-product matrices,
//! angle wrapping, and the small dense SVD ([`svd`]). Imports no system of kinema.

pub(crate) mod svd;

use glam::{DMat3, DVec3};
use std::f64::consts::{PI, TAU};

/// `a bᵀ`, the 3×3 outer product.
#[inline(always)]
pub fn outer(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// `[a]ₓ`, the matrix of `p ↦ a × p`.
#[inline(always)]
pub fn skew(a: DVec3) -> DMat3 {
    DMat3::from_cols(
        DVec3::new(0.0, a.z, -a.y),
        DVec3::new(-a.z, 0.0, a.x),
        DVec3::new(a.y, -a.x, 0.0),
    )
}

/// The angle `a` (rad) wrapped to `(-π, π]`: `a − 2π ⌈(a − π)/2π⌉`, exact (returned unchanged)
/// for `a` already in that range, one rounding otherwise.
#[inline]
pub fn wrap_angle(a: f64) -> f64 {
    a - TAU * ((a - PI) / TAU).ceil()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outer_and_skew_are_the_products_they_stand_for() {
        let (a, b, p) =
            (DVec3::new(1.0, -2.0, 3.0), DVec3::new(0.5, 4.0, -1.0), DVec3::new(2.0, 1.0, -3.0));
        assert_eq!(outer(a, b) * p, a * b.dot(p));
        assert_eq!(skew(a) * p, a.cross(p));
    }

    #[test]
    fn wrap_angle_lands_in_the_half_open_interval() {
        for a in [0.0, 1.0, -1.0, PI, 3.0, -3.0] {
            assert_eq!(wrap_angle(a), a, "{a} is in range");
        }
        assert_eq!(wrap_angle(-PI), PI);
        for k in -50..=50 {
            let a = 0.37 * k as f64;
            let w = wrap_angle(a);
            assert!(w > -PI && w <= PI, "{a} -> {w}");
            let turns = (a - w) / TAU;
            assert!((turns - turns.round()).abs() < 1e-12, "{a} -> {w}");
        }
    }
}
