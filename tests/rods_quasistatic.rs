//! The quasi-static twist (`Settings::quasistatic_twist`; Bergou et al. 2008, sec. 6): the
//! twists have no inertia, so each implicit step leaves them minimising the energy given the
//! centreline. A straight isotropic rod clamped at both ends, one clamp turned by `φ` in a
//! single step, is twisted uniformly at once (the analytic minimiser: the twist angle grows
//! linearly from one clamped edge to the other), where the dynamic twist is still a
//! travelling torsion wave; the dynamic twist relaxes to the same distribution.

use glam::{DQuat, DVec3};
use kinema::rods::{End, Integrator, Material, Rod, Settings};

const MATERIAL: Material =
    Material { youngs_modulus: 1e6, shear_modulus: 1e6 / 3.0, density: 1000.0, radius: [0.01; 2] };

/// A straight rod along +x of `n` edges over 1 m, clamped at both ends, without gravity,
/// its far clamp turned by `phi` (rad) by the end of the next step.
fn twisted(n: usize, phi: f64, quasistatic_twist: bool) -> Rod {
    let points: Vec<DVec3> = (0..=n).map(|i| DVec3::new(i as f64 / n as f64, 0.0, 0.0)).collect();
    let settings = Settings { gravity: DVec3::ZERO, quasistatic_twist, ..Settings::default() };
    let mut rod = Rod::new(&points, MATERIAL, settings, None).unwrap();
    rod.model_mut().clamp(End::First);
    rod.model_mut().clamp(End::Last);
    rod.move_clamp(End::Last, DQuat::from_rotation_x(phi), DVec3::ZERO).unwrap();
    rod
}

/// The largest distance of the twists from the uniform distribution `θ_j = φ j / (n − 1)`
/// (edge 0 and edge `n − 1` clamped at 0 and `φ`), in rad.
fn from_uniform(rod: &Rod, phi: f64) -> f64 {
    let t = rod.state().twists();
    let n = t.len();
    t.iter()
        .enumerate()
        .map(|(j, &a)| (a - phi * j as f64 / (n - 1) as f64).abs())
        .fold(0.0, f64::max)
}

/// One step of 1/60 s: the quasi-static twist is uniform to 1e-9 rad and the centreline
/// straight; the dynamic twist is off by more than 0.05 rad (the torsion wave, speed
/// √(G/ρ) = 18 m/s, has not settled), and after 2 s of implicit steps has relaxed to the
/// uniform twist within 1e-6 rad.
#[test]
fn the_quasistatic_twist_is_uniform_between_turned_clamps_at_once() {
    let (n, phi) = (20, 1.0);
    let mut fast = twisted(n, phi, true);
    fast.step(1.0 / 60.0, 1).unwrap();
    let mut slow = twisted(n, phi, false);
    slow.step(1.0 / 60.0, 1).unwrap();
    let (q, d) = (from_uniform(&fast, phi), from_uniform(&slow, phi));
    println!("after one step: quasi-static {q:e} rad, dynamic {d:e} rad from uniform");
    assert!(q < 1e-9, "{q:e}");
    assert!(d > 0.05, "{d:e}");
    let off_axis = fast.state().positions().iter().map(|p| p.y.hypot(p.z)).fold(0.0, f64::max);
    assert!(off_axis < 1e-12, "{off_axis:e}");
    slow.step(1.0 / 60.0, 120).unwrap();
    let d = from_uniform(&slow, phi);
    println!("dynamic after 2 s: {d:e} rad");
    assert!(d < 1e-6, "{d:e}");
}

/// A stiff hair (E = 1 GPa, r = 50 µm, 10 cm in 16 edges, curved in its rest shape so that
/// bending and twist couple) clamped and dropped for 2 s at dt = 1/60 with the quasi-static
/// twist: it converges and hangs; symplectic Euler refuses the option (`quasistatic_twist`).
#[test]
fn quasistatic_twist_on_a_curved_hair_and_refused_without_implicit_euler() {
    let hair =
        Material { youngs_modulus: 1e9, shear_modulus: 4e8, density: 1300.0, radius: [5e-5; 2] };
    let points: Vec<DVec3> = (0..=16)
        .map(|i| {
            let s = i as f64 / 16.0;
            DVec3::new(0.1 * s, 0.0, 0.02 * (3.0 * s).sin())
        })
        .collect();
    let settings = Settings { quasistatic_twist: true, ..Settings::default() };
    let mut rod = Rod::new(&points, hair, settings, None).unwrap();
    rod.model_mut().clamp(End::First);
    rod.step(1.0 / 60.0, 120).unwrap();
    assert!(rod.state().positions()[16].y < -0.05);
    let explicit = Settings { integrator: Integrator::SymplecticEuler, ..settings };
    let err = Rod::new(&points, hair, explicit, None).unwrap_err();
    assert!(err.to_string().contains("quasistatic_twist"), "{err}");
}
