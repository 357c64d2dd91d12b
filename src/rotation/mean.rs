//! The weighted mean rotation of Markley, Cheng, Crassidis & Oshman 2007, "Averaging
//! Quaternions" (J. Guidance, Control, and Dynamics 30(4)), eq. 13: the unit quaternion
//! maximising `Σ wᵢ (qᵢ · q)²`, the eigenvector of the largest eigenvalue of
//! `Σ wᵢ qᵢ qᵢᵀ`; it minimises the weighted sum of squared chordal distances between the
//! rotation matrices and does not depend on the signs of the `qᵢ`.

use super::quat::quat_from_wxyz;
use crate::batch::sum;
use crate::error::{Error, Result};
use nalgebra::Matrix4;

/// The mean of the quaternions `quats` (scalar-first; normalised as [`quat_from_wxyz`] does)
/// with non-negative `weights` (one per quaternion), as a scalar-first unit quaternion with
/// `w >= 0`. The sum `Σ wᵢ qᵢ qᵢᵀ` is taken in fixed chunks ([`crate::batch::sum`]), in
/// parallel for large sets and bitwise the same for any thread count.
///
/// # Errors
/// [`Error::InvalidInput`] naming `quat` (zero or non-finite, with its index) or `weights`
/// (negative or non-finite, with its index; or summing to 0, including an empty set).
pub fn mean(quats: &[[f64; 4]], weights: &[f64]) -> Result<[f64; 4]> {
    if weights.len() != quats.len() {
        return Err(Error::invalid("weights", "must hold one weight per rotation"));
    }
    // The 10 entries of the upper triangle of Σ wᵢ qᵢ qᵢᵀ, row by row, and Σ wᵢ. A chunk of
    // unit quaternions and valid weights (the common case) is summed in one branch-free
    // loop; any other chunk again row by row through `quat_from_wxyz`, which normalises and
    // reports a bad row (and takes unit rows unchanged, so both loops give the same bits).
    let s = sum(quats.len(), |range| {
        let (mut acc, mut fine) = ([0.0; 11], true);
        for k in range.clone() {
            let (v, w) = (quats[k], weights[k]);
            let n2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2] + v[3] * v[3];
            fine &= (n2 - 1.0).abs() <= 4.0 * f64::EPSILON && w >= 0.0 && w.is_finite();
            add_outer(&mut acc, v, w);
        }
        if !fine {
            acc = [0.0; 11];
            for k in range {
                let w = weights[k];
                if !(w >= 0.0 && w.is_finite()) {
                    return Err(Error::invalid("weights", "must be finite and non-negative").at(k));
                }
                let q = quat_from_wxyz(&quats[k]).map_err(|e| e.at(k))?;
                add_outer(&mut acc, [q.w, q.x, q.y, q.z], w);
            }
        }
        Ok(acc)
    })?;
    let total = s[10];
    if !(total > 0.0 && total.is_finite()) {
        return Err(Error::invalid("weights", "must have a positive, finite sum"));
    }
    #[rustfmt::skip]
    let a = Matrix4::new(
        s[0], s[1], s[2], s[3],
        s[1], s[4], s[5], s[6],
        s[2], s[5], s[7], s[8],
        s[3], s[6], s[8], s[9],
    ) / total;
    let eig = a.symmetric_eigen();
    let v = eig.eigenvectors.column(eig.eigenvalues.imax()).normalize();
    let s = if v[0] < 0.0 { -1.0 } else { 1.0 };
    Ok([s * v[0], s * v[1], s * v[2], s * v[3]])
}

/// Add `w v vᵀ` (upper triangle, row by row) and `w` to `acc`.
#[inline(always)]
fn add_outer(acc: &mut [f64; 11], v: [f64; 4], w: f64) {
    let wv = v.map(|c| w * c);
    let terms = [
        wv[0] * v[0],
        wv[0] * v[1],
        wv[0] * v[2],
        wv[0] * v[3],
        wv[1] * v[1],
        wv[1] * v[2],
        wv[1] * v[3],
        wv[2] * v[2],
        wv[2] * v[3],
        wv[3] * v[3],
        w,
    ];
    for (a, t) in acc.iter_mut().zip(terms) {
        *a += t;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DQuat, DVec3};

    fn rows(qs: &[DQuat]) -> Vec<[f64; 4]> {
        qs.iter().map(|q| [q.w, q.x, q.y, q.z]).collect()
    }

    #[test]
    fn mean_of_symmetric_pair_and_sign_invariance() {
        // Rotations by ±a about z average to the identity, whatever the quaternions' signs.
        let (p, m) = (DQuat::from_rotation_z(0.4), DQuat::from_rotation_z(-0.4));
        let got = mean(&rows(&[p, -m]), &[1.0, 1.0]).unwrap();
        assert!(
            (got[0] - 1.0).abs() < 1e-14 && got[1..].iter().all(|c| c.abs() < 1e-14),
            "{got:?}"
        );
        // Weights 3:1 on the identity and a turn by `a` about one axis: the mean turns about
        // that axis by atan2(sin a, 3 + cos a) (maximise 3cos²φ + cos²(φ - a/2), φ half the angle).
        let (axis, a) = (DVec3::new(0.0, 0.6, 0.8), 1.0_f64);
        let q =
            mean(&rows(&[DQuat::from_axis_angle(axis, a), DQuat::IDENTITY]), &[1.0, 3.0]).unwrap();
        let want = DQuat::from_axis_angle(axis, a.sin().atan2(3.0 + a.cos()));
        assert!((q[0] - want.w).abs() < 1e-15 && (q[3] - want.z).abs() < 1e-15, "{q:?}");
        assert!(q[1].abs() < 1e-15 && (q[2] * 0.8 - q[3] * 0.6).abs() < 1e-15);
        assert!(mean(&rows(&[p]), &[-1.0]).is_err() && mean(&[], &[]).is_err());
        assert!(mean(&rows(&[p, m]), &[0.0, 0.0]).is_err());
        assert!(mean(&[[0.0; 4]], &[1.0]).is_err());
    }
}
