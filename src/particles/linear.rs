//! Implicit Euler for particle models whose forces are all linear ([`Model::linear`]: gravity,
//! damping, linear drag, springs of rest length 0 without damping), in the velocity form of
//! Baraff & Witkin 1998 ("Large steps in cloth simulation", §3, eq. 6, multiplied by `M`):
//!
//! `(M - h D - h² K) Δv = h (f(x₀, v₀) + h K v₀)`,  `v₁ = v₀ + Δv`,  `x₁ = x₀ + h v₁`,
//!
//! with `K = ∂f/∂x`, `D = ∂f/∂v`. Since the force is affine this is the implicit Euler step
//! `y₁ = y₀ + h f(y₁)` of the `6N` first-order system solved exactly, as one Newton update of
//! [`crate::ode::Workspace`] solves it, on `3N` unknowns instead of `6N`. For these forces `K`
//! and `D` are scalar `N x N` matrices times the 3-D identity (a spring of stiffness `k`
//! between `a` and `b` adds `-k (e_a - e_b)(e_a - e_b)ᵀ`, damping of rate `c` adds `-c m_i` and
//! linear drag `-k₁` to the diagonal), so the matrix is `A ⊗ I₃` with `A` symmetric, strictly
//! diagonally dominant with a positive diagonal, hence positive definite: one sparse Cholesky
//! factorisation of `A` (faer, AMD ordering; [`SparseCholesky`]) solves the three coordinates
//! together. The right-hand side is one evaluation of the forces, at `(x₀ + h v₀, v₀)`: `K`
//! acts on positions only, and damping, gravity, the drag's wind and the external forces
//! (held constant within a step) are the same at both states, so
//! `f(x₀ + h v₀, v₀) = f(x₀, v₀) + h K v₀`. Pinned and dead slots have identity rows and a
//! zero right-hand side (they stay put, as in the general path).
//!
//! Each call rebuilds `A`'s values (`O(N + springs)`) and keeps the factorisation when they
//! are bitwise the factorised ones (the same springs, masses, live slots and step): across the
//! steps of a call and across calls. The pattern (the springs' graph) and its symbolic analysis
//! are redone only when the springs change.

// The loops index the state, the masses and the pattern's slots by particle, as the formulas do.
#![allow(clippy::needless_range_loop)]

use super::{Dynamics, Force, Model};
use crate::error::{filled, Error, Result};
use crate::linalg::SparseCholesky;
use crate::ode::OdeSystem;

/// The workspace of the velocity-form step (see the module docs). Scratch only: cloning gives
/// an empty one, rebuilt at the next call.
#[derive(Default)]
pub(super) struct LinearImplicit {
    /// The springs' pairs (every [`Force::Springs`] in force order) the pattern was built for.
    pairs: Vec<[usize; 2]>,
    /// Slot in `values` of each diagonal entry, and of each spring's off-diagonal entry.
    diag: Vec<usize>,
    off: Vec<usize>,
    /// `A`'s lower triangle in the pattern's order, and the values `factor` holds the
    /// factors of (empty: none).
    values: Vec<f64>,
    factored: Vec<f64>,
    factor: Option<SparseCholesky>,
    /// The step's state `(x₀ + h v₀, v₀)` and the derivative `[v; a]` there (`6N` each).
    stage: Vec<f64>,
    derivative: Vec<f64>,
    /// The right-hand side, then `Δv`: the `x`, `y` and `z` coordinates of the `N` slots
    /// one after another (`3N`).
    rhs: Vec<f64>,
    /// The new state `[x₁; v₁]` (`6N`), written to the state only when it is finite.
    y_new: Vec<f64>,
}

impl Clone for LinearImplicit {
    fn clone(&self) -> Self {
        LinearImplicit::default()
    }
}

impl std::fmt::Debug for LinearImplicit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "LinearImplicit(n = {}, springs = {})", self.diag.len(), self.pairs.len())
    }
}

/// Whether slot `i` moves: alive, with a finite mass.
fn free(alive: &[bool], inv_mass: &[f64], i: usize) -> bool {
    alive[i] && inv_mass[i] > 0.0
}

