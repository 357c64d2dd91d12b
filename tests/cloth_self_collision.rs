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

/// Two separate triangles (no shared vertex), the upper one `gap` (m) above the lower, moving
/// towards each other at `speed` (m/s) each, without gravity; self-collision on.
fn two_layers(gap: f64, speed: f64) -> (Model, State) {
    let positions = vec![
        [0.0, 0.0, 0.0],
        [0.1, 0.0, 0.0],
        [0.0, 0.0, 0.1],
        [0.02, gap, 0.01],
        [0.12, gap, 0.01],
        [0.02, gap, 0.11],
    ];
    let mesh = Mesh::new(positions, vec![[0, 2, 1], [3, 5, 4]], None).unwrap();
    let mut model = Model::new(mesh, Elasticity::BaraffWitkin, material(), DVec3::ZERO).unwrap();
    model.set_thickness(0.01).unwrap();
    model.set_self_collision(Some(SelfCollision::default())).unwrap();
    let mut state = model.state();
    let x = state.positions().to_vec();
    let v: Vec<DVec3> =
        (0..6).map(|i| DVec3::new(0.3, if i < 3 { speed } else { -speed }, 0.1)).collect();
    state.set_motion(&x, &v).unwrap();
    (model, state)
}

fn momentum(model: &Model, state: &State) -> DVec3 {
    model.masses().iter().zip(state.velocities()).map(|(m, v)| *v * *m).sum()
}

#[test]
fn repulsion_and_collision_impulses_conserve_linear_momentum() {
    // Close (inside the thickness: proximity) and far but fast (crossing within the step:
    // CCD); the elastic forces are internal, the Cholesky solve exact to rounding.
    for (gap, speed, proximity) in [(0.005, 0.2, true), (0.05, 4.0, false)] {
        let (model, mut state) = two_layers(gap, speed);
        let before = momentum(&model, &state);
        let mut solver = Solver::new(&model);
        let options = SolveOptions { solver: LinearSolver::Cholesky, ..SolveOptions::default() };
        let stats =
            solver.step(&model, &mut state, 0.01, 1, Method::ImplicitEuler, options).unwrap();
        let after = momentum(&model, &state);
        assert!((after - before).length() < 1e-15, "{before} {after} {stats:?}");
        if proximity {
            assert!(stats.proximities >= 3, "{stats:?}");
        } else {
            assert!(stats.proximities == 0 && stats.ccd_iterations >= 1, "{stats:?}");
        }
        // The layers end the step apart: no intersection, no vertex within the kept distance.
        let x = state.positions();
        assert!(intersecting_triangles(x, model.triangles()).is_empty());
        let closest = min_distance(x, model.triangles(), 1.0);
        assert!(closest >= MIN_DISTANCE * model.thickness() * 0.99, "{closest}");
    }
}

#[test]
fn one_solver_steps_two_states_with_self_collision_bit_for_bit() {
    let model = model(10, 10, (0.5, 0.5), |x, z| DVec3::new(x, 0.3 + 0.3 * (x + z), 0.0), true);
    let mut a = model.state();
    a.pin(&[0], None).unwrap();
    let mut b = model.state();
    let x: Vec<DVec3> = b.positions().iter().map(|p| *p + DVec3::new(0.0, 0.1, 0.02)).collect();
    b.set_motion(&x, &vec![DVec3::new(0.0, -1.0, 0.3); x.len()]).unwrap();
    let options = SolveOptions::default();
    let go = |solver: &mut Solver, s: &mut State| {
        solver.step(&model, s, 0.01, 1, Method::Bdf2, options).unwrap();
    };
    let (mut alone_a, mut alone_b) = (a.clone(), b.clone());
    let (mut sa, mut sb) = (Solver::new(&model), Solver::new(&model));
    let mut shared = Solver::new(&model);
    for _ in 0..20 {
        go(&mut sa, &mut alone_a);
        go(&mut sb, &mut alone_b);
        let before_b = b.clone();
        go(&mut shared, &mut a);
        assert_eq!(b, before_b, "stepping one state changed the other");
        go(&mut shared, &mut b);
        assert_eq!(a, alone_a);
        assert_eq!(b, alone_b);
    }
}

