//! The weighted mean rotation of Markley, Cheng, Crassidis & Oshman 2007, "Averaging
//! Quaternions" (J. Guidance, Control, and Dynamics 30(4)), eq. 13: the unit quaternion
//! maximising `Σ wᵢ (qᵢ · q)²`, the eigenvector of the largest eigenvalue of
//! `Σ wᵢ qᵢ qᵢᵀ`; it minimises the weighted sum of squared chordal distances between the
//! rotation matrices and does not depend on the signs of the `qᵢ`.

use crate::error::{Error, Result};
use glam::DQuat;
use nalgebra::{Matrix4, Vector4};

/// The mean of unit quaternions `quats` (scalar-first) with non-negative `weights` (one per
/// quaternion), as a scalar-first unit quaternion with `w >= 0`.
///
/// # Errors
/// [`Error::InvalidInput`] (argument `weights`) for a negative or non-finite weight or when
/// the weights sum to 0 (including an empty set).
pub fn mean(quats: &[DQuat], weights: &[f64]) -> Result<[f64; 4]> {
    let mut a = Matrix4::zeros();
    let mut total = 0.0;
    for (k, (q, &w)) in quats.iter().zip(weights).enumerate() {
        if !(w >= 0.0 && w.is_finite()) {
            return Err(Error::invalid("weights", "must be finite and non-negative").at(k));
        }
        let v = Vector4::new(q.w, q.x, q.y, q.z);
        a += w * v * v.transpose();
        total += w;
    }
    if !(total > 0.0 && total.is_finite()) {
        return Err(Error::invalid("weights", "must have a positive, finite sum"));
    }
    let eig = (a / total).symmetric_eigen();
    let v = eig.eigenvectors.column(eig.eigenvalues.imax()).normalize();
    let s = if v[0] < 0.0 { -1.0 } else { 1.0 };
    Ok([s * v[0], s * v[1], s * v[2], s * v[3]])
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn mean_of_symmetric_pair_and_sign_invariance() {
        // Rotations by ±a about z average to the identity, whatever the quaternions' signs.
        let (p, m) = (DQuat::from_rotation_z(0.4), DQuat::from_rotation_z(-0.4));
        let got = mean(&[p, -m], &[1.0, 1.0]).unwrap();
        assert!(
            (got[0] - 1.0).abs() < 1e-14 && got[1..].iter().all(|c| c.abs() < 1e-14),
            "{got:?}"
        );
        // Weights 3:1 on the identity and a turn by `a` about one axis: the mean turns about
        // that axis by atan2(sin a, 3 + cos a) (maximise 3cos²φ + cos²(φ - a/2), φ half the angle).
        let (axis, a) = (DVec3::new(0.0, 0.6, 0.8), 1.0_f64);
        let q = mean(&[DQuat::from_axis_angle(axis, a), DQuat::IDENTITY], &[1.0, 3.0]).unwrap();
        let want = DQuat::from_axis_angle(axis, a.sin().atan2(3.0 + a.cos()));
        assert!((q[0] - want.w).abs() < 1e-15 && (q[3] - want.z).abs() < 1e-15, "{q:?}");
        assert!(q[1].abs() < 1e-15 && (q[2] * 0.8 - q[3] * 0.6).abs() < 1e-15);
        assert!(mean(&[p], &[-1.0]).is_err() && mean(&[], &[]).is_err());
        assert!(mean(&[p, m], &[0.0, 0.0]).is_err());
    }
}
