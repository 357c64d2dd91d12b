//! The recursive algorithms of Featherstone, "Rigid Body Dynamics Algorithms" (2008), on a
//! [`Model`]'s tree, in body coordinates with spatial vectors angular first:
//!
//! - kinematics (§5.3): `X_i = X_J(q_i) X_T(i)`, `v_i = X_i v_λ(i) + S_i q̇_i`,
//!   `c_i = c_J + v_i ×ₘ S_i q̇_i`;
//! - the recursive Newton–Euler algorithm (RNEA, Table 5.1): `τ = ID(q, q̇, q̈, f_ext)`,
//!   gravity as a fictitious base acceleration `a_0 = −g`;
//! - the composite-rigid-body algorithm (CRBA, Table 6.2): the joint-space inertia `M(q)`;
//! - the articulated-body algorithm (ABA, Table 7.1): `q̈ = FD(q, q̇, τ, f_ext)` in O(n).
//!
//! External forces `f_ext` are spatial forces in body coordinates ([`Tree::f_ext`]).

use super::joints;
use super::model::Model;
use super::spatial::{angular, linear, spatial, SMat, SVec, Transform};
use glam::{DQuat, DVec3};
use nalgebra::DMatrix;

/// The per-body workspace of the recursive algorithms (no allocation after the first use
/// on a model of the same size).
#[derive(Clone, Debug, Default)]
pub struct Tree {
    /// `X_i`: parent (or world) frame to body frame.
    pub(super) x_up: Vec<Transform>,
    /// Motion subspace of each joint, padded to 6 columns.
    pub(super) s: Vec<SMat>,
    /// Body orientations (world).
    pub(super) rot: Vec<DQuat>,
    /// Body frame origins (m, world).
    pub(super) pos: Vec<DVec3>,
    /// Body spatial velocities (body coordinates).
    pub(super) v: Vec<SVec>,
    /// Velocity-product accelerations `c_i` (body coordinates).
    pub(super) c: Vec<SVec>,
    /// External spatial forces on the bodies (body coordinates), set before RNEA/ABA.
    pub f_ext: Vec<SVec>,
    a: Vec<SVec>,
    f: Vec<SVec>,
    ia: Vec<SMat>,
    pa: Vec<SVec>,
    u_mat: Vec<SMat>,
    d_inv: Vec<SMat>,
    u: Vec<SVec>,
    /// The joint-space inertia `M` of the last [`Tree::crba`] (`nv x nv`).
    pub mass_matrix: DMatrix<f64>,
    /// Scratch of `nv` values for solves with `M`'s factor.
    pub(super) column: Vec<f64>,
    /// The parent of each degree of freedom (`nv`; [`super::servo::NO_PARENT`] for the
    /// first): the previous one of its joint, else the last of the nearest ancestor joint
    /// with one (Featherstone's expanded parent array, §6.5).
    dof_parents: Vec<usize>,
    /// Each degree of freedom's path to the root in `dof_parents` (rebuilt when they change).
    pub(super) dof_paths: super::servo::Paths,
    /// The ground contacts of the last implicit step's forces ([`super::forces::passive`]).
    pub(super) contacts: Vec<super::forces::Contact>,
}

