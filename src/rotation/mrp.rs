//! Modified Rodrigues parameters `p = n tan(θ/4)` (Schaub & Junkins, "Analytical Mechanics of
//! Space Systems", 2003, sec. 3.8): finite for every rotation, norm at most 1 on the
//! shorter-angle representation.

use crate::error::{ensure_finite, Result};
use glam::{DQuat, DVec3};

/// The MRPs of `q` taken with `w >= 0` (angle in `[0, π]`, so `|p| <= 1`): `v / (1 + w)`.
pub fn quat_to_mrp(q: DQuat) -> [f64; 3] {
    let q = if q.w < 0.0 { -q } else { q };
    let s = 1.0 / (1.0 + q.w);
    [q.x * s, q.y * s, q.z * s]
}

/// The rotation of MRPs `p` (any finite 3-vector; `p` and its shadow `-p/|p|²` give the same
/// rotation): `q = ((1 - |p|²), 2p) / (1 + |p|²)`.
///
/// # Errors
/// [`crate::Error::InvalidInput`] (argument `mrp`) for a non-finite vector.
pub fn quat_from_mrp(p: &[f64; 3]) -> Result<DQuat> {
    ensure_finite("mrp", p)?;
    let v = DVec3::from_array(*p);
    let n2 = v.length_squared();
    if !n2.is_finite() {
        // Beyond 1e154: the shadow set -p/|p|² is the same rotation and small.
        let u = v / v.length();
        return quat_from_mrp(&(-u / v.length()).to_array());
    }
    let s = 1.0 / (1.0 + n2);
    let xyz = 2.0 * s * v;
    Ok(DQuat::from_xyzw(xyz.x, xyz.y, xyz.z, (1.0 - n2) * s).normalize())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_quarter_angle_tangent() {
        let q = DQuat::from_axis_angle(DVec3::new(0.0, 0.6, 0.8), 2.0);
        let p = quat_to_mrp(q);
        assert!((DVec3::from_array(p).length() - 0.5_f64.tan()).abs() < 1e-15);
        assert!(quat_from_mrp(&p).unwrap().dot(q).abs() > 1.0 - 1e-15);
        // The half turn has |p| = 1; a huge p is its shadow.
        assert!((quat_to_mrp(DQuat::from_rotation_x(std::f64::consts::PI))[0] - 1.0).abs() < 1e-15);
        assert!(
            quat_from_mrp(&[1e200, 0.0, 0.0]).unwrap().dot(DQuat::IDENTITY).abs() > 1.0 - 1e-15
        );
        assert!(quat_from_mrp(&[f64::NAN, 0.0, 0.0]).is_err());
    }
}
