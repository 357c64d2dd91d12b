//! The explicit step kernel: symplectic Euler with the collision response in one pass over
//! the state, for systems without forces between particles (the common emitter case).
//!
//! The particles are taken in blocks of [`BLOCK`]. A block is copied into a structure of arrays
//! on the stack (positions, velocities, forces, masses: small enough for the L1 cache; with
//! AVX shuffles where the CPU has them, [`Transpose`], and the state of the blocks a few
//! blocks ahead prefetched); each force is then one loop over the block (forces outer,
//! particles inner: no dispatch per particle, and the simple forces vectorise; gravity shares
//! its loop with the force after it), the block is
//! integrated, the colliders are met in turn (a plane first finds its penetrating particles
//! with one vectorised loop) and the block is written back (the caller ages the particles
//! after each step when the system has emitters, otherwise once per call). When
//! every slot is alive with one mass ([`Model::uniform`]), masses and alive flags are not
//! read per particle. Per particle the arithmetic is that of [`super::particle_force`], of
//! the symplectic Euler of [`crate::ode`] and of [`super::collide::collide_one`], in the same order, so
//! the results are bitwise those of the general path whatever the blocks and the threads (a
//! test holds both to it). Each parallel task runs through [`pulp::Arch::dispatch`], which
//! compiles it for AVX2 and AVX-512 too and picks a build at run time as the CPU has them
//! (safe code; no fused multiply-add is introduced, so the results do not depend on the
//! instruction set either).
//!
//! Without emitters nothing happens between the steps of a call of
//! [`super::ParticleSystem::step`] but the steps, and the particles do not interact, so
//! [`commit`] takes each block through all the steps of the call while it is in the cache: the
//! state is read and written once per call instead of once per step. With emitters it is
//! called once per step.
//!
//! A call either completes or leaves the state at its last good step, and each step is
//! computed once: [`commit`] writes every block and reports the first step, and the first
//! particle in it, that came out non-finite. Its first step also copies the state it reads
//! (one write of the state per call, not a computation); when a step fails, the caller
//! restores that copy and takes the good steps again, which gives bitwise the state they had
//! written since a step depends on nothing but the state and the model.

use super::collide::{respond, surface, Collider};
use super::Force;
use crate::geometry::{Plane, Shape};
use glam::DVec3;
use rayon::prelude::*;

/// Particles per block: the block's arrays take 4 KB. (Blocks of 256, 34 KB, execute as many
/// instructions but took 45 % more time, likely from 4 KB aliasing between arrays 2 KB apart.)
pub(super) const BLOCK: usize = 32;

/// Blocks ahead whose state is prefetched (4 took 4–6 % less time per step than none at
/// 10^6 particles; 12 no less than 4).
const PREFETCH: usize = 4;

/// Particles per parallel task.
const TASK: usize = 128 * BLOCK;

/// What a step reads besides the state.
pub(super) struct Model<'a> {
    pub(super) forces: &'a [Force],
    pub(super) colliders: &'a [Collider],
    pub(super) mass: &'a [f64],
    pub(super) inv_mass: &'a [f64],
    /// Forces set from outside (`3 capacity` values), or empty.
    pub(super) external: &'a [f64],
    /// Time step (s).
    pub(super) dt: f64,
    /// The sum of the uniform gravity fields (m/s²), for resting contacts.
    pub(super) gravity: DVec3,
    /// `(mass, inverse mass)` when every slot is alive and moves with this same mass (and
    /// nothing emits or retires during the call): then `mass`, `inv_mass` and the alive flags
    /// are not read per particle.
    pub(super) uniform: Option<(f64, f64)>,
}

/// Three coordinates of every particle of a block, one array per axis.
type Vectors = [[f64; BLOCK]; 3];

/// The transposes between a block's interleaved vectors (`x, y, z` per particle, as the
/// state stores them) and its arrays per axis: with AVX shuffles where the CPU has them
/// (four particles, three registers, six shuffles each way), else one value at a time.
/// Either way the values are moved, not computed.
#[derive(Clone, Copy)]
struct Transpose {
    #[cfg(target_arch = "x86_64")]
    avx: Option<pulp::x86::V3>,
}

impl Transpose {
    fn new() -> Self {
        Transpose {
            #[cfg(target_arch = "x86_64")]
            avx: pulp::x86::V3::try_new(),
        }
    }

