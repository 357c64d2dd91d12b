//! The flock solver: the boids sorted by cell and the accelerations of a step. Every boid's
//! steering is computed from the state at the start of the step alone, in the cells' sorted
//! order (`cells.rs`), sweeping its neighbours in a fixed order, in parallel; so results are
//! bitwise the same on any number of threads. Within one call the boids stay in the cells'
//! order from step to step (re-sorted each step from the last order) and are written back to
//! the state in index order at the end; nothing is carried from one call to the next.
//!
//! Steering (Reynolds 1999, "Steering behaviors for autonomous characters"): each of
//! Reynolds' (1987) three rules gives a desired direction; its steering is the desired
//! velocity (that direction at the maximum speed) minus the current velocity, at most
//! `max_force` long. The acceleration is the weighted sum, again at most `max_force`; then
//! semi-implicit Euler `v += a dt` (speed capped at `max_speed`), `p += v dt`.

use super::cells::{Bounds, Cells, Moved};
#[cfg(target_arch = "x86_64")]
use super::lanes::Span;
use super::lanes::{Group, LANES};
use super::steering::{self, Behaviour, Steering, View};
use super::{Model, Settings, State};
use crate::error::{Error, Result};
use glam::{DVec2, DVec3};
use rayon::prelude::*;

/// Boids per parallel task.
const CHUNK: usize = 512;

/// Workspaces of a flock step (see the module docs).
#[derive(Clone, Debug, Default)]
pub struct Solver {
    /// The boids of the step, sorted by cell.
    cells: Cells,
    /// The boids the step moved, in the same slots.
    moved: Moved,
}

impl Solver {
    /// A solver for `model` (buffers grow on the first step).
    pub fn new(_model: &Model) -> Self {
        Solver::default()
    }

    /// Advance `state` by `steps` steps of `dt` seconds.
    ///
    /// # Errors
    /// `dt` not finite and positive (`dt`); a non-finite position or velocity after a step
    /// ([`Error::Diverged`], naming the step and the lowest such boid). The state is then as
    /// it was (it is written only after the last step).
    pub fn step(&mut self, model: &Model, state: &mut State, dt: f64, steps: usize) -> Result<()> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(Error::invalid("dt", "must be finite and > 0"));
        }
        let n = state.len();
        for s in &model.steering {
            if let Behaviour::Pursue(j) | Behaviour::Evade(j) = s.behaviour {
                if j as usize >= n {
                    return Err(Error::invalid("target", "no boid of that index"));
                }
            }
        }
        let set = &model.settings;
        let cos_half = (0.5 * set.field_of_view).cos();
        self.moved.load(&state.positions, &state.velocities, set.neighbour_radius);
        self.cells.load(n, set.neighbour_radius);
        let mut time = state.time;
        for step in 0..steps {
            self.cells.sort(&self.moved);
            if !model.steering.is_empty() {
                self.cells.update_rank();
            }
            let cells = &self.cells;
            let flock = View {
                positions: &cells.positions,
                velocities: &cells.velocities,
                rank: &cells.rank,
                time,
            };
            #[cfg(target_arch = "x86_64")]
            let avx = pulp::x86::V3::try_new().filter(|_| cells.flat());
            let Moved { positions, velocities, cells: moved_cells, .. } = &mut self.moved;
            let chunks = (
                positions.par_chunks_mut(CHUNK),
                velocities.par_chunks_mut(CHUNK),
                moved_cells.par_chunks_mut(CHUNK),
            );
            self.moved.bounds = chunks
                .into_par_iter()
                .enumerate()
                .map(|(k, (p, v, c))| {
                    let task = Task { model, cos_half, dt, cells, flock: &flock, first: k * CHUNK };
                    #[cfg(target_arch = "x86_64")]
                    if let Some(simd) = avx {
                        return simd.vectorize(Avx2 { task, simd, p, v, c });
                    }
                    task.run(None, p, v, c)
                })
                .reduce(|| Bounds::EMPTY, Bounds::join);
            time += dt;
            if self.moved.bounds.bad != u32::MAX {
                return Err(Error::Diverged {
                    step,
                    index: self.moved.bounds.bad as usize,
                    reason: "non-finite boid position or velocity".into(),
                });
            }
        }
        self.moved.store(&mut self.cells, &mut state.positions, &mut state.velocities);
        state.time = time;
        Ok(())
    }
}