#[test]
fn settings_are_checked_kept_in_snapshots_and_refused_with_explicit_integrators() {
    let mut model = model(5, 5, (1.0, 1.0), |x, z| DVec3::new(x, 0.0, z), true);
    let bad = SelfCollision { friction: -1.0, ..SelfCollision::default() };
    let err = model.set_self_collision(Some(bad)).unwrap_err().to_string();
    assert!(err.contains("friction"), "{err}");
    assert_eq!(model.self_collision(), Some(SelfCollision::default()));
    let mut cloth = Cloth::from_model(model.clone());
    cloth.step(0.01, 2, Method::ImplicitEuler, SolveOptions::default()).unwrap();
    let restored = Cloth::from_snapshot(&cloth.to_snapshot().unwrap()).unwrap();
    assert_eq!(restored.model().self_collision(), Some(SelfCollision::default()));
    assert_eq!(restored.model().fingerprint(), cloth.model().fingerprint());
    let before = cloth.state().clone();
    let err = cloth.step(1e-4, 1, Method::Rk4, SolveOptions::default()).unwrap_err();
    assert!(err.to_string().contains("integrator"), "{err}");
    assert_eq!(cloth.state(), &before);
    // Off: no tree is built and the step is that of a model that never had it.
    let mut off = model.clone();
    off.set_self_collision(None).unwrap();
    let (mut s1, mut s2) = (off.state(), off.state());
    let plain = Model::new(
        Mesh::grid(5, 5, 1.0, 1.0, Triangulation::Alternating).unwrap(),
        Elasticity::BaraffWitkin,
        material(),
        DVec3::new(0.0, -9.81, 0.0),
    )
    .unwrap();
    let mut plain = plain;
    plain.set_thickness(off.thickness()).unwrap();
    Solver::new(&off)
        .step(&off, &mut s1, 0.01, 3, Method::ImplicitEuler, SolveOptions::default())
        .unwrap();
    Solver::new(&plain)
        .step(&plain, &mut s2, 0.01, 3, Method::ImplicitEuler, SolveOptions::default())
        .unwrap();
    assert_eq!(s1.positions(), s2.positions());
}

/// The largest edge strain `length / rest - 1` of `x` over `edges` `(a, b, rest (m))`.
fn max_strain(x: &[DVec3], edges: &[(usize, usize, f64)]) -> f64 {
    edges.iter().map(|&(a, b, rest)| (x[b] - x[a]).length() / rest - 1.0).fold(f64::MIN, f64::max)
}

/// The demo's folding sheet (`kinema demo cloth`) at 16²: the default cotton-like material
/// and step options (strain limit 3 %, subdivision on), self-collision at the default
/// thickness, dropped upright onto the ground and folding, 100 steps of 1/100 s. After every
/// step the edges are within the strain limit (to 0.2 %: the last impulses of a step may
/// stretch an edge slightly) and no two triangles intersect. Before the strain limit was
/// applied again after the collision impulses (and let touching vertices slide) edges of this
/// scene stretched by up to 170 %.
#[test]
fn a_folding_sheet_keeps_the_strain_limit() {
    let mut mesh = Mesh::grid(16, 16, 1.0, 1.0, Triangulation::Alternating).unwrap();
    for p in &mut mesh.positions {
        *p = [p[0], 0.52 + p[2], 0.02 * (9.0 * p[2]).sin()];
    }
    let g = DVec3::new(0.0, -9.81, 0.0);
    let mut model = Model::new(mesh, Elasticity::BaraffWitkin, Material::default(), g).unwrap();
    model.set_thickness(0.1 * model.mean_edge_length()).unwrap();
    model.set_self_collision(Some(SelfCollision::default())).unwrap();
    let x0 = model.state().positions().to_vec();
    let edges: Vec<(usize, usize, f64)> = model
        .triangles()
        .iter()
        .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
        .map(|(a, b)| (a, b, (x0[a] - x0[b]).length()))
        .collect();
    let mut state = model.state();
    let floor = Shape::Plane(Plane { normal: DVec3::Y, point: DVec3::ZERO });
    state.add_collider(Collider { shape: floor, velocity: DVec3::ZERO, friction: 0.5 }).unwrap();
    let mut solver = Solver::new(&model);
    let (mut worst, mut proximities): (f64, usize) = (0.0, 0);
    for k in 0..100 {
        let options = SolveOptions::default();
        let stats = solver.step(&model, &mut state, 0.01, 1, Method::ImplicitEuler, options);
        proximities += stats.unwrap().proximities;
        let strain = max_strain(state.positions(), &edges);
        worst = worst.max(strain);
        assert!(strain <= options.max_strain + 0.002, "step {k}: strain {strain}");
        let crossing = intersecting_triangles(state.positions(), model.triangles());
        assert!(crossing.is_empty(), "step {k}: {crossing:?}");
    }
    assert!(proximities > 100, "the sheet must fold onto itself: {proximities}");
    assert!(worst > 0.02, "the sheet must be stretched towards the limit: {worst}");
}
