//! The right-hand side of the particle equations of motion, `ẏ = [v; M⁻¹ f(x, v)]` over
//! `y = [x; v]` (Witkin & Baraff, "Particle system dynamics"), as an [`OdeSystem`]: forces on
//! single particles in one parallel pass, forces between particles (springs, the hash-grid
//! repulsion, all-pairs gravity) sequentially in a fixed order.

use super::*;
use rayon::prelude::*;

/// The externally set force on slot `i` (zero when none is set).
pub(super) fn external_force(external: &[f64], i: usize) -> DVec3 {
    if external.is_empty() {
        DVec3::ZERO
    } else {
        DVec3::from_slice(&external[3 * i..3 * i + 3])
    }
}

/// The particle equations of motion as an [`OdeSystem`] over `y = [x; v]`.
pub(crate) struct Dynamics<'a> {
    pub(super) n: usize,
    pub(super) forces: &'a [Force],
    pub(super) mass: &'a [f64],
    pub(super) inv_mass: &'a [f64],
    pub(super) alive: &'a [bool],
    pub(super) external: &'a [f64],
    pub(super) cells: &'a mut Vec<(u64, u32)>,
    /// Buffers of the sparse Jacobian; `None` offers none (the dense path).
    pub(super) jacobian: Option<&'a mut jacobian::JacobianWork>,
    /// [`OdeSystem::constant_jacobian`]: a key of this call when every force is linear and
    /// nothing changes the Jacobian within the call ([`super::Model::linear`], no emitters).
    pub(super) constant: Option<u64>,
}

impl OdeSystem for Dynamics<'_> {
    fn dim(&self) -> usize {
        6 * self.n
    }

    fn sparse_jacobian(&mut self, _t: f64, y: &[f64], jac: &mut SparseJacobian) -> Result<bool> {
        Ok(jacobian::fill(self, y, jac))
    }

    fn constant_jacobian(&self) -> Option<u64> {
        self.constant
    }

    fn rhs(&mut self, _t: f64, y: &[f64], dydt: &mut [f64]) -> Result<()> {
        let n = self.n;
        let (x, v) = y.split_at(3 * n);
        let (dx, f) = dydt.split_at_mut(3 * n);
        self.single_forces(x, v, dx, f);
        self.pair_forces(x, v, f);
        self.accelerations(dx, f);
        Ok(())
    }
}

/// The vector of slot `i` in a buffer of 3 values per slot.
fn at(x: &[f64], i: usize) -> DVec3 {
    DVec3::from_slice(&x[3 * i..3 * i + 3])
}

/// Add `a` to slot `i` of a buffer of 3 values per slot.
fn add(f: &mut [f64], i: usize, a: DVec3) {
    // One bounds check for the three.
    let f = &mut f[3 * i..3 * i + 3];
    f[0] += a.x;
    f[1] += a.y;
    f[2] += a.z;
}

