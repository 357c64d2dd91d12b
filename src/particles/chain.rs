//! The explicit methods in structure of arrays for particles joined in chains: models whose
//! forces are gravity, velocity damping and at most one set of springs, each spring joining a
//! slot `a` to the slot `a + 1` with `a` increasing along the list (a rope, several ropes, a
//! chain with gaps), without colliders or emitters. [`super::Solver::step`] takes this path
//! for such models by itself.
//!
//! The state is copied once per call into one array per coordinate (`x, y, z` of the
//! positions, then of the velocities) and written back once. Each stage of a method is then
//! one pass over the slots per coordinate, which forms a slot's slopes `[v; M⁻¹ f]` and at
//! once its values of the method's next stage or state. Linear springs (rest length 0, no
//! damping: `f = -k d`) are evaluated inside that pass, the spring ending at a slot (from
//! `a - 1`) and the one starting at it (to `a + 1`) from the stage's positions at `a - 1`, `a`
//! and `a + 1`, so that an evaluation writes and reads no buffer of forces; the first and the
//! last slot are taken apart from the loop over the others, which then runs without bounds
//! and, on one rope through every slot, without the masks of absent springs. Other springs
//! couple the coordinates through their length and are evaluated first, in a pass of their
//! own over the springs (each spring's force on its first end, `+0` where none starts), which
//! the stage's pass reads at `a - 1` and `a`. Velocity damping makes the forces on single
//! particles a pass of its own per evaluation. Without it, when every slot that moves has the
//! same mass and the same forces on itself (a rope of equal masses under gravity), the passes
//! read that mass and force as constants instead of per slot, and the slots that stay put are
//! taken apart from the loop (the slopes `(0, 0)`) instead of masked in it: two loads and two
//! masks fewer per slot and coordinate, the same operations on the same values otherwise.
//! Every loop runs over contiguous arrays and is
//! compiled for AVX2 where the CPU has it ([`crate::batch::vectorize`]; no fused multiply-add
//! is introduced).
//!
//! Per particle the arithmetic is that of the general path (`particles/dynamics.rs` and the
//! explicit steps of [`crate::ode::Workspace`]) in the same order, so the results are bitwise
//! those of the general path: each particle's force is its forces on itself in the order added,
//! plus the external force, then minus the spring that ends at it, then plus the one that
//! starts at it, which is the order in which the general path's loop over the springs adds
//! them. Where no spring ends or starts, `+0` is subtracted or added instead, which changes no
//! value: a sum that starts at `+0` is never `-0`, and adding `±0` to anything but `-0` gives
//! it back. Pinned and dead slots get the slopes `0` (the general path's `x' = v' = 0`) and
//! their state is put back after each step.
//!
//! A step writes the next state into a second array and the two are swapped. The steps of a
//! call run in blocks of [`BLOCK`] from a copy of the state taken at the block's start, and
//! the state is checked for non-finite values once, at the block's end: a value that goes
//! non-finite stays so at every later step (each new value is the old one plus an increment,
//! and `±∞ + x` and `NaN + x` are not finite), so the block holds a failed step exactly when
//! its last state is not finite. Then the block is taken again from its copy, each step checked
//! before it is swapped in, the same operations giving the same values, up to the step that
//! fails; the last good state is written back and the error names the step and the first
//! particle (positions before velocities) that went non-finite, as the general path does.

use super::solver::Step;
use super::{Force, Model};
use crate::error::{Error, Result};
use crate::ode::Method;

/// Steps a block of a call takes between the checks of its state (see the module docs).
const BLOCK: usize = 16;

/// How an evaluation gets the springs' forces (see the module docs): linear springs joining
/// every slot `a` to `a + 1` (one rope through all slots), linear springs with gaps (or
/// none), or springs of any kind read from [`Forces::springs`].
const ROPE: u8 = 0;
const GAPS: u8 = 1;
const BUFFER: u8 = 2;

