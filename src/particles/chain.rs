//! The explicit methods in structure of arrays for particles joined in chains: models whose
//! forces are gravity, velocity damping and at most one set of springs, each spring joining a
//! slot `a` to the slot `a + 1` with `a` increasing along the list (a rope, several ropes, a
//! chain with gaps), without colliders or emitters. [`super::Solver::step`] takes this path
//! for such models by itself.
//!
//! The state is copied once per call into one array per coordinate (`x, y, z` of the
//! positions, then of the velocities) and written back once. An evaluation of the forces is
//! then one pass over the springs (the force of the spring starting at each slot, zero where
//! none starts) and, with damping, one over the slots; the slopes `[v; M⁻¹ f]` are formed in
//! the pass that combines them into the method's next stage or state, and the springs' forces
//! are read there at `a - 1` and `a` instead of being added where each spring points (no
//! scattered writes). Every loop runs over contiguous arrays and is compiled for AVX2 where
//! the CPU has it ([`crate::batch::vectorize`]; no fused multiply-add is introduced).
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
//! A step writes the next state into a second array and the two are swapped when it is
//! finite, so a failed step leaves the last good state to write back; the error names the
//! step and the first particle (positions before velocities) that went non-finite, as the
//! general path does.

use super::solver::Step;
use super::{Force, Model};
use crate::error::{Error, Result};
use crate::ode::Method;

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
    /// The next state, written by a step and swapped with `y` when it is finite.
    next: Vec<f64>,
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
    /// Each slot's forces on itself (gravity, damping, in the order added) plus its external
    /// force (N), `3 capacity` values: made once per call without damping, at each evaluation
    /// with it.
    base: Vec<f64>,
    /// Whether external forces are set, and they (N) by coordinate (`3 capacity` values).
    any_external: bool,
    external: Vec<f64>,
    /// The force of the spring starting at slot `a` on that slot, at entry `a + 1` of each
    /// coordinate's `capacity + 1` values (N); zero where no spring starts, and at entry 0.
    springs: Vec<f64>,
    /// Whether there is a spring; whether one starts at each slot (as a mask: all bits set,
    /// or none), and its rest length (m).
    any_spring: bool,
    linked: Vec<u64>,
    rest: Vec<f64>,
    /// The springs' stiffness (N/m) and damping (N s/m), and whether every spring is linear
    /// (rest length 0 and no damping: `f = -k d`).
    stiffness: f64,
    damping: f64,
    linear: bool,
    /// Whether the forces on single particles depend on the velocities (damping).
    varying: bool,
    /// Mass (kg) and inverse mass (1/kg) of each slot, and whether it moves (alive and not
    /// pinned; as a mask, all bits set or none).
    mass: Vec<f64>,
    inv_mass: Vec<f64>,
    movable: Vec<u64>,
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

impl Forces {
    /// Evaluate the forces at `at` (laid out as [`ChainWork::y`]): the forces on single
    /// particles when they depend on the velocities, and the springs' forces.
    #[inline(always)]
    fn evaluate(&mut self, list: &[Force], at: &[f64]) {
        if self.varying {
            self.single(list, at);
        }
        if self.any_spring {
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
        let g = [&mut g0[1..n], &mut g1[1..n], &mut g2[1..n]];
        let x = [part(at, n, 0), part(at, n, 1), part(at, n, 2)];
        if self.linear {
            for (g, x) in g.into_iter().zip(x) {
                let (from, to) = (&x[..n - 1], &x[1..]);
                for (((g, &a), &b), &l) in g.iter_mut().zip(from).zip(to).zip(linked) {
                    *g = masked(-k * (a - b), l);
                }
            }
            return;
        }
        let v = [part(at, n, 3), part(at, n, 4), part(at, n, 5)];
        let [g0, g1, g2] = g;
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

    /// The slopes of coordinate `c` (`0..3`) at `at`, after [`Forces::evaluate`] at `at`.
    #[inline(always)]
    fn slopes<'a>(&'a self, at: &'a [f64], c: usize) -> Slopes<'a> {
        let (n, springs) = (self.n, &self.springs[c * (self.n + 1)..][..self.n + 1]);
        Slopes {
            v: part(at, n, 3 + c),
            base: &self.base[c * n..][..n],
            ending: &springs[..n],
            starting: &springs[1..],
            inv_mass: &self.inv_mass[..n],
            movable: &self.movable[..n],
        }
    }
}

/// One coordinate's slopes `(x', v') = (v, f / m)` at a stage, per slot.
struct Slopes<'a> {
    v: &'a [f64],
    base: &'a [f64],
    /// The force of the spring ending at each slot on its first end, and of the one starting.
    ending: &'a [f64],
    starting: &'a [f64],
    inv_mass: &'a [f64],
    movable: &'a [u64],
}

impl Slopes<'_> {
    /// Slot `i`'s slopes: `(v, ((base - ending) + starting) / m)`, or `(0, 0)` when it stays
    /// put (`particles/dynamics.rs`'s accelerations).
    #[inline(always)]
    fn at(&self, i: usize) -> (f64, f64) {
        let f = (self.base[i] - self.ending[i]) + self.starting[i];
        let movable = self.movable[i];
        (masked(self.v[i], movable), masked(f * self.inv_mass[i], movable))
    }
}

