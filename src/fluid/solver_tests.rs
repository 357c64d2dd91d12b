//! Why the DFSPH solves are relaxed (`ω = 0.5`, [`super::RELAXATION`]): the Jacobi
//! iteration `κ ← κ + ω α (r₀/dt² − A κ)` converges only if `ω λ_max(α A) < 2`, and on the
//! column at rest the largest eigenvalue of `α A` (`α_i = 1/A_ii`, Bender & Koschier 2017,
//! eq. 8) is measured here above 2 (2.70): the paper's `ω = 1` diverges there.
//! SPlisHSPlasH (2.x, `TimeStepDFSPH::pressureSolveIteration`)
//! also relaxes by 0.5 and projects on `κ ≥ 0`.

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
    let mut solver = Solver::new(fluid.model());
    let n = fluid.state().len();
    solver.points.clone_from(&fluid.state().positions);
    solver.v = vec![DVec3::ZERO; n];
    solver.emit(fluid.model(), 0.0).unwrap();
    solver.search(fluid.model(), 0.0);
    solver.densities(fluid.model(), true);
    (fluid, solver)
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