/// Whether [`super::Solver::step`] takes this path for `method` on `model` (the caller checks
/// that there are neither colliders nor emitters): an explicit method, and forces that are
/// gravity, velocity damping and at most one set of springs each joining some slot `a` to
/// `a + 1`, with `a` increasing along the list.
pub(super) fn takes(model: &Model, method: Method) -> bool {
    let springs = model.forces.iter().filter(|f| matches!(f, Force::Springs { .. })).count();
    !method.is_implicit()
        && springs <= 1
        && model.forces.iter().all(|f| match f {
            Force::Gravity { .. } | Force::Damping { .. } => true,
            Force::Springs { pairs, .. } => {
                pairs.iter().all(|p| p[1] == p[0] + 1)
                    && pairs.windows(2).all(|w| w[0][0] < w[1][0])
            }
            _ => false,
        })
}

/// The buffers of this path, sized at each call (allocating only when the capacity changes;
/// nothing is allocated in a step). Nothing in them is read by a later call.
#[derive(Clone, Debug, Default)]
pub(super) struct ChainWork {
    /// The state, by coordinate: `6 capacity` values (positions `x, y, z`, then velocities).
    y: Vec<f64>,
    /// The next state, written by a step and swapped with `y`.
    next: Vec<f64>,
    /// The state at the start of the current block of steps, laid out as `y`.
    start: Vec<f64>,
    /// Two stages of the multistage methods, laid out as `y`.
    stages: [Vec<f64>; 2],
    /// Heun's first slope, or RK4's running sum `k₁ + 2 k₂ + 2 k₃`, laid out as `y`.
    sum: Vec<f64>,
    /// The forces, as the evaluations read and write them.
    forces: Forces,
}

/// What an evaluation of the forces reads and writes, per slot and by coordinate.
#[derive(Clone, Debug, Default)]
struct Forces {
    /// Capacity.
    n: usize,
    /// How the springs' forces are found: [`ROPE`], [`GAPS`] or [`BUFFER`].
    kind: u8,
    /// Each slot's forces on itself (gravity, damping, in the order added) plus its external
    /// force (N), `3 capacity` values: made once per call without damping, at each evaluation
    /// with it.
    base: Vec<f64>,
    /// Whether external forces are set, and they (N) by coordinate (`3 capacity` values).
    any_external: bool,
    external: Vec<f64>,
    /// With [`BUFFER`]: the force of the spring starting at slot `a` on that slot, at entry
    /// `a + 1` of each coordinate's `capacity + 1` values (N); zero where no spring starts,
    /// and at entry 0.
    springs: Vec<f64>,
    /// Whether a spring starts at each slot (as a mask: all bits set, or none), and its rest
    /// length (m).
    linked: Vec<u64>,
    rest: Vec<f64>,
    /// The springs' stiffness `k` (N/m), `-k`, and their damping (N s/m).
    stiffness: f64,
    minus_k: f64,
    damping: f64,
    /// Whether the forces on single particles depend on the velocities (damping).
    varying: bool,
    /// Mass (kg) and inverse mass (1/kg) of each slot, and whether it moves (alive and not
    /// pinned; as a mask, all bits set or none).
    mass: Vec<f64>,
    inv_mass: Vec<f64>,
    movable: Vec<u64>,
    /// Whether every slot that moves has the same inverse mass and the same forces on itself
    /// (bit for bit, fixed for the call: no damping), which the passes then read as the
    /// constants `uniform_base` (N, by coordinate) and `uniform_inv_mass` (1/kg) instead of
    /// per slot, with `still` (the slots `0 < i < n - 1` that stay put, in order) taken apart
    /// from the loop instead of masked in it.
    uniform: bool,
    uniform_base: [f64; 3],
    uniform_inv_mass: f64,
    still: Vec<usize>,
}

/// `value` where `mask` has all bits set, `+0` where it has none: a select without a branch.
#[inline(always)]
fn masked(value: f64, mask: u64) -> f64 {
    f64::from_bits(value.to_bits() & mask)
}

/// The mask of [`masked`] that keeps a value when `keep`.
fn mask(keep: bool) -> u64 {
    if keep {
        u64::MAX
    } else {
        0
    }
}

/// Rows of three values (`x, y, z` per slot) into one array per coordinate (`out`: the `x`
/// of every slot, then the `y`, then the `z`).
fn by_coordinate(rows: &[f64], out: &mut [f64]) {
    let n = rows.len() / 3;
    let (xs, rest) = out.split_at_mut(n);
    let (ys, zs) = rest.split_at_mut(n);
    for (((row, x), y), z) in rows.chunks_exact(3).zip(xs).zip(ys).zip(zs) {
        (*x, *y, *z) = (row[0], row[1], row[2]);
    }
}