impl Dynamics<'_> {
    /// Pass 1, parallel over particles: `x' = v` into `dx` and every force acting on one
    /// particle alone into `f` (each particle's sum in the order the forces were added,
    /// whatever the threads).
    fn single_forces(&self, x: &[f64], v: &[f64], dx: &mut [f64], f: &mut [f64]) {
        let (all_forces, mass, alive, external) =
            (self.forces, self.mass, self.alive, self.external);
        // Without forces on single particles (springs alone, say) the pass is two copies: the
        // sum below would add zeros, whose sign and bits are those of the copy (0 + x = x for
        // every x but -0, and a sum that starts at +0 never yields -0).
        let local = all_forces.iter().any(Force::acts_alone);
        dx.par_chunks_mut(3 * CHUNK).zip(f.par_chunks_mut(3 * CHUNK)).enumerate().for_each(
            |(c, (dxc, fc))| {
                let (start, len) = (3 * c * CHUNK, dxc.len());
                dxc.copy_from_slice(&v[start..start + len]);
                if !local {
                    match external.is_empty() {
                        true => fc.fill(0.0),
                        // `0 + e` as the sum below (which turns -0 into +0).
                        false => fc
                            .iter_mut()
                            .zip(&external[start..start + len])
                            .for_each(|(f, e)| *f = 0.0 + e),
                    }
                    for (f, _) in
                        fc.chunks_exact_mut(3).zip(&alive[c * CHUNK..]).filter(|(_, &a)| !a)
                    {
                        f.fill(0.0);
                    }
                    return;
                }
                for k in 0..dxc.len() / 3 {
                    let i = c * CHUNK + k;
                    let acc = if alive[i] {
                        particle_force(all_forces, at(x, i), at(v, i), mass[i])
                            + external_force(external, i)
                    } else {
                        DVec3::ZERO
                    };
                    fc[3 * k..3 * k + 3].copy_from_slice(&acc.to_array());
                }
            },
        );
    }

    /// Pass 2, sequential in a fixed order: forces between particles (springs, the hash-grid
    /// repulsion, all-pairs gravity) added into `f`.
    fn pair_forces(&mut self, x: &[f64], v: &[f64], f: &mut [f64]) {
        let (n, alive, mass, inv_mass) = (self.n, self.alive, self.mass, self.inv_mass);
        for force in self.forces {
            match force {
                Force::Springs { pairs, rest, stiffness, damping } => {
                    for (pair, l) in pairs.iter().zip(rest) {
                        let (a, b) = (pair[0], pair[1]);
                        let d = at(x, a) - at(x, b);
                        if *l == 0.0 && *damping == 0.0 {
                            // The linear force -k d, without the length and direction that
                            // the general form below takes (and equals it to rounding).
                            let fa = -stiffness * d;
                            add(f, a, fa);
                            add(f, b, -fa);
                            continue;
                        }
                        let len = d.length();
                        if len == 0.0 {
                            continue;
                        }
                        let dir = d / len;
                        let relative = (at(v, a) - at(v, b)).dot(dir);
                        let fa = -(stiffness * (len - l) + damping * relative) * dir;
                        add(f, a, fa);
                        add(f, b, -fa);
                    }
                }
                Force::NeighborRepulsion { radius, stiffness } => {
                    for_each_close_pair(self.cells, n, alive, x, *radius, |i, j, d, dist| {
                        let fi = stiffness * (radius - dist) / dist * d;
                        add(f, i, fi);
                        add(f, j, -fi);
                    });
                }
                Force::NBodyGravity { constant, softening } => {
                    let free = |i: usize| alive[i] && inv_mass[i] > 0.0;
                    for i in (0..n).filter(|&i| free(i)) {
                        for j in (i + 1..n).filter(|&j| free(j)) {
                            let d = at(x, j) - at(x, i);
                            let s = (d.length_squared() + softening * softening).powf(1.5);
                            let fi = constant * mass[i] * mass[j] / s * d;
                            add(f, i, fi);
                            add(f, j, -fi);
                        }
                    }
                }
                _ => {}
            }
        }
    }

    /// Pass 3, parallel: forces into accelerations; pinned (where `m g` is infinite) and dead
    /// slots stay put (`x' = v' = 0`).
    fn accelerations(&self, dx: &mut [f64], f: &mut [f64]) {
        let (alive, inv_mass) = (self.alive, self.inv_mass);
        dx.par_chunks_mut(3 * CHUNK).zip(f.par_chunks_mut(3 * CHUNK)).enumerate().for_each(
            |(c, (dxc, fc))| {
                let slots = c * CHUNK..;
                let each = fc.chunks_exact_mut(3).zip(dxc.chunks_exact_mut(3));
                for ((a, dx), (&alive, &inv_m)) in
                    each.zip(alive[slots.clone()].iter().zip(&inv_mass[slots]))
                {
                    if alive && inv_m > 0.0 {
                        a.iter_mut().for_each(|a| *a *= inv_m);
                    } else {
                        a.fill(0.0);
                        dx.fill(0.0);
                    }
                }
            },
        );
    }
}
