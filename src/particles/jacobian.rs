//! The analytic sparse Jacobian of the particle equations of motion, for the implicit methods.
//!
//! With `y = [x; v]` and `f = [v; a(x, v)]` the Jacobian is
//! `[[0, I], [∂a/∂x, ∂a/∂v]]` where `∂a/∂x` and `∂a/∂v` are block sparse: one 3x3 block per
//! particle for the forces acting on it alone, and the blocks `(i, j)`, `(j, i)` for each pair
//! coupled by a spring or by the neighbour repulsion. Block `(i, j)` holds `∂F_i/∂x_j` (and
//! `∂F_i/∂v_j`) scaled by `1/m_i`; the rows of pinned (infinite mass) and dead particles are
//! zero, as their equations are `x' = v' = 0`.
//!
//! Derivatives (`Q = I - d̂ d̂ᵀ`, `ℓ = |d|`):
//! - drag `F = -(k₁ + k₂|u|) u`, `u = v - w`: `∂F/∂v = -k₁ I - k₂ (|u| I + u uᵀ/|u|)`;
//! - damping `F = -c m v`: `∂F/∂v = -c m I`;
//! - attractor `F = s m r / q^{3/2}`, `r = c - x`, `q = |r|² + ε²`:
//!   `∂F/∂x = -s m (q I - 3 r rᵀ) / q^{5/2}`;
//! - vortex `F = s m (â × p)/(|p| + ε)`, `p` the offset from the axis:
//!   `∂F/∂x = s m ([â]ₓ/(|p| + ε) - (â × p) p̂ᵀ/(|p| + ε)²)`;
//! - spring `F_i = -[k (ℓ - L) + c v·d̂] d̂`, `d = x_i - x_j`, `v = v_i - v_j` (Baraff & Witkin
//!   1998, "Large steps in cloth simulation", §4.5, with the damping term's position
//!   derivative kept): `∂F_i/∂x_i = -k d̂ d̂ᵀ - (k (1 - L/ℓ) + c v·d̂/ℓ) Q - (c/ℓ) d̂ vᵀ Q`,
//!   `∂F_i/∂v_i = -c d̂ d̂ᵀ`, and `∂F_i/∂x_j = ∂F_j/∂x_i = -∂F_i/∂x_i` (the same for `v`);
//! - neighbour repulsion `F_i = k (r/ℓ - 1) d` for `ℓ < r`:
//!   `∂F_i/∂x_i = k ((r/ℓ - 1) I - (r/ℓ) d̂ d̂ᵀ)`, with the same signs between the pair.
//!
//! Turbulence (curl noise) has no analytic derivative here: its block is found by central
//! differences per particle, 6 evaluations of that force alone for every particle (a local
//! force depends only on its particle's position). Forces set from outside
//! ([`super::ParticleSystem::set_external_forces`], e.g. Python callables) are held constant
//! within a step, so their derivative is zero. Newtonian gravity between all pairs couples
//! every particle to every other; with it the system offers no sparse Jacobian and the
//! implicit methods fall back to the dense path.
//!
//! The repulsion pairs are those within the radius at the state where the Jacobian is
//! evaluated, so the pattern changes when pairs come into or out of range; the stepper then
//! redoes its symbolic factorisation (see [`crate::ode::SparseJacobian`]).

use super::{for_each_close_pair, particle_force, Dynamics, Force};
use crate::math::{outer, skew};
use crate::ode::SparseJacobian;
use glam::{DMat3, DVec3};

/// Reusable buffers of the particle Jacobian, rebuilt from the forces at every evaluation.
#[derive(Clone, Debug, Default)]
pub(crate) struct JacobianWork {
    /// Pairs within range of each repulsion force: (force index, i, j), in force order.
    close: Vec<[u32; 3]>,
    /// Coupled (column particle, row particle) pairs, sorted, then the adjacency built from
    /// them: the row particles of column particle `j` are `adj[adj_ptr[j]..adj_ptr[j + 1]]`.
    entries: Vec<(u32, u32)>,
    adj_ptr: Vec<usize>,
    adj: Vec<u32>,
    /// `∂F_i/∂x_j` and `∂F_i/∂v_j` for each adjacency slot.
    dx: Vec<DMat3>,
    dv: Vec<DMat3>,
}

impl JacobianWork {
    /// The adjacency slot of block (row particle `i`, column particle `j`).
    fn slot(&self, i: usize, j: usize) -> usize {
        let (lo, hi) = (self.adj_ptr[j], self.adj_ptr[j + 1]);
        lo + self.adj[lo..hi].binary_search(&(i as u32)).expect("pair is in the pattern")
    }