/// The inverse of [`by_coordinate`].
fn by_row(coordinates: &[f64], rows: &mut [f64]) {
    let n = rows.len() / 3;
    let (xs, rest) = coordinates.split_at(n);
    let (ys, zs) = rest.split_at(n);
    for (((row, x), y), z) in rows.chunks_exact_mut(3).zip(xs).zip(ys).zip(zs) {
        (row[0], row[1], row[2]) = (*x, *y, *z);
    }
}

/// Coordinate `j` (`0..6`: positions `x, y, z`, then velocities) of a buffer laid out as
/// [`ChainWork::y`].
#[inline(always)]
fn part(buffer: &[f64], n: usize, j: usize) -> &[f64] {
    &buffer[j * n..][..n]
}

/// Whether every value of `values` is finite (a count, which vectorises better than a flag).
#[inline(always)]
fn finite(values: &[f64]) -> bool {
    values.iter().fold(0_u64, |bad, x| bad + u64::from(!x.is_finite())) == 0
}

impl Forces {
    /// Set [`Forces::uniform`] and its constants, and [`Forces::still`], after the rest of
    /// the call's set-up. Taken only when few slots stay put (at most one in 8), so that the
    /// runs between them stay long.
    fn find_uniform(&mut self) {
        let n = self.n;
        self.still.clear();
        self.still.extend((1..n.saturating_sub(1)).filter(|&i| self.movable[i] == 0));
        let first = (0..n).find(|&i| self.movable[i] != 0);
        self.uniform = false;
        let (Some(first), false) = (first, self.varying) else { return };
        self.uniform_base = std::array::from_fn(|c| self.base[c * n + first]);
        self.uniform_inv_mass = self.inv_mass[first];
        let bits =
            [self.uniform_inv_mass, self.uniform_base[0], self.uniform_base[1]].map(f64::to_bits);
        let (bits_z, (x, yz)) = (self.uniform_base[2].to_bits(), self.base.split_at(n));
        let (y, z) = yz.split_at(n);
        let slots = self.movable.iter().zip(&self.inv_mass).zip(x).zip(y).zip(z);
        self.uniform = 8 * self.still.len() <= n
            && slots.fold(true, |same, ((((&moves, inv), x), y), z)| {
                let slot = [inv, x, y].map(|v| v.to_bits()) == bits && z.to_bits() == bits_z;
                same & (moves == 0 || slot)
            });
    }

    /// The evaluations that precede a stage's pass at `at` (laid out as [`ChainWork::y`]):
    /// the forces on single particles when they depend on the velocities, and the springs'
    /// forces when they are read from [`Forces::springs`].
    #[inline(always)]
    fn evaluate<const K: u8>(&mut self, list: &[Force], at: &[f64]) {
        if self.varying {
            self.single(list, at);
        }
        if K == BUFFER {
            self.springs(at);
        }
    }

    /// [`Forces::base`] at the velocities of `at`: for each slot `0`, plus each force on it
    /// alone in the order added ([`super::particle_force`]'s sum), plus its external force.
    #[inline(always)]
    fn single(&mut self, list: &[Force], at: &[f64]) {
        let n = self.n;
        for c in 0..3 {
            let (base, mass) = (&mut self.base[c * n..][..n], &self.mass[..n]);
            let (v, external) = (part(at, n, 3 + c), &self.external[c * n..][..n]);
            base.fill(0.0);
            for force in list {
                match *force {
                    Force::Gravity { g } => {
                        let g = g[c];
                        // `super::gravity`: `m g`.
                        for (b, m) in base.iter_mut().zip(mass) {
                            *b += m * g;
                        }
                    }
                    Force::Damping { rate } => {
                        // `super::damping`: `-rate m v`.
                        for ((b, m), v) in base.iter_mut().zip(mass).zip(v) {
                            *b += -rate * m * v;
                        }
                    }
                    _ => {}
                }
            }
            // Without external forces, `+ 0` is left out: the sum is never `-0`, so it changes
            // nothing.
            if self.any_external {
                for (b, e) in base.iter_mut().zip(external) {
                    *b += e;
                }
            }
        }
    }

