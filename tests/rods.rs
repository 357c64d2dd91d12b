//! Discrete elastic rods (`kinema::rods`) against beam theory: the cantilever's static tip
//! deflection (Euler–Bernoulli) under a tip load and under gravity, the observed order of
//! convergence in the vertex count, the first bending frequency of the clamped rod, and the
//! stability of stiff hair at dt = 1/60 (implicit Euler) against symplectic Euler.

use glam::DVec3;
use kinema::rods::{End, Integrator, Material, Rod, Settings};
use std::f64::consts::PI;

/// A horizontal cantilever along +x, `length` (m) from the clamp to the tip: `n + 1` edges
/// of `h = length / (n + ½)`, the first clamped. The clamp point (x = 0) is the middle of
/// the clamped edge: the curvature at vertex 1 is spread over its Voronoi region, which
/// reaches half an edge back, so the discrete beam bends from there (clamping at vertex 1
/// instead would make it half an edge longer: a first-order error, 3.8 % at 40 edges).
fn cantilever(n: usize, length: f64, material: Material, settings: Settings) -> Rod {
    let h = length / (n as f64 + 0.5);
    let points: Vec<DVec3> =
        (0..=n + 1).map(|i| DVec3::new((i as f64 - 0.5) * h, 0.0, 0.0)).collect();
    let mut rod = Rod::new(&points, material, settings, None).unwrap();
    rod.model_mut().clamp(End::First);
    rod
}

const SOFT: Material =
    Material { youngs_modulus: 1e6, shear_modulus: 4e5, density: 1000.0, radius: [0.01, 0.01] };

fn bending(m: &Material) -> f64 {
    m.youngs_modulus * PI * m.radius[0].powi(4) / 4.0
}

/// The tip's downward deflection (m) of a static cantilever of `n` edges, 1 m long, under
/// a tip force `force` (N) and gravity `g` (m/s²).
fn static_tip(n: usize, force: f64, g: f64) -> f64 {
    let settings = Settings { gravity: DVec3::new(0.0, -g, 0.0), ..Settings::default() };
    let mut rod = cantilever(n, 1.0, SOFT, settings);
    rod.state_mut().set_force(n + 1, DVec3::new(0.0, -force, 0.0)).unwrap();
    rod.solve_static().unwrap();
    -rod.state().positions()[n + 1].y
}

/// Tip load `F`: `δ = F L³ / (3 E I)` within 1 % (δ/L = 4e-3, so the geometric
/// nonlinearity is below 1e-5).
#[test]
fn cantilever_under_a_tip_load_matches_euler_bernoulli() {
    let f = 1e-4;
    let exact = f / (3.0 * bending(&SOFT));
    let got = static_tip(40, f, 0.0);
    println!("tip load: {got:e} m, Euler-Bernoulli {exact:e} m, error {:e}", got / exact - 1.0);
    assert!((got / exact - 1.0).abs() < 0.01);
}

/// Gravity `w = ρ A g`: `δ = w L⁴ / (8 E I)` within 1 % (δ/L = 1e-3).
#[test]
fn cantilever_under_gravity_matches_euler_bernoulli() {
    let g = 2e-4;
    let w = SOFT.density * PI * SOFT.radius[0].powi(2) * g;
    let exact = w / (8.0 * bending(&SOFT));
    let got = static_tip(40, 0.0, g);
    println!("gravity: {got:e} m, Euler-Bernoulli {exact:e} m, error {:e}", got / exact - 1.0);
    assert!((got / exact - 1.0).abs() < 0.01);
}

/// Doubling the vertex count of the cantilever under gravity: the error of the tip
/// deflection against Euler–Bernoulli falls with an observed order of at least 1.8 (the
/// lumped load and the Voronoi curvature are second-order accurate), at a load where the
/// geometric nonlinearity (~(δ/L)²) is far below the discretisation error.
#[test]
fn tip_deflection_converges_at_second_order() {
    let g = 2e-4;
    let w = SOFT.density * PI * SOFT.radius[0].powi(2) * g;
    let exact = w / (8.0 * bending(&SOFT));
    let errors: Vec<f64> =
        [5, 10, 20, 40].iter().map(|&n| (static_tip(n, 0.0, g) / exact - 1.0).abs()).collect();
    for k in 1..errors.len() {
        let order = (errors[k - 1] / errors[k]).log2();
        println!("n = {}: error {:e}, observed order {order:.3}", 5 << k, errors[k]);
        assert!(order >= 1.8, "{errors:?}");
    }
}