    /// The vectors of a whole block, `x, y, z` per particle, as one array per axis.
    #[inline(always)]
    fn split(self, xyz: &[f64; 3 * BLOCK], to: &mut Vectors) {
        #[cfg(target_arch = "x86_64")]
        if let Some(simd) = self.avx {
            use pulp::bytemuck::cast;
            use std::arch::x86_64::__m256d;
            let avx = simd.avx;
            let [tx, ty, tz] = to;
            let groups = xyz.as_chunks::<12>().0;
            let outs = tx.as_chunks_mut::<4>().0.iter_mut();
            let outs = outs.zip(ty.as_chunks_mut::<4>().0).zip(tz.as_chunks_mut::<4>().0);
            for (g, ((tx, ty), tz)) in groups.iter().zip(outs) {
                let [a, b, c]: [[f64; 4]; 3] = cast(*g);
                let [a, b, c]: [__m256d; 3] = [cast(a), cast(b), cast(c)];
                // a = x0 y0 z0 x1, b = y1 z1 x2 y2, c = z2 x3 y3 z3
                let xy = avx._mm256_blend_pd::<0b1100>(a, b); // x0 y0 x2 y2
                let zx = avx._mm256_permute2f128_pd::<0x21>(a, c); // z0 x1 z2 x3
                let yz = avx._mm256_blend_pd::<0b1100>(b, c); // y1 z1 y3 z3
                *tx = cast(avx._mm256_shuffle_pd::<0b1010>(xy, zx));
                *ty = cast(avx._mm256_shuffle_pd::<0b0101>(xy, yz));
                *tz = cast(avx._mm256_shuffle_pd::<0b1010>(zx, yz));
            }
            return;
        }
        for k in 0..BLOCK {
            for c in 0..3 {
                to[c][k] = xyz[3 * k + c];
            }
        }
    }

    /// Ask for the `3 BLOCK` values from `at` on to be brought into the cache (a hint: `at`
    /// may point anywhere, it is not dereferenced).
    #[inline(always)]
    fn prefetch(self, at: *const f64) {
        #[cfg(target_arch = "x86_64")]
        if let Some(simd) = self.avx {
            for line in 0..3 * BLOCK / 8 {
                simd.sse._mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(
                    at.wrapping_add(8 * line).cast(),
                );
            }
        }
    }

    /// The inverse of [`Transpose::split`].
    #[inline(always)]
    fn interleave(self, from: &Vectors, xyz: &mut [f64; 3 * BLOCK]) {
        #[cfg(target_arch = "x86_64")]
        if let Some(simd) = self.avx {
            use pulp::bytemuck::cast;
            use std::arch::x86_64::__m256d;
            let avx = simd.avx;
            let [fx, fy, fz] = from;
            let ins = fx.as_chunks::<4>().0.iter();
            let ins = ins.zip(fy.as_chunks::<4>().0).zip(fz.as_chunks::<4>().0);
            for (g, ((x, y), z)) in xyz.as_chunks_mut::<12>().0.iter_mut().zip(ins) {
                let [x, y, z]: [__m256d; 3] = [cast(*x), cast(*y), cast(*z)];
                let xy = avx._mm256_unpacklo_pd(x, y); // x0 y0 x2 y2
                let zx = avx._mm256_shuffle_pd::<0b1010>(z, x); // z0 x1 z2 x3
                let yz = avx._mm256_unpackhi_pd(y, z); // y1 z1 y3 z3
                let a = avx._mm256_permute2f128_pd::<0x20>(xy, zx); // x0 y0 z0 x1
                let b = avx._mm256_blend_pd::<0b0011>(xy, yz); // y1 z1 x2 y2
                let c = avx._mm256_permute2f128_pd::<0x31>(zx, yz); // z2 x3 y3 z3
                let [a, b, c]: [[f64; 4]; 3] = [cast(a), cast(b), cast(c)];
                *g = cast([a, b, c]);
            }
            return;
        }
        for k in 0..BLOCK {
            for c in 0..3 {
                xyz[3 * k + c] = from[c][k];
            }
        }
    }
}

/// Something to do with the per-particle function of a force ([`with_force`]).
trait WithForce {
    fn call(self, force: impl Fn(DVec3, DVec3, f64) -> DVec3);
}