    /// Add the blocks of a pair force with `∂F_i/∂x_i = kx`, `∂F_i/∂v_i = kv` (and
    /// `F_j = -F_i`).
    fn add_pair(&mut self, i: usize, j: usize, kx: DMat3, kv: DMat3) {
        for (r, c, sign) in [(i, i, 1.0), (i, j, -1.0), (j, i, -1.0), (j, j, 1.0)] {
            let s = self.slot(r, c);
            self.dx[s] += sign * kx;
            self.dv[s] += sign * kv;
        }
    }
}

/// `(∂F/∂x, ∂F/∂v)` of the forces acting on one particle alone, analytic except turbulence
/// (central differences).
fn local_blocks(forces: &[Force], x: DVec3, v: DVec3, m: f64) -> (DMat3, DMat3) {
    let (mut jx, mut jv) = (DMat3::ZERO, DMat3::ZERO);
    for force in forces {
        match force {
            Force::Drag { linear, quadratic, wind } => {
                let u = v - *wind;
                let speed = u.length();
                jv -= DMat3::from_diagonal(DVec3::splat(linear + quadratic * speed));
                if speed > 0.0 {
                    jv -= *quadratic / speed * outer(u, u);
                }
            }
            Force::Damping { rate } => jv -= DMat3::from_diagonal(DVec3::splat(rate * m)),
            Force::Attractor { center, strength, softening } => {
                let r = *center - x;
                let q = r.length_squared() + softening * softening;
                let block = DMat3::from_diagonal(DVec3::splat(q)) - 3.0 * outer(r, r);
                jx -= strength * m / q.powf(2.5) * block;
            }
            Force::Vortex { center, axis, strength, core } => {
                let r = x - *center;
                let p = r - r.dot(*axis) * *axis;
                let (len, s) = (p.length(), strength * m);
                jx += s / (len + core) * skew(*axis);
                if len > 0.0 {
                    jx -= s / ((len + core).powi(2) * len) * outer(axis.cross(p), p);
                }
            }
            Force::Turbulence { scale, .. } => {
                let h = f64::EPSILON.cbrt() * scale;
                let one = std::slice::from_ref(force);
                let cols = [DVec3::X, DVec3::Y, DVec3::Z].map(|e| {
                    (particle_force(one, x + h * e, v, m) - particle_force(one, x - h * e, v, m))
                        / (2.0 * h)
                });
                jx += DMat3::from_cols(cols[0], cols[1], cols[2]);
            }
            Force::Gravity { .. }
            | Force::Springs { .. }
            | Force::NeighborRepulsion { .. }
            | Force::NBodyGravity { .. } => {}
        }
    }
    (jx, jv)
}

/// Write `∂f/∂y` at `y` into `jac` (see the module docs) and return `true`, or return `false`
/// when the system offers no sparse Jacobian: it was given no buffers (the dense path was
/// asked for) or all-pairs gravity couples every particle.
pub(super) fn fill(dynamics: &mut Dynamics<'_>, y: &[f64], jac: &mut SparseJacobian) -> bool {
    let all_pairs = dynamics.forces.iter().any(|f| matches!(f, Force::NBodyGravity { .. }));
    let Some(w) = dynamics.jacobian.as_deref_mut().filter(|_| !all_pairs) else {
        return false;
    };
    let n = dynamics.n;
    let (x, v) = y.split_at(3 * n);
    let (forces, alive, inv_mass) = (dynamics.forces, dynamics.alive, dynamics.inv_mass);
    let free = |i: usize| alive[i] && inv_mass[i] > 0.0;
    w.pattern(forces, dynamics.cells, n, alive, x);
    w.blocks(forces, dynamics.mass, &free, x, v);
    w.compress(n, &free, inv_mass, jac);
    true
}