/// The boids in the sorted slots `first..first + len` moved by one step of `dt` (s): their
/// accelerations (a flat flock's boids four at a time where `lanes` sweeps them, `lanes.rs`
/// with AVX2, and they can be, [`group`]; else one at a time), then semi-implicit Euler.
struct Task<'a> {
    model: &'a Model,
    cos_half: f64,
    dt: f64,
    cells: &'a Cells,
    flock: &'a View<'a>,
    first: usize,
}

impl Task<'_> {
    /// Write the moved boids' positions, velocities and cells into `p`, `v` and `c` (the
    /// task's slots), and return their [`Bounds`].
    #[inline(always)]
    fn run(
        self,
        #[cfg(target_arch = "x86_64")] simd: Option<pulp::x86::V3>,
        #[cfg(not(target_arch = "x86_64"))] simd: Option<()>,
        p: &mut [DVec3],
        v: &mut [DVec3],
        c: &mut [[i64; 3]],
    ) -> Bounds {
        let Task { model, cos_half, dt, cells, flock, first } = self;
        let set = &model.settings;
        let flat = cells.flat();
        let mut bounds = Bounds::EMPTY;
        // The lanes move a flat flock's groups (`Group::advance`): all at the `z` of the
        // task's first boid (finite, else the scalar sweep, which reports it), and the cells'
        // bounds gathered in the lanes.
        #[cfg(target_arch = "x86_64")]
        let z = cells.positions[first].z + 0.0;
        #[cfg(target_arch = "x86_64")]
        let mut span = simd.filter(|_| z.is_finite()).map(Span::new);
        #[cfg(target_arch = "x86_64")]
        let cz = cells.cell_of(DVec3::new(0.0, 0.0, z))[2];
        for (g, ((p, v), c)) in
            p.chunks_mut(LANES).zip(v.chunks_mut(LANES)).zip(c.chunks_mut(LANES)).enumerate()
        {
            let first = first + g * LANES;
            let mut swept: Option<[DVec3; LANES]> = None;
            #[cfg(target_arch = "x86_64")]
            if let (Some(simd), Some(span)) = (simd, &mut span) {
                if let Some(g) = group(set, cos_half, cells, first, p.len()) {
                    if !model.steering.is_empty() {
                        swept = Some(g.accelerations(simd, set));
                    } else if g.advance(simd, set, (dt, cells.inv_h()), cz, p, v, c, span) {
                        continue;
                    } else {
                        // A boid not finite or far out: its cell and bounds one by one.
                        for (l, ((p, v), c)) in p.iter().zip(&*v).zip(c).enumerate() {
                            *c = cells.cell_of(*p);
                            bounds.add(*c, *p, *v, cells.order[first + l]);
                        }
                        continue;
                    }
                }
            }
            #[cfg(not(target_arch = "x86_64"))]
            let _ = simd;
            let swept = swept.map_or([None; LANES], |s| s.map(Some));
            for (l, (((p, v), c), swept)) in p.iter_mut().zip(v).zip(c).zip(swept).enumerate() {
                let s = first + l;
                let own = match swept {
                    Some(own) => own,
                    None if flat => flocking::<DVec2>(set, cos_half, cells, s),
                    None => flocking::<DVec3>(set, cos_half, cells, s),
                };
                let i = cells.order[s];
                let a = match model.steering.as_slice() {
                    [] => own,
                    list => behaviours(set, list, flock, i as usize, own),
                };
                *v = (cells.velocities[s] + a * dt).clamp_length_max(set.max_speed);
                *p = cells.positions[s] + *v * dt;
                *c = cells.cell_of(*p);
                bounds.add(*c, *p, *v, i);
            }
        }
        #[cfg(target_arch = "x86_64")]
        if let Some((lo, hi)) = span.and_then(Span::extent) {
            bounds = bounds.join(Bounds::plane(lo, hi, cz, z));
        }
        bounds
    }
}