    /// [`Forces::springs`] at the state `at`: the spring from `a` to `a + 1` pulls `a` with
    /// `-k d` when linear, else `-(k (|d| - L) + c (v_a - v_b)·d̂) d̂`, `d = x_a - x_(a+1)`
    /// (none at zero length), as `particles/dynamics.rs` computes it.
    #[inline(always)]
    fn springs(&mut self, at: &[f64]) {
        let n = self.n;
        if n < 2 {
            return;
        }
        let (linked, rest) = (&self.linked[..n - 1], &self.rest[..n - 1]);
        let (k, damping) = (self.stiffness, self.damping);
        let (g0, rest_g) = self.springs.split_at_mut(n + 1);
        let (g1, g2) = rest_g.split_at_mut(n + 1);
        let [g0, g1, g2] = [&mut g0[1..n], &mut g1[1..n], &mut g2[1..n]];
        let x = [part(at, n, 0), part(at, n, 1), part(at, n, 2)];
        let v = [part(at, n, 3), part(at, n, 4), part(at, n, 5)];
        for i in 0..n - 1 {
            let d = [x[0][i] - x[0][i + 1], x[1][i] - x[1][i + 1], x[2][i] - x[2][i + 1]];
            let dv = [v[0][i] - v[0][i + 1], v[1][i] - v[1][i + 1], v[2][i] - v[2][i + 1]];
            let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let dir = [d[0] / len, d[1] / len, d[2] / len];
            let relative = dv[0] * dir[0] + dv[1] * dir[1] + dv[2] * dir[2];
            let s = -(k * (len - rest[i]) + damping * relative);
            let linear = rest[i] == 0.0 && damping == 0.0;
            let f = if linear {
                [-k * d[0], -k * d[1], -k * d[2]]
            } else {
                [s * dir[0], s * dir[1], s * dir[2]]
            };
            let keep = if linear || len != 0.0 { linked[i] } else { 0 };
            (g0[i], g1[i], g2[i]) = (masked(f[0], keep), masked(f[1], keep), masked(f[2], keep));
        }
    }
}

/// One coordinate's slopes `(x', v') = (v, f / m)` at a stage, per slot.
struct Slopes<'a> {
    /// The stage's positions and velocities.
    x: &'a [f64],
    v: &'a [f64],
    base: &'a [f64],
    /// With [`BUFFER`], each spring's force on its first end at entry `a + 1`.
    springs: &'a [f64],
    linked: &'a [u64],
    minus_k: f64,
    inv_mass: &'a [f64],
    movable: &'a [u64],
    /// [`Forces::uniform_base`] of this coordinate and [`Forces::uniform_inv_mass`].
    uniform_base: f64,
    uniform_inv_mass: f64,
}

