//! The two blends of bone transforms at one vertex: linear blend skinning and dual
//! quaternion skinning (Kavan, Collins, Žára & O'Sullivan 2008).

use glam::{DQuat, DVec3};

/// A rigid transform `x ↦ R x + t`.
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub(super) struct Transform {
    pub(super) rotation: DQuat,
    pub(super) translation: DVec3,
}

impl Transform {
    /// The transform that undoes this one.
    pub(super) fn inverse(&self) -> Transform {
        let rotation = self.rotation.conjugate();
        Transform { rotation, translation: -(rotation * self.translation) }
    }

    /// `self ∘ first`: `first` applied, then `self`.
    pub(super) fn then(&self, first: &Transform) -> Transform {
        Transform {
            rotation: (self.rotation * first.rotation).normalize(),
            translation: self.rotation * first.translation + self.translation,
        }
    }

    fn apply(&self, x: DVec3) -> DVec3 {
        self.rotation * x + self.translation
    }
}

/// Linear blend skinning of `x`: `Σ w_i S_{b_i} x` over the influences `(bones, weights)`.
pub(super) fn linear(skinning: &[Transform], bones: &[u32], weights: &[f64], x: DVec3) -> DVec3 {
    bones.iter().zip(weights).fold(DVec3::ZERO, |sum, (&b, &w)| {
        if w == 0.0 {
            sum
        } else {
            sum + w * skinning[b as usize].apply(x)
        }
    })
}

/// Dual quaternion skinning of `x` (Kavan et al. 2008, eq. 4–5): the dual quaternions
/// `q̂_i = q_i + ε ½ t_i q_i` of the influences blended with the weights, each signed to lie
/// in the hemisphere of the most weighted one's rotation (section 4.1), normalised by the
/// real part's norm, then applied: `x' = r x r̄ + 2 vec(d r̄)`.
pub(super) fn dual_quaternion(
    skinning: &[Transform],
    bones: &[u32],
    weights: &[f64],
    x: DVec3,
) -> DVec3 {
    let pivot = weights
        .iter()
        .enumerate()
        .fold(0, |best, (i, &w)| if w > weights[best] { i } else { best });
    let reference = skinning[bones[pivot] as usize].rotation;
    let (mut real, mut dual) =
        (DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0), DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0));
    for (&b, &w) in bones.iter().zip(weights) {
        if w == 0.0 {
            continue;
        }
        let s = &skinning[b as usize];
        let w = if s.rotation.dot(reference) < 0.0 { -w } else { w };
        let t = s.translation;
        let d = DQuat::from_xyzw(t.x, t.y, t.z, 0.0) * s.rotation * 0.5;
        real += s.rotation * w;
        dual += d * w;
    }
    let n = real.length();
    let (r, d) = (real * (1.0 / n), dual * (1.0 / n));
    let t = d * r.conjugate();
    r * x + 2.0 * DVec3::new(t.x, t.y, t.z)
}