/// The clamped rod released from a small static deflection oscillates at the first
/// bending frequency `f1 = 1.875² / (2π) √(EI / (ρ A L⁴))` within 2 % (implicit Euler at
/// 400 steps per period, whose phase error is `(ωh)²/3` = 0.008 %; frequency from the times
/// of the tip's upward zero crossings over two periods).
#[test]
fn first_bending_frequency_matches_beam_theory() {
    let settings = Settings { gravity: DVec3::ZERO, ..Settings::default() };
    let n = 30;
    let mut rod = cantilever(n, 1.0, SOFT, settings);
    let rho_a = SOFT.density * PI * SOFT.radius[0].powi(2);
    let f1 = 1.875f64.powi(2) / (2.0 * PI) * (bending(&SOFT) / rho_a).sqrt();
    rod.state_mut().set_force(n + 1, DVec3::new(0.0, -1e-5, 0.0)).unwrap();
    rod.solve_static().unwrap();
    rod.state_mut().set_force(n + 1, DVec3::ZERO).unwrap();
    let dt = 1.0 / (400.0 * f1);
    let mut crossings = Vec::new();
    let mut last = rod.state().positions()[n + 1].y;
    while crossings.len() < 3 {
        rod.step(dt, 1).unwrap();
        let y = rod.state().positions()[n + 1].y;
        if last < 0.0 && y >= 0.0 {
            crossings.push(rod.state().time() - dt * y / (y - last));
        }
        last = y;
        assert!(rod.state().time() < 5.0 / f1, "no oscillation");
    }
    let f = 2.0 / (crossings[2] - crossings[0]);
    println!("first frequency {f} Hz, beam theory {f1} Hz, error {:e}", f / f1 - 1.0);
    assert!((f / f1 - 1.0).abs() < 0.02);
}

/// A stiff hair (E = 1 GPa, r = 50 µm, 10 cm in 16 segments), clamped horizontally and
/// dropped under gravity: implicit Euler at dt = 1/60 stays bounded (every vertex within
/// the hair's length of the root, edges within 0.1 % of their rest length) for 2 s;
/// symplectic Euler diverges at that step and at a step 1000 times shorter (an error
/// naming the step), and needs one near 1e-7 s: 1.7e5 times shorter.
#[test]
fn stiff_hair_is_stable_at_animation_steps_with_implicit_euler_only() {
    let hair =
        Material { youngs_modulus: 1e9, shear_modulus: 4e8, density: 1300.0, radius: [5e-5; 2] };
    let mut rod = cantilever(16, 0.1, hair, Settings::default());
    rod.step(1.0 / 60.0, 120).unwrap();
    let x = rod.state().positions();
    assert!(x.iter().all(|p| p.length() <= 0.1 + 1e-9), "{x:?}");
    for (w, l) in x.windows(2).zip(rod.model().rest_lengths()) {
        assert!(((w[1] - w[0]).length() / l - 1.0).abs() < 1e-3);
    }
    // It hangs down: the tip below the root by most of the length.
    assert!(x[17].y < -0.05, "{}", x[17].y);
    // Symplectic Euler is stable only below 2/ω_max; the stretching mode of an edge gives
    // ω_max ≈ 2 √(EA / (l m)) ≈ 9e6 rad/s here, a limit near 2.2e-7 s: it diverges at
    // 1/60 s and still at 1000 times less, and is bounded at 1e-7 s.
    let explicit = Settings { integrator: Integrator::SymplecticEuler, ..Settings::default() };
    for (dt, steps) in [(1.0 / 60.0, 120), (1.0 / 60_000.0, 3000)] {
        let mut rod = cantilever(16, 0.1, hair, explicit);
        let err = rod.step(dt, steps).unwrap_err();
        assert!(matches!(err, kinema::Error::Diverged { .. }), "{dt}: {err}");
    }
    let mut rod = cantilever(16, 0.1, hair, explicit);
    rod.step(1e-7, 20_000).unwrap();
    let x = rod.state().positions();
    assert!(x.iter().all(|p| p.length() <= 0.1 + 1e-9), "{x:?}");
}

