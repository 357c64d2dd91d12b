//! Why the DFSPH solves are relaxed (`ω = 0.5`, [`super::dfsph::RELAXATION`]): the Jacobi
//! iteration `κ ← κ + ω α (r₀/dt² − A κ)` converges only if `ω λ_max(α A) < 2`, and on the
//! column at rest the largest eigenvalue of `α A` (`α_i = 1/A_ii`, Bender & Koschier 2017,
//! eq. 8) is measured here above 2 (2.70): the paper's `ω = 1` diverges there.
//! SPlisHSPlasH (2.x, `TimeStepDFSPH::pressureSolveIteration`)
//! also relaxes by 0.5 and projects on `κ ≥ 0`.

use super::dfsph::{Solve, RELAXATION};
use super::*;
use crate::fluid::{Fluid, Settings, Wall};

/// The column of `tests/fluid.rs` (0.2 × 0.4 m, slab of 4, `s` = 2 cm, in a tank of its
/// footprint) and a solver with its neighbours, densities and factors at rest.
fn column() -> (Fluid, Solver) {
    let (s, w, h, d) = (0.02, 0.2, 0.4, 0.08);
    let mut fluid = Fluid::new(Settings::new(s)).unwrap();
    let tank = Wall::Box { lower: DVec3::ZERO, upper: DVec3::new(w, 0.6, d) };
    fluid.add_wall(tank).unwrap();
    fluid.add_block(DVec3::ZERO, DVec3::new(w, h, d), DVec3::ZERO).unwrap();
    let solver = at_rest(&fluid);
    (fluid, solver)
}

/// A solver of `fluid` at rest with its neighbours, densities and factors.
fn at_rest(fluid: &Fluid) -> Solver {
    let mut solver = Solver::new(fluid.model());
    let n = fluid.state().len();
    solver.points.clone_from(&fluid.state().positions);
    solver.v = vec![DVec3::ZERO; n];
    solver.emit(fluid.model(), 0.0).unwrap();
    solver.search(fluid.model(), 0.0);
    solver.densities(fluid.model(), true);
    solver
}

/// `α A κ`: the change of the predicted density of the density solve that the pressures
/// `κ` cause over a substep `dt`, `-(r(κ) - r(0)) α / dt²`.
fn alpha_a(model: &Model, solver: &mut Solver, kappa: &[f64], dt: f64, out: &mut Vec<f64>) {
    let n = kappa.len();
    solver.v.iter_mut().for_each(|v| *v = DVec3::ZERO);
    solver.residuals(model, dt, Solve::Density);
    let r0 = solver.residual.clone();
    solver.k.copy_from_slice(kappa);
    solver.apply(model, dt);
    solver.residuals(model, dt, Solve::Density);
    out.clear();
    out.extend((0..n).map(|i| -(solver.residual[i] - r0[i]) * solver.alpha[i] / (dt * dt)));
}

/// The largest eigenvalue of `α A` by the power iteration (`A` is symmetric positive
/// semi-definite and `α` positive, so `α A` has real eigenvalues `≥ 0`), from alternating
/// pressures.
fn largest_eigenvalue(fluid: &Fluid, solver: &mut Solver) -> f64 {
    let model = fluid.model();
    let n = fluid.state().len();
    let mut x: Vec<f64> = (0..n).map(|i| if i % 2 == 0 { 1.0 } else { -0.7 }).collect();
    let mut y = Vec::new();
    let mut lambda = 0.0;
    for _ in 0..300 {
        let norm = x.iter().map(|v| v * v).sum::<f64>().sqrt();
        x.iter_mut().for_each(|v| *v /= norm);
        alpha_a(model, solver, &x, 1e-3, &mut y);
        lambda = x.iter().zip(&y).map(|(a, b)| a * b).sum::<f64>();
        std::mem::swap(&mut x, &mut y);
    }
    lambda
}

/// The diagonal of `α A` is 1 (the factor is the inverse diagonal), and the largest
/// eigenvalue lies between 2 and 4: `ω = 1` diverges, `ω = 0.5` converges.
#[test]
fn relaxation_is_below_the_jacobi_limit_of_the_column() {
    let (fluid, mut solver) = column();
    let n = fluid.state().len();
    let mut unit = vec![0.0; n];
    let i = n / 2;
    unit[i] = 1.0;
    let mut y = Vec::new();
    alpha_a(fluid.model(), &mut solver, &unit, 1e-3, &mut y);
    assert!((y[i] - 1.0).abs() < 1e-9, "diagonal {}", y[i]);
    let lambda = largest_eigenvalue(&fluid, &mut solver);
    eprintln!("largest eigenvalue of alpha A on the column: {lambda}");
    assert!(lambda > 2.0 && lambda < 4.0, "{lambda}");
    assert!(RELAXATION * lambda < 2.0, "ω λ_max = {}", RELAXATION * lambda);
}

