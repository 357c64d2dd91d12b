//! The particle fluid (`kinema::fluid`): the mass rule, a column at rest (incompressibility,
//! hydrostatic pressure), the dam break against Martin & Moyce (1952) and Koshizuka & Oka
//! (1996), several states of one model, and the extremes.

use glam::DVec3;
use kinema::fluid::{Fluid, Kernel, Model, Pressure, Settings, Solver, State, Viscosity, Wall};
use kinema::snapshot::Stamped;
use kinema::Error;

fn tank(fluid: &mut Fluid, lower: [f64; 3], upper: [f64; 3]) {
    let wall = Wall::Box { lower: DVec3::from_array(lower), upper: DVec3::from_array(upper) };
    fluid.add_wall(wall).unwrap();
}

/// A cubic lattice of the spacing has the rest density: the particle volume is chosen so
/// (`V = 1 / Σ W` over the lattice), and that volume is the spacing cubed within the
/// kernel's quadrature error (2 % for the cubic spline, 5 % for Wendland at `h = 2 s`).
#[test]
fn lattice_at_the_spacing_has_the_rest_density() {
    for (kernel, tol) in [(Kernel::CubicSpline, 0.02), (Kernel::WendlandC2, 0.05)] {
        let s = 0.05;
        let mut fluid = Fluid::new(Settings { kernel, ..Settings::new(s) }).unwrap();
        fluid.add_block(DVec3::ZERO, DVec3::splat(0.5), DVec3::ZERO).unwrap();
        let rho = fluid.densities();
        let centre = fluid
            .state()
            .positions()
            .iter()
            .position(|p| (*p - DVec3::splat(0.275)).length() < 1e-9)
            .unwrap();
        assert!((rho[centre] / 1000.0 - 1.0).abs() < 1e-12, "{kernel:?}: {}", rho[centre]);
        let mass = fluid.model().particle_mass();
        assert!((mass / (1000.0 * s * s * s) - 1.0).abs() < tol, "{kernel:?}: {mass}");
        // A corner particle has far fewer neighbours: about 1/8 of the kernel's mass plus
        // the faces' halves, well below the rest density.
        assert!(rho[0] < 0.7 * 1000.0, "{}", rho[0]);
    }
}