impl Slopes<'_> {
    /// The slopes of coordinate `c` at `at`, after [`Forces::evaluate`] at `at`.
    #[inline(always)]
    fn of<'a>(forces: &'a Forces, at: &'a [f64], c: usize) -> Slopes<'a> {
        let n = forces.n;
        let springs =
            if forces.kind == BUFFER { &forces.springs[c * (n + 1)..][..n + 1] } else { &[] };
        Slopes {
            x: part(at, n, c),
            v: part(at, n, 3 + c),
            base: &forces.base[c * n..][..n],
            springs,
            linked: &forces.linked[..n],
            minus_k: forces.minus_k,
            inv_mass: &forces.inv_mass[..n],
            movable: &forces.movable[..n],
            uniform_base: forces.uniform_base[c],
            uniform_inv_mass: forces.uniform_inv_mass,
        }
    }

    /// Slot `i`'s slopes with the force `ending` of the spring that ends at it on its first
    /// end and `starting` of the one that starts at it: `(v, ((base - ending) + starting) /
    /// m)`, or `(0, 0)` when it stays put (`particles/dynamics.rs`'s accelerations). With `U`
    /// ([`Forces::uniform`]) the slot is one that moves and its base force and inverse mass
    /// are the constants.
    #[inline(always)]
    fn with<const U: bool>(&self, i: usize, ending: f64, starting: f64) -> (f64, f64) {
        if U {
            let f = (self.uniform_base - ending) + starting;
            return (self.v[i], f * self.uniform_inv_mass);
        }
        let f = (self.base[i] - ending) + starting;
        let movable = self.movable[i];
        (masked(self.v[i], movable), masked(f * self.inv_mass[i], movable))
    }

    /// Slot `i`'s slopes, for any slot.
    #[inline(always)]
    fn at<const K: u8>(&self, i: usize) -> (f64, f64) {
        let n = self.x.len();
        if K == BUFFER {
            return self.with::<false>(i, self.springs[i], self.springs[i + 1]);
        }
        let spring = |a: usize| masked(self.minus_k * (self.x[a] - self.x[a + 1]), self.linked[a]);
        let ending = if i > 0 { spring(i - 1) } else { 0.0 };
        let starting = if i + 1 < n { spring(i) } else { 0.0 };
        self.with::<false>(i, ending, starting)
    }

    /// Slot `i`'s slopes for `0 < i < n - 1`, the springs computed without branches (and
    /// with [`ROPE`] without masks: every spring is there); with `U`, of a slot that moves.
    #[inline(always)]
    fn inner<const K: u8, const U: bool>(&self, i: usize) -> (f64, f64) {
        let (x, k) = (self.x, self.minus_k);
        match K {
            BUFFER => self.with::<U>(i, self.springs[i], self.springs[i + 1]),
            ROPE => self.with::<U>(i, k * (x[i - 1] - x[i]), k * (x[i] - x[i + 1])),
            _ => {
                let ending = masked(k * (x[i - 1] - x[i]), self.linked[i - 1]);
                self.with::<U>(i, ending, masked(k * (x[i] - x[i + 1]), self.linked[i]))
            }
        }
    }
}

/// Slot `i`'s new values of `outs` (`o`, one coordinate) from its slopes `(kx, kv)` and its
/// values in `ins` (`ix`, `iv`) and `outs` by `f` (see [`combine`]); always inlined, so that
/// the loop over the slots vectorises.
#[inline(always)]
fn slot<const I: usize, const O: usize>(
    i: usize,
    (kx, kv): (f64, f64),
    ix: &[&[f64]; I],
    iv: &[&[f64]; I],
    o: &mut [(&mut [f64], &mut [f64]); O],
    f: &impl Fn(f64, f64, [[f64; 2]; I], [[f64; 2]; O]) -> [[f64; 2]; O],
) {
    let old = std::array::from_fn(|j| [o[j].0[i], o[j].1[i]]);
    let new = f(kx, kv, std::array::from_fn(|j| [ix[j][i], iv[j][i]]), old);
    for (j, [x, v]) in new.into_iter().enumerate() {
        (o[j].0[i], o[j].1[i]) = (x, v);
    }
}

/// One pass of a step over every coordinate and slot: the slopes at `at` (after
/// [`Forces::evaluate`] there) and each slot's values in `ins` and `outs` (as `[position,
/// velocity]` of one coordinate) give the new values of `outs` by `f(x', v', ins, outs)`.
#[inline(always)]
fn combine<const K: u8, const U: bool, const I: usize, const O: usize>(
    forces: &Forces,
    at: &[f64],
    ins: [&[f64]; I],
    mut outs: [&mut [f64]; O],
    f: impl Fn(f64, f64, [[f64; 2]; I], [[f64; 2]; O]) -> [[f64; 2]; O],
) {
    let n = forces.n;
    for c in 0..3 {
        let slopes = Slopes::of(forces, at, c);
        let (ix, iv) = (ins.map(|b| part(b, n, c)), ins.map(|b| part(b, n, 3 + c)));
        let mut o = outs.each_mut().map(|b| {
            let (xs, vs) = b.split_at_mut(3 * n);
            (&mut xs[c * n..][..n], &mut vs[c * n..][..n])
        });
        if n == 0 {
            continue;
        }
        slot(0, slopes.at::<K>(0), &ix, &iv, &mut o, &f);
        if n > 1 {
            slot(n - 1, slopes.at::<K>(n - 1), &ix, &iv, &mut o, &f);
        }
        if !U {
            for i in 1..n.saturating_sub(1) {
                slot(i, slopes.inner::<K, false>(i), &ix, &iv, &mut o, &f);
            }
            continue;
        }
        // The slots that stay put get the slopes `(0, 0)`, the runs between them the loop
        // without per-slot masses, forces or masks.
        let mut from = 1;
        for &still in &forces.still {
            for i in from..still {
                slot(i, slopes.inner::<K, true>(i), &ix, &iv, &mut o, &f);
            }
            slot(still, (0.0, 0.0), &ix, &iv, &mut o, &f);
            from = still + 1;
        }
        for i in from..n.saturating_sub(1) {
            slot(i, slopes.inner::<K, true>(i), &ix, &iv, &mut o, &f);
        }
    }
}