/// Why the viscosity is implicit (Weiler et al. 2018): on the column at rest, for a
/// honey-like `ν` = 0.05 m²/s at the default 5 ms substep, the largest eigenvalue of
/// `-dt ν ∇²` (the paper's Laplacian with the walls' term) is measured above 2, so forward
/// Euler `v ← v + dt ν ∇²v` multiplies that mode by `|1 - λ| > 1` every substep and
/// diverges (shown: 30 such substeps grow a velocity field a thousandfold), while the
/// implicit system `A = I - dt ν ∇²` has every eigenvalue `≥ 1`.
#[test]
fn explicit_viscosity_diverges_on_the_honey_column() {
    let (fluid, solver) = column();
    let model = fluid.model();
    let (dt, nu) = (0.005, 0.05);
    let system = solver.viscosity_system(model, dt * nu);
    let n = fluid.state().len();
    let start: Vec<DVec3> =
        (0..n).map(|i| DVec3::new(1.0, -0.7, 0.3) * if i % 2 == 0 { 1.0 } else { -0.8 }).collect();
    let norm = |x: &[DVec3]| x.iter().map(|v| v.length_squared()).sum::<f64>().sqrt();
    // Power iteration on A (symmetric positive definite).
    let (mut x, mut y) = (start.clone(), vec![DVec3::ZERO; n]);
    let mut lambda = 0.0;
    for _ in 0..300 {
        let s = norm(&x);
        x.iter_mut().for_each(|v| *v /= s);
        system.product(&x, &mut y);
        lambda = x.iter().zip(&y).map(|(a, b)| a.dot(*b)).sum::<f64>();
        std::mem::swap(&mut x, &mut y);
    }
    let explicit = lambda - 1.0;
    // Forward Euler: v ← v + dt ν ∇²v = (2I - A) v.
    let mut v = start.clone();
    for _ in 0..30 {
        system.product(&v, &mut y);
        v.iter_mut().zip(&y).for_each(|(v, a)| *v = *v * 2.0 - *a);
    }
    let growth = norm(&v) / norm(&start);
    eprintln!("largest eigenvalue of -dt nu Laplacian: {explicit}; forward Euler growth {growth}");
    assert!(explicit > 2.0, "{explicit}");
    assert!(growth > 1e3, "{growth}");
}

/// The paper's Laplacian (eq. 11, `2(d + 2)` = 10) of the shear `v = (y², 0, 0)`
/// (`∇²v = (2, 0, 0)`) at the centre of a block of the lattice: its value is the lattice sum
/// `10 Σ_k V x_k² y_k² (-W'(r_k))/(r_k (r_k² + 0.01 h²))` (computed here apart, 1.40 for the
/// cubic spline: 70 % of the continuum's 2), and the same shear along a diagonal of the
/// lattice, `e₁ (x·e₂)²`, gets 2.86 (143 %): the sum at `h = 2 s` on a cubic lattice is
/// anisotropic (docs/fluid.md, "Implicit viscosity").
#[test]
fn laplacian_of_a_shear_on_the_lattice() {
    let s = 0.02;
    let mut fluid = Fluid::new(Settings::new(s)).unwrap();
    fluid.add_block(DVec3::ZERO, DVec3::splat(12.0 * s), DVec3::ZERO).unwrap();
    let solver = at_rest(&fluid);
    let n = fluid.state().len();
    let model = fluid.model();
    let system = solver.viscosity_system(model, 1.0);
    let h = model.support;
    let mut lattice = 0.0;
    for k in -2i32..=2 {
        for j in -2i32..=2 {
            for i in -2i32..=2 {
                let x = DVec3::new(f64::from(i), f64::from(j), f64::from(k)) * s;
                let r = x.length();
                if r > 0.0 {
                    let slope = model.settings.kernel.derivative(r, h);
                    lattice -= x.x * x.x * x.y * x.y * slope / (r * (r * r + 0.01 * h * h));
                }
            }
        }
    }
    let lattice = 10.0 * model.volume * lattice;
    let centre = DVec3::splat(6.5 * s);
    let i = (0..n).find(|&i| (solver.points[i] - centre).length() < 1e-9).unwrap();
    let mut av = vec![DVec3::ZERO; n];
    let axis: Vec<DVec3> = solver.points[..n].iter().map(|p| DVec3::X * (p.y * p.y)).collect();
    system.product(&axis, &mut av);
    let along = axis[i] - av[i];
    let e1 = DVec3::new(1.0, 1.0, 0.0) / 2f64.sqrt();
    let e2 = DVec3::new(1.0, -1.0, 0.0) / 2f64.sqrt();
    let diagonal: Vec<DVec3> =
        solver.points[..n].iter().map(|p| e1 * (p.dot(e2) * p.dot(e2))).collect();
    system.product(&diagonal, &mut av);
    let across = (diagonal[i] - av[i]).dot(e1);
    eprintln!("shear along an axis {along} (lattice sum {lattice}), along a diagonal {across}");
    assert!((along.x - lattice).abs() < 1e-9 && along.y.abs() + along.z.abs() < 1e-9);
    assert!((along.x / 2.0 - 0.698).abs() < 0.005, "{along}");
    assert!((across / 2.0 - 1.432).abs() < 0.005, "{across}");
}