impl JacobianWork {
    /// The pattern: every particle with itself, and the coupled pairs (springs, repulsion
    /// pairs within range, found by the hash grid into `close`) both ways.
    fn pattern(
        &mut self,
        forces: &[Force],
        cells: &mut Vec<(u64, u32)>,
        n: usize,
        alive: &[bool],
        x: &[f64],
    ) {
        self.close.clear();
        for (k, force) in forces.iter().enumerate() {
            if let Force::NeighborRepulsion { radius, .. } = force {
                let close = &mut self.close;
                for_each_close_pair(cells, n, alive, x, *radius, |i, j, _, _| {
                    close.push([k as u32, i as u32, j as u32]);
                });
            }
        }
        self.entries.clear();
        self.entries.extend((0..n as u32).map(|i| (i, i)));
        let springs = forces.iter().filter_map(|f| match f {
            Force::Springs { pairs, .. } => Some(pairs.iter().map(|p| [p[0] as u32, p[1] as u32])),
            _ => None,
        });
        for [a, b] in springs.flatten().chain(self.close.iter().map(|c| [c[1], c[2]])) {
            self.entries.push((a, b));
            self.entries.push((b, a));
        }
        self.entries.sort_unstable();
        self.entries.dedup();
        self.adj.clear();
        self.adj.extend(self.entries.iter().map(|e| e.1));
        self.adj_ptr.clear();
        self.adj_ptr.resize(n + 1, 0);
        for e in &self.entries {
            self.adj_ptr[e.0 as usize + 1] += 1;
        }
        for j in 0..n {
            self.adj_ptr[j + 1] += self.adj_ptr[j];
        }
        self.dx.clear();
        self.dx.resize(self.adj.len(), DMat3::ZERO);
        self.dv.clear();
        self.dv.resize(self.adj.len(), DMat3::ZERO);
    }

    /// The blocks of `∂F/∂x` and `∂F/∂v` at `(x, v)`: those of the forces on single particles
    /// on the diagonal, then each spring and repulsion pair.
    fn blocks(
        &mut self,
        forces: &[Force],
        mass: &[f64],
        free: &impl Fn(usize) -> bool,
        x: &[f64],
        v: &[f64],
    ) {
        let p = |i: usize| DVec3::from_slice(&x[3 * i..3 * i + 3]);
        let vel = |i: usize| DVec3::from_slice(&v[3 * i..3 * i + 3]);
        for i in (0..self.adj_ptr.len() - 1).filter(|&i| free(i)) {
            let (jx, jv) = local_blocks(forces, p(i), vel(i), mass[i]);
            let s = self.slot(i, i);
            self.dx[s] = jx;
            self.dv[s] = jv;
        }
        let mut close = 0;
        for (f, force) in forces.iter().enumerate() {
            match force {
                Force::Springs { pairs, rest, stiffness, damping } => {
                    for (pair, l) in pairs.iter().zip(rest) {
                        let (a, b) = (pair[0], pair[1]);
                        if *l == 0.0 && *damping == 0.0 {
                            // The linear force -k d: its Jacobian written exactly (the general
                            // form equals it only to rounding), so that the Newton matrix of
                            // such springs is bitwise constant and keeps its factorisation.
                            self.add_pair(a, b, -stiffness * DMat3::IDENTITY, DMat3::ZERO);
                            continue;
                        }
                        let d = p(a) - p(b);
                        let len = d.length();
                        if len == 0.0 {
                            continue;
                        }
                        let dir = d / len;
                        let rel = vel(a) - vel(b);
                        let q = DMat3::IDENTITY - outer(dir, dir);
                        let along = stiffness * (1.0 - l / len) + damping * rel.dot(dir) / len;
                        let kx = -stiffness * outer(dir, dir)
                            - along * q
                            - damping / len * outer(dir, q * rel);
                        let kv = -damping * outer(dir, dir);
                        self.add_pair(a, b, kx, kv);
                    }
                }
                Force::NeighborRepulsion { radius, stiffness } => {
                    while close < self.close.len() && self.close[close][0] == f as u32 {
                        let [_, i, j] = self.close[close].map(|i| i as usize);
                        close += 1;
                        let d = p(i) - p(j);
                        let len = d.length();
                        let dir = d / len;
                        let kx = stiffness
                            * (DMat3::from_diagonal(DVec3::splat(radius / len - 1.0))
                                - radius / len * outer(dir, dir));
                        self.add_pair(i, j, kx, DMat3::ZERO);
                    }
                }
                _ => {}
            }
        }
    }

