//! Implicit Euler for particles joined in chains: models whose forces are gravity, velocity
//! damping and at most one set of linear springs (rest length 0, no damping: `f = -k d`), each
//! spring joining a slot `a` to the slot `a + 1` with `a` increasing along the list (a rope,
//! several ropes, a chain with gaps), without colliders or emitters.
//! [`super::Solver::step`] takes this path for such models by itself.
//!
//! The step is the velocity form of `particles/linear.rs` (Baraff & Witkin 1998, §3, eq. 6,
//! multiplied by `M`): `(M - h D - h² K) Δv = h f(x₀ + h v₀, v₀)`, `v₁ = v₀ + Δv`, `x₁ = x₀ +
//! h v₁`, which solves the implicit Euler step of the `6N` first-order system exactly (the
//! force is affine). With the springs joining neighbouring slots, `A = M - h D - h² K` is
//! tridiagonal in the slots' own order (times the 3-D identity): symmetric and strictly
//! diagonally dominant with a positive diagonal, so its factorisation `A = L D Lᵀ` (`L` unit
//! lower bidiagonal: `d₀ = a₀`, `lᵢ = eᵢ / dᵢ₋₁`, `dᵢ = aᵢ - lᵢ eᵢ`, with `eᵢ` the entry
//! below the diagonal; Golub & Van Loan, *Matrix Computations*, 4th ed., §4.3.6) has no
//! fill and needs no ordering. Pinned and dead slots have identity rows, no coupling and a zero
//! right-hand side.
//!
//! A call keeps the factor while the model's forces, the state's masses and live slots and the
//! step are those it was made for (the keys of `particles/linear.rs`), gathers the state into
//! rows of four (`x, y, z, 0`) once and writes it back once. A step is two sweeps over the
//! rows, the three coordinates side by side: the forward one `L z = b`, each `b = h f` made
//! just before it is used (the forces on single particles and the two springs at the stage
//! `x₀ + h v₀`), and the backward one `D Lᵀ Δv = z`, each row followed by its new velocity,
//! position and next stage. The new state goes to a second pair of buffers, swapped in when
//! all of it is finite; nothing is allocated in a step.
//!
//! Results equal those of the general velocity form to rounding, not bit for bit: that one
//! factorises `P A Pᵀ` in the AMD ordering of faer, and sums the forces on single particles
//! force by force.

// The sweeps index their rows by slot, as the formulas do.
#![allow(clippy::needless_range_loop)]

use super::{Force, Model};
use crate::error::{Error, Result};
use glam::DVec3;

/// The `x`, `y`, `z` of one slot and a zero: one row in one AVX register.
type Row = [f64; 4];

/// Whether [`super::Solver::step`] takes this path for implicit Euler on `model` (the caller
/// checks that there are neither colliders nor emitters): forces that are gravity, velocity
/// damping and at most one set of linear springs each joining some slot `a` to `a + 1`, with
/// `a` increasing along the list.
pub(super) fn takes(model: &Model) -> bool {
    let springs = model.forces.iter().filter(|f| matches!(f, Force::Springs { .. })).count();
    springs <= 1
        && model.forces.iter().all(|f| match f {
            Force::Gravity { .. } | Force::Damping { .. } => true,
            Force::Springs { pairs, rest, damping, .. } => {
                *damping == 0.0
                    && rest.iter().all(|&l| l == 0.0)
                    && pairs.iter().all(|p| p[1] == p[0] + 1)
                    && pairs.windows(2).all(|w| w[0][0] < w[1][0])
            }
            _ => false,
        })
}

/// `value` where `mask` has all bits set, `+0` where it has none, on each entry of a row.
#[inline(always)]
fn masked(row: Row, mask: u64) -> Row {
    row.map(|v| f64::from_bits(v.to_bits() & mask))
}

/// The workspace of the chain's implicit Euler (see the module docs). Scratch and kept factor
/// only: cloning gives an empty one, rebuilt at the next call.
#[derive(Default)]
pub(super) struct ChainImplicit {
    /// The model's forces key, the state's slots key and the step's bits of the factor.
    built: Option<(u64, u64, u64)>,
    /// Per slot: whether it moves (alive, finite mass; a mask of all bits or none), `h k` of
    /// the spring ending at it and of the one starting at it (0 where none, or where it does
    /// not move), `lᵢ` (0 at slot 0) and `1 / dᵢ`.
    movable: Vec<u64>,
    ending: Vec<f64>,
    starting: Vec<f64>,
    lower: Vec<f64>,
    inv_pivot: Vec<f64>,
    /// The slots that do not move.
    still: Vec<usize>,
    /// The sum of the damping rates (1/s) and of the gravities (m/s²).
    rate: f64,
    gravity: DVec3,
    /// Per slot, during a call: `m g` plus the external force (N), and `-c m` (kg/s).
    base: Vec<Row>,
    damping: Vec<f64>,
    /// Per slot, during a call: the last good positions and velocities, the new ones of the
    /// step being taken, the forward sweep's `z` (then `Δv`), and the stage `x + h v` of the
    /// next step at entry `i + 1` (entries 0 and `n + 1` stay zero).
    x: Vec<Row>,
    v: Vec<Row>,
    x1: Vec<Row>,
    v1: Vec<Row>,
    z: Vec<Row>,
    stage: Vec<Row>,
}