impl ChainWork {
    /// Size the buffers for `model` and copy `state`'s values into them.
    fn prepare(&mut self, model: &Model, state: &super::State) {
        let n = model.n;
        for buffer in [&mut self.y, &mut self.next, &mut self.start, &mut self.sum]
            .into_iter()
            .chain(self.stages.iter_mut())
        {
            buffer.resize(6 * n, 0.0);
        }
        let ((x, v), (to_x, to_v)) = (state.y.split_at(3 * n), self.y.split_at_mut(3 * n));
        by_coordinate(x, to_x);
        by_coordinate(v, to_v);
        let forces = &mut self.forces;
        forces.n = n;
        forces.base.resize(3 * n, 0.0);
        forces.external.resize(3 * n, 0.0);
        forces.linked.clear();
        forces.linked.resize(n, 0);
        forces.rest.resize(n, 0.0);
        forces.mass.clone_from(&state.mass);
        forces.inv_mass.clone_from(&state.inv_mass);
        forces.movable.clear();
        forces
            .movable
            .extend(state.alive.iter().zip(&state.inv_mass).map(|(&a, &inv)| mask(a && inv > 0.0)));
        forces.any_external = !state.external.is_empty();
        if forces.any_external {
            by_coordinate(&state.external, &mut forces.external);
        }
        (forces.stiffness, forces.damping, forces.kind) = (0.0, 0.0, GAPS);
        for force in &model.forces {
            if let Force::Springs { pairs, rest, stiffness, damping } = force {
                for (p, &l) in pairs.iter().zip(rest) {
                    (forces.linked[p[0]], forces.rest[p[0]]) = (mask(true), l);
                }
                (forces.stiffness, forces.damping) = (*stiffness, *damping);
                let linear = *damping == 0.0 && rest.iter().all(|&l| l == 0.0);
                forces.kind = match linear {
                    false => BUFFER,
                    true if pairs.len() + 1 == n => ROPE,
                    true => GAPS,
                };
            }
        }
        forces.minus_k = -forces.stiffness;
        if forces.kind == BUFFER {
            // Entries 0 and `n` of each coordinate stay zero; the others are written by every
            // evaluation.
            forces.springs.resize(3 * (n + 1), 0.0);
            for c in 0..3 {
                (forces.springs[c * (n + 1)], forces.springs[c * (n + 1) + n]) = (0.0, 0.0);
            }
        }
        forces.varying = model.forces.iter().any(|f| matches!(f, Force::Damping { .. }));
        if !forces.varying {
            forces.single(&model.forces, &self.y);
        }
        forces.find_uniform();
    }