impl Tree {
    /// Size the workspace for `model`.
    pub fn resize(&mut self, model: &Model) {
        let n = model.bodies().len();
        self.x_up.resize(n, Transform::default());
        self.s.resize(n, SMat::zeros());
        self.rot.resize(n, DQuat::IDENTITY);
        self.pos.resize(n, DVec3::ZERO);
        for v in [&mut self.v, &mut self.c, &mut self.f_ext, &mut self.a, &mut self.f] {
            v.resize(n, SVec::zeros());
        }
        self.pa.resize(n, SVec::zeros());
        self.u.resize(n, SVec::zeros());
        for m in [&mut self.ia, &mut self.u_mat, &mut self.d_inv] {
            m.resize(n, SMat::zeros());
        }
        let nv = model.nv();
        if self.mass_matrix.shape() != (nv, nv) {
            self.mass_matrix = DMatrix::zeros(nv, nv);
        }
        self.column.resize(nv, 0.0);
        self.dof_parents.resize(nv, super::servo::NO_PARENT);
        let last = |mut p: Option<usize>| {
            while let Some(j) = p {
                let n = model.bodies()[j].joint.nv();
                if n > 0 {
                    return model.starts(j).1 + n - 1;
                }
                p = model.bodies()[j].parent;
            }
            super::servo::NO_PARENT
        };
        let mut changed = self.dof_paths.len() != nv;
        for (i, b) in model.bodies().iter().enumerate() {
            let iv = model.starts(i).1;
            for k in 0..b.joint.nv() {
                let parent = if k > 0 { iv + k - 1 } else { last(b.parent) };
                changed |= self.dof_parents[iv + k] != parent;
                self.dof_parents[iv + k] = parent;
            }
        }
        if changed {
            self.dof_paths.build(&self.dof_parents);
        }
        // At most a contact per capsule end with the ground, and per end and one inner
        // contact with each collider (`super::forces`).
        let colliders = model.colliders().len();
        let most: usize = model
            .bodies()
            .iter()
            .filter_map(|b| b.shape)
            .map(|c| 1 + (c.a != c.b) as usize)
            .map(|ends| ends + colliders * (ends + 1))
            .sum();
        self.contacts.reserve(most.saturating_sub(self.contacts.len()));
    }

    /// Positions, orientations, velocities and velocity products of every body at
    /// `(q, q̇)`; clears [`Tree::f_ext`].
    pub fn kinematics(&mut self, model: &Model, q: &[f64], qd: &[f64]) {
        self.resize(model);
        for (i, b) in model.bodies().iter().enumerate() {
            let (iq, iv) = model.starts(i);
            let nv = b.joint.nv();
            let (rel, shift) = joints::relative(b.joint, &q[iq..]);
            let x_j = Transform::new(rel, shift);
            self.x_up[i] = x_j.compose(&model.tree[i]);
            self.s[i] = joints::subspace(b.joint, &x_j);
            let mut vj = SVec::zeros();
            for k in 0..nv {
                vj += self.s[i].column(k) * qd[iv + k];
            }
            let cj = joints::bias(b.joint, &x_j, &qd[iv..]);
            let (pr, pp, pv) = match b.parent {
                Some(p) => (self.rot[p], self.pos[p], self.x_up[i].motion(&self.v[p])),
                None => (DQuat::IDENTITY, DVec3::ZERO, SVec::zeros()),
            };
            self.rot[i] = (pr * rel).normalize();
            self.pos[i] = pp + pr * (b.offset + shift);
            self.v[i] = pv + vj;
            self.c[i] = cj + super::spatial::cross_motion(&self.v[i], &vj);
            self.f_ext[i] = SVec::zeros();
        }
    }

    /// The transform from world to body `i`'s frame (after [`Tree::kinematics`]).
    pub fn world(&self, i: usize) -> Transform {
        Transform::new(self.rot[i], self.pos[i])
    }

    /// Body orientations (world) after [`Tree::kinematics`].
    pub fn orientations(&self) -> &[DQuat] {
        &self.rot
    }

    /// Body frame origins (m, world) after [`Tree::kinematics`].
    pub fn positions(&self) -> &[DVec3] {
        &self.pos
    }