/// One pass of a step over every coordinate and slot: the slopes at `at` (after
/// [`Forces::evaluate`] there) and each slot's values in `ins` and `outs` (as `[position,
/// velocity]` of one coordinate) give the new values of `outs` by `f(x', v', ins, outs)`.
/// Returns whether a value written to the first `check` outputs is not finite.
#[inline(always)]
fn combine<const I: usize, const O: usize>(
    forces: &Forces,
    at: &[f64],
    ins: [&[f64]; I],
    mut outs: [&mut [f64]; O],
    check: usize,
    f: impl Fn(f64, f64, [[f64; 2]; I], [[f64; 2]; O]) -> [[f64; 2]; O],
) -> bool {
    let n = forces.n;
    // A count, which vectorises better than a flag.
    let mut bad = 0_u64;
    for c in 0..3 {
        let slopes = forces.slopes(at, c);
        let (ix, iv) = (ins.map(|b| part(b, n, c)), ins.map(|b| part(b, n, 3 + c)));
        let o = outs.each_mut().map(|b| {
            let (xs, vs) = b.split_at_mut(3 * n);
            (&mut xs[c * n..][..n], &mut vs[c * n..][..n])
        });
        for i in 0..n {
            let (kx, kv) = slopes.at(i);
            let old = std::array::from_fn(|j| [o[j].0[i], o[j].1[i]]);
            let new = f(kx, kv, std::array::from_fn(|j| [ix[j][i], iv[j][i]]), old);
            for (j, [x, v]) in new.into_iter().enumerate() {
                (o[j].0[i], o[j].1[i]) = (x, v);
                if j < check {
                    bad += u64::from(!x.is_finite()) + u64::from(!v.is_finite());
                }
            }
        }
    }
    bad > 0
}

impl ChainWork {
    /// Size the buffers for `model` and copy `state`'s values into them.
    fn prepare(&mut self, model: &Model, state: &super::State) {
        let n = model.n;
        for buffer in
            [&mut self.y, &mut self.next, &mut self.sum].into_iter().chain(self.stages.iter_mut())
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
        // Entries 0 and `n` of each coordinate stay zero; the others are written by every
        // evaluation when there are springs.
        forces.springs.resize(3 * (n + 1), 0.0);
        for c in 0..3 {
            (forces.springs[c * (n + 1)], forces.springs[c * (n + 1) + n]) = (0.0, 0.0);
        }
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
        (forces.stiffness, forces.damping, forces.linear) = (0.0, 0.0, true);
        forces.any_spring = false;
        for force in &model.forces {
            if let Force::Springs { pairs, rest, stiffness, damping } = force {
                for (p, &l) in pairs.iter().zip(rest) {
                    (forces.linked[p[0]], forces.rest[p[0]]) = (mask(true), l);
                }
                (forces.stiffness, forces.damping) = (*stiffness, *damping);
                forces.linear = *damping == 0.0 && rest.iter().all(|&l| l == 0.0);
                forces.any_spring = !pairs.is_empty();
            }
        }
        if !forces.any_spring {
            forces.springs.fill(0.0);
        }
        forces.varying = model.forces.iter().any(|f| matches!(f, Force::Damping { .. }));
        if !forces.varying {
            forces.single(&model.forces, &self.y);
        }
    }