/// A water column filling the bottom of a closed tank, at rest: with DFSPH the mean density
/// error after each substep's solve stays under the 0.05 % tolerance, the column keeps its
/// height (after the first 0.5 s, in which the free surface's lattice settles: particles of
/// the top layers, short of neighbours, sink into the gaps below), and the pressure, averaged
/// over the last 0.5 s, grows with depth as `ρ g`.
#[test]
fn column_at_rest_keeps_its_height_and_hydrostatic_pressure() {
    let (s, w, h, d) = (0.02, 0.2, 0.4, 0.08);
    let mut fluid = Fluid::new(Settings::new(s)).unwrap();
    tank(&mut fluid, [0.0, 0.0, 0.0], [w, 0.6, d]);
    fluid.add_block(DVec3::ZERO, DVec3::new(w, h, d), DVec3::ZERO).unwrap();
    // The column's height: twice the mean height of its particles.
    let height = |f: &Fluid| {
        2.0 * f.state().positions().iter().map(|p| p.y).sum::<f64>() / f.state().len() as f64
    };
    let mut iterations = 0;
    let mut h0 = 0.0;
    // Each particle's height and pressure summed over the last 30 frames.
    let mut sums = vec![(0.0, 0.0); fluid.state().len()];
    for frame in 0..90 {
        fluid.step(1.0 / 60.0, 1).unwrap();
        let st = fluid.stats;
        assert!(st.density_error <= 0.05, "frame {frame}: {st:?}");
        iterations += st.density_iterations;
        if frame == 29 {
            h0 = height(&fluid);
            eprintln!("settled height {h0} (from {h})");
        } else if frame > 29 {
            let y = height(&fluid);
            assert!((y - h0).abs() <= 0.005 * h0, "frame {frame}: height {y} vs {h0}");
        }
        if frame >= 60 {
            let now = fluid.state().positions().iter().zip(fluid.pressures());
            for (sum, (x, p)) in sums.iter_mut().zip(now) {
                *sum = (sum.0 + x.y / 30.0, sum.1 + p / 30.0);
            }
        }
    }
    eprintln!("{:?}, {iterations} density iterations in 90 frames", fluid.stats);
    // Hydrostatics: below the settled surface, the mean pressure is linear in depth with
    // slope ρ g (a least-squares fit over the particles 3 spacings or more from the floor and
    // the surface). The pressure of one frame is not: the surface's jitter makes its slope
    // swing between 0.65 and 1.4 ρ g from frame to frame (measured over the last 4 frames).
    let pts: Vec<(f64, f64)> =
        sums.into_iter().filter(|(y, _)| *y > 3.0 * s && *y < h0 - 3.0 * s).collect();
    let n = pts.len() as f64;
    let (my, mp) =
        (pts.iter().map(|q| q.0).sum::<f64>() / n, pts.iter().map(|q| q.1).sum::<f64>() / n);
    let slope = pts.iter().map(|q| (q.0 - my) * (q.1 - mp)).sum::<f64>()
        / pts.iter().map(|q| (q.0 - my) * (q.0 - my)).sum::<f64>();
    let surface = my + mp / -slope;
    eprintln!("dp/dy = {slope} Pa/m (rho g = 9810), zero pressure at y = {surface} (surface {h0})");
    // Measured: 0.949 ρ g, zero 1.7 cm below the surface.
    assert!((slope / -9810.0 - 1.0).abs() < 0.1, "{slope}");
    assert!((surface - h0).abs() < 2.0 * s, "{surface}");
    // The surface particles still jitter (measured: 0.27 m/s at most after 1.5 s).
    let vmax = fluid.state().velocities().iter().map(|v| v.length()).fold(0.0, f64::max);
    assert!(vmax < 0.5, "{vmax}");
}

/// A column 25 particles deep at a spacing of 5 mm stays at rest with the default settings.
/// With substeps of `max_dt` = 5 ms (`|g| dt² / s` = 0.049, allowed before session 20) it
/// blew up in its third frame (mean speed 3.7 m/s); docs/fluid.md, "Speed". It is not
/// still: its mean speed is 0.05–0.10 m/s at any step limit (measured at 0.02, 0.01 and
/// 0.005), the alternating layers of `GRAVITY_STEP`'s note bouncing on each other.
#[test]
fn fine_column_at_rest_stays_at_rest() {
    let s = 0.005;
    let mut fluid = Fluid::new(Settings::new(s)).unwrap();
    tank(&mut fluid, [0.0; 3], [8.0 * s, 37.5 * s, 4.0 * s]);
    fluid.add_block(DVec3::ZERO, DVec3::new(8.0 * s, 25.0 * s, 4.0 * s), DVec3::ZERO).unwrap();
    for frame in 0..6 {
        fluid.step(1.0 / 60.0, 1).unwrap();
        let v = fluid.state().velocities();
        let mean = v.iter().map(|v| v.length()).sum::<f64>() / v.len() as f64;
        eprintln!("frame {frame}: {} substeps, mean speed {mean:.3} m/s", fluid.stats.substeps);
        assert!(mean < 0.2, "frame {frame}: mean speed {mean} m/s");
    }
}