/// Call `then` with the force on one particle, `(x, v, m) -> f`, of `force` (zero for the
/// forces between particles, which take another path).
#[inline(always)]
fn with_force(force: &Force, then: impl WithForce) {
    match *force {
        Force::Gravity { g } => then.call(|_, _, m| super::gravity(g, m)),
        Force::Drag { linear, quadratic, wind } => {
            then.call(|_, v, _| super::drag(linear, quadratic, wind, v))
        }
        Force::Damping { rate } => then.call(|_, v, m| super::damping(rate, m, v)),
        Force::Attractor { center, strength, softening } => {
            then.call(|x, _, m| super::attractor(center, strength, softening, x, m))
        }
        Force::Vortex { center, axis, strength, core } => {
            then.call(|x, _, m| super::vortex(center, axis, strength, core, x, m))
        }
        Force::Turbulence { strength, scale, seed } => {
            then.call(|x, _, m| super::turbulence(strength, scale, seed, x, m))
        }
        Force::Springs { .. } | Force::NeighborRepulsion { .. } | Force::NBodyGravity { .. } => {
            then.call(|_, _, _| DVec3::ZERO)
        }
    }
}

/// Add a force to a block's accumulator ([`Block::add`]).
struct Add<'a> {
    block: &'a mut Block,
    from: usize,
    /// Whether it is the first force (the accumulator starts from zero).
    first: bool,
    /// Uniform gravity (m/s²) to add before it in the same loop, if any.
    gravity: Option<DVec3>,
}

impl WithForce for Add<'_> {
    #[inline(always)]
    fn call(self, force: impl Fn(DVec3, DVec3, f64) -> DVec3) {
        let Add { block, from, first, gravity } = self;
        if first {
            block.add::<true>(from, gravity, force);
        } else {
            block.add::<false>(from, gravity, force);
        }
    }
}

/// One block of particles as a structure of arrays.
struct Block {
    /// Index of the block's first particle.
    start: usize,
    /// Particles in the block (the slots past it are not live).
    len: usize,
    /// Positions (m): a step goes from one of the two to the other.
    x: [Vectors; 2],
    /// Velocities (m/s), updated in place.
    v: Vectors,
    /// Force accumulator (N).
    f: Vectors,
    /// Masses (kg).
    m: [f64; BLOCK],
    /// Inverse masses (1/kg).
    inv_m: [f64; BLOCK],
    /// Whether the slot moves: alive and not pinned.
    live: [bool; BLOCK],
    /// Signed distance to the plane being met (m).
    d: [f64; BLOCK],
    transpose: Transpose,
}

impl Block {
    fn new(model: &Model) -> Self {
        let z = [0.0; BLOCK];
        let (m, inv_m) = model.uniform.unwrap_or((0.0, 0.0));
        Block {
            start: 0,
            len: 0,
            x: [[z; 3]; 2],
            v: [z; 3],
            f: [z; 3],
            m: [m; BLOCK],
            inv_m: [inv_m; BLOCK],
            live: [model.uniform.is_some(); BLOCK],
            d: z,
            transpose: Transpose::new(),
        }
    }

    /// Copy in the particles from `start` on, whose positions and velocities are `xs` and `vs`
    /// (`3 len` values each, `len <= BLOCK`, positions into `x[0]`) and whose alive flags are
    /// `alive`.
    #[inline(always)]
    fn load(&mut self, model: &Model, start: usize, xs: &[f64], vs: &[f64], alive: &[bool]) {
        let len = xs.len() / 3;
        (self.start, self.len) = (start, len);
        let [x, ..] = &mut self.x;
        if let (Ok(xs), Ok(vs)) = (xs.try_into(), vs.try_into()) {
            self.transpose.split(xs, x);
            self.transpose.split(vs, &mut self.v);
        } else {
            for (k, (p, u)) in xs.chunks_exact(3).zip(vs.chunks_exact(3)).enumerate() {
                for c in 0..3 {
                    x[c][k] = p[c];
                    self.v[c][k] = u[c];
                }
            }
        }
        if model.uniform.is_some() {
            // Masses and flags were set by `Block::new`; only the last block may be short.
            self.live[len..].fill(false);
            return;
        }
        let slots = start..start + len;
        self.m[..len].copy_from_slice(&model.mass[slots.clone()]);
        self.inv_m[..len].copy_from_slice(&model.inv_mass[slots.clone()]);
        for ((live, &alive), &inv_m) in self.live.iter_mut().zip(alive).zip(&model.inv_mass[slots])
        {
            *live = alive & (inv_m != 0.0);
        }
        self.live[len..].fill(false);
    }

