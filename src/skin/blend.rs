//! The two blends of bone transforms at one vertex: linear blend skinning and dual
//! quaternion skinning (Kavan, Collins, Žára & O'Sullivan 2008).
//!
//! A pose's skinning transforms are prepared once per pose and bone ([`Matrix`] for LBS,
//! [`Dual`] for DQS), so that the vertex loop only blends a few numbers per influence and
//! applies the blend: no quaternion product per vertex.

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
}

/// A transform as the rows of its 3×4 matrix `[R | t]`, row-major.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Matrix([f64; 12]);

impl From<&Transform> for Matrix {
    fn from(s: &Transform) -> Matrix {
        let r = glam::DMat3::from_quat(s.rotation);
        let t = s.translation;
        Matrix([
            r.x_axis.x, r.y_axis.x, r.z_axis.x, t.x, //
            r.x_axis.y, r.y_axis.y, r.z_axis.y, t.y, //
            r.x_axis.z, r.y_axis.z, r.z_axis.z, t.z,
        ])
    }
}

/// A transform as the unit dual quaternion `q + ε ½ t q`: real part then dual part, each
/// `(w, x, y, z)`.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Dual([f64; 8]);

impl From<&Transform> for Dual {
    fn from(s: &Transform) -> Dual {
        let t = s.translation;
        let (q, d) = (s.rotation, DQuat::from_xyzw(t.x, t.y, t.z, 0.0) * s.rotation * 0.5);
        Dual([q.w, q.x, q.y, q.z, d.w, d.x, d.y, d.z])
    }
}

/// Linear blend skinning of `x`: `(Σ w_i M_{b_i}) x` over the influences `(bones, weights)`
/// (the same as `Σ w_i S_{b_i} x`).
#[inline(always)]
pub(super) fn linear(skinning: &[Matrix], bones: &[u32], weights: &[f64], x: [f64; 3]) -> [f64; 3] {
    let mut m = [0.0; 12];
    for (&b, &w) in bones.iter().zip(weights) {
        let s = &skinning[b as usize].0;
        for i in 0..12 {
            m[i] += w * s[i];
        }
    }
    let row = |r: &[f64]| r[0] * x[0] + r[1] * x[1] + r[2] * x[2] + r[3];
    [row(&m[0..4]), row(&m[4..8]), row(&m[8..12])]
}

/// Dual quaternion skinning of `x` (Kavan et al. 2008, eq. 4–5): the dual quaternions of the
/// influences blended with the weights, each signed to lie in the hemisphere of the most
/// weighted one's rotation (section 4.1), then applied as the rigid transform of the blend
/// normalised by its real part's norm `n`: for the blend `(r, d)`,
/// `x' = x + 2 r⃗ × (r⃗ × x + r₀ x) / n² + 2 (r₀ d⃗ − d₀ r⃗ + r⃗ × d⃗) / n²`.
#[inline(always)]
pub(super) fn dual_quaternion(
    skinning: &[Dual],
    bones: &[u32],
    weights: &[f64],
    x: [f64; 3],
) -> [f64; 3] {
    let pivot = weights
        .iter()
        .enumerate()
        .fold(0, |best, (i, &w)| if w > weights[best] { i } else { best });
    let p = &skinning[bones[pivot] as usize].0;
    let mut q = [0.0; 8];
    for (&b, &w) in bones.iter().zip(weights) {
        let s = &skinning[b as usize].0;
        let dot = s[0] * p[0] + s[1] * p[1] + s[2] * p[2] + s[3] * p[3];
        let w = if dot < 0.0 { -w } else { w };
        for i in 0..8 {
            q[i] += w * s[i];
        }
    }
    let (r0, r, d0, d) = (q[0], DVec3::new(q[1], q[2], q[3]), q[4], DVec3::new(q[5], q[6], q[7]));
    let x = DVec3::from_array(x);
    let scale = 2.0 / (r0 * r0 + r.length_squared());
    let moved = x + scale * (r.cross(r.cross(x) + r0 * x) + (r0 * d - d0 * r + r.cross(d)));
    moved.to_array()
}