/// The dam break at `L/50` (the spacing of the 100k run in docs/fluid.md, "Speed"), reduced
/// to a slab 4 particles thick (20,000 particles): its first three frames of 1/60 s match
/// the coarse runs — mean speeds after frames 2 and 3 within 5 % of `L/10`'s and `L/20`'s
/// (0.271 / 0.270 and 0.398 / 0.395 m/s, the 0.4 L slab of `bench/bench_fluid.py`;
/// measured here 0.266 and 0.393) — and the fastest particle is at the front (within
/// 0.1 L of it). With the gravity limit of session 20 (`|g| dt² / s` up to 0.02) the
/// column's bottom came apart: mean 0.427 m/s after frame 2, its fastest particle at
/// 3.4 m/s in the column's corner (x = 0.02 L).
#[test]
fn fine_dam_break_agrees_with_the_coarse_ones() {
    let l = 0.146;
    let s = l / 50.0;
    let mut fluid = Fluid::new(Settings::new(s)).unwrap();
    tank(&mut fluid, [0.0; 3], [4.0 * l, 3.0 * l, 4.0 * s]);
    fluid.add_block(DVec3::ZERO, DVec3::new(l, 2.0 * l, 4.0 * s), DVec3::ZERO).unwrap();
    for (frame, coarse) in [(1, None), (2, Some(0.2705)), (3, Some(0.3965))] {
        fluid.step(1.0 / 60.0, 1).unwrap();
        let (x, v) = (fluid.state().positions(), fluid.state().velocities());
        let mean = v.iter().map(|v| v.length()).sum::<f64>() / v.len() as f64;
        let fastest = (0..v.len()).max_by(|&a, &b| v[a].length().total_cmp(&v[b].length()));
        let fastest = x[fastest.unwrap()].x / l;
        let front = x.iter().map(|p| p.x).fold(0.0, f64::max) / l;
        eprintln!("frame {frame}: mean speed {mean:.3} m/s, fastest at x = {fastest:.2} L, front {front:.2} L");
        assert!(front - fastest < 0.1, "frame {frame}: fastest at {fastest} L, front {front} L");
        if let Some(coarse) = coarse {
            assert!((mean / coarse - 1.0f64).abs() < 0.05, "frame {frame}: {mean} m/s");
        }
    }
}

/// Martin & Moyce (1952), "An experimental study of the collapse of liquid columns on a
/// rigid horizontal plane", Phil. Trans. R. Soc. A 244, 312–324, fig. 3: the surge front
/// `Z/L` against `T = t sqrt(2g/L)` of a column of width `L = a = 2.25 in` and height `2L`
/// (`n² = 2`), points up to `T = 3` as digitised in PySPH's `examples/db_exp_data.py`.
const MARTIN_MOYCE: [(f64, f64); 4] =
    [(0.832, 1.217), (1.219, 1.474), (1.997, 2.292), (2.547, 2.995)];

/// Koshizuka & Oka (1996), "Moving-particle semi-implicit method for fragmentation of
/// incompressible fluid", Nucl. Sci. Eng. 123, 421–434: the experimental surge front as
/// digitised and shipped with DualSPHysics (`examples/main/01_DamBreak/
/// EXP_X-DamTipPosition_Koshizula&Oka1996.txt`, Froude-scaled to its column of width
/// `a = 1 m` and height `2a`): `(t in s, X in m)`, so `T = t sqrt(2g / 1 m)` and `Z/L = X`;
/// the points up to `T = 3` (13 of 15; the last two lie beyond a tank of `4a`).
const KOSHIZUKA_OKA: [(f64, f64); 13] = [
    (0.092031603, 1.128),
    (0.190699774, 1.244),
    (0.266343115, 1.464),
    (0.32214447, 1.695),
    (0.368058691, 1.903),
    (0.413950339, 2.123),
    (0.446591422, 2.365),
    (0.495801354, 2.584),
    (0.521851016, 2.804),
    (0.56462754, 3.034),
    (0.594018059, 3.219),
    (0.636591422, 3.462),
    (0.669255079, 3.704),
];