    /// One step of `method` with step `h` from `y` into `next`.
    #[inline(always)]
    fn step<const K: u8, const U: bool>(&mut self, list: &[Force], method: Method, h: f64) {
        let ChainWork { y, next, stages: [s0, s1], sum, forces, .. } = self;
        let (y, next, s0, s1, sum) =
            (&y[..], &mut next[..], &mut s0[..], &mut s1[..], &mut sum[..]);
        let half = 0.5 * h;
        forces.evaluate::<K>(list, y);
        match method {
            Method::ExplicitEuler => {
                combine::<K, U, 1, 1>(forces, y, [y], [next], |kx, kv, [[x, v]], _| {
                    [[x + h * kx, v + h * kv]]
                })
            }
            Method::SymplecticEuler => {
                combine::<K, U, 1, 1>(forces, y, [y], [next], |_, kv, [[x, v]], _| {
                    let v1 = v + h * kv;
                    [[x + h * v1, v1]]
                })
            }
            Method::Midpoint => {
                combine::<K, U, 1, 1>(forces, y, [y], [s0], |kx, kv, [[x, v]], _| {
                    [[x + half * kx, v + half * kv]]
                });
                forces.evaluate::<K>(list, s0);
                combine::<K, U, 1, 1>(forces, s0, [y], [next], |kx, kv, [[x, v]], _| {
                    [[x + h * kx, v + h * kv]]
                });
            }
            Method::Heun => {
                combine::<K, U, 1, 2>(forces, y, [y], [s0, sum], |kx, kv, [[x, v]], _| {
                    [[x + h * kx, v + h * kv], [kx, kv]]
                });
                forces.evaluate::<K>(list, s0);
                combine::<K, U, 2, 1>(
                    forces,
                    s0,
                    [y, sum],
                    [next],
                    |kx, kv, [[x, v], [sx, sv]], _| [[x + half * (sx + kx), v + half * (sv + kv)]],
                );
            }
            Method::Rk4 => {
                combine::<K, U, 1, 2>(forces, y, [y], [s0, sum], |kx, kv, [[x, v]], _| {
                    [[x + half * kx, v + half * kv], [kx, kv]]
                });
                forces.evaluate::<K>(list, s0);
                combine::<K, U, 1, 2>(
                    forces,
                    s0,
                    [y],
                    [s1, sum],
                    |kx, kv, [[x, v]], [_, [sx, sv]]| {
                        [[x + half * kx, v + half * kv], [sx + 2.0 * kx, sv + 2.0 * kv]]
                    },
                );
                forces.evaluate::<K>(list, s1);
                combine::<K, U, 1, 2>(
                    forces,
                    s1,
                    [y],
                    [s0, sum],
                    |kx, kv, [[x, v]], [_, [sx, sv]]| {
                        [[x + 1.0 * h * kx, v + 1.0 * h * kv], [sx + 2.0 * kx, sv + 2.0 * kv]]
                    },
                );
                forces.evaluate::<K>(list, s0);
                let sixth = h / 6.0;
                combine::<K, U, 2, 1>(
                    forces,
                    s0,
                    [y, sum],
                    [next],
                    |kx, kv, [[x, v], [sx, sv]], _| {
                        [[x + sixth * (sx + kx), v + sixth * (sv + kv)]]
                    },
                );
            }
            Method::VelocityVerlet => {
                // Kick–drift–kick as `ode::Workspace`: the half kick into `next`, the drift's
                // positions into `next` and the stage, and the stage's velocities `v + h a₀`;
                // then the second half kick at the stage.
                combine::<K, U, 1, 2>(forces, y, [y], [next, s0], |_, kv, [[x, v]], _| {
                    let v_half = v + half * kv;
                    let x1 = x + h * v_half;
                    [[x1, v_half], [x1, v + h * kv]]
                });
                forces.evaluate::<K>(list, s0);
                combine::<K, U, 0, 1>(forces, s0, [], [next], |_, kv, [], [[x, v]]| {
                    [[x, v + half * kv]]
                });
            }
            Method::ImplicitEuler | Method::Trapezoidal | Method::Bdf2 => {
                unreachable!("`takes` admits explicit methods only")
            }
        }
    }

    /// Take a step (see [`Self::step`]) and make its state the current one, with the slots
    /// that stay put as they were.
    #[inline(always)]
    fn advance<const K: u8, const U: bool>(
        &mut self,
        list: &[Force],
        still: &[(usize, [f64; 6])],
        method: Method,
        h: f64,
    ) {
        self.step::<K, U>(list, method, h);
        self.swap(still);
    }

    /// Make the state `next` the current one, with the slots that stay put as they were.
    #[inline(always)]
    fn swap(&mut self, still: &[(usize, [f64; 6])]) {
        let n = self.forces.n;
        std::mem::swap(&mut self.y, &mut self.next);
        for (i, kept) in still {
            for (j, &value) in kept.iter().enumerate() {
                self.y[j * n + i] = value;
            }
        }
    }

