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
//! the symplectic Euler of [`crate::ode`] and of [`super::collide_one`], in the same order, so
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

use super::{respond, surface, Collider, Force};
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
        let plane = if let Collider::Plane { point, normal, .. } = *collider {
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

/// The magnitude no value of a step may reach for [`step_bound`] to certify it: far enough
/// below `f64::MAX` (1.8e308) that neither the rounding of the bounds nor the small constant
/// factors they leave out can matter.
const LIMIT: f64 = 1e300;

/// A bound on |component| of the curl noise of [`super::forces::curl_noise`]: each gradient
/// component of a noise field is a sum over 8 corners of `w g + (g·d) s w w` with the weights
/// `w` in [0, 1], `|g_c| <= 1`, `|g·d| <= 2` and the fade's slope `|s| <= 1.875`, so at most
/// `8 (1 + 2 · 1.875) = 38`, and a curl component is the difference of two.
const CURL_BOUND: f64 = 100.0;

/// What a step reads besides the state and the model's forces and colliders, as bounds:
/// the largest mass and inverse mass of a slot that moves (kg, 1/kg) and the largest
/// |component| of the external forces (N).
#[derive(Clone, Copy, Debug)]
pub(super) struct Extremes {
    pub(super) mass: f64,
    pub(super) inv_mass: f64,
    pub(super) external: f64,
}

/// Bounds on the magnitudes of the values of a step, each checked as it is formed.
struct Magnitudes {
    /// Whether every bound so far was below [`LIMIT`] (false after a NaN or an infinity too).
    within: std::cell::Cell<bool>,
}

impl Magnitudes {
    /// Note `bound`, a bound on the magnitude of some value of the step, and return it.
    fn note(&self, bound: f64) -> f64 {
        self.within.set(self.within.get() & (bound < LIMIT));
        bound
    }
}

/// The largest |component| of `v`.
pub(super) fn mag(v: DVec3) -> f64 {
    v.abs().max_element()
}

/// A certificate that a step of the kernel cannot come out non-finite: given `bound`, a bound
/// on |component| of the positions and velocities of the particles that move (m, m/s), a
/// bound on those of the state after one step of `dt` with `forces` and `colliders` (and
/// `gravity`, the sum of the uniform gravity fields) — or infinity when it cannot certify the
/// step. A call whose steps are certified needs no copy of the state to undo them
/// ([`super::ParticleSystem::explicit_steps`]).
///
/// Floating-point arithmetic on finite values gives a non-finite value only by overflow or
/// by an invalid operation (`0/0`, the root or fractional power of a negative number). A step
/// has no invalid operation on finite values: it divides only by `(|r|² + s²)^1.5 >= s³ > 0`
/// (attractor, checked below not to underflow), by `|r⊥| + core >= core > 0` (vortex), by the
/// noise scale `> 0`, by lengths it has tested to be positive, or where the quotient is
/// clamped to a finite range (`min(1)`, `clamp(0, 1)`, which map ±∞ to a finite value); its
/// roots and powers take sums of squares. So it remains to bound the magnitude of every value
/// the step forms: this function follows the step's arithmetic ([`super::particle_force`], the
/// symplectic Euler update, [`super::surface`] and [`super::respond`]) with bounds on the
/// components — `|a·b| <= 3 A B`, `|a × b| <= 2 A B`, `|a| <= 2 A`, a vector divided by its own
/// length at most 2 per component (1.3 where the squares underflow), a unit quaternion's
/// rotation at most 16 times the vector's bound in its intermediate values — and requires
/// each of them to stay below [`LIMIT`], 10⁸ times below overflow. Forces between particles
/// are never certified (they do not take this kernel).
pub(super) fn step_bound(
    forces: &[Force],
    colliders: &[Collider],
    dt: f64,
    gravity: DVec3,
    extremes: Extremes,
    bound: f64,
) -> f64 {
    let m = Magnitudes { within: std::cell::Cell::new(true) };
    let b = m.note(bound);
    let Extremes { mass, inv_mass, external } = extremes;
    let mut f = m.note(external);
    for force in forces {
        f += match *force {
            Force::Gravity { g } => m.note(mass * mag(g)),
            Force::Drag { linear, quadratic, wind } => {
                let u = m.note(b + mag(wind));
                m.note(3.0 * u * u);
                let speed = m.note(quadratic.abs() * 2.0 * u);
                m.note((linear.abs() + speed) * u)
            }
            Force::Damping { rate } => m.note(m.note(rate.abs() * mass) * b),
            Force::Attractor { center, strength, softening } => {
                let r = m.note(b + mag(center));
                let s2 = softening * softening;
                let least = s2.powf(1.5);
                if least == 0.0 {
                    return f64::INFINITY;
                }
                m.note((m.note(3.0 * r * r) + s2).powf(1.5));
                let q = m.note(m.note(strength.abs() * mass) / least);
                m.note(q * r)
            }
            Force::Vortex { center, axis, strength, core } => {
                let (r, a) = (m.note(b + mag(center)), mag(axis));
                let perp = m.note(r + m.note(m.note(3.0 * r * a) * a));
                m.note(3.0 * perp * perp);
                let q = m.note(m.note(strength.abs() * mass) / core);
                m.note(q * m.note(2.0 * a * perp))
            }
            Force::Turbulence { strength, scale, .. } => {
                m.note(b / scale + 100.0);
                m.note(m.note(strength.abs() * mass) * CURL_BOUND)
            }
            Force::Springs { .. }
            | Force::NeighborRepulsion { .. }
            | Force::NBodyGravity { .. } => {
                return f64::INFINITY;
            }
        };
    }
    let f = m.note(f);
    let mut v = m.note(b + m.note(dt * m.note(f * inv_mass)));
    let mut x = m.note(b + m.note(dt * v));
    let gravity = mag(gravity);
    for collider in colliders {
        // The contact: distance, normal and collider velocity, bounded.
        let sphere = |m: &Magnitudes, center: f64, radius: f64| {
            let d = m.note(x + center);
            m.note(3.0 * d * d);
            (m.note(2.0 * d + radius), 2.0)
        };
        let ((d, n), mu, vc) = match *collider {
            Collider::Plane { point, normal, friction, .. } => {
                let n = mag(normal);
                ((m.note(3.0 * m.note(x + mag(point)) * n), n), friction, 0.0)
            }
            Collider::Sphere { center, radius, friction, velocity, .. } => {
                (sphere(&m, mag(center), radius), friction, mag(velocity))
            }
            Collider::Capsule { a, b: end, radius, friction, velocity, .. } => {
                let ab = m.note(mag(a) + mag(end));
                m.note(3.0 * ab * ab);
                m.note(3.0 * m.note(x + mag(a)) * ab);
                let center = m.note(mag(a) + ab);
                (sphere(&m, center, radius), friction, mag(velocity))
            }
            Collider::Box { center, half, friction, velocity, .. } => {
                let q = m.note(16.0 * m.note(x + mag(center)));
                let excess = m.note(q + mag(half));
                m.note(3.0 * excess * excess);
                ((m.note(2.0 * excess), 32.0), friction, mag(velocity))
            }
        };
        // The response, as `respond` forms it (restitution at most 1).
        let x1 = m.note(x + m.note(d * n));
        let moved = m.note(x1 + b + m.note(vc * dt));
        let moved_t = m.note(moved + m.note(m.note(3.0 * moved * n) * n));
        m.note(3.0 * moved_t * moved_t);
        m.note(mu * d);
        x = m.note(x1 + moved_t);
        let u = m.note(v + vc);
        let vn = m.note(3.0 * u * n);
        m.note(2.0 * m.note(3.0 * gravity * n) * dt);
        let jn = m.note(2.0 * vn);
        let vt = m.note(u + m.note(vn * n));
        m.note(3.0 * vt * vt);
        m.note(mu * jn);
        v = v.max(m.note(vc + m.note((vn + jn) * n) + vt));
    }
    if m.within.get() {
        x.max(v)
    } else {
        f64::INFINITY
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;

    /// Random numbers for the cases (SplitMix64).
    struct Rng(u64);

    impl Rng {
        /// Uniform in [0, 1).
        fn unit(&mut self) -> f64 {
            (super::super::splitmix(&mut self.0) >> 11) as f64 / (1u64 << 53) as f64
        }
        /// A positive value with a magnitude from `10^lo` to `10^hi`, uniform in the exponent.
        fn magnitude(&mut self, lo: f64, hi: f64) -> f64 {
            10f64.powf(lo + (hi - lo) * self.unit())
        }
        fn signed(&mut self, lo: f64, hi: f64) -> f64 {
            let m = self.magnitude(lo, hi);
            if self.unit() < 0.5 {
                -m
            } else {
                m
            }
        }
        fn vector(&mut self, lo: f64, hi: f64) -> DVec3 {
            DVec3::new(self.signed(lo, hi), self.signed(lo, hi), self.signed(lo, hi))
        }
        fn direction(&mut self) -> DVec3 {
            self.vector(-1.0, 0.0).normalize()
        }
        fn force(&mut self) -> Force {
            match (6.0 * self.unit()) as usize {
                0 => Force::Gravity { g: self.vector(-2.0, 8.0) },
                1 => Force::Drag {
                    linear: self.magnitude(-6.0, 6.0),
                    quadratic: self.magnitude(-6.0, 6.0),
                    wind: self.vector(-2.0, 6.0),
                },
                2 => Force::Damping { rate: self.magnitude(-3.0, 8.0) },
                3 => Force::Attractor {
                    center: self.vector(-2.0, 6.0),
                    strength: self.signed(-3.0, 12.0),
                    softening: self.magnitude(-170.0, 1.0),
                },
                4 => Force::Vortex {
                    center: self.vector(-2.0, 6.0),
                    axis: self.direction(),
                    strength: self.signed(-3.0, 12.0),
                    core: self.magnitude(-12.0, 1.0),
                },
                _ => Force::Turbulence {
                    strength: self.signed(-3.0, 8.0),
                    scale: self.magnitude(-150.0, 2.0),
                    seed: 7,
                },
            }
        }
        fn collider(&mut self) -> Collider {
            let (restitution, friction) = (self.unit(), self.magnitude(-3.0, 1.0));
            let velocity = self.vector(-3.0, 4.0);
            match (4.0 * self.unit()) as usize {
                0 => Collider::Plane {
                    point: self.vector(-2.0, 4.0),
                    normal: self.direction(),
                    restitution,
                    friction,
                },
                1 => Collider::Sphere {
                    center: self.vector(-2.0, 4.0),
                    radius: self.magnitude(-3.0, 4.0),
                    inside: self.unit() < 0.5,
                    restitution,
                    friction,
                    velocity,
                },
                2 => Collider::Capsule {
                    a: self.vector(-2.0, 4.0),
                    b: self.vector(-2.0, 4.0),
                    radius: self.magnitude(-3.0, 4.0),
                    restitution,
                    friction,
                    velocity,
                },
                _ => Collider::Box {
                    center: self.vector(-2.0, 4.0),
                    rotation: DQuat::from_axis_angle(self.direction(), 6.0 * self.unit()),
                    half: DVec3::new(self.magnitude(-3.0, 3.0), 1.0, self.magnitude(-3.0, 3.0)),
                    restitution,
                    friction,
                    velocity,
                },
            }
        }
    }

    /// The largest |component| of a slice.
    fn largest(values: &[f64]) -> f64 {
        values.iter().fold(0.0, |m, v| m.max(v.abs()))
    }

    /// `step_bound` is a certificate: whenever it is finite, a step of the kernel from a state
    /// within the given bound comes out finite and within the bound it returns. The cases
    /// span the magnitudes on both sides of the limit (states from 1e-30 to 1e200, masses
    /// from 1e-20 to 1e20 kg, steps from 1e-8 to 1e3 s, every force of the kernel and every
    /// collider with parameters over many decades, softenings down to 1e-170 and noise scales
    /// down to 1e-150, where squares underflow and quotients overflow), and the test checks
    /// that a good share is
    /// certified, some of them close to the limit, so that it cannot pass by certifying
    /// nothing.
    #[test]
    fn step_bound_certifies_finite_steps_and_bounds_them() {
        const N: usize = 2 * BLOCK + 5;
        let mut rng = Rng(1);
        let (mut certified, mut near_limit) = (0, 0);
        let cases = 6000;
        for case in 0..cases {
            let forces: Vec<Force> =
                (0..1 + (3.0 * rng.unit()) as usize).map(|_| rng.force()).collect();
            let colliders: Vec<Collider> =
                (0..(3.0 * rng.unit()) as usize).map(|_| rng.collider()).collect();
            let gravity = forces
                .iter()
                .map(|f| if let Force::Gravity { g } = f { *g } else { DVec3::ZERO })
                .sum();
            let m = rng.magnitude(-20.0, 20.0);
            let dt = rng.magnitude(-8.0, 3.0);
            let external =
                if rng.unit() < 0.3 { vec![rng.signed(-3.0, 10.0); 3 * N] } else { vec![] };
            let top = rng.magnitude(-1.0, 2.3);
            let mut state: Vec<f64> = (0..6 * N).map(|_| rng.signed(-30.0, top)).collect();
            let bound = largest(&state);
            let (mass, inv_mass) = (vec![m; N], vec![1.0 / m; N]);
            let extremes = Extremes { mass: m, inv_mass: 1.0 / m, external: largest(&external) };
            let after = step_bound(&forces, &colliders, dt, gravity, extremes, bound);
            let model = Model {
                forces: &forces,
                colliders: &colliders,
                mass: &mass,
                inv_mass: &inv_mass,
                external: &external,
                dt,
                gravity,
                uniform: Some((m, 1.0 / m)),
            };
            let mut kept = vec![0.0; 6 * N];
            let (xs, vs) = state.split_at_mut(3 * N);
            let done = commit(&model, xs, vs, &[true; N], &mut kept, Guard::Check, 1);
            if after.is_finite() {
                certified += 1;
                near_limit += usize::from(after > 1e150);
                assert!(done.bad.is_none(), "case {case}: a certified step went non-finite");
                let reached = largest(&state);
                assert!(reached <= after, "case {case}: {reached:e} beyond the bound {after:e}");
                assert_eq!(done.bound, reached, "case {case}: the kernel's bound");
            }
        }
        assert!(certified > cases / 5 && certified < cases * 19 / 20, "certified {certified}");
        assert!(near_limit > 20, "certified close to the limit: {near_limit}");
    }

    /// The bench's scene (gravity, quadratic drag, a ground plane): one step from any state
    /// within 10 km and 10 km/s is certified, with a bound within a small factor of the
    /// state's; the bound compounds over the steps of a call (a factor of about 24 in the
    /// first step of 1 ms from 100 m and 100 m/s, more after), and a call of 4 such steps is
    /// certified too.
    #[test]
    fn an_ordinary_scene_is_certified() {
        let forces = [
            Force::Gravity { g: DVec3::new(0.0, -9.81, 0.0) },
            Force::Drag { linear: 0.0, quadratic: 1e-3, wind: DVec3::ZERO },
        ];
        let colliders = [Collider::Plane {
            point: DVec3::ZERO,
            normal: DVec3::Y,
            restitution: 0.5,
            friction: 0.3,
        }];
        let extremes = Extremes { mass: 1.0, inv_mass: 1.0, external: 0.0 };
        let gravity = DVec3::new(0.0, -9.81, 0.0);
        let once = step_bound(&forces, &colliders, 1.0 / 60.0, gravity, extremes, 1e4);
        assert!(once < 1e8, "{once:e}");
        let mut bound = 100.0;
        for _ in 0..4 {
            bound = step_bound(&forces, &colliders, 1e-3, gravity, extremes, bound);
        }
        assert!(bound.is_finite());
    }
}