    /// One step of `method` with step `h` from `y` into `next`; whether `next` is finite.
    #[inline(always)]
    fn step(&mut self, list: &[Force], method: Method, h: f64) -> bool {
        let ChainWork { y, next, stages: [s0, s1], sum, forces } = self;
        let (y, next, s0, s1, sum) =
            (&y[..], &mut next[..], &mut s0[..], &mut s1[..], &mut sum[..]);
        let half = 0.5 * h;
        forces.evaluate(list, y);
        match method {
            Method::ExplicitEuler => {
                combine(forces, y, [y], [next], 1, |kx, kv, [[x, v]], _| [[x + h * kx, v + h * kv]])
            }
            Method::SymplecticEuler => combine(forces, y, [y], [next], 1, |_, kv, [[x, v]], _| {
                let v1 = v + h * kv;
                [[x + h * v1, v1]]
            }),
            Method::Midpoint => {
                combine(forces, y, [y], [s0], 0, |kx, kv, [[x, v]], _| {
                    [[x + half * kx, v + half * kv]]
                });
                forces.evaluate(list, s0);
                combine(forces, s0, [y], [next], 1, |kx, kv, [[x, v]], _| {
                    [[x + h * kx, v + h * kv]]
                })
            }
            Method::Heun => {
                combine(forces, y, [y], [s0, sum], 0, |kx, kv, [[x, v]], _| {
                    [[x + h * kx, v + h * kv], [kx, kv]]
                });
                forces.evaluate(list, s0);
                combine(forces, s0, [y, sum], [next], 1, |kx, kv, [[x, v], [sx, sv]], _| {
                    [[x + half * (sx + kx), v + half * (sv + kv)]]
                })
            }
            Method::Rk4 => {
                combine(forces, y, [y], [s0, sum], 0, |kx, kv, [[x, v]], _| {
                    [[x + half * kx, v + half * kv], [kx, kv]]
                });
                forces.evaluate(list, s0);
                combine(forces, s0, [y], [s1, sum], 0, |kx, kv, [[x, v]], [_, [sx, sv]]| {
                    [[x + half * kx, v + half * kv], [sx + 2.0 * kx, sv + 2.0 * kv]]
                });
                forces.evaluate(list, s1);
                combine(forces, s1, [y], [s0, sum], 0, |kx, kv, [[x, v]], [_, [sx, sv]]| {
                    [[x + 1.0 * h * kx, v + 1.0 * h * kv], [sx + 2.0 * kx, sv + 2.0 * kv]]
                });
                forces.evaluate(list, s0);
                let sixth = h / 6.0;
                combine(forces, s0, [y, sum], [next], 1, |kx, kv, [[x, v], [sx, sv]], _| {
                    [[x + sixth * (sx + kx), v + sixth * (sv + kv)]]
                })
            }
            Method::VelocityVerlet => {
                // Kick–drift–kick as `ode::Workspace`: the half kick into `next`, the drift's
                // positions into `next` and the stage, and the stage's velocities `v + h a₀`.
                combine(forces, y, [y], [next, s0], 0, |_, kv, [[x, v]], _| {
                    let v_half = v + half * kv;
                    let x1 = x + h * v_half;
                    [[x1, v_half], [x1, v + h * kv]]
                });
                forces.evaluate(list, s0);
                let n = forces.n;
                let (x1, v1) = next.split_at_mut(3 * n);
                for c in 0..3 {
                    let slopes = forces.slopes(s0, c);
                    for (i, v) in v1[c * n..][..n].iter_mut().enumerate() {
                        *v += half * slopes.at(i).1;
                    }
                }
                x1.iter().chain(&*v1).fold(false, |bad, x| bad | !x.is_finite())
            }
            Method::ImplicitEuler | Method::Trapezoidal | Method::Bdf2 => {
                unreachable!("`takes` admits explicit methods only")
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

impl pulp::WithSimd for Run<'_> {
    /// The number of good steps, and whether the step after them failed.
    type Output = (usize, bool);

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) -> (usize, bool) {
        let Run { work, forces, still, method, h, steps } = self;
        let n = work.forces.n;
        for s in 0..steps {
            if work.step(forces, method, h) {
                return (s, true);
            }
            std::mem::swap(&mut work.y, &mut work.next);
            for (i, kept) in still {
                for (j, &value) in kept.iter().enumerate() {
                    work.y[j * n + i] = value;
                }
            }
        }
        (steps, false)
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