    /// Inverse dynamics by the RNEA (Featherstone Table 5.1): the joint forces `tau` (`nv`)
    /// that give accelerations `qdd` at the state of the last [`Tree::kinematics`], under
    /// gravity and [`Tree::f_ext`].
    pub fn rnea(&mut self, model: &Model, qdd: &[f64], tau: &mut [f64]) {
        let a0 = spatial(DVec3::ZERO, -model.settings.gravity);
        let bodies = model.bodies();
        for (i, b) in bodies.iter().enumerate() {
            let iv = model.starts(i).1;
            let ap = b.parent.map_or(a0, |p| self.a[p]);
            let mut a = self.x_up[i].motion(&ap) + self.c[i];
            for k in 0..b.joint.nv() {
                a += self.s[i].column(k) * qdd[iv + k];
            }
            self.a[i] = a;
            let h = model.inertias[i] * self.v[i];
            self.f[i] =
                model.inertias[i] * a + super::spatial::cross_force(&self.v[i], &h) - self.f_ext[i];
        }
        for (i, b) in bodies.iter().enumerate().rev() {
            let iv = model.starts(i).1;
            for k in 0..b.joint.nv() {
                tau[iv + k] = self.s[i].column(k).dot(&self.f[i]);
            }
            if let Some(p) = b.parent {
                let fp = self.x_up[i].force_to_parent(&self.f[i]);
                self.f[p] += fp;
            }
        }
    }

    /// The joint-space inertia `M(q)` by the CRBA (Featherstone Table 6.2) into
    /// [`Tree::mass_matrix`], at the `q` of the last [`Tree::kinematics`].
    pub fn crba(&mut self, model: &Model) {
        self.ia.clone_from_slice(&model.inertias);
        self.composite(model);
    }

    /// `M + dt Σ Jᵀ C J` by the CRBA into [`Tree::mass_matrix`] for the recorded
    /// [`Tree::contacts`]: `J` a contact point's world velocity per joint rate, `C =
    /// c_t (1 − n nᵀ) + c_n n nᵀ` (world, `n` the contact's normal: `+Y` on the ground, the
    /// collider's closest-point normal otherwise) its viscous coefficients. With it, `(M + dt Jᵀ C J) q̈ = …`
    /// takes the contacts' damping at the next step's velocity, `−C J (q̇ + dt q̈)` (the
    /// explicit part `−C J q̇` is in [`Tree::f_ext`]). Each contact adds to its body's
    /// inertia the 6 × 6 `dt Gᵀ C_b G` (body axes, `G = [−p×, 1]` the point's velocity from
    /// the body's `[ω; v]`, `C_b = Rᵀ C R`) before the composite inertias are summed, so the
    /// terms cost `O(contacts)` and keep the tree's sparsity.
    pub(super) fn crba_with_contacts(&mut self, model: &Model, dt: f64) {
        self.ia.clone_from_slice(&model.inertias);
        for c in &self.contacts {
            let rot = self.rot[c.body];
            let p = super::spatial::skew(rot.conjugate() * (c.point - self.pos[c.body]));
            let up = super::spatial::vec3(rot.conjugate() * c.direction);
            let cb = nalgebra::Matrix3::identity() * c.tangent
                + up * up.transpose() * (c.normal - c.tangent);
            let mut d = SMat::zeros();
            d.fixed_view_mut::<3, 3>(0, 0).copy_from(&(-(p * cb * p)));
            d.fixed_view_mut::<3, 3>(0, 3).copy_from(&(p * cb));
            d.fixed_view_mut::<3, 3>(3, 0).copy_from(&(-(cb * p)));
            d.fixed_view_mut::<3, 3>(3, 3).copy_from(&cb);
            self.ia[c.body] += d * dt;
        }
        self.composite(model);
    }