/// Why the substep is limited by gravity ([`super::GRAVITY_STEP`]): on the lattice at
/// `h = 2 s` the discrete divergence `Σ_j V (v_i − v_j)·∇W_ij` couples a layer only to the
/// layers just above and below (the next ones lie at `2 s = h`), so it is a centred
/// difference and cannot see the layers moving alternately: every other layer may fall
/// freely while the solves report no error. The column at rest 25 particles deep at
/// `s` = 5 mm, one substep from the lattice with both solves converged far below their
/// defaults (1e-4 %), a substep of 2 ms: the even layers (the bottom one is layer 0) fall
/// at `g dt` within 10 % from layer 2 to 20 (measured 0.97–1.09 `g dt`), each odd layer up
/// to 9 at least 0.1 `g dt` slower than both its neighbours (−0.06, 0.35, 0.60, 0.74,
/// 0.83 `g dt`), and the floor holds layers 0 and 1 (0.49 and −0.06 `g dt`). Only the compression that the displacement causes at second order
/// pushes back, a substep later; it stays small against the spacing only while `g dt² / s`
/// does.
#[test]
fn converged_solves_let_every_other_layer_fall() {
    let s = 0.005;
    let mut settings = Settings::new(s);
    settings.pressure = Pressure::Dfsph {
        density_tolerance: 1e-4,
        divergence_tolerance: 1e-4,
        max_iterations: 5000,
    };
    let mut fluid = Fluid::new(settings).unwrap();
    let tank = Wall::Box { lower: DVec3::ZERO, upper: DVec3::new(8.0 * s, 37.5 * s, 4.0 * s) };
    fluid.add_wall(tank).unwrap();
    fluid.add_block(DVec3::ZERO, DVec3::new(8.0 * s, 25.0 * s, 4.0 * s), DVec3::ZERO).unwrap();
    let layer: Vec<usize> =
        fluid.state().positions().iter().map(|p| (p.y / s).floor() as usize).collect();
    let dt = 0.002;
    fluid.step(dt, 1).unwrap();
    assert_eq!(fluid.stats.substeps, 1);
    assert!(fluid.stats.density_error < 1e-4, "not converged: {}", fluid.stats.density_error);
    let mut mean = [(0.0, 0.0); 25];
    for (l, v) in layer.iter().zip(fluid.state().velocities()) {
        mean[*l].0 += v.y;
        mean[*l].1 += 1.0;
    }
    let fall: Vec<f64> = mean.iter().map(|(v, n)| -v / n / (9.81 * dt)).collect();
    eprintln!("fall of each layer / (g dt): {fall:.3?}");
    for k in (2..=20).step_by(2) {
        assert!((fall[k] - 1.0).abs() < 0.1, "layer {k}: {}", fall[k]);
    }
    for k in (1..=9).step_by(2) {
        assert!(fall[k] < fall[k - 1].min(fall[k + 1]) - 0.1, "layer {k}: {}", fall[k]);
    }
    assert!(fall[0] < 0.8 && fall[1] < 0.3, "{} {}", fall[0], fall[1]);
}
