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
//! After each factorisation the factor is copied once into plain compressed columns (and
//! rows) in the form `L = U diag(l)` (`U` unit lower triangular), so that `A = Pᵀ U D Uᵀ P`
//! with `D = diag(l²)`. A call gathers the state into rows in the factor's order
//! ([`LinearImplicit::begin`]), takes its steps there and scatters the last good one back
//! ([`LinearImplicit::end`]). A step is two passes (Davis, *Direct Methods for Sparse Linear
//! Systems*, SIAM 2006, §4.1 and §4.6: `lsolve` by rows and `ltsolve`): the forward sweep
//! `U z = b` by rows, each row's right-hand side `b = h f` assembled just before it is used
//! (the forces on single particles, the springs at the stage `x₀ + h v₀`), and the backward
//! sweep `Uᵀ Δv = D⁻¹ z` by rows of `Uᵀ`, each row followed by its new velocity, position and
//! next stage, the three coordinates of a particle side by side. The new state goes to a
//! second pair of buffers, swapped in when all of it is finite. Nothing is allocated in a
//! step.
//!
//! [`LinearImplicit::prepare`] rebuilds `A`'s values (`O(N + springs)`) only when the model's
//! forces, the state's masses and live slots or the step changed since it last ran (their keys:
//! [`super::Model`]'s `forces_key`, the state's `summary.slots`), and refactorises only when
//! the values are not bitwise the factorised ones. The pattern (the springs' graph) and its
//! symbolic analysis are redone only when the springs change.

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
    /// The model's forces key, the state's slots key and the step's bits that `prepare` last
    /// set up for.
    built: Option<(u64, u64, u64)>,
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
    /// `U`'s entries below the diagonal (positions) in compressed columns, the same in
    /// compressed rows (each row's columns ascending), and `1 / l_j²`.
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    unit: Vec<f64>,
    row_ptr: Vec<usize>,
    col_idx: Vec<usize>,
    unit_by_rows: Vec<f64>,
    inv_pivot: Vec<f64>,
    /// Whether the slot at each position moves (alive, finite mass), and its mass (kg).
    moves: Vec<bool>,
    mass: Vec<f64>,
    /// The springs at each position that moves, in force order: `springs[ends[j]..ends[j +
    /// 1]]` holds the position at the other end and `h k` of each spring of position `j`.
    ends: Vec<usize>,
    springs: Vec<(usize, f64)>,
    /// Per position, during a call: the positions and velocities of the last good step, the
    /// new ones of the step being taken, the stage `x + h v` of the next step, and the
    /// forward sweep's `z` (then `Δv`).
    x: Vec<Row>,
    v: Vec<Row>,
    x1: Vec<Row>,
    v1: Vec<Row>,
    stage: Vec<Row>,
    z: Vec<Row>,
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
#[inline(always)]
fn row(v: DVec3) -> Row {
    [v.x, v.y, v.z, 0.0]
}

/// The vector of a row.
#[inline(always)]
fn vector(r: &Row) -> DVec3 {
    DVec3::new(r[0], r[1], r[2])
}

/// Whether slot `i` moves: alive, with a finite mass.
fn free(alive: &[bool], inv_mass: &[f64], i: usize) -> bool {
    alive[i] && inv_mass[i] > 0.0
}

impl LinearImplicit {
    /// Whether [`Self::prepare`] last set up for the forces of `forces_key`, the masses and
    /// live slots of `slots_key` and steps of `h`: a linear model whose factors are at hand.
    pub(super) fn prepared(&self, forces_key: u64, slots_key: u64, h: f64) -> bool {
        self.built == Some((forces_key, slots_key, h.to_bits()))
    }

