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
//! factorisation `P A Pᵀ = L Lᵀ` (faer, AMD ordering, simplicial; [`SparseCholesky`]) serves
//! the three coordinates. The right-hand side is one evaluation of the forces, at
//! `(x₀ + h v₀, v₀)`: `K` acts on positions only, and damping, gravity, the drag's wind and
//! the external forces (held constant within a step) are the same at both states, so
//! `f(x₀ + h v₀, v₀) = f(x₀, v₀) + h K v₀`. Pinned and dead slots have identity rows and a
//! zero right-hand side (they stay put, as in the general path).
//!
//! After each factorisation the factor is copied once into plain compressed columns in the
//! form `L = U diag(l)` (`U` unit lower triangular), so that `A = Pᵀ U D Uᵀ P` with
//! `D = diag(l²)`, and a step solves it by a hand-written forward sweep over `U`'s columns and
//! a backward sweep over its rows (Davis, *Direct Methods for Sparse Linear Systems*, SIAM
//! 2006, §4.1 and §4.6: `lsolve` and `ltsolve`), the three coordinates of a particle side by
//! side, in the factor's order: the right-hand side is assembled in that order (the stage, the
//! forces on single particles, the springs), and the new state is computed into the step's
//! buffers and written to the state only when all of it is finite. Nothing is allocated in a
//! step.
//!
//! Each call rebuilds `A`'s values (`O(N + springs)`) and keeps the factorisation when they
//! are bitwise the factorised ones (the same springs, masses, live slots and step): across the
//! steps of a call and across calls. The pattern (the springs' graph) and its symbolic analysis
//! are redone only when the springs change.

// The loops index the state, the masses and the pattern's slots by particle, as the formulas do.
#![allow(clippy::needless_range_loop)]

use super::dynamics::external_force;
use super::{particle_force, Force, Model};
use crate::error::{filled, Error, Result};
use crate::linalg::SparseCholesky;
use glam::DVec3;

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
    /// The factorisation's order: `order[j]` is the slot at position `j` of `P A Pᵀ`, and
    /// `position` its inverse.
    order: Vec<usize>,
    position: Vec<usize>,
    /// `U`'s entries below the diagonal in compressed columns (positions), and `1 / l_j²`.
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    unit: Vec<f64>,
    inv_pivot: Vec<f64>,
    /// Whether the slot at each position moves (alive, finite mass), as `A` was built.
    moves: Vec<bool>,
    /// The springs at each position that moves, in force order: `springs[ends[j]..ends[j +
    /// 1]]` holds the position at the other end and `h k` of each spring of position `j`.
    ends: Vec<usize>,
    springs: Vec<(usize, f64)>,
    /// Per position: the stage positions `x₀ + h v₀`, then the new positions; the right-hand
    /// side `h f`, then `Δv`, then the new velocities.
    stage: Vec<Row>,
    rhs: Vec<Row>,
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

/// The `x`, `y`, `z` of one particle and a zero: rows of four, read and written as two pairs
/// by every loop (rows of three were read as one value and a pair where the loop before had
/// written a pair and one value, which stalls every load on the stores before it).
type Row = [f64; 4];