impl LinearImplicit {
    /// Set up `A` for steps of `h` of a linear `model` (see [`Model::linear`]) with these
    /// masses (kg, per slot), inverse masses and live slots, factorising it unless its factors
    /// are at hand; returns whether it factorised.
    ///
    /// # Errors
    /// Out of memory for the workspaces (argument `capacity`), or a factorisation that fails
    /// ([`Error::SolverFailed`]; `A` is positive definite for valid models).
    pub(super) fn prepare(
        &mut self,
        model: &Model,
        mass: &[f64],
        inv_mass: &[f64],
        alive: &[bool],
        h: f64,
    ) -> Result<bool> {
        let n = model.n;
        let springs = || {
            model.forces.iter().filter_map(|f| match f {
                Force::Springs { pairs, stiffness, .. } => Some((pairs, *stiffness)),
                _ => None,
            })
        };
        let same = self.factor.is_some()
            && self.diag.len() == n
            && springs().flat_map(|(p, _)| p.iter()).eq(self.pairs.iter());
        if !same {
            self.analyse(n, springs().flat_map(|(p, _)| p.iter().copied()))?;
        }
        let (mut rate, mut linear) = (0.0, 0.0);
        for force in &model.forces {
            match force {
                Force::Damping { rate: c } => rate += c,
                Force::Drag { linear: k, .. } => linear += k,
                _ => {}
            }
        }
        self.values.fill(0.0);
        for i in 0..n {
            self.values[self.diag[i]] = if free(alive, inv_mass, i) {
                mass[i] + h * (rate * mass[i] + linear)
            } else {
                1.0
            };
        }
        let mut s = 0;
        for (pairs, k) in springs() {
            let hk = h * h * k;
            for &[a, b] in pairs {
                let (fa, fb) = (free(alive, inv_mass, a), free(alive, inv_mass, b));
                if fa {
                    self.values[self.diag[a]] += hk;
                }
                if fb {
                    self.values[self.diag[b]] += hk;
                }
                if fa && fb {
                    self.values[self.off[s]] -= hk;
                }
                s += 1;
            }
        }
        let same = |a: &[f64], b: &[f64]| {
            a.len() == b.len() && a.iter().zip(b).all(|(a, b)| a.to_bits() == b.to_bits())
        };
        if same(&self.values, &self.factored) {
            return Ok(false);
        }
        self.factored.clear();
        let factor = self.factor.as_mut().expect("analyse builds the factor");
        factor.factorize(&self.values)?;
        self.factored.extend_from_slice(&self.values);
        Ok(true)
    }

    /// The pattern of `A` (lower triangle: every diagonal entry, and one entry per coupled
    /// pair), the slots of its entries, its symbolic factorisation and the step's buffers.
    fn analyse(&mut self, n: usize, pairs: impl Iterator<Item = [usize; 2]>) -> Result<()> {
        self.factor = None;
        self.factored.clear();
        self.pairs.clear();
        self.pairs.extend(pairs);
        // (column, row) with row >= column, sorted by column then row.
        let mut entries: Vec<(usize, usize)> = (0..n).map(|i| (i, i)).collect();
        entries.extend(self.pairs.iter().map(|&[a, b]| (a.min(b), a.max(b))));
        entries.sort_unstable();
        entries.dedup();
        let mut col_ptr = vec![0; n + 1];
        for &(c, _) in &entries {
            col_ptr[c + 1] += 1;
        }
        for c in 0..n {
            col_ptr[c + 1] += col_ptr[c];
        }
        let slot = |c: usize, r: usize| {
            entries.binary_search(&(c, r)).expect("every entry is in the pattern")
        };
        self.diag = (0..n).map(|i| slot(i, i)).collect();
        self.off = self.pairs.iter().map(|&[a, b]| slot(a.min(b), a.max(b))).collect();
        self.values = vec![0.0; entries.len()];
        let row_idx = entries.iter().map(|e| e.1).collect();
        self.factor = Some(SparseCholesky::new(n, col_ptr, row_idx)?);
        for buffer in [&mut self.stage, &mut self.derivative, &mut self.y_new] {
            *buffer = filled("capacity", 6 * n, 0.0)?;
        }
        self.rhs = filled("capacity", 3 * n, 0.0)?;
        Ok(())
    }

    /// One implicit Euler step of `h` from `y = [x; v]` at time `t` (after [`Self::prepare`]
    /// for this `h` and these masses), written into `y` only when the new state is finite.
    ///
    /// # Errors
    /// A system error, or a non-finite new state ([`Error::Diverged`], step 0, the first bad
    /// component of `y`); `y` is unchanged then.
    pub(super) fn step(
        &mut self,
        dynamics: &mut Dynamics<'_>,
        t: f64,
        y: &mut [f64],
        h: f64,
    ) -> Result<()> {
        let n = dynamics.n;
        let (alive, inv_mass, mass) = (dynamics.alive, dynamics.inv_mass, dynamics.mass);
        let (x, v) = y.split_at(3 * n);
        let (sx, sv) = self.stage.split_at_mut(3 * n);
        for i in 0..n {
            let moves = free(alive, inv_mass, i);
            for c in 3 * i..3 * i + 3 {
                sx[c] = if moves { x[c] + h * v[c] } else { x[c] };
            }
        }
        sv.copy_from_slice(v);
        dynamics.rhs(t, &self.stage, &mut self.derivative)?;
        let a = &self.derivative[3 * n..];
        for i in 0..n {
            let hm = if free(alive, inv_mass, i) { h * mass[i] } else { 0.0 };
            for c in 0..3 {
                self.rhs[c * n + i] = hm * a[3 * i + c];
            }
        }
        self.factor.as_mut().expect("prepare comes first").solve_in_place(&mut self.rhs);
        let (nx, nv) = self.y_new.split_at_mut(3 * n);
        for i in 0..n {
            for c in 0..3 {
                let k = 3 * i + c;
                nv[k] = v[k] + self.rhs[c * n + i];
                nx[k] = if free(alive, inv_mass, i) { x[k] + h * nv[k] } else { x[k] };
            }
        }
        if let Some(bad) = self.y_new.iter().position(|x| !x.is_finite()) {
            return Err(Error::Diverged {
                step: 0,
                index: bad,
                reason: "implicit_euler produced a non-finite state".into(),
            });
        }
        y.copy_from_slice(&self.y_new);
        Ok(())
    }
}
