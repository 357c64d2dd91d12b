//! Spatial (6-D) vector algebra of Featherstone, "Rigid Body Dynamics Algorithms" (2008),
//! ch. 2, in the **angular-first** convention used everywhere in this module: a motion
//! vector is `[ω; v]` (rad/s; m/s of the frame's origin), a force vector `[n; f]` (N m about
//! the frame's origin; N), both in the coordinates of one body frame.

use glam::{DMat3, DQuat, DVec3};
use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};

/// A spatial motion or force vector, angular part first (rows 0–2), linear part last.
pub type SVec = Vector6<f64>;
/// A spatial 6x6 matrix (inertia, articulated inertia, motion subspace padded to 6 columns).
pub type SMat = Matrix6<f64>;

/// `v` as an nalgebra vector.
pub fn vec3(v: DVec3) -> Vector3<f64> {
    Vector3::new(v.x, v.y, v.z)
}

/// The angular (rows 0–2) part of `s`.
pub fn angular(s: &SVec) -> DVec3 {
    DVec3::new(s[0], s[1], s[2])
}

/// The linear (rows 3–5) part of `s`.
pub fn linear(s: &SVec) -> DVec3 {
    DVec3::new(s[3], s[4], s[5])
}

/// The spatial vector `[a; l]`.
pub fn spatial(a: DVec3, l: DVec3) -> SVec {
    SVec::new(a.x, a.y, a.z, l.x, l.y, l.z)
}

/// The skew matrix `[v]×` (`[v]× u = v × u`).
pub fn skew(v: DVec3) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// `v ×ₘ m`, the spatial cross product of motion vectors (Featherstone eq. 2.31):
/// `[ω × mω; ω × mv + v × mω]`.
pub fn cross_motion(v: &SVec, m: &SVec) -> SVec {
    let (w, l) = (angular(v), linear(v));
    let (mw, ml) = (angular(m), linear(m));
    spatial(w.cross(mw), w.cross(ml) + l.cross(mw))
}

/// `v ×* f`, the spatial cross product of a motion and a force vector (eq. 2.32):
/// `[ω × n + v × f; ω × f]`.
pub fn cross_force(v: &SVec, f: &SVec) -> SVec {
    let (w, l) = (angular(v), linear(v));
    let (n, ff) = (angular(f), linear(f));
    spatial(w.cross(n) + l.cross(ff), w.cross(ff))
}

/// A Plücker coordinate transform from frame A to frame B, `X = rot(E) xlt(r)` (eq. 2.24):
/// `E` turns A coordinates into B coordinates, `r` is B's origin in A coordinates (m).
#[derive(serde::Serialize, serde::Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    /// Rotation from A coordinates to B coordinates.
    pub rot: DMat3,
    /// Position of B's origin in A (m).
    pub pos: DVec3,
}

impl Default for Transform {
    fn default() -> Self {
        Transform { rot: DMat3::IDENTITY, pos: DVec3::ZERO }
    }
}

impl Transform {
    /// The transform to a frame at `pos` (in A) turned by `orientation` (B's axes in A
    /// coordinates), i.e. `E = Rᵀ`.
    pub fn new(orientation: DQuat, pos: DVec3) -> Self {
        Transform { rot: DMat3::from_quat(orientation).transpose(), pos }
    }

    /// `X m` for a motion vector: `[E ω; E (v − r × ω)]`.
    pub fn motion(&self, m: &SVec) -> SVec {
        let w = angular(m);
        spatial(self.rot * w, self.rot * (linear(m) - self.pos.cross(w)))
    }

    /// `X⁻¹ m` for a motion vector given in B: `[Eᵀ ω; Eᵀ v + r × Eᵀ ω]`.
    pub fn inv_motion(&self, m: &SVec) -> SVec {
        let w = self.rot.transpose() * angular(m);
        spatial(w, self.rot.transpose() * linear(m) + self.pos.cross(w))
    }

    /// `Xᵀ f`: a force vector given in B, expressed in A: `[Eᵀ n + r × Eᵀ f; Eᵀ f]`.
    pub fn force_to_parent(&self, f: &SVec) -> SVec {
        let ff = self.rot.transpose() * linear(f);
        spatial(self.rot.transpose() * angular(f) + self.pos.cross(ff), ff)
    }

    /// `X* f = X⁻ᵀ f`: a force vector given in A, expressed in B: `[E (n − r × f); E f]`.
    pub fn force(&self, f: &SVec) -> SVec {
        let ff = linear(f);
        spatial(self.rot * (angular(f) - self.pos.cross(ff)), self.rot * ff)
    }

    /// The 6x6 matrix of `X` acting on motion vectors.
    pub fn matrix(&self) -> SMat {
        let e = Matrix3::from_column_slice(&self.rot.to_cols_array());
        let mut x = SMat::zeros();
        x.fixed_view_mut::<3, 3>(0, 0).copy_from(&e);
        x.fixed_view_mut::<3, 3>(3, 3).copy_from(&e);
        x.fixed_view_mut::<3, 3>(3, 0).copy_from(&(-e * skew(self.pos)));
        x
    }