    /// Write the blocks into `jac` as compressed sparse columns: the x columns, then the v
    /// columns (whose first entry is the identity of `x' = v`), each row block scaled by `1/mᵢ`
    /// (zero for pinned and dead rows).
    fn compress(
        &self,
        n: usize,
        free: &impl Fn(usize) -> bool,
        inv_mass: &[f64],
        jac: &mut SparseJacobian,
    ) {
        let scale = |i: u32| if free(i as usize) { inv_mass[i as usize] } else { 0.0 };
        jac.col_ptr.clear();
        jac.row_idx.clear();
        jac.values.clear();
        jac.col_ptr.push(0);
        for (blocks, velocity_columns) in [(&self.dx, false), (&self.dv, true)] {
            for j in 0..n {
                for b in 0..3 {
                    if velocity_columns {
                        jac.row_idx.push(3 * j + b);
                        jac.values.push(if free(j) { 1.0 } else { 0.0 });
                    }
                    let slots = self.adj_ptr[j]..self.adj_ptr[j + 1];
                    for (&i, block) in self.adj[slots.clone()].iter().zip(&blocks[slots]) {
                        let (k, col) = (scale(i), block.col(b));
                        for a in 0..3 {
                            jac.row_idx.push(3 * n + 3 * i as usize + a);
                            jac.values.push(k * col[a]);
                        }
                    }
                    jac.col_ptr.push(jac.row_idx.len());
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ode::{Method, OdeSystem, Stepper};
    use crate::particles::ParticleSystem;
    use nalgebra::DMatrix;

    /// Uniform numbers in [-1, 1) from a fixed seed.
    fn rng(seed: u64) -> impl FnMut() -> f64 {
        let mut s = seed;
        move || (super::super::emit::splitmix(&mut s) >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }

    /// 8 slots: 7 live particles at random states in a ball of radius 0.6 (so that repulsion
    /// pairs exist), particle 2 pinned, slot 7 dead, with `force` added.
    fn system(force: Force, seed: u64) -> ParticleSystem {
        let mut u = rng(seed);
        let mut r = || DVec3::new(u(), u(), u());
        let x: Vec<DVec3> = (0..7).map(|_| 0.6 * r()).collect();
        let v: Vec<DVec3> = (0..7).map(|_| 2.0 * r()).collect();
        let mut m: Vec<f64> = (0..7).map(|i| 0.5 + 0.1 * i as f64).collect();
        m[2] = f64::INFINITY;
        let mut s = ParticleSystem::new(&x, &v, &m, 8).unwrap();
        s.add_force(force).unwrap();
        s
    }

    fn dense(jac: &SparseJacobian, n: usize) -> DMatrix<f64> {
        let mut d = DMatrix::zeros(n, n);
        for c in 0..n {
            for e in jac.col_ptr[c]..jac.col_ptr[c + 1] {
                d[(jac.row_idx[e], c)] = jac.values[e];
            }
        }
        d
    }

    /// The analytic Jacobian and central differences of the right-hand side over every
    /// column, with steps `1e-6 max(|y_j|, 1)`.
    fn analytic_and_differenced(s: &mut ParticleSystem) -> (DMatrix<f64>, DMatrix<f64>) {
        let (model, state, solver) = s.parts();
        let free = solver.free(model, state).unwrap();
        let (mut dyn_, y) = (free.dynamics, free.y.to_vec());
        let n = y.len();
        let mut jac = SparseJacobian::default();
        assert!(dyn_.sparse_jacobian(0.0, &y, &mut jac).unwrap());
        let (mut yp, mut fp, mut fm) = (y.clone(), vec![0.0; n], vec![0.0; n]);
        let mut fd = DMatrix::zeros(n, n);
        for c in 0..n {
            let h = 1e-6 * y[c].abs().max(1.0);
            yp[c] = y[c] + h;
            dyn_.rhs(0.0, &yp, &mut fp).unwrap();
            yp[c] = y[c] - h;
            dyn_.rhs(0.0, &yp, &mut fm).unwrap();
            yp[c] = y[c];
            for r in 0..n {
                fd[(r, c)] = (fp[r] - fm[r]) / (2.0 * h);
            }
        }
        (dense(&jac, n), fd)
    }

    fn every_force() -> Vec<(&'static str, Force)> {
        let pairs = vec![[0, 1], [1, 2], [2, 3], [3, 4], [4, 5], [5, 6], [6, 0], [0, 3]];
        vec![
            ("gravity", Force::Gravity { g: DVec3::new(0.0, -9.81, 0.0) }),
            ("drag", Force::Drag { linear: 0.3, quadratic: 0.7, wind: DVec3::new(1.0, 0.5, -0.2) }),
            ("damping", Force::Damping { rate: 0.8 }),
            (
                "attractor",
                Force::Attractor {
                    center: DVec3::new(0.2, 1.0, -0.3),
                    strength: 3.0,
                    softening: 0.2,
                },
            ),
            (
                "vortex",
                Force::Vortex {
                    center: DVec3::new(0.1, 0.0, 0.2),
                    axis: DVec3::new(0.3, 1.0, 0.1),
                    strength: 2.0,
                    core: 0.1,
                },
            ),
            ("turbulence", Force::Turbulence { strength: 2.0, scale: 0.7, seed: 5 }),
            (
                "springs",
                Force::Springs {
                    rest: (0..pairs.len()).map(|k| 0.3 + 0.05 * k as f64).collect(),
                    pairs,
                    stiffness: 50.0,
                    damping: 1.5,
                },
            ),
            ("repulsion", Force::NeighborRepulsion { radius: 0.7, stiffness: 40.0 }),
        ]
    }

    #[test]
    fn analytic_jacobian_matches_central_differences_for_every_force() {
        for (name, force) in every_force() {
            for seed in 0..5 {
                let mut s = system(force.clone(), seed);
                let (an, fd) = analytic_and_differenced(&mut s);
                let scale = an.amax().max(1.0);
                let err = (&an - &fd).amax();
                // Turbulence is itself differenced (step ε^{1/3} L), the others are exact.
                let tol = if name == "turbulence" { 1e-5 } else { 1e-8 };
                assert!(err <= tol * scale, "{name} seed {seed}: error {err:e}, scale {scale}");
                // Pinned (2) and dead (7) particles have zero rows.
                for pinned in [2, 7] {
                    for r in [3 * pinned, 24 + 3 * pinned] {
                        assert!(an.row(r).amax() == 0.0, "{name}: row {r}");
                    }
                }
            }
        }
        // All forces together, and the repulsion really found pairs.
        let mut s = system(Force::Damping { rate: 0.1 }, 9);
        for (_, f) in every_force() {
            s.add_force(f).unwrap();
        }
        let (an, fd) = analytic_and_differenced(&mut s);
        assert!((&an - &fd).amax() <= 1e-5 * an.amax());
        assert!(!s.solver.jacobian.close.is_empty());
    }

    /// The particle equations offering only the dense Jacobian: the sparse one converted
    /// (`analytic`), or none (the stepper differences).
    struct DenseOnly<'a, 'b> {
        inner: &'b mut Dynamics<'a>,
        analytic: bool,
    }

    impl OdeSystem for DenseOnly<'_, '_> {
        fn dim(&self) -> usize {
            self.inner.dim()
        }
        fn rhs(&mut self, t: f64, y: &[f64], dydt: &mut [f64]) -> crate::Result<()> {
            self.inner.rhs(t, y, dydt)
        }
        fn jacobian(&mut self, t: f64, y: &[f64], jac: &mut DMatrix<f64>) -> crate::Result<bool> {
            if !self.analytic {
                return Ok(false);
            }
            let mut sparse = SparseJacobian::default();
            self.inner.sparse_jacobian(t, y, &mut sparse)?;
            *jac = dense(&sparse, y.len());
            Ok(true)
        }
    }

    #[test]
    fn sparse_and_dense_newton_take_the_same_step() {
        for method in [Method::ImplicitEuler, Method::Trapezoidal, Method::Bdf2] {
            let base = {
                let mut s = system(every_force()[6].1.clone(), 3);
                s.add_force(Force::Drag { linear: 0.1, quadratic: 0.2, wind: DVec3::X }).unwrap();
                s
            };
            let run = |mode: u8| {
                let mut s = base.clone();
                let mut stepper = Stepper::new(method, 48).unwrap();
                let (model, state, solver) = s.parts();
                let free = solver.free(model, state).unwrap();
                let (mut d, y) = (free.dynamics, free.y);
                for k in 0..5 {
                    let t = 0.01 * k as f64;
                    match mode {
                        0 => stepper.step(&mut d, t, y, 0.01),
                        m => stepper.step(
                            &mut DenseOnly { inner: &mut d, analytic: m == 1 },
                            t,
                            y,
                            0.01,
                        ),
                    }
                    .unwrap();
                }
                y.to_vec()
            };
            let (sparse, dense_analytic, dense_fd) = (run(0), run(1), run(2));
            let diff = |a: &[f64], b: &[f64]| {
                a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
            };
            let moved = diff(
                &sparse,
                base.positions()
                    .iter()
                    .chain(base.velocities())
                    .copied()
                    .collect::<Vec<_>>()
                    .as_slice(),
            );
            assert!(moved > 1e-3, "{}: the springs moved the particles", method.name());
            assert!(diff(&sparse, &dense_analytic) <= 1e-12, "{}", method.name());
            // Differenced Jacobian: the same solution to the Newton tolerance.
            assert!(diff(&sparse, &dense_fd) <= 1e-8, "{}", method.name());
        }
    }
}
