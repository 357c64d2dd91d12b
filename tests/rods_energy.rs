//! The energies of discrete elastic rods (`kinema::rods`): analytic gradients and Hessians
//! against central differences on random rods (curved rest shape, anisotropic section,
//! twisted), invariance under rigid motions, and a straight untwisted rod at rest.

use glam::{DMat3, DQuat, DVec3};
use kinema::rods::{elastic, elastic_energy, Band, Frames, Material, Model, Rod, Settings, State};
use proptest::prelude::*;

const MATERIAL: Material =
    Material { youngs_modulus: 2e5, shear_modulus: 7e4, density: 1000.0, radius: [0.06, 0.035] };

/// Deterministic pseudo-random numbers in `[-0.5, 0.5)`.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    }
    fn vec(&mut self) -> DVec3 {
        DVec3::new(self.next(), self.next(), self.next())
    }
}

/// A random curved rest shape of `n` edges (a wobbly helix), and a configuration near it:
/// the same points moved, stretched by 15 % (every edge in tension, where the stretching
/// Hessian is exact), and twisted.
struct Case {
    model: Model,
    /// Frames of the configuration, the base of the differences.
    base_tangents: Vec<DVec3>,
    base_reference: Vec<DVec3>,
    base_twist: Vec<f64>,
    q: Vec<f64>,
}

fn case(seed: u64, n: usize) -> Case {
    let mut rng = Rng(seed);
    let rest: Vec<DVec3> = (0..=n)
        .map(|i| {
            let s = i as f64 * 0.3;
            DVec3::new(0.4 * s.cos(), 0.15 * i as f64, 0.4 * s.sin()) + 0.03 * rng.vec()
        })
        .collect();
    let model = Model::new(&rest, MATERIAL, Settings::default()).unwrap();
    let state = State::new(&model);
    let x: Vec<DVec3> = rest.iter().map(|p| 1.15 * (*p + 0.02 * rng.vec())).collect();
    let theta: Vec<f64> = (0..n).map(|_| 2.0 * rng.next()).collect();
    // The configuration's frames, transported from the rest shape's.
    let rest_tangents: Vec<DVec3> = rest.windows(2).map(|w| (w[1] - w[0]).normalize()).collect();
    let mut frames = Frames::default();
    let rest_twist = vec![0.0; n - 1];
    let reference: Vec<DVec3> = state_reference(&model, &state);
    assert!(frames.update(&x, &theta, &rest_tangents, &reference, &rest_twist, 0.0));
    Case {
        model,
        base_tangents: frames.tangents.clone(),
        base_reference: frames.reference.clone(),
        base_twist: frames.reference_twist.clone(),
        q: pack(&x, &theta),
    }
}

/// The reference directors of a fresh state (the rest shape's), read through the frames of
/// the rod's material directors at zero twist.
fn state_reference(model: &Model, state: &State) -> Vec<DVec3> {
    let mut rod =
        Rod::new(model.rest_positions(), *model.material(), Settings::default(), None).unwrap();
    assert_eq!(rod.state().positions(), state.positions());
    rod.material_frames().iter().map(|f| f[1]).collect()
}

fn pack(x: &[DVec3], theta: &[f64]) -> Vec<f64> {
    let mut q = Vec::new();
    for (i, p) in x.iter().enumerate() {
        q.extend(p.to_array());
        if let Some(t) = theta.get(i) {
            q.push(*t);
        }
    }
    q
}

/// Energy and gradient at `q`, the frames transported from the case's base; with `band`,
/// the Hessian too.
fn eval(c: &Case, q: &[f64], band: Option<&mut Band>) -> (f64, Vec<f64>) {
    let n = c.model.edges();
    let x: Vec<DVec3> = (0..=n).map(|i| DVec3::from_slice(&q[4 * i..])).collect();
    let theta: Vec<f64> = (0..n).map(|j| q[4 * j + 3]).collect();
    let mut frames = Frames::default();
    assert!(frames.update(&x, &theta, &c.base_tangents, &c.base_reference, &c.base_twist, 0.0));
    let mut grad = vec![0.0; q.len()];
    let e = elastic(&c.model, &frames, &theta, &mut grad, band);
    (e, grad)
}