/// Large loads and steps: a static solve straight into a large deflection (tip load
/// `F L²/(EI)` = 3, the tip drops by about 0.6 L), a heavy soft rod (`w L³/(EI)` = 4000)
/// settling in one static solve from horizontal to hanging, and implicit steps of 0.5 s of
/// a soft rod dropped from horizontal all converge. Full Newton steps (no line search)
/// cycle without converging on the heavy rod: its first step, from the linearised beam,
/// lands far beyond the hanging shape.
#[test]
fn large_loads_and_steps_converge_with_the_line_search() {
    let settings = Settings { gravity: DVec3::ZERO, ..Settings::default() };
    let mut rod = cantilever(40, 1.0, SOFT, settings);
    rod.state_mut().set_force(41, DVec3::new(0.0, -3.0 * bending(&SOFT), 0.0)).unwrap();
    rod.solve_static().unwrap();
    let tip = rod.state().positions()[41];
    assert!(tip.y < -0.55 && tip.y > -0.7, "{tip}");
    let heavy = Settings { gravity: DVec3::new(0.0, -100.0, 0.0), ..Settings::default() };
    let mut rod = cantilever(40, 1.0, SOFT, heavy);
    rod.solve_static().unwrap();
    let tip = rod.state().positions()[41];
    assert!(tip.x.abs() < 0.05 && tip.y < -1.0, "{tip}");
    let mut rod = cantilever(20, 1.0, SOFT, Settings::default());
    rod.step(0.5, 4).unwrap();
    assert!(rod.state().positions()[21].y < -0.8);
}

/// A steel cable (E = 200 GPa, G = 80 GPa, ρ = 7850 kg/m³, r = 5 mm, 2 m in 40 edges),
/// clamped horizontally and dropped under gravity: implicit Euler at dt = 1/60 stays bounded
/// (edges within 0.1 % of their rest length, every vertex within the cable's length of the
/// root) for 2 s and sags; symplectic Euler diverges at 1/60 s and at 1/60000 s
/// (the stretching mode `ω ≈ 2 √(E/ρ) / l ≈ 2e5 rad/s` limits it to about 1e-5 s) and is
/// bounded at 5e-6 s: explicit steps must be more than 1000 times shorter.
#[test]
fn a_steel_cable_is_stable_at_animation_steps_with_implicit_euler_only() {
    let steel =
        Material { youngs_modulus: 2e11, shear_modulus: 8e10, density: 7850.0, radius: [5e-3; 2] };
    let mut rod = cantilever(39, 2.0, steel, Settings::default());
    rod.step(1.0 / 60.0, 120).unwrap();
    let x = rod.state().positions();
    assert!(x.iter().all(|p| p.length() <= 2.0 + 1e-9), "{x:?}");
    for (w, l) in x.windows(2).zip(rod.model().rest_lengths()) {
        assert!(((w[1] - w[0]).length() / l - 1.0).abs() < 1e-3);
    }
    assert!(x[40].y < -0.05, "{}", x[40].y); // it sags (statically w L⁴/(8EI) = 0.12 m)
    let explicit = Settings { integrator: Integrator::SymplecticEuler, ..Settings::default() };
    for (dt, steps) in [(1.0 / 60.0, 120), (1.0 / 60_000.0, 3000)] {
        let mut rod = cantilever(39, 2.0, steel, explicit);
        let err = rod.step(dt, steps).unwrap_err();
        assert!(matches!(err, kinema::Error::Diverged { .. }), "{dt}: {err}");
    }
    let mut rod = cantilever(39, 2.0, steel, explicit);
    rod.step(5e-6, 10_000).unwrap();
    let x = rod.state().positions();
    assert!(x.iter().all(|p| p.length() <= 2.0 + 1e-6), "{x:?}");
    assert!(x[40].y < -1e-3, "{}", x[40].y);
}