/// Both experiments as `(T, Z/L, name)`.
fn experiments() -> impl Iterator<Item = (f64, f64, &'static str)> {
    let ko = KOSHIZUKA_OKA.into_iter().map(|(t, x)| (t * (2.0 * 9.81f64).sqrt(), x, "K&O"));
    MARTIN_MOYCE.into_iter().map(|(t, z)| (t, z, "M&M")).chain(ko)
}

/// The surge front of a dam break of `L = 0.146 m` with particles `L / per_width` apart, in a
/// slab `layers` particles thick between walls: `(T, Z/L)` every 1/240 s up to `T = 3.1`.
fn dam_break(per_width: f64, layers: f64) -> Vec<(f64, f64)> {
    let l = 0.146;
    let s = l / per_width;
    let mut fluid = Fluid::new(Settings::new(s)).unwrap();
    tank(&mut fluid, [0.0, 0.0, 0.0], [4.0 * l, 3.0 * l, layers * s]);
    fluid.add_block(DVec3::ZERO, DVec3::new(l, 2.0 * l, layers * s), DVec3::ZERO).unwrap();
    let scale = (2.0 * 9.81 / l).sqrt();
    let mut out = vec![(0.0, 1.0)];
    while out.last().unwrap().0 < 3.1 {
        fluid.step(1.0 / 240.0, 1).unwrap();
        let front = fluid.state().positions().iter().map(|p| p.x).fold(0.0, f64::max) + 0.5 * s;
        out.push((fluid.state().time() * scale, front / l));
    }
    out
}

/// `Z/L` at `t` by linear interpolation of a front history.
fn front_at(history: &[(f64, f64)], t: f64) -> f64 {
    let k = history.iter().position(|p| p.0 >= t).unwrap();
    let (a, b) = (history[k - 1], history[k]);
    a.1 + (b.1 - a.1) * (t - a.0) / (b.0 - a.0)
}

#[test]
fn dam_break_front_follows_martin_and_moyce() {
    // Measured at L/10, 4 layers: +12 %, +18 %, +16 %, +13 % against Martin & Moyce, from
    // -4 % (T = 0.41) to +15 % (T = 1.4-1.8) against Koshizuka & Oka (ahead of the
    // experiments, as inviscid simulations without the gate's opening and the walls'
    // friction are; see docs/fluid.md); the 5 % is not met.
    let history = dam_break(10.0, 4.0);
    for (t, z, name) in experiments() {
        let got = front_at(&history, t);
        let off = 100.0 * (got / z - 1.0);
        eprintln!("T = {t:.3}: Z/L = {got:.3}, {name} {z} ({off:+.1} %)");
        assert!((got / z - 1.0).abs() < 0.2, "T = {t}: {got} vs {name} {z}");
    }
}

/// The same at `L/20` (8 layers): too slow for the default run (`cargo test --release
/// --test fluid -- --ignored`); prints the comparison. Measured (optimised test build, the
/// same set-up): +15.3 %, +19.5 %, +18.1 %, +14.9 %: refining moves the front further
/// ahead, not towards the experiment (docs/fluid.md).
#[test]
#[ignore = "L/20: cargo test --release --test fluid -- --ignored"]
fn dam_break_finer() {
    let history = dam_break(20.0, 8.0);
    for (t, z, name) in experiments() {
        let got = front_at(&history, t);
        let off = 100.0 * (got / z - 1.0);
        eprintln!("T = {t:.3}: Z/L = {got:.3}, {name} {z} ({off:+.1} %)");
    }
}

/// A small tank with a block of fluid, for the tests below.
fn small(settings: Settings) -> Fluid {
    let mut fluid = Fluid::new(settings).unwrap();
    tank(&mut fluid, [0.0, 0.0, 0.0], [0.3, 0.3, 0.12]);
    fluid.add_block(DVec3::ZERO, DVec3::new(0.1, 0.2, 0.12), DVec3::ZERO).unwrap();
    fluid
}

