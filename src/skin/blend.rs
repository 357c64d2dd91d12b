//! The two blends of bone transforms at one vertex: linear blend skinning and dual
//! quaternion skinning (Kavan, Collins, Žára & O'Sullivan 2008), each for `N` poses at once.
//!
//! A pose's skinning transforms are prepared once per pose and bone as a few numbers
//! ([`Blend::values`]: a 3×4 matrix for LBS, a unit dual quaternion for DQS), so that the
//! vertex loop only blends them per influence and applies the blend: no quaternion product
//! per vertex. The poses are the lanes: `bone(b, i)` gives value `i` of bone `b` in each of
//! the `N` poses, so that with `N = 8` (SIMD) every operation is the same on the eight lanes
//! and the loads are contiguous; `N = 1` is the same arithmetic on one pose, bitwise.

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

/// A blend of the bones' skinning transforms at a vertex.
pub(super) trait Blend: Sync {
    /// Numbers per bone and pose.
    const VALUES: usize;

    /// The numbers of the skinning transform `s` ([`Blend::VALUES`] of them).
    fn values(s: &Transform) -> [f64; 12];

    /// The vertex at rest position `x` with influences `(bones, weights)` in `N` poses, by
    /// component (`[x, y, z]`, one lane per pose); `bone(b, i)` is value `i` of bone `b`.
    /// `work` has a row per influence. Sums run over the influences in their order for each
    /// number in turn (few accumulators, kept in registers).
    fn blend<const N: usize>(
        bone: impl Fn(u32, usize) -> [f64; N],
        bones: &[u32],
        weights: &[f64],
        x: [f64; 3],
        work: &mut [[f64; N]],
    ) -> [[f64; N]; 3];
}

/// Linear blend skinning: `(Σ w_i M_{b_i}) x` over the influences (the same as
/// `Σ w_i S_{b_i} x`), with `M` the rows of the 3×4 matrix `[R | t]`, row-major.
pub(super) struct Linear;

impl Blend for Linear {
    const VALUES: usize = 12;

    fn values(s: &Transform) -> [f64; 12] {
        let r = glam::DMat3::from_quat(s.rotation);
        let t = s.translation;
        [
            r.x_axis.x, r.y_axis.x, r.z_axis.x, t.x, //
            r.x_axis.y, r.y_axis.y, r.z_axis.y, t.y, //
            r.x_axis.z, r.y_axis.z, r.z_axis.z, t.z,
        ]
    }

    #[inline(always)]
    fn blend<const N: usize>(
        bone: impl Fn(u32, usize) -> [f64; N],
        bones: &[u32],
        weights: &[f64],
        x: [f64; 3],
        _: &mut [[f64; N]],
    ) -> [[f64; N]; 3] {
        let mut out = [[0.0; N]; 3];
        for (r, out) in out.iter_mut().enumerate() {
            let mut m = [[0.0; N]; 4];
            for (j, m) in m.iter_mut().enumerate() {
                for (&b, &w) in bones.iter().zip(weights) {
                    let s = bone(b, 4 * r + j);
                    for l in 0..N {
                        m[l] += w * s[l];
                    }
                }
            }
            for l in 0..N {
                out[l] = m[0][l] * x[0] + m[1][l] * x[1] + m[2][l] * x[2] + m[3][l];
            }
        }
        out
    }
}

/// Dual quaternion skinning (Kavan et al. 2008, eq. 4–5): the unit dual quaternions
/// `q + ε ½ t q` (real part then dual part, each `(w, x, y, z)`) of the influences blended
/// with the weights, each signed to lie in the hemisphere of the most weighted one's rotation
/// (section 4.1), then applied as the rigid transform of the blend normalised by its real
/// part's norm `n`: for the blend `(r, d)`,
/// `x' = x + 2 r⃗ × (r⃗ × x + r₀ x) / n² + 2 (r₀ d⃗ − d₀ r⃗ + r⃗ × d⃗) / n²`.
pub(super) struct DualQuaternion;

impl Blend for DualQuaternion {
    const VALUES: usize = 8;

    fn values(s: &Transform) -> [f64; 12] {
        let t = s.translation;
        let (q, d) = (s.rotation, DQuat::from_xyzw(t.x, t.y, t.z, 0.0) * s.rotation * 0.5);
        [q.w, q.x, q.y, q.z, d.w, d.x, d.y, d.z, 0.0, 0.0, 0.0, 0.0]
    }

    #[inline(always)]
    fn blend<const N: usize>(
        bone: impl Fn(u32, usize) -> [f64; N],
        bones: &[u32],
        weights: &[f64],
        x: [f64; 3],
        signed: &mut [[f64; N]],
    ) -> [[f64; N]; 3] {
        let pivot = weights
            .iter()
            .enumerate()
            .fold(0, |best, (i, &w)| if w > weights[best] { i } else { best });
        let b = bones[pivot];
        let p = [bone(b, 0), bone(b, 1), bone(b, 2), bone(b, 3)];
        for ((&b, &w), signed) in bones.iter().zip(weights).zip(signed.iter_mut()) {
            let s = [bone(b, 0), bone(b, 1), bone(b, 2), bone(b, 3)];
            for l in 0..N {
                let dot =
                    s[0][l] * p[0][l] + s[1][l] * p[1][l] + s[2][l] * p[2][l] + s[3][l] * p[3][l];
                signed[l] = if dot < 0.0 { -w } else { w };
            }
        }
        let mut q = [[0.0; N]; 8];
        for (i, q) in q.iter_mut().enumerate() {
            for (&b, w) in bones.iter().zip(signed.iter()) {
                let s = bone(b, i);
                for l in 0..N {
                    q[l] += w[l] * s[l];
                }
            }
        }
        let mut out = [[0.0; N]; 3];
        for l in 0..N {
            let (r0, r, d0) = (q[0][l], [q[1][l], q[2][l], q[3][l]], q[4][l]);
            let d = [q[5][l], q[6][l], q[7][l]];
            // The arithmetic of glam's `DVec3` (dot, cross, products by a scalar), written
            // out per lane: the same bits as `x + s (r × (r × x + r₀ x) + (r₀ d − d₀ r + r × d))`.
            let cross = |a: [f64; 3], b: [f64; 3]| {
                [a[1] * b[2] - b[1] * a[2], a[2] * b[0] - b[2] * a[0], a[0] * b[1] - b[0] * a[1]]
            };
            let scale = 2.0 / (r0 * r0 + (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]));
            let rx = cross(r, x);
            let a = cross(r, [rx[0] + r0 * x[0], rx[1] + r0 * x[1], rx[2] + r0 * x[2]]);
            let rd = cross(r, d);
            for i in 0..3 {
                let b = r0 * d[i] - d0 * r[i] + rd[i];
                out[i][l] = x[i] + scale * (a[i] + b);
            }
        }
        out
    }
}