impl Clone for ChainImplicit {
    fn clone(&self) -> Self {
        ChainImplicit::default()
    }
}

impl std::fmt::Debug for ChainImplicit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "ChainImplicit(n = {})", self.movable.len())
    }
}

impl ChainImplicit {
    /// Whether the factor at hand is that of the forces of `forces_key`, the masses and live
    /// slots of `slots_key` and steps of `h`.
    pub(super) fn prepared(&self, forces_key: u64, slots_key: u64, h: f64) -> bool {
        self.built == Some((forces_key, slots_key, h.to_bits()))
    }

    /// Make the factor of `A` for steps of `h` of `model` (one [`takes`]) with these masses
    /// (kg, per slot), inverse masses and live slots (of key `slots_key`) unless it is at
    /// hand; returns whether it factorised.
    ///
    /// # Errors
    /// A pivot that is not positive and finite ([`Error::SolverFailed`]; `A` is positive
    /// definite for valid models). Nothing is kept then.
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
        let (mut rate, mut gravity, mut k) = (0.0, DVec3::ZERO, 0.0);
        let mut pairs: &[[usize; 2]] = &[];
        for force in &model.forces {
            match force {
                Force::Damping { rate: c } => rate += c,
                Force::Gravity { g } => gravity += *g,
                Force::Springs { pairs: p, stiffness, .. } => (pairs, k) = (p, *stiffness),
                _ => {}
            }
        }
        (self.rate, self.gravity) = (rate, gravity);
        let free = |i: usize| alive[i] && inv_mass[i] > 0.0;
        self.movable.clear();
        self.movable.extend((0..n).map(|i| if free(i) { u64::MAX } else { 0 }));
        self.still.clear();
        self.still.extend((0..n).filter(|&i| !free(i)));
        // `A` as `particles/linear.rs` assembles it: its diagonal into `inv_pivot` and the
        // entries below it into `lower`, then factorised in place.
        let hk2 = h * h * k;
        self.inv_pivot.clear();
        self.inv_pivot.extend((0..n).map(|i| {
            if free(i) {
                mass[i] + h * (rate * mass[i] + 0.0)
            } else {
                1.0
            }
        }));
        for buffer in [&mut self.lower, &mut self.ending, &mut self.starting] {
            buffer.clear();
            buffer.resize(n, 0.0);
        }
        for &[a, b] in pairs {
            let (fa, fb) = (free(a), free(b));
            if fa {
                (self.inv_pivot[a], self.starting[a]) = (self.inv_pivot[a] + hk2, h * k);
            }
            if fb {
                (self.inv_pivot[b], self.ending[b]) = (self.inv_pivot[b] + hk2, h * k);
            }
            if fa && fb {
                self.lower[b] = -hk2;
            }
        }
        let mut before = 1.0;
        for i in 0..n {
            let e = self.lower[i];
            let l = e / before;
            let d = self.inv_pivot[i] - l * e;
            if !(d.is_finite() && d > 0.0) {
                return Err(Error::SolverFailed {
                    reason: format!("implicit Euler's matrix has the pivot {d} at particle {i}"),
                });
            }
            (self.lower[i], self.inv_pivot[i], before) = (l, 1.0 / d, d);
        }
        self.built = Some((model.forces_key, slots_key, h.to_bits()));
        Ok(true)
    }

    /// Start a call of steps of `h` (after [`Self::prepare`]) from `y = [x; v]`, with these
    /// masses (kg) and external forces (N, `3 capacity` values or empty): the state into rows,
    /// the forces on single particles that do not change within the call, the first stage.
    pub(super) fn begin(&mut self, y: &[f64], mass: &[f64], external: &[f64], h: f64) {
        let n = self.movable.len();
        let (x, v) = y.split_at(3 * n);
        for rows in
            [&mut self.x, &mut self.v, &mut self.x1, &mut self.v1, &mut self.z, &mut self.base]
        {
            rows.resize(n, [0.0; 4]);
        }
        self.stage.resize(n + 2, [0.0; 4]);
        self.damping.resize(n, 0.0);
        let g = self.gravity;
        let at = |b: &[f64], i: usize| [b[3 * i], b[3 * i + 1], b[3 * i + 2], 0.0];
        for i in 0..n {
            (self.x[i], self.v[i]) = (at(x, i), at(v, i));
            let (m, e) = (mass[i], if external.is_empty() { [0.0; 4] } else { at(external, i) });
            self.base[i] = [m * g.x + e[0], m * g.y + e[1], m * g.z + e[2], 0.0];
            self.damping[i] = -self.rate * m;
            let (xi, vi) = (self.x[i], self.v[i]);
            self.stage[i + 1] =
                if self.movable[i] != 0 { std::array::from_fn(|c| xi[c] + h * vi[c]) } else { xi };
        }
    }

    /// Write the state of the last good step back into `y` (the slots that move).
    pub(super) fn end(&self, y: &mut [f64]) {
        let n = self.movable.len();
        let (x, v) = y.split_at_mut(3 * n);
        for i in (0..n).filter(|&i| self.movable[i] != 0) {
            x[3 * i..3 * i + 3].copy_from_slice(&self.x[i][..3]);
            v[3 * i..3 * i + 3].copy_from_slice(&self.v[i][..3]);
        }
    }

    /// `steps` steps of `h` between [`Self::begin`] and [`Self::end`]: the number of good
    /// steps, and the error of the step after them, if one failed.
    pub(super) fn steps(&mut self, h: f64, steps: usize) -> (usize, Result<()>) {
        crate::batch::vectorize(Steps { work: self, h, steps })
    }

    /// One step of `h` (see the module docs); the new state becomes the last good one only
    /// when it is finite.
    ///
    /// # Errors
    /// A non-finite new state ([`Error::Diverged`], step 0, the index of the first slot that
    /// went non-finite); the last good state is unchanged then.
    #[inline(always)]
    fn step(&mut self, h: f64) -> Result<()> {
        let damped = self.rate != 0.0;
        let ChainImplicit {
            movable, ending, starting, lower, inv_pivot, still, base, damping, ..
        } = self;
        let (movable, ending, starting): (&[u64], &[f64], &[f64]) = (movable, ending, starting);
        let (lower, inv_pivot, base, damping): (&[f64], &[f64], &[Row], &[f64]) =
            (lower, inv_pivot, base, damping);
        let (x, v, x1, v1) = (&self.x[..], &self.v[..], &mut self.x1[..], &mut self.v1[..]);
        let (z, stage) = (&mut self.z[..], &mut self.stage[..]);
        let n = movable.len();
        // `L z = b` by rows, each `b = h f` made just before: the forces on single particles,
        // then the springs' `-h k d` at the stage (zero where the slot does not move).
        let mut before: Row = [0.0; 4];
        for i in 0..n {
            let (prev, s, next) = (stage[i], stage[i + 1], stage[i + 2]);
            let f = if damped {
                std::array::from_fn(|c| base[i][c] + damping[i] * v[i][c])
            } else {
                base[i]
            };
            let (he, hs, l) = (ending[i], starting[i], lower[i]);
            let b: Row =
                std::array::from_fn(|c| (h * f[c] - he * (s[c] - prev[c])) - hs * (s[c] - next[c]));
            let b = masked(b, movable[i]);
            before = std::array::from_fn(|c| b[c] - l * before[c]);
            z[i] = before;
        }
        // `D Lᵀ Δv = z` by rows from the last, each followed by the new velocity, position
        // and next stage; `nan` stays zero while they are finite (0 · ±inf and 0 · NaN are
        // NaN).
        let (mut after, mut nan): (Row, Row) = ([0.0; 4], [0.0; 4]);
        let mut l_after = 0.0;
        for i in (0..n).rev() {
            let d = inv_pivot[i];
            after = std::array::from_fn(|c| z[i][c] * d - l_after * after[c]);
            l_after = lower[i];
            let vn: Row = std::array::from_fn(|c| v[i][c] + after[c]);
            let xn: Row = std::array::from_fn(|c| x[i][c] + h * vn[c]);
            stage[i + 1] = std::array::from_fn(|c| xn[c] + h * vn[c]);
            let check = masked(std::array::from_fn(|c| xn[c] * 0.0 + vn[c] * 0.0), movable[i]);
            nan = std::array::from_fn(|c| nan[c] + check[c]);
            (x1[i], v1[i]) = (xn, vn);
        }
        if nan.iter().any(|&e| e != 0.0) {
            let bad =
                |i: usize| movable[i] != 0 && !x1[i].iter().chain(&v1[i]).all(|v| v.is_finite());
            return Err(Error::Diverged {
                step: 0,
                index: (0..n).find(|&i| bad(i)).unwrap_or(0),
                reason: "implicit_euler produced a non-finite state".into(),
            });
        }
        std::mem::swap(&mut self.x, &mut self.x1);
        std::mem::swap(&mut self.v, &mut self.v1);
        for &i in still.iter() {
            (self.x[i], self.v[i]) = (self.x1[i], self.v1[i]);
            self.stage[i + 1] = self.x[i];
        }
        Ok(())
    }
}

/// The steps of one call, run through [`crate::batch::vectorize`] (a row in one AVX
/// register where the CPU has them).
struct Steps<'a> {
    work: &'a mut ChainImplicit,
    h: f64,
    steps: usize,
}

impl pulp::WithSimd for Steps<'_> {
    type Output = (usize, Result<()>);

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) -> (usize, Result<()>) {
        for s in 0..self.steps {
            if let Err(e) = self.work.step(self.h) {
                return (s, Err(e));
            }
        }
        (self.steps, Ok(()))
    }
}