/// The largest difference between analytic and central-difference derivatives, relative
/// to the largest analytic entry: the gradient against first differences of the energy,
/// the Hessian against its second differences (the frames transported from the base
/// configuration, as within a step: the analytic Hessian is that of this energy, which is
/// the symmetric part of the derivative of the gradient field, not the derivative itself,
/// because transporting frames along two paths differs by a holonomy).
fn check_derivatives(seed: u64, n: usize) -> (f64, f64) {
    let c = case(seed, n);
    let mut band = Band::default();
    band.reset(c.q.len(), 10);
    let (_, grad) = eval(&c, &c.q, Some(&mut band));
    let energy = |k: usize, a: f64, r: usize, b: f64| {
        let mut q = c.q.clone();
        q[k] += a;
        q[r] += b;
        eval(&c, &q, None).0
    };
    let (h, hh) = (1e-6, 1e-4);
    let (mut gerr, mut herr, mut gmax, mut hmax) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for (k, g) in grad.iter().enumerate() {
        let fd = (energy(k, h, k, 0.0) - energy(k, -h, k, 0.0)) / (2.0 * h);
        gerr = gerr.max((fd - g).abs());
        gmax = gmax.max(g.abs());
        for r in 0..=k {
            let fd = (energy(k, hh, r, hh) - energy(k, hh, r, -hh) - energy(k, -hh, r, hh)
                + energy(k, -hh, r, -hh))
                / (4.0 * hh * hh);
            let an = if k - r <= 10 { band.get(k, r) } else { 0.0 };
            herr = herr.max((fd - an).abs());
            hmax = hmax.max(an.abs());
        }
    }
    (gerr / gmax, herr / hmax)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Gradient and Hessian of stretching + bending + twisting agree with central
    /// differences of the energy to 1e-6 of their largest entry.
    #[test]
    fn gradient_and_hessian_match_central_differences(seed in any::<u64>(), n in 2usize..9) {
        let (g, h) = check_derivatives(seed, n);
        prop_assert!(g < 1e-6, "gradient relative error {g:e}");
        prop_assert!(h < 1e-6, "Hessian relative error {h:e}");
    }

    /// The energy alone (`elastic_energy`, what the solver's line search and predictor
    /// evaluate) is bitwise the value of `elastic`, so skipping the derivatives changes no
    /// step's result.
    #[test]
    fn the_energy_alone_is_bitwise_the_value_with_derivatives(seed in any::<u64>(), n in 2usize..9) {
        let c = case(seed, n);
        let x: Vec<DVec3> = (0..=n).map(|i| DVec3::from_slice(&c.q[4 * i..])).collect();
        let theta: Vec<f64> = (0..n).map(|j| c.q[4 * j + 3]).collect();
        let mut frames = Frames::default();
        prop_assert!(frames.update(&x, &theta, &c.base_tangents, &c.base_reference, &c.base_twist, 0.0));
        let alone = elastic_energy(&c.model, &frames, &theta);
        prop_assert_eq!(alone.to_bits(), eval(&c, &c.q, None).0.to_bits());
        prop_assert!(alone > 0.0);
    }
}

/// Moving the whole rod rigidly (its frames moved with it) changes no energy, and turns
/// every force by the rotation.
#[test]
fn energy_is_invariant_under_rigid_motions() {
    let c = case(7, 8);
    let (e0, g0) = eval(&c, &c.q, None);
    let rot = DQuat::from_axis_angle(DVec3::new(1.0, -2.0, 0.5).normalize(), 1.1);
    let shift = DVec3::new(3.0, -1.0, 2.0);
    let n = c.model.edges();
    let mut moved = Case {
        model: c.model.clone(),
        base_tangents: c.base_tangents.iter().map(|t| rot * *t).collect(),
        base_reference: c.base_reference.iter().map(|d| rot * *d).collect(),
        base_twist: c.base_twist.clone(),
        q: c.q.clone(),
    };
    for i in 0..=n {
        let p = rot * DVec3::from_slice(&c.q[4 * i..]) + shift;
        moved.q[4 * i..4 * i + 3].copy_from_slice(&p.to_array());
    }
    let (e1, g1) = eval(&moved, &moved.q, None);
    assert!((e1 - e0).abs() < 1e-12 * e0, "{e0} {e1}");
    let r = DMat3::from_quat(rot);
    for i in 0..=n {
        let (a, b) = (DVec3::from_slice(&g0[4 * i..]), DVec3::from_slice(&g1[4 * i..]));
        assert!((r * a - b).length() < 1e-9 * (1.0 + a.length()), "{i}: {a} {b}");
    }
    for j in 0..n {
        assert!((g0[4 * j + 3] - g1[4 * j + 3]).abs() < 1e-9, "twist torque {j}");
    }
}

/// A straight untwisted rod has zero energy and zero elastic force and torque, and stays
/// where it is (without gravity) for a hundred implicit steps.
#[test]
fn straight_untwisted_rod_is_at_rest() {
    let points: Vec<DVec3> = (0..12).map(|i| DVec3::new(0.1, 0.2, -0.3) * i as f64).collect();
    let settings = Settings { gravity: DVec3::ZERO, ..Settings::default() };
    let mut rod = Rod::new(&points, MATERIAL, settings, None).unwrap();
    assert!(rod.energy() < 1e-25, "{}", rod.energy());
    let (mut f, mut t) = (Vec::new(), Vec::new());
    let model = rod.model().clone();
    kinema::rods::Solver::new(&model).elastic_forces(&model, rod.state(), &mut f, &mut t);
    assert!(f.iter().all(|v| v.length() < 1e-12), "{f:?}");
    assert!(t.iter().all(|v| v.abs() < 1e-12), "{t:?}");
    rod.step(1.0 / 60.0, 100).unwrap();
    for (p, q) in rod.state().positions().iter().zip(&points) {
        assert!((*p - *q).length() < 1e-12, "{p} {q}");
    }
}