fn bits(state: &State) -> Vec<u64> {
    let x = state.positions().iter().chain(state.velocities()).flat_map(|v| v.to_array());
    x.chain(state.pressures().iter().copied()).chain([state.time()]).map(f64::to_bits).collect()
}

/// One model, two states with different initial conditions, one solver stepping them
/// interleaved: each trajectory is bitwise that of the state stepped alone with a fresh
/// solver, and stepping one leaves the other untouched.
#[test]
fn one_solver_steps_two_states_of_one_model() {
    let fluid = small(Settings::new(0.02));
    let model: &Model = fluid.model();
    let a0 = fluid.state().clone();
    let mut b0 = a0.clone();
    let v: Vec<DVec3> = b0.velocities().iter().map(|_| DVec3::new(0.5, 0.0, 0.0)).collect();
    b0.set_velocities(&v).unwrap();
    let alone = |mut s: State| {
        let mut solver = Solver::new(model);
        (0..4)
            .map(|_| {
                solver.step(model, &mut s, 1.0 / 60.0, 1).unwrap();
                bits(&s)
            })
            .collect::<Vec<_>>()
    };
    let (want_a, want_b) = (alone(a0.clone()), alone(b0.clone()));
    let (mut a, mut b) = (a0, b0);
    let mut solver = Solver::new(model);
    for k in 0..4 {
        let before = bits(&b);
        solver.step(model, &mut a, 1.0 / 60.0, 1).unwrap();
        assert_eq!(bits(&b), before);
        assert_eq!(bits(&a), want_a[k], "a, frame {k}");
        solver.step(model, &mut b, 1.0 / 60.0, 1).unwrap();
        assert_eq!(bits(&b), want_b[k], "b, frame {k}");
    }
    assert_ne!(want_a, want_b);
}

#[test]
fn same_bits_on_one_and_two_threads() {
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            let mut fluid = small(Settings::new(0.02));
            fluid.step(1.0 / 30.0, 3).unwrap();
            bits(fluid.state())
        })
    };
    assert_eq!(run(1), run(2));
}

/// The solver sorts its copy of the particles by cell each frame (`src/fluid/order.rs`); the
/// state keeps the order they were added in: after a frame every particle of the block is
/// within a fifth of a spacing of where it started (the fastest falls 2.8 mm = 0.14 spacing
/// in 1/60 s), where the sorted order would put most of them spacings away. Frames in one
/// call or one a call give the same bits (each frame's order depends on its positions only).
#[test]
fn particles_keep_the_state_order_and_frames_batch() {
    let mut fluid = small(Settings::new(0.02));
    let start = fluid.state().positions().to_vec();
    let mut batched = fluid.clone();
    fluid.step(1.0 / 60.0, 1).unwrap();
    let far = fluid.state().positions().iter().zip(&start).map(|(p, q)| (*p - *q).length());
    let far = far.fold(0.0, f64::max);
    assert!(far < 0.2 * 0.02, "a particle moved {far} m in its slot");
    fluid.step(1.0 / 60.0, 1).unwrap();
    batched.step(1.0 / 60.0, 2).unwrap();
    assert_eq!(bits(fluid.state()), bits(batched.state()));
}

#[test]
fn snapshots_round_trip_and_name_their_model() {
    use kinema::snapshot::Snapshot;
    let mut fluid = small(Settings::new(0.02));
    fluid.step(1.0 / 60.0, 2).unwrap();
    let mut copy = Fluid::from_snapshot(&fluid.to_snapshot().unwrap()).unwrap();
    fluid.step(1.0 / 60.0, 2).unwrap();
    copy.step(1.0 / 60.0, 2).unwrap();
    assert_eq!(bits(fluid.state()), bits(copy.state()));
    let data = fluid.state().to_snapshot(fluid.model()).unwrap();
    assert_eq!(bits(&State::from_snapshot(fluid.model(), &data).unwrap()), bits(fluid.state()));
    let other = small(Settings { viscosity: Viscosity::Xsph(0.02), ..Settings::new(0.02) });
    let err = State::from_snapshot(other.model(), &data).unwrap_err();
    assert!(matches!(err, Error::InvalidInput { ref arg, .. } if arg == "model"), "{err}");
}