    /// `Xᵀ I X`: a symmetric spatial (articulated) inertia `inertia` given in B, expressed
    /// in A. The product done by blocks: with `X = rot(E) xlt(r)`, first the blocks
    /// `[A, B; Bᵀ, C]` turned, `A' = Eᵀ A E` (and so `B'`, `C'`), then shifted,
    /// `[A' − B' r× − (B' r×)ᵀ − r× C' r×, B' − (C' r×)ᵀ; ·ᵀ, C']`: 243 multiplications
    /// instead of the 432 of the two 6 × 6 products.
    pub fn inertia_to_parent(&self, inertia: &SMat) -> SMat {
        let e = Matrix3::from_column_slice(&self.rot.to_cols_array());
        let et = e.transpose();
        let a = et * inertia.fixed_view::<3, 3>(0, 0) * e;
        let b = et * inertia.fixed_view::<3, 3>(0, 3) * e;
        let c = et * inertia.fixed_view::<3, 3>(3, 3) * e;
        let rx = skew(self.pos);
        let (b_rx, c_rx) = (b * rx, c * rx);
        let top_right = b - c_rx.transpose();
        let mut out = SMat::zeros();
        out.fixed_view_mut::<3, 3>(0, 0).copy_from(&(a - b_rx - b_rx.transpose() - rx * c_rx));
        out.fixed_view_mut::<3, 3>(0, 3).copy_from(&top_right);
        out.fixed_view_mut::<3, 3>(3, 0).copy_from(&top_right.transpose());
        out.fixed_view_mut::<3, 3>(3, 3).copy_from(&c);
        out
    }

    /// `self ∘ inner`: first `inner` (A to B), then `self` (B to C).
    pub fn compose(&self, inner: &Transform) -> Transform {
        Transform { rot: self.rot * inner.rot, pos: inner.pos + inner.rot.transpose() * self.pos }
    }
}

/// The spatial inertia at a body frame's origin of a body of `mass` (kg) with its centre of
/// mass at `com` (m, body frame) and rotational inertia `inertia` about the centre of mass
/// (kg m², body axes) (eq. 2.63): `[Ī_c + m c× c×ᵀ, m c×; m c×ᵀ, m 1]`.
pub fn rigid_inertia(mass: f64, com: DVec3, inertia: DMat3) -> SMat {
    let c = skew(com);
    let ic = Matrix3::from_column_slice(&inertia.to_cols_array());
    let mut s = SMat::zeros();
    s.fixed_view_mut::<3, 3>(0, 0).copy_from(&(ic + mass * c * c.transpose()));
    s.fixed_view_mut::<3, 3>(0, 3).copy_from(&(mass * c));
    s.fixed_view_mut::<3, 3>(3, 0).copy_from(&(mass * c.transpose()));
    s.fixed_view_mut::<3, 3>(3, 3).copy_from(&(mass * Matrix3::identity()));
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> (Transform, SVec, SVec) {
        let q = DQuat::from_euler(glam::EulerRot::XYZ, 0.3, -0.7, 1.1);
        let x = Transform::new(q, DVec3::new(0.2, -0.4, 0.9));
        (x, SVec::new(1.0, -2.0, 0.5, 0.3, 0.7, -1.2), SVec::new(-0.4, 0.1, 2.0, 1.5, -0.6, 0.8))
    }

    #[test]
    fn transforms_agree_with_their_matrix_and_inverse() {
        let (x, m, f) = sample();
        let mat = x.matrix();
        assert!((x.motion(&m) - mat * m).norm() < 1e-14);
        assert!((x.inv_motion(&x.motion(&m)) - m).norm() < 1e-14);
        assert!((x.force_to_parent(&f) - mat.transpose() * f).norm() < 1e-14);
        assert!((x.force_to_parent(&x.force(&f)) - f).norm() < 1e-14);
        // Power is invariant: (X m)·(X* f) = m·f.
        assert!((x.motion(&m).dot(&x.force(&f)) - m.dot(&f)).abs() < 1e-14);
        let i = rigid_inertia(
            2.0,
            DVec3::new(0.1, -0.3, 0.2),
            DMat3::from_diagonal(DVec3::new(0.3, 0.5, 0.4)),
        );
        let i = i + SMat::from_fn(|r, c| 0.1 * ((r * c) as f64 + 1.0).sin()).symmetric_part();
        let dense = mat.transpose() * i * mat;
        assert!((x.inertia_to_parent(&i) - dense).amax() < 1e-13 * dense.amax());
        let y = Transform::new(DQuat::from_rotation_y(0.4), DVec3::new(1.0, 0.0, -0.5));
        assert!((y.compose(&x).matrix() - y.matrix() * x.matrix()).norm() < 1e-14);
    }

    #[test]
    fn cross_products_are_dual() {
        let (_, m, f) = sample();
        let v = SVec::new(0.3, 0.2, -0.1, 1.0, 0.5, 2.0);
        // (v ×* f)·m = −f·(v ×ₘ m) (eq. 2.33).
        assert!((cross_force(&v, &f).dot(&m) + f.dot(&cross_motion(&v, &m))).abs() < 1e-13);
    }

    #[test]
    fn rigid_inertia_gives_momentum_and_energy() {
        let (mass, com) = (2.0, DVec3::new(0.1, -0.3, 0.2));
        let ic = DMat3::from_diagonal(DVec3::new(0.3, 0.5, 0.4));
        let i = rigid_inertia(mass, com, ic);
        let (w, v) = (DVec3::new(0.5, -1.0, 2.0), DVec3::new(1.0, 0.2, -0.3));
        let h = i * spatial(w, v);
        // Linear momentum m (v + ω × c); kinetic energy ½ m |v_c|² + ½ ωᵀ I_c ω.
        let vc = v + w.cross(com);
        assert!((linear(&h) - mass * vc).length() < 1e-14);
        let t = 0.5 * spatial(w, v).dot(&h);
        assert!((t - (0.5 * mass * vc.length_squared() + 0.5 * w.dot(ic * w))).abs() < 1e-13);
    }
}