    /// Copy the positions `x[at]` out to `xs` and the velocities to `vs`.
    #[inline(always)]
    fn store(&self, at: usize, xs: &mut [f64], vs: &mut [f64]) {
        let x = &self.x[at];
        if let (Ok(xs), Ok(vs)) = (xs.try_into(), vs.try_into()) {
            self.transpose.interleave(x, xs);
            self.transpose.interleave(&self.v, vs);
        } else {
            for (k, (p, u)) in xs.chunks_exact_mut(3).zip(vs.chunks_exact_mut(3)).enumerate() {
                for c in 0..3 {
                    p[c] = x[c][k];
                    u[c] = self.v[c][k];
                }
            }
        }
    }

    /// Add `force(x, v, m)` of every slot, at positions `x[from]`, to the force accumulator,
    /// or set the accumulator to it (`0 + force`, as a sum from zero) when `FIRST`; with
    /// `gravity`, set the accumulator to `(0 + m gravity) + force` instead (gravity added
    /// first, then `force`, in one loop).
    #[inline(always)]
    fn add<const FIRST: bool>(
        &mut self,
        from: usize,
        gravity: Option<DVec3>,
        force: impl Fn(DVec3, DVec3, f64) -> DVec3,
    ) {
        let Block { x, v, f, m, .. } = self;
        let x = &x[from];
        for k in 0..BLOCK {
            let a = force(
                DVec3::new(x[0][k], x[1][k], x[2][k]),
                DVec3::new(v[0][k], v[1][k], v[2][k]),
                m[k],
            );
            let before = gravity.map(|g| DVec3::ZERO + super::gravity(g, m[k]));
            for (c, a) in [a.x, a.y, a.z].into_iter().enumerate() {
                let sum = match before {
                    Some(b) => b[c],
                    None if FIRST => 0.0,
                    None => f[c][k],
                };
                f[c][k] = sum + a;
            }
        }
    }

    /// One step from positions `x[from]` and the velocities to positions `x[1 - from]` and
    /// new velocities; returns the number of contacts.
    #[inline(always)]
    fn advance(&mut self, model: &Model, from: usize) -> usize {
        // Gravity followed by another force: both in one loop.
        let (mut forces, gravity) = match model.forces {
            [Force::Gravity { g }, _, ..] => (&model.forces[1..], Some(*g)),
            all => (all, None),
        };
        let mut first = true;
        while let [force, rest @ ..] = forces {
            let add = Add { block: self, from, first, gravity: gravity.filter(|_| first) };
            with_force(force, add);
            (forces, first) = (rest, false);
        }
        if model.forces.is_empty() {
            self.f = [[0.0; BLOCK]; 3];
        }
        if !model.external.is_empty() {
            let ext = &model.external[3 * self.start..3 * (self.start + self.len)];
            for (k, e) in ext.chunks_exact(3).enumerate() {
                for (f, e) in self.f.iter_mut().zip(e) {
                    f[k] += e;
                }
            }
        }
        if self.live.iter().all(|&live| live) {
            self.integrate::<true>(model, from);
        } else {
            self.integrate::<false>(model, from);
        }
        let mut contacts = 0;
        for collider in model.colliders {
            contacts += self.collide(collider, model, 1 - from);
        }
        contacts
    }

    /// Symplectic Euler as `crate::ode` computes it, from positions `x[from]` to `x[1 - from]`;
    /// the slots that do not move (unless `ALL_LIVE`: all move) keep their position and velocity.
    #[inline(always)]
    fn integrate<const ALL_LIVE: bool>(&mut self, model: &Model, from: usize) {
        // Without external forces the general path adds a zero one (turning -0 into +0).
        let zero = if model.external.is_empty() { 0.0 } else { -0.0 };
        let dt = model.dt;
        let Block { x, v, f, inv_m, live, .. } = self;
        let [a, b] = x;
        let (x0, x1) = if from == 0 { (a, b) } else { (b, a) };
        for k in 0..BLOCK {
            let moves = ALL_LIVE || live[k];
            for c in 0..3 {
                let v1 = v[c][k] + dt * ((f[c][k] + zero) * inv_m[k]);
                let p1 = x0[c][k] + dt * v1;
                x1[c][k] = if moves { p1 } else { x0[c][k] };
                v[c][k] = if moves { v1 } else { v[c][k] };
            }
        }
    }