/// A task run with the lanes' sweep inside [`pulp::x86::V3::vectorize`], so that it is
/// compiled for AVX2 (`call` is inlined there).
#[cfg(target_arch = "x86_64")]
struct Avx2<'a, 'b> {
    task: Task<'a>,
    simd: pulp::x86::V3,
    p: &'b mut [DVec3],
    v: &'b mut [DVec3],
    c: &'b mut [[i64; 3]],
}

#[cfg(target_arch = "x86_64")]
impl pulp::NullaryFnOnce for Avx2<'_, '_> {
    type Output = Bounds;

    #[inline(always)]
    fn call(self) -> Bounds {
        self.task.run(Some(self.simd), self.p, self.v, self.c)
    }
}

/// Reynolds' steering towards the desired direction `desired` (any length; none if zero):
/// `desired / |desired| · max_speed - v`, at most `max_force` long (m/s²).
fn steer(set: &Settings, desired: DVec3, v: DVec3) -> DVec3 {
    let length = desired.length();
    if length == 0.0 {
        return DVec3::ZERO;
    }
    (desired * (set.max_speed / length) - v).clamp_length_max(set.max_force)
}

/// The vectors a sweep works in: 3-D, or 2-D for flat flocks (the `x` and `y` of the same
/// operations in the same order, so the same results without the third component).
trait Vector:
    Copy
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<f64, Output = Self>
    + std::ops::AddAssign
    + std::ops::SubAssign
{
    const ZERO: Self;
    /// The components of `v` it keeps.
    fn of(v: DVec3) -> Self;
    fn dot(self, other: Self) -> f64;
    /// Back to 3-D (`z` zero from 2-D).
    fn widen(self) -> DVec3;
}

impl Vector for DVec3 {
    const ZERO: Self = DVec3::ZERO;
    fn of(v: DVec3) -> Self {
        v
    }
    fn dot(self, other: Self) -> f64 {
        DVec3::dot(self, other)
    }
    fn widen(self) -> DVec3 {
        self
    }
}

impl Vector for DVec2 {
    const ZERO: Self = DVec2::ZERO;
    fn of(v: DVec3) -> Self {
        DVec2::new(v.x, v.y)
    }
    fn dot(self, other: Self) -> f64 {
        DVec2::dot(self, other)
    }
    fn widen(self) -> DVec3 {
        DVec3::new(self.x, self.y, 0.0)
    }
}

/// The acceleration (m/s²) of the boid in sorted slot `s` from its neighbours (those closer
/// than the neighbour radius) that lie in its field of view, `d · v ≥ cos_half |d| |v|`
/// (`cos_half` the cosine of half the field of view): separation away from those closer than
/// the separation distance, each weighted by the inverse distance (`-Σ d / |d|²`), alignment
/// towards their mean velocity, cohesion towards their centre; in the vectors `V` (2-D for a
/// flat flock). The field of view is tested without a square root or a branch: with
/// `c = cos_half |v|`, `d · v ≥ c |d|` is `(d · v) |d · v| ≥ c |c| |d|²` (`x ↦ x |x|` is
/// increasing). Only the separation's division is behind a branch, on the distance alone
/// (few candidates are that close).
fn flocking<V: Vector>(set: &Settings, cos_half: f64, cells: &Cells, s: usize) -> DVec3 {
    let v = V::of(cells.velocities[s]);
    let (sees_all, cc) = view(set, cos_half, v);
    let separation2 = set.separation_distance * set.separation_distance;
    let (mut away, mut velocity, mut offset, mut count) = (V::ZERO, V::ZERO, V::ZERO, 0.0);
    let (p, h2) = (V::of(cells.positions[s]), cells.h2());
    cells.for_each_candidate(s, |t, next| {
        let d = V::of(cells.positions[t]) - p;
        let (d2, dot) = (d.dot(d), d.dot(v));
        let near = next & (d2 < h2) & (t != s);
        let seen = near & (sees_all | (dot * dot.abs() >= cc * d2));
        // Whether a candidate is seen is a coin toss for the branch predictor: no branch.
        let w = std::hint::select_unpredictable(seen, 1.0, 0.0);
        count += w;
        velocity += V::of(cells.velocities[t]) * w;
        offset += d * w;
        // Rare, so well predicted, and on the distance alone (w zero: no change).
        if (d2 < separation2) & (d2 > 0.0) {
            away -= d * (w / d2);
        }
    });
    rules(set, v, away, velocity, offset, count)
}

