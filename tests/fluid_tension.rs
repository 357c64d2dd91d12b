//! Surface tension (Akinci, Akinci & Teschner 2013): a cube of fluid without gravity rounds
//! towards a sphere; without surface tension it stays a cube.

use glam::DVec3;
use kinema::fluid::{Fluid, Settings};

/// The farthest particle's distance from the centroid over the radius of gyration: about
/// 1.55 for this lattice cube (corners), `sqrt(5/3)` = 1.29 for a filled ball.
fn corner_ratio(x: &[DVec3]) -> f64 {
    let c = x.iter().copied().sum::<DVec3>() / x.len() as f64;
    let gyration =
        (x.iter().map(|p| (*p - c).length_squared()).sum::<f64>() / x.len() as f64).sqrt();
    x.iter().map(|p| (*p - c).length()).fold(0.0, f64::max) / gyration
}

/// The corner ratio of an 8³ cube of fluid (spacing 2 cm, no gravity, no walls, surface
/// tension `gamma`) at the start and averaged over the frames from 0.5 s to 1.5 s (the drop
/// oscillates about its round shape).
fn cube_rounding(gamma: f64) -> (f64, f64) {
    let s = 0.02;
    let settings = Settings { gravity: DVec3::ZERO, surface_tension: gamma, ..Settings::new(s) };
    let mut fluid = Fluid::new(settings).unwrap();
    fluid.add_block(DVec3::ZERO, DVec3::splat(8.0 * s), DVec3::ZERO).unwrap();
    let before = corner_ratio(fluid.state().positions());
    fluid.step(1.0 / 60.0, 30).unwrap();
    let mut sum = 0.0;
    for _ in 0..60 {
        fluid.step(1.0 / 60.0, 1).unwrap();
        sum += corner_ratio(fluid.state().positions());
    }
    (before, sum / 60.0)
}

/// Measured (corner ratio, mean over 0.5-1.5 s): 1.528 at the start and without surface
/// tension (a lattice cube at rest stays one), 1.494 at `γ` = 1, 1.422 at 2, 1.237 at 5
/// (a ball of particles: about 1.25).
#[test]
fn cube_rounds_with_surface_tension_only() {
    let (before, off) = cube_rounding(0.0);
    assert!((before - 1.528).abs() < 1e-3, "{before}");
    assert!((off - before).abs() < 1e-3, "without surface tension: {off}");
    let (_, weak) = cube_rounding(1.0);
    let (_, strong) = cube_rounding(5.0);
    eprintln!("corner ratio: {before} cube, {weak} at gamma 1, {strong} at gamma 5");
    assert!(weak < before - 0.01, "gamma 1: {weak}");
    assert!(strong < 1.3 && strong < weak, "gamma 5: {strong}");
}

/// A negative or non-finite coefficient is refused, naming it.
#[test]
fn surface_tension_is_checked() {
    for bad in [-1.0, f64::NAN, f64::INFINITY] {
        let settings = Settings { surface_tension: bad, ..Settings::new(0.02) };
        match Fluid::new(settings) {
            Err(kinema::Error::InvalidInput { arg, .. }) => assert_eq!(arg, "surface_tension"),
            other => panic!("{bad}: {other:?}"),
        }
    }
}