    /// Meet `collider` at positions `x[to]` (that were `x[1 - to]` before the step); returns
    /// the number of contacts.
    #[inline(always)]
    fn collide(&mut self, collider: &Collider, model: &Model, to: usize) -> usize {
        let plane = if let (Shape::Plane(Plane { point, normal }), false) =
            (collider.shape, collider.inside)
        {
            // The same distance as `surface`, for the whole block in one loop (slots that do
            // not move are skipped below).
            let Block { x, d, .. } = self;
            let x = &x[to];
            let mut inside = 0;
            for k in 0..BLOCK {
                d[k] = (DVec3::new(x[0][k], x[1][k], x[2][k]) - point).dot(normal);
                inside += usize::from(d[k] < 0.0 || d[k].is_nan());
            }
            if inside == 0 {
                return 0;
            }
            true
        } else {
            false
        };
        let Block { x, v, live, d, .. } = self;
        let [a, b] = x;
        let (prev, x) = if to == 1 { (a, b) } else { (b, a) };
        let mut contacts = 0;
        for k in 0..BLOCK {
            if !live[k] || (plane && d[k] >= 0.0) {
                continue;
            }
            let p = DVec3::new(x[0][k], x[1][k], x[2][k]);
            let contact = surface(collider, p);
            if contact.distance >= 0.0 {
                continue;
            }
            contacts += 1;
            let (p1, v1) = respond(
                &contact,
                p,
                DVec3::new(v[0][k], v[1][k], v[2][k]),
                DVec3::new(prev[0][k], prev[1][k], prev[2][k]),
                model.dt,
                model.gravity,
            );
            for (c, (p1, v1)) in [(p1.x, v1.x), (p1.y, v1.y), (p1.z, v1.z)].into_iter().enumerate()
            {
                x[c][k] = p1;
                v[c][k] = v1;
            }
        }
        contacts
    }

    /// The largest |component| of the positions `x[at]` and the velocities of the slots that
    /// move (0 when none does).
    #[inline(always)]
    fn bound(&self, at: usize) -> f64 {
        // Eight lanes of maxima written as comparisons, which compile to packed maxima (the
        // values of the slots that move are finite here; the others may be anything).
        let max = |a: f64, b: f64| if a > b { a } else { b };
        let mut lanes = [0.0f64; 8];
        let all_live = self.live.iter().all(|&live| live);
        for c in 0..3 {
            let (x, v) = (self.x[at][c].as_chunks::<8>().0, self.v[c].as_chunks::<8>().0);
            for ((x, v), live) in x.iter().zip(v).zip(self.live.as_chunks::<8>().0) {
                for l in 0..8 {
                    let m = max(x[l].abs(), v[l].abs());
                    lanes[l] = max(lanes[l], if all_live || live[l] { m } else { 0.0 });
                }
            }
        }
        lanes.into_iter().fold(0.0, max)
    }

    /// The first live particle whose position `x[at]` or velocity is not finite.
    #[inline(always)]
    fn first_bad(&self, at: usize) -> Option<usize> {
        let Block { x, v, live, .. } = self;
        let x = &x[at];
        // A sum `s` of finite values has `0 s = 0` unless it overflows; a non-finite value
        // makes it NaN. (The exact test below also skips the slots that do not move.)
        let mut bad = 0;
        for k in 0..BLOCK {
            let s = x[0][k] + x[1][k] + x[2][k] + v[0][k] + v[1][k] + v[2][k];
            bad += usize::from(0.0 * s != 0.0);
        }
        if bad == 0 {
            return None;
        }
        let finite = |k: usize| (0..3).all(|c| x[c][k].is_finite() && v[c][k].is_finite());
        (0..BLOCK).find(|&k| live[k] && !finite(k)).map(|k| self.start + k)
    }
}

/// What [`commit`] found.
pub(super) struct Committed {
    /// Contacts of the steps.
    pub(super) contacts: usize,
    /// The first step (from 0) in which a live particle's position or velocity came out
    /// non-finite, and the first such particle, if any: the steps must then be undone.
    pub(super) bad: Option<(usize, usize)>,
    /// Without `bad`: the largest |component| of the positions and velocities of the live,
    /// movable particles after the steps (m, m/s), for [`step_bound`].
    pub(super) bound: f64,
}