    /// The first slot with a non-finite position in `next`, else the first with a non-finite
    /// velocity (the general path's order: positions before velocities).
    fn first_bad(&self) -> usize {
        let n = self.forces.n;
        let bad =
            |j: usize, i: usize| !(0..3).all(|c| part(&self.next, n, 3 * j + c)[i].is_finite());
        (0..n).find(|&i| bad(0, i)).or_else(|| (0..n).find(|&i| bad(1, i))).unwrap_or(0)
    }

    /// Write the state `y` back into `state` (interleaved, positions then velocities).
    fn write_back(&self, state: &mut [f64]) {
        let n = self.forces.n;
        let ((x, v), (from_x, from_v)) = (state.split_at_mut(3 * n), self.y.split_at(3 * n));
        by_row(from_x, x);
        by_row(from_v, v);
    }
}

/// The steps of one call, run through [`crate::batch::vectorize`].
struct Run<'a> {
    work: &'a mut ChainWork,
    forces: &'a [Force],
    /// The slots that stay put, with their positions and velocities.
    still: &'a [(usize, [f64; 6])],
    method: Method,
    h: f64,
    steps: usize,
}

impl Run<'_> {
    /// The steps in blocks (see the module docs): the number of good steps, and whether the
    /// step after them failed.
    #[inline(always)]
    fn blocks<const K: u8, const U: bool>(self) -> (usize, bool) {
        let Run { work, forces, still, method, h, steps } = self;
        let mut done = 0;
        while done < steps {
            let block = (steps - done).min(BLOCK);
            if block > 1 {
                work.start.copy_from_slice(&work.y);
                for _ in 0..block {
                    work.advance::<K, U>(forces, still, method, h);
                }
                if finite(&work.y) {
                    done += block;
                    continue;
                }
                work.y.copy_from_slice(&work.start);
            }
            // Each step checked before it is taken in.
            for _ in 0..block {
                work.step::<K, U>(forces, method, h);
                if !finite(&work.next) {
                    return (done, true);
                }
                work.swap(still);
                done += 1;
            }
        }
        (steps, false)
    }
}

impl pulp::WithSimd for Run<'_> {
    /// The number of good steps, and whether the step after them failed.
    type Output = (usize, bool);

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) -> (usize, bool) {
        match (self.work.forces.kind, self.work.forces.uniform) {
            (ROPE, true) => self.blocks::<ROPE, true>(),
            (ROPE, false) => self.blocks::<ROPE, false>(),
            (GAPS, true) => self.blocks::<GAPS, true>(),
            (GAPS, false) => self.blocks::<GAPS, false>(),
            (_, true) => self.blocks::<BUFFER, true>(),
            (_, false) => self.blocks::<BUFFER, false>(),
        }
    }
}

impl Step<'_> {
    /// `steps` steps of an explicit method on a model this path [`takes`], without colliders
    /// or emitters, after `general_steps` has settled the ages and listed the slots that stay
    /// put. On a non-finite step the state is left at the last good step and the error names
    /// the step and the particle, as on the general path.
    pub(super) fn chain_steps(&mut self, dt: f64, steps: usize) -> Result<()> {
        let (model, state, solver) = (self.model, &mut *self.state, &mut *self.solver);
        let method = state.history.as_ref().expect("history created in step").method();
        solver.chain.prepare(model, state);
        let run = Run {
            work: &mut solver.chain,
            forces: &model.forces,
            still: &solver.still,
            method,
            h: dt,
            steps,
        };
        let (good, failed) = crate::batch::vectorize(run);
        let evaluations = match method {
            Method::ExplicitEuler | Method::SymplecticEuler => 1,
            Method::Rk4 => 4,
            _ => 2,
        };
        let history = state.history.as_mut().expect("history created in step");
        history.nfev += evaluations * (good + usize::from(failed));
        for _ in 0..good {
            state.time += dt;
        }
        solver.chain.write_back(&mut state.y);
        state.age_pending = (dt, good);
        if failed {
            state.state_changed();
            return Err(Error::Diverged {
                step: good,
                index: solver.chain.first_bad(),
                reason: "non-finite particle state".into(),
            });
        }
        Ok(())
    }
}