    /// The CRBA's sums of the composite inertias (from `self.ia`, the bodies' own) and the
    /// joint-space matrix from them.
    fn composite(&mut self, model: &Model) {
        let bodies = model.bodies();
        for (i, b) in bodies.iter().enumerate().rev() {
            if let Some(p) = b.parent {
                let ic = self.x_up[i].inertia_to_parent(&self.ia[i]);
                self.ia[p] += ic;
            }
        }
        let m = &mut self.mass_matrix;
        m.fill(0.0);
        for (i, b) in bodies.iter().enumerate() {
            let (iv, ni) = (model.starts(i).1, b.joint.nv());
            // `F = I_c S_i`, one spatial force per degree of freedom, carried to the root.
            let mut f = [SVec::zeros(); 6];
            for (k, f) in f[..ni].iter_mut().enumerate() {
                *f = joints::inertia_times_column(b.joint, &self.ia[i], &self.s[i], k);
            }
            let (mut j, mut jv, mut nj) = (i, iv, ni);
            loop {
                for r in 0..nj {
                    for (k, f) in f[..ni].iter().enumerate() {
                        let h = joints::column_dot(bodies[j].joint, &self.s[j], r, f);
                        m[(jv + r, iv + k)] = h;
                        if j != i {
                            m[(iv + k, jv + r)] = h;
                        }
                    }
                }
                let Some(p) = bodies[j].parent else { break };
                for f in &mut f[..ni] {
                    *f = self.x_up[j].force_to_parent(f);
                }
                j = p;
                (jv, nj) = (model.starts(j).1, bodies[j].joint.nv());
            }
        }
    }

    /// Forward dynamics by the ABA (Featherstone Table 7.1): the accelerations `qdd` (`nv`)
    /// under joint forces `tau`, gravity and [`Tree::f_ext`], at the state of the last
    /// [`Tree::kinematics`]. Non-finite if an articulated inertia is singular.
    pub fn aba(&mut self, model: &Model, tau: &[f64], qdd: &mut [f64]) {
        let bodies = model.bodies();
        for i in 0..bodies.len() {
            self.ia[i] = model.inertias[i];
            let h = model.inertias[i] * self.v[i];
            self.pa[i] = super::spatial::cross_force(&self.v[i], &h) - self.f_ext[i];
        }
        for (i, b) in bodies.iter().enumerate().rev() {
            let (iv, n) = (model.starts(i).1, b.joint.nv());
            let s = &self.s[i];
            let u_mat = self.ia[i] * s;
            let mut d = s.transpose() * u_mat;
            let mut u = -(s.transpose() * self.pa[i]);
            for k in 0..6 {
                if k < n {
                    u[k] += tau[iv + k];
                } else {
                    d[(k, k)] = 1.0;
                }
            }
            let mut d_inv = d.try_inverse().unwrap_or_else(|| SMat::from_element(f64::NAN));
            for k in n..6 {
                d_inv[(k, k)] = 0.0;
            }
            if let Some(p) = b.parent {
                let ia = self.ia[i] - u_mat * d_inv * u_mat.transpose();
                let pa = self.pa[i] + ia * self.c[i] + u_mat * (d_inv * u);
                let ip = self.x_up[i].inertia_to_parent(&ia);
                let fp = self.x_up[i].force_to_parent(&pa);
                self.ia[p] += ip;
                self.pa[p] += fp;
            }
            (self.u_mat[i], self.d_inv[i], self.u[i]) = (u_mat, d_inv, u);
        }
        let a0 = spatial(DVec3::ZERO, -model.settings.gravity);
        for (i, b) in bodies.iter().enumerate() {
            let (iv, n) = (model.starts(i).1, b.joint.nv());
            let ap = b.parent.map_or(a0, |p| self.a[p]);
            let a = self.x_up[i].motion(&ap) + self.c[i];
            let acc = self.d_inv[i] * (self.u[i] - self.u_mat[i].transpose() * a);
            qdd[iv..iv + n].copy_from_slice(&acc.as_slice()[..n]);
            self.a[i] = a + self.s[i] * acc;
        }
    }

    /// Kinetic energy `Σ ½ vᵢᵀ Iᵢ vᵢ` (J) at the last [`Tree::kinematics`].
    pub fn kinetic_energy(&self, model: &Model) -> f64 {
        (0..self.v.len()).map(|i| 0.5 * self.v[i].dot(&(model.inertias[i] * self.v[i]))).sum()
    }