    /// Set up `A` for steps of `h` of a linear `model` (see [`Model::linear`]) with these
    /// masses (kg, per slot), inverse masses and live slots (of key `slots_key`, see
    /// [`Self::prepared`]), factorising it unless its factors are at hand; returns whether it
    /// factorised. Nothing is done when it is already set up for them.
    ///
    /// # Errors
    /// Out of memory for the workspaces (argument `capacity`), or a factorisation that fails
    /// ([`Error::SolverFailed`]; `A` is positive definite for valid models).
    pub(super) fn prepare(
        &mut self,
        model: &Model,
        slots_key: u64,
        mass: &[f64],
        inv_mass: &[f64],
        alive: &[bool],
        h: f64,
    ) -> Result<bool> {
        if self.prepared(model.forces_key, slots_key, h) {
            return Ok(false);
        }
        self.built = None;
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
        // What the steps read per position: whether it moves, its mass, and the springs.
        for j in 0..n {
            self.moves[j] = free(alive, inv_mass, self.order[j]);
            self.mass[j] = mass[self.order[j]];
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
        self.built = Some((model.forces_key, slots_key, h.to_bits()));
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
        self.mass = vec![0.0; n];
        self.ends = Vec::with_capacity(n + 1);
        self.springs = Vec::with_capacity(2 * self.pairs.len());
        for rows in [&mut self.x, &mut self.v, &mut self.x1, &mut self.v1] {
            *rows = filled("capacity", n, [0.0; 4])?;
        }
        self.stage = filled("capacity", n, [0.0; 4])?;
        self.z = filled("capacity", n, [0.0; 4])?;
        Ok(())
    }

    /// Copy the factor just computed into `order`, `position`, `U` by columns and by rows,
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
        // The transpose by counting: columns visited in order give each row's ascending.
        self.row_ptr.clear();
        self.row_ptr.resize(n + 1, 0);
        for &r in &self.row_idx {
            self.row_ptr[r + 1] += 1;
        }
        for r in 0..n {
            self.row_ptr[r + 1] += self.row_ptr[r];
        }
        let mut next = self.row_ptr.clone();
        self.col_idx.resize(self.row_idx.len(), 0);
        self.unit_by_rows.resize(self.row_idx.len(), 0.0);
        for j in 0..n {
            for k in self.col_ptr[j]..self.col_ptr[j + 1] {
                let r = self.row_idx[k];
                (self.col_idx[next[r]], self.unit_by_rows[next[r]]) = (j, self.unit[k]);
                next[r] += 1;
            }
        }
    }

    /// Start a call of steps of `h` (after [`Self::prepare`]) from `y = [x; v]`: the state
    /// into rows in the factor's order (in both pairs of buffers: the rows that stay put are
    /// never written), and the first stage.
    pub(super) fn begin(&mut self, y: &[f64], h: f64) {
        let n = self.order.len();
        let (x, v) = y.split_at(3 * n);
        let at = |x: &[f64], i: usize| row(DVec3::from_slice(&x[3 * i..3 * i + 3]));
        for (j, &i) in self.order.iter().enumerate() {
            (self.x[j], self.v[j]) = (at(x, i), at(v, i));
            let s = vector(&self.x[j]) + h * vector(&self.v[j]);
            self.stage[j] = if self.moves[j] { row(s) } else { self.x[j] };
        }
        self.x1.copy_from_slice(&self.x);
        self.v1.copy_from_slice(&self.v);
    }

    /// Write the state of the last good step back into `y` (the slots that move).
    pub(super) fn end(&self, y: &mut [f64]) {
        let n = self.order.len();
        let (x, v) = y.split_at_mut(3 * n);
        for (j, &i) in self.order.iter().enumerate() {
            if self.moves[j] {
                x[3 * i..3 * i + 3].copy_from_slice(&self.x[j][..3]);
                v[3 * i..3 * i + 3].copy_from_slice(&self.v[j][..3]);
            }
        }
    }