/// The row of a vector.
fn row(v: DVec3) -> Row {
    [v.x, v.y, v.z, 0.0]
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
        let refactor = !same(&self.values, &self.factored);
        if refactor {
            self.factored.clear();
            let factor = self.factor.as_mut().expect("analyse builds the factor");
            factor.factorize(&self.values)?;
            self.factored.extend_from_slice(&self.values);
            self.extract();
        }
        // What the steps of this call read per position: whether it moves, and the springs.
        for j in 0..n {
            self.moves[j] = free(alive, inv_mass, self.order[j]);
        }
        self.ends.clear();
        self.ends.resize(n + 1, 0);
        for (pairs, _) in springs() {
            for &[a, b] in pairs {
                for p in [self.position[a], self.position[b]] {
                    self.ends[p + 1] += usize::from(self.moves[p]);
                }
            }
        }
        for j in 0..n {
            self.ends[j + 1] += self.ends[j];
        }
        self.springs.resize(self.ends[n], (0, 0.0));
        for (pairs, k) in springs() {
            for &[a, b] in pairs {
                let (pa, pb) = (self.position[a], self.position[b]);
                for (p, other) in [(pa, pb), (pb, pa)] {
                    if self.moves[p] {
                        self.springs[self.ends[p]] = (other, h * k);
                        self.ends[p] += 1;
                    }
                }
            }
        }
        // Each `ends[j]` is now the start of position `j + 1`'s springs.
        self.ends.rotate_right(1);
        self.ends[0] = 0;
        Ok(refactor)
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
        self.factor = Some(SparseCholesky::simplicial(n, col_ptr, row_idx)?);
        self.moves = vec![false; n];
        self.ends = Vec::with_capacity(n + 1);
        self.springs = Vec::with_capacity(2 * self.pairs.len());
        self.stage = filled("capacity", n, [0.0; 4])?;
        self.rhs = filled("capacity", n, [0.0; 4])?;
        Ok(())
    }

    /// Copy the factor just computed into `order`, `position`, `col_ptr`, `row_idx`, `unit`
    /// and `inv_pivot` (see the module docs).
    fn extract(&mut self) {
        let factor = self.factor.as_ref().expect("analyse builds the factor");
        let (perm, col_ptr, row_idx, values) =
            factor.simplicial_factor().expect("a simplicial L Lᵀ factorisation");
        let n = col_ptr.len() - 1;
        self.order.clear();
        match perm {
            Some(perm) => self.order.extend_from_slice(perm),
            None => self.order.extend(0..n),
        }
        self.position.resize(n, 0);
        for (j, &i) in self.order.iter().enumerate() {
            self.position[i] = j;
        }
        self.col_ptr.clear();
        self.row_idx.clear();
        self.unit.clear();
        self.inv_pivot.clear();
        self.col_ptr.push(0);
        for j in 0..n {
            let (start, end) = (col_ptr[j], col_ptr[j + 1]);
            debug_assert_eq!(row_idx[start], j, "the diagonal entry comes first");
            let l = values[start];
            self.inv_pivot.push(1.0 / (l * l));
            self.row_idx.extend_from_slice(&row_idx[start + 1..end]);
            self.unit.extend(values[start + 1..end].iter().map(|v| v / l));
            self.col_ptr.push(self.row_idx.len());
        }
    }

    /// One implicit Euler step of `h` from `y = [x; v]` (after [`Self::prepare`] for this `h`
    /// and these masses, live slots and springs) under `forces` and the `external` forces
    /// (N, `3 capacity` values or empty), written into `y` only when the new state is finite.
    ///
    /// # Errors
    /// A non-finite new state ([`Error::Diverged`], step 0, index `3 i` for the first slot
    /// `i` that went non-finite); `y` is unchanged then.
    pub(super) fn step(
        &mut self,
        forces: &[Force],
        mass: &[f64],
        external: &[f64],
        y: &mut [f64],
        h: f64,
    ) -> Result<()> {
        let n = self.order.len();
        let (x, v) = y.split_at(3 * n);
        let at = |x: &[f64], i: usize| DVec3::from_slice(&x[3 * i..3 * i + 3]);
        // The stage, then the forces times h: on single particles, then the springs' `-k d`
        // (zero where nothing moves). Each row is written once.
        for ((&i, &moves), stage) in self.order.iter().zip(&self.moves).zip(&mut self.stage) {
            let xi = at(x, i);
            *stage = row(if moves { xi + h * at(v, i) } else { xi });
        }
        let local = forces.iter().any(Force::acts_alone);
        for j in 0..n {
            if !self.moves[j] {
                self.rhs[j] = [0.0; 4];
                continue;
            }
            let i = self.order[j];
            let f = if local {
                let s = DVec3::from_slice(&self.stage[j]);
                particle_force(forces, s, at(v, i), mass[i]) + external_force(external, i)
            } else {
                DVec3::ZERO + external_force(external, i)
            };
            let (mut f, s) = (row(h * f), self.stage[j]);
            for &(other, hk) in &self.springs[self.ends[j]..self.ends[j + 1]] {
                let o = self.stage[other];
                for c in 0..4 {
                    f[c] -= hk * (s[c] - o[c]);
                }
            }
            self.rhs[j] = f;
        }
        // `U z = b` by columns, then `Uᵀ Δv = D⁻¹ z` by rows. Where the next row is the
        // neighbour of the one just done (a chain's factor), its value is taken from the
        // register that computed it rather than loaded back from the row just stored: the
        // sweeps are bound by that latency.
        let rhs = &mut self.rhs;
        let mut next = None;
        for j in 0..n {
            let z = next.take().unwrap_or(rhs[j]);
            let (start, end) = (self.col_ptr[j], self.col_ptr[j + 1]);
            for (&r, &u) in self.row_idx[start..end].iter().zip(&self.unit[start..end]) {
                let row = rhs[r];
                let updated = std::array::from_fn(|c| row[c] - u * z[c]);
                rhs[r] = updated;
                if r == j + 1 {
                    // Column `j` is the last to update row `j + 1`.
                    next = Some(updated);
                }
            }
        }
        let mut done: Option<Row> = None;
        for j in (0..n).rev() {
            let d = self.inv_pivot[j];
            let mut t = rhs[j].map(|z| z * d);
            let (start, end) = (self.col_ptr[j], self.col_ptr[j + 1]);
            for (&r, &u) in self.row_idx[start..end].iter().zip(&self.unit[start..end]) {
                let x = match done {
                    Some(x) if r == j + 1 => x,
                    _ => rhs[r],
                };
                for c in 0..4 {
                    t[c] -= u * x[c];
                }
            }
            (rhs[j], done) = (t, Some(t));
        }
        // The new state into the buffers (velocities over `Δv`, positions over the stage).
        let mut finite = true;
        for j in 0..n {
            if !self.moves[j] {
                continue;
            }
            let i = self.order[j];
            for c in 0..3 {
                let v1 = v[3 * i + c] + rhs[j][c];
                let x1 = x[3 * i + c] + h * v1;
                (rhs[j][c], self.stage[j][c]) = (v1, x1);
                finite &= v1.is_finite() & x1.is_finite();
            }
        }
        if !finite {
            let bad = |j: usize| {
                self.moves[j] && !rhs[j].iter().chain(&self.stage[j]).all(|v| v.is_finite())
            };
            let i = (0..n).find(|&i| bad(self.position[i])).expect("a non-finite value");
            return Err(Error::Diverged {
                step: 0,
                index: 3 * i,
                reason: "implicit_euler produced a non-finite state".into(),
            });
        }
        let (x, v) = y.split_at_mut(3 * n);
        for j in 0..n {
            if self.moves[j] {
                let i = self.order[j];
                x[3 * i..3 * i + 3].copy_from_slice(&self.stage[j][..3]);
                v[3 * i..3 * i + 3].copy_from_slice(&rhs[j][..3]);
            }
        }
        Ok(())
    }
}