    /// Gravitational potential energy `−Σ mᵢ g · cᵢ` (J, zero at y = 0 for the default
    /// gravity) at the last [`Tree::kinematics`].
    pub fn potential_energy(&self, model: &Model) -> f64 {
        let g = model.settings.gravity;
        model.bodies().iter().enumerate().map(|(i, b)| -b.mass * g.dot(self.com_of(model, i))).sum()
    }

    /// World position (m) of body `i`'s centre of mass.
    pub fn com_of(&self, model: &Model, i: usize) -> DVec3 {
        self.pos[i] + self.rot[i] * model.bodies()[i].com
    }

    /// Centre of mass of the whole tree (m, world).
    pub fn com(&self, model: &Model) -> DVec3 {
        let m: DVec3 =
            model.bodies().iter().enumerate().map(|(i, b)| b.mass * self.com_of(model, i)).sum();
        m / model.mass()
    }

    /// Velocity of the tree's centre of mass (m/s, world) at the last [`Tree::kinematics`]:
    /// `Σ mᵢ Rᵢ (vᵢ + ωᵢ × cᵢ) / Σ mᵢ`, each body's centre-of-mass velocity from its spatial
    /// velocity `[ω; v]` (body axes) and centre of mass `cᵢ` (body frame) — the linear part of
    /// [`Tree::momentum`] over the mass, without its angular part.
    pub fn com_velocity(&self, model: &Model) -> DVec3 {
        let momentum: DVec3 = model
            .bodies()
            .iter()
            .enumerate()
            .map(|(i, b)| {
                let v = &self.v[i];
                b.mass * (self.rot[i] * (linear(v) + angular(v).cross(b.com)))
            })
            .sum();
        momentum / model.mass()
    }

    /// Spatial momentum of the tree in world coordinates about the world origin: angular
    /// momentum (kg m²/s) and linear momentum (kg m/s).
    pub fn momentum(&self, model: &Model) -> (DVec3, DVec3) {
        let mut total = SVec::zeros();
        for i in 0..self.v.len() {
            total += self.world(i).force_to_parent(&(model.inertias[i] * self.v[i]));
        }
        (angular(&total), linear(&total))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::character::biped3d::biped3d;
    use crate::character::joints::integrate;
    use crate::character::model::Settings;

    /// The centre of mass's velocity is the derivative of the centre of mass along the
    /// rates (central differences over `q ⊕ ±h q̇`) and the linear momentum over the mass,
    /// on the 3-D biped in a bent pose with every rate non-zero.
    #[test]
    fn the_com_velocity_is_the_derivative_of_the_com() {
        let model = biped3d(Settings::default()).unwrap();
        let neutral = model.neutral();
        let turn: Vec<f64> = (0..model.nv()).map(|k| 0.3 * ((k as f64) * 1.7).sin()).collect();
        let mut q = neutral.clone();
        integrate(&model, &neutral, &turn, 1.0, &mut q);
        let qd: Vec<f64> = (0..model.nv()).map(|k| ((k * 7) as f64 * 0.61).sin()).collect();
        let mut tree = Tree::default();
        tree.kinematics(&model, &q, &qd);
        let velocity = tree.com_velocity(&model);
        let by_momentum = tree.momentum(&model).1 / model.mass();
        assert!((velocity - by_momentum).length() < 1e-13 * velocity.length(), "{velocity}");
        let h = 1e-5;
        let mut com = [DVec3::ZERO; 2];
        for (c, sign) in com.iter_mut().zip([1.0, -1.0]) {
            let mut moved = q.clone();
            integrate(&model, &q, &qd, sign * h, &mut moved);
            tree.kinematics(&model, &moved, &qd);
            *c = tree.com(&model);
        }
        let difference = (com[0] - com[1]) / (2.0 * h);
        assert!((velocity - difference).length() < 1e-8, "{velocity} vs {difference}");
        assert!(velocity.length() > 0.3, "{velocity}");
    }
}