/// How [`commit`] makes sure that steps which go non-finite can be undone.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Guard {
    /// Copy the state before the steps, and check every step.
    Copy,
    /// Check every step (the state was copied before an earlier call).
    Check,
    /// Nothing: the steps were certified not to go non-finite ([`step_bound`]).
    Certified,
}

/// Write `steps` steps of all particles (positions `xs`, velocities `vs`, `3 capacity` values
/// each, alive flags `alive`) in place, each block going through all of them while it is in
/// the cache (the particles do not interact; the caller makes sure that nothing else happens
/// between the steps); with [`Guard::Copy`], copy the state before the steps into `kept`
/// (positions then velocities, as `xs` and `vs`: `6 capacity` values, whatever the guard).
/// Every block is written even when one goes bad, so that steps that fail can be undone from
/// the copy.
pub(super) fn commit(
    model: &Model,
    xs: &mut [f64],
    vs: &mut [f64],
    alive: &[bool],
    kept: &mut [f64],
    guard: Guard,
    steps: usize,
) -> Committed {
    debug_assert_eq!(kept.len(), xs.len() + vs.len(), "one task per chunk of the state");
    let arch = pulp::Arch::new();
    let (kept_x, kept_v) = kept.split_at_mut(xs.len());
    xs.par_chunks_mut(3 * TASK)
        .zip(vs.par_chunks_mut(3 * TASK))
        .zip(kept_x.par_chunks_mut(3 * TASK).zip(kept_v.par_chunks_mut(3 * TASK)))
        .zip(alive.par_chunks(TASK))
        .enumerate()
        .map(|(t, (((xs, vs), kept), alive))| {
            let kept = (guard == Guard::Copy).then_some(kept);
            let check = guard != Guard::Certified;
            arch.dispatch(Commit { model, start: t * TASK, xs, vs, alive, kept, check, steps })
        })
        .reduce(
            || Committed { contacts: 0, bad: None, bound: 0.0 },
            |a, b| Committed {
                contacts: a.contacts + b.contacts,
                bad: a.bad.into_iter().chain(b.bad).min(),
                bound: a.bound.max(b.bound),
            },
        )
}

/// [`commit`] of one task's particles, compiled for the SIMD instruction set found at run time.
struct Commit<'a> {
    model: &'a Model<'a>,
    start: usize,
    xs: &'a mut [f64],
    vs: &'a mut [f64],
    alive: &'a [bool],
    /// Where to copy the positions and velocities before the steps, if asked.
    kept: Option<(&'a mut [f64], &'a mut [f64])>,
    /// Whether to check each step for non-finite values.
    check: bool,
    steps: usize,
}

impl pulp::WithSimd for Commit<'_> {
    type Output = Committed;

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) -> Committed {
        let Commit { model, start, xs, vs, alive, kept, check, steps } = self;
        if let Some((kept_x, kept_v)) = kept {
            kept_x.copy_from_slice(xs);
            kept_v.copy_from_slice(vs);
        }
        let mut block = Block::new(model);
        // Where the task's state starts, to prefetch the blocks ahead (the pointers are not
        // dereferenced).
        let (ahead_x, ahead_v) = (xs.as_ptr(), vs.as_ptr());
        let mut done = Committed { contacts: 0, bad: None, bound: 0.0 };
        let blocks =
            xs.chunks_mut(3 * BLOCK).zip(vs.chunks_mut(3 * BLOCK)).zip(alive.chunks(BLOCK));
        for (b, ((xb, vb), alive)) in blocks.enumerate() {
            let ahead = 3 * BLOCK * (b + PREFETCH);
            block.transpose.prefetch(ahead_x.wrapping_add(ahead));
            block.transpose.prefetch(ahead_v.wrapping_add(ahead));
            block.load(model, start + b * BLOCK, xb, vb, alive);
            let mut at = 0; // the positions of the last step are `block.x[at]`
            for s in 0..steps {
                done.contacts += block.advance(model, at);
                at = 1 - at;
                debug_assert!(check || block.first_bad(at).is_none(), "certified steps");
                if let Some(i) = check.then(|| block.first_bad(at)).flatten() {
                    done.bad = Some(done.bad.map_or((s, i), |bad| bad.min((s, i))));
                    break;
                }
            }
            if done.bad.is_none() {
                done.bound = done.bound.max(block.bound(at));
            }
            block.store(at, xb, vb);
        }
        done
    }
}