/// Both solvers keep every particle in the tank; WCSPH (c = 30 m/s) keeps the density
/// error near `(v/c)²`, well under 1 %.
#[test]
fn wcsph_and_dfsph_keep_the_fluid_in_the_tank() {
    for pressure in [Pressure::DFSPH, Pressure::WCSPH] {
        let mut fluid = small(Settings { pressure, ..Settings::new(0.02) });
        let mut worst: f64 = 0.0;
        for _ in 0..30 {
            fluid.step(1.0 / 60.0, 1).unwrap();
            worst = worst.max(fluid.stats.density_error);
        }
        let inside =
            |p: &DVec3| p.cmpge(DVec3::ZERO).all() && p.cmple(DVec3::new(0.3, 0.3, 0.12)).all();
        assert!(fluid.state().positions().iter().all(inside), "{pressure:?}");
        // The fluid has spread along the floor.
        let front = fluid.state().positions().iter().map(|p| p.x).fold(0.0, f64::max);
        assert!(front > 0.2, "{pressure:?}: {front}");
        eprintln!("{pressure:?}: mean density error up to {worst} %");
        assert!(worst < 1.0, "{pressure:?}: {worst}");
    }
}

#[test]
fn extremes_empty_fluid_and_walls_without_fluid() {
    let mut empty = Fluid::new(Settings::new(0.05)).unwrap();
    empty.step(0.1, 3).unwrap();
    assert!((empty.state().time() - 0.3).abs() < 1e-15);
    tank(&mut empty, [0.0; 3], [1.0; 3]);
    empty.step(0.1, 1).unwrap();
    assert_eq!(empty.stats.substeps, 0);
    assert!(empty.densities().is_empty());
}

#[test]
fn extremes_bad_settings_and_blocks_are_named() {
    let arg = |e: Error| match e {
        Error::InvalidInput { arg, .. } => arg,
        other => panic!("{other}"),
    };
    assert_eq!(arg(Fluid::new(Settings::new(0.0)).unwrap_err()), "spacing");
    assert_eq!(arg(Fluid::new(Settings::new(f64::NAN)).unwrap_err()), "spacing");
    let bad = Settings { rest_density: -1.0, ..Settings::new(0.1) };
    assert_eq!(arg(Fluid::new(bad).unwrap_err()), "rest_density");
    let mut fluid = Fluid::new(Settings::new(0.1)).unwrap();
    tank(&mut fluid, [0.0; 3], [1.0; 3]);
    let e = fluid.add_block(DVec3::splat(0.5), DVec3::splat(1.5), DVec3::ZERO).unwrap_err();
    assert_eq!(arg(e), "lower");
    let e = fluid.add_block(DVec3::ZERO, DVec3::splat(0.05), DVec3::ZERO).unwrap_err();
    assert_eq!(arg(e), "upper");
    let e = fluid.add_block(DVec3::ZERO, DVec3::new(f64::NAN, 1.0, 1.0), DVec3::ZERO).unwrap_err();
    assert_eq!(arg(e), "lower");
    assert_eq!(fluid.state().len(), 0);
    assert_eq!(arg(fluid.step(f64::NAN, 1).unwrap_err()), "dt");
    assert_eq!(arg(fluid.step(-1.0, 1).unwrap_err()), "dt");
}