/// The field of view of a boid flying at `v` (see [`flocking`]): whether it sees all round
/// (a full circle, or at rest), and `c |c|` with `c = cos_half |v|`.
fn view<V: Vector>(set: &Settings, cos_half: f64, v: V) -> (bool, f64) {
    let speed = v.dot(v).sqrt();
    let c = cos_half * speed;
    (set.field_of_view >= std::f64::consts::TAU || speed == 0.0, c * c.abs())
}

/// The flocking acceleration (m/s²) of a boid flying at `v` from the sums of its neighbours
/// in view ([`flocking`]): `away` (`-Σ d / |d|²` over the close ones), `velocity` and
/// `offset` (`Σ d`, m) summed over the `count` seen (none: zero).
fn rules<V: Vector>(set: &Settings, v: V, away: V, velocity: V, offset: V, count: f64) -> DVec3 {
    if count == 0.0 {
        return DVec3::ZERO;
    }
    let inv = 1.0 / count;
    let v = v.widen();
    let a = set.separation * steer(set, away.widen(), v)
        + set.alignment * steer(set, (velocity * inv).widen(), v)
        + set.cohesion * steer(set, (offset * inv).widen(), v);
    a.clamp_length_max(set.max_force)
}

/// The group of the boids in slots `first..first + len` for the lanes' sweep (`lanes.rs`), if
/// there are [`LANES`] of them, in one row of cells of a dense flock (else the scalar sweep).
fn group<'a>(
    set: &Settings,
    cos_half: f64,
    cells: &'a Cells,
    first: usize,
    len: usize,
) -> Option<Group<'a>> {
    if len != LANES || !cells.same_row(first, first + LANES - 1) {
        return None;
    }
    let rows = cells.rows::<LANES>(first)?;
    // The union of the lanes' ranges is the first's start to the last's end only if they
    // follow each other in the table: a row whose buckets run past the table's end onto its
    // start (the numbers of a layer are offset by the layer, `cells.rs`) does not.
    for row in &rows {
        if row.windows(2).any(|w| w[1].start < w[0].start || w[1].end < w[0].end) {
            return None;
        }
    }
    Some(Group {
        positions: &cells.positions,
        velocities: &cells.velocities,
        first,
        rows,
        h2: cells.h2(),
        separation2: set.separation_distance * set.separation_distance,
        cos_half,
        full_circle: set.field_of_view >= std::f64::consts::TAU,
    })
}