    /// One implicit Euler step of `h` (between [`Self::begin`] and [`Self::end`]) under
    /// `forces` and the `external` forces (N, `3 capacity` values or empty); the new state
    /// becomes the last good one only when it is finite.
    ///
    /// # Errors
    /// A non-finite new state ([`Error::Diverged`], step 0, index `3 i` for the first slot
    /// `i` that went non-finite); the last good state is unchanged then.
    pub(super) fn step(&mut self, forces: &[Force], external: &[f64], h: f64) -> Result<()> {
        // Every buffer as a local slice: the compiler then knows that the stores into one do
        // not change the others, and keeps their addresses in registers.
        let LinearImplicit { order, moves, mass, ends, springs, inv_pivot, .. } = self;
        let (order, moves, mass): (&[usize], &[bool], &[f64]) = (order, moves, mass);
        let (ends, springs, inv_pivot): (&[usize], &[(usize, f64)], &[f64]) =
            (ends, springs, inv_pivot);
        let (row_ptr, col_idx, unit_by_rows) =
            (&self.row_ptr[..], &self.col_idx[..], &self.unit_by_rows[..]);
        let (col_ptr, row_idx, unit) = (&self.col_ptr[..], &self.row_idx[..], &self.unit[..]);
        let (x, v, x1, v1) = (&self.x[..], &self.v[..], &mut self.x1[..], &mut self.v1[..]);
        let (stage, z) = (&mut self.stage[..], &mut self.z[..]);
        let n = order.len();
        let local = forces.iter().any(Force::acts_alone);
        // `U z = b` by rows, each `b_j = h f_j` made just before: the forces on single
        // particles, then the springs' `-k d` at the stage (zero where nothing moves). Where
        // the row before is in the sum (a chain's factor), its value is taken from the
        // register that computed it rather than loaded back from the row just stored: the
        // sweeps are bound by that latency.
        let mut before: Row = [0.0; 4];
        for j in 0..n {
            let mut b = if moves[j] {
                let i = order[j];
                let f = if local {
                    let (s, v) = (vector(&stage[j]), vector(&v[j]));
                    particle_force(forces, s, v, mass[j]) + external_force(external, i)
                } else {
                    DVec3::ZERO + external_force(external, i)
                };
                let (mut f, s) = (row(h * f), stage[j]);
                for &(other, hk) in &springs[ends[j]..ends[j + 1]] {
                    let o = stage[other];
                    f = std::array::from_fn(|c| f[c] - hk * (s[c] - o[c]));
                }
                f
            } else {
                [0.0; 4]
            };
            let (start, end) = (row_ptr[j], row_ptr[j + 1]);
            for (&k, &u) in col_idx[start..end].iter().zip(&unit_by_rows[start..end]) {
                let zk = if k + 1 == j { before } else { z[k] };
                b = std::array::from_fn(|c| b[c] - u * zk[c]);
            }
            (z[j], before) = (b, b);
        }
        // `Uᵀ Δv = D⁻¹ z` by rows, each followed by the new velocity, position and next
        // stage; `nan` stays zero while they are finite (0 · ±inf and 0 · NaN are NaN).
        let mut nan: Row = [0.0; 4];
        let mut after: Row = [0.0; 4];
        for j in (0..n).rev() {
            let d = inv_pivot[j];
            let mut t = z[j].map(|z| z * d);
            let (start, end) = (col_ptr[j], col_ptr[j + 1]);
            for (&r, &u) in row_idx[start..end].iter().zip(&unit[start..end]) {
                let dv = if r == j + 1 { after } else { z[r] };
                t = std::array::from_fn(|c| t[c] - u * dv[c]);
            }
            (z[j], after) = (t, t);
            if moves[j] {
                let (xj, vj) = (x[j], v[j]);
                let vn: Row = std::array::from_fn(|c| vj[c] + t[c]);
                let xn: Row = std::array::from_fn(|c| xj[c] + h * vn[c]);
                stage[j] = std::array::from_fn(|c| xn[c] + h * vn[c]);
                nan = std::array::from_fn(|c| nan[c] + (xn[c] * 0.0 + vn[c] * 0.0));
                (x1[j], v1[j]) = (xn, vn);
            }
        }
        let finite = nan.iter().all(|&e| e == 0.0);
        if !finite {
            let bad = |j: usize| {
                self.moves[j] && !self.x1[j].iter().chain(&self.v1[j]).all(|v| v.is_finite())
            };
            let i = (0..n).find(|&i| bad(self.position[i])).expect("a non-finite value");
            return Err(Error::Diverged {
                step: 0,
                index: 3 * i,
                reason: "implicit_euler produced a non-finite state".into(),
            });
        }
        std::mem::swap(&mut self.x, &mut self.x1);
        std::mem::swap(&mut self.v, &mut self.v1);
        Ok(())
    }
}