/// A frame ten times the CFL substep is taken in substeps; a frame needing more than
/// `max_substeps` fails and leaves the fluid exactly as it was.
#[test]
fn extremes_long_frames_are_substepped_or_refused_unchanged() {
    let mut fluid = small(Settings::new(0.02));
    fluid.step(1.0 / 60.0, 6).unwrap();
    let limit = 0.005; // max_dt
    fluid.step(10.0 * limit, 1).unwrap();
    assert!(fluid.stats.substeps >= 10, "{:?}", fluid.stats);
    let mut strict = small(Settings { max_substeps: 3, ..Settings::new(0.02) });
    let before = bits(strict.state());
    let err = strict.step(1.0, 1).unwrap_err();
    assert!(matches!(err, Error::SolverFailed { .. }), "{err}");
    assert_eq!(bits(strict.state()), before);
}

/// Particles on top of each other cannot be made: a block overlapping fluid already added
/// is refused (DFSPH would need to remove a 100 % compression at once). A block dropped
/// from 10 m stays finite and in the tank.
#[test]
fn extremes_overlapping_blocks_and_a_drop_from_ten_metres() {
    let mut fluid = Fluid::new(Settings::new(0.02)).unwrap();
    tank(&mut fluid, [0.0; 3], [0.2, 0.3, 0.1]);
    fluid.add_block(DVec3::ZERO, DVec3::new(0.1, 0.1, 0.1), DVec3::ZERO).unwrap();
    let before = bits(fluid.state());
    let err = fluid.add_block(DVec3::splat(0.05), DVec3::splat(0.1), DVec3::ZERO).unwrap_err();
    assert!(matches!(err, Error::InvalidInput { ref arg, .. } if arg == "lower"), "{err}");
    assert_eq!(bits(fluid.state()), before);
    // Touching but not overlapping is fine.
    fluid.add_block(DVec3::new(0.1, 0.0, 0.0), DVec3::new(0.2, 0.1, 0.1), DVec3::ZERO).unwrap();
    let all_finite = |f: &Fluid| {
        f.state().positions().iter().chain(f.state().velocities()).all(|v| v.is_finite())
    };

    // A block dropped from 10 m into a tank: lands at ~14 m/s, stays finite and inside.
    let mut drop = Fluid::new(Settings::new(0.04)).unwrap();
    tank(&mut drop, [0.0; 3], [0.4, 10.6, 0.16]);
    drop.add_block(DVec3::new(0.1, 10.0, 0.0), DVec3::new(0.3, 10.4, 0.16), DVec3::ZERO).unwrap();
    // Mechanical energy per unit mass (J/kg): kinetic plus potential.
    let energy = |f: &Fluid| {
        let (x, v) = (f.state().positions(), f.state().velocities());
        let sum: f64 = x.iter().zip(v).map(|(x, v)| 0.5 * v.length_squared() + 9.81 * x.y).sum();
        sum / x.len() as f64
    };
    let e0 = energy(&drop);
    let (mut vmax, mut gain): (f64, f64) = (0.0, f64::NEG_INFINITY);
    for _ in 0..100 {
        drop.step(1.0 / 60.0, 1).unwrap();
        let v = drop.state().velocities().iter().map(|v| v.length()).fold(0.0, f64::max);
        vmax = vmax.max(v);
        gain = gain.max(energy(&drop) - e0);
    }
    assert!(all_finite(&drop));
    // Lands at 14 m/s; the impact throws a few particles up faster (measured: 27 m/s at
    // most, a splash sheet), but the fluid's energy never grows (measured: never above its
    // start, to 1e-4 J/kg of 100 J/kg; after the impact it has lost most of it).
    eprintln!(
        "drop: fastest {vmax} m/s, largest energy gain {gain} J/kg, finally {}",
        energy(&drop) - e0
    );
    assert!(vmax > 13.0 && vmax < 50.0, "{vmax}");
    assert!(gain < 1e-3 * e0, "{gain}");
    assert!(energy(&drop) - e0 < -0.5 * e0);
    let inside =
        |p: &DVec3| p.cmpge(DVec3::ZERO).all() && p.cmple(DVec3::new(0.4, 10.6, 0.16)).all();
    assert!(drop.state().positions().iter().all(inside));
}