/// The flocking acceleration `flocking` of boid `i` plus its weighted steering behaviours,
/// at most `max_force` long (m/s²; `flocking` itself when none acts on it).
fn behaviours(set: &Settings, list: &[Steering], flock: &View, i: usize, flocking: DVec3) -> DVec3 {
    let mut a = flocking;
    let mut any = false;
    for s in list.iter().filter(|s| (s.boids[0] as usize..s.boids[1] as usize).contains(&i)) {
        a += s.weight * steering::force(set, &s.behaviour, flock, i);
        any = true;
    }
    if any {
        a.clamp_length_max(set.max_force)
    } else {
        flocking
    }
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::*;
    use crate::geometry::grid::random_points;

    /// The lanes' sweep and rules (AVX2; skipped on a CPU without it) give every boid of a
    /// group bitwise the acceleration of the scalar 2-D sweep and rules, and the lanes' step
    /// (`Group::advance`) bitwise its scalar velocity, position and cell, and the cells'
    /// bounds, with coincident
    /// boids, boids at rest, narrow and full fields of view, radii whose inverse is inexact,
    /// and groups whose rows run past the end of the bucket table (without the check of
    /// `group` the test fails there: 2003 boids, radius 1.3 m); and most groups of a dense
    /// flock take the lanes.
    #[test]
    fn lanes_match_the_scalar_sweep_bitwise() {
        let Some(simd) = pulp::x86::V3::try_new() else { return };
        let fovs = [1.5 * std::f64::consts::PI, 1.0, std::f64::consts::TAU];
        // Sizes, radii and seeds enough that some groups' rows run past the end of the bucket
        // table (rare: about one group a flock, where the wrap falls inside a row).
        let sizes = [2003, 3001, 4003, 5000, 6007];
        let cases = sizes.into_iter().flat_map(|n| [1.3, 1.7, 2.0, 2.3].map(move |h| (n, h)));
        for (case, (n, h)) in cases.flat_map(|c| [c; 4]).enumerate() {
            let fov = fovs[case % 3];
            let side = (n as f64 / 0.5).sqrt();
            let mut p = random_points(n, 3 + case as u64, side);
            let mut v = random_points(n, 40 + case as u64, 2.0);
            // Speeds up to 2.1 m/s: some are capped at `max_speed` (2 m/s) after the step.
            for (p, v) in p.iter_mut().zip(&mut v) {
                (p.z, v.x, v.y, v.z) = (0.0, 1.5 * (v.x - 1.0), 1.5 * (v.y - 1.0), 0.0);
            }
            (p[7], v[9], v[10]) = (p[8], DVec3::ZERO, DVec3::ZERO);
            let set = Settings {
                field_of_view: fov,
                neighbour_radius: h,
                separation_distance: 0.7,
                ..Settings::default()
            };
            let cos_half = (0.5 * fov).cos();
            let (mut cells, mut moved) = (Cells::default(), Moved::default());
            moved.load(&p, &v, set.neighbour_radius);
            cells.load(n, set.neighbour_radius);
            cells.sort(&moved);
            assert!(cells.flat());
            let mut grouped = 0;
            let (dt, mut span, mut lo, mut hi) =
                (0.05, Span::new(simd), [i64::MAX; 2], [i64::MIN; 2]);
            let z = cells.positions[0].z + 0.0;
            let cz = cells.cell_of(DVec3::new(0.0, 0.0, z))[2];
            for first in (0..n).step_by(LANES) {
                let Some(g) = group(&set, cos_half, &cells, first, LANES.min(n - first)) else {
                    continue;
                };
                grouped += 1;
                let got = simd.vectorize(|| g.accelerations(simd, &set));
                let g = group(&set, cos_half, &cells, first, LANES).unwrap();
                let (mut p, mut v, mut c) =
                    ([DVec3::ZERO; LANES], [DVec3::ZERO; LANES], [[0; 3]; LANES]);
                let moved = simd.vectorize(|| {
                    g.advance(
                        simd,
                        &set,
                        (dt, cells.inv_h()),
                        cz,
                        &mut p,
                        &mut v,
                        &mut c,
                        &mut span,
                    )
                });
                assert!(moved);
                let bits = |a: DVec3| a.to_array().map(f64::to_bits);
                for (l, &got) in got.iter().enumerate() {
                    let s = first + l;
                    let want = flocking::<DVec2>(&set, cos_half, &cells, s);
                    assert_eq!(bits(got), bits(want), "{n} boids, radius {h}, slot {s}");
                    // Moved as `Task::run` moves a boid one by one.
                    let vs = (cells.velocities[s] + want * dt).clamp_length_max(set.max_speed);
                    let ps = cells.positions[s] + vs * dt;
                    let cs = cells.cell_of(ps);
                    assert_eq!(
                        (bits(v[l]), bits(p[l]), c[l]),
                        (bits(vs), bits(ps), cs),
                        "slot {s}"
                    );
                    lo = [lo[0].min(cs[0]), lo[1].min(cs[1])];
                    hi = [hi[0].max(cs[0]), hi[1].max(cs[1])];
                }
            }
            assert_eq!(span.extent(), Some((lo, hi)));
            assert!(grouped * LANES > 9 * n / 10, "{grouped} groups of {n} boids");
        }
    }
}
