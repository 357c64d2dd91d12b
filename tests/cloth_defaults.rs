//! The defaults (issue #21): the default material is cotton-like, and hung from two corners
//! with the default step options (3% strain limit) it stretches by 3% at most; strain limiting
//! is what holds it.

use glam::DVec3;
use kinema::cloth::{Cloth, Collider, Elasticity, Material, Mesh, SolveOptions, Triangulation};
use kinema::geometry::{Plane, Shape};
use kinema::ode::Method;

const G: DVec3 = DVec3::new(0.0, -9.81, 0.0);

/// The largest edge strain `l/L - 1` of an `n` x `n` grid of 1 m (rest spacing `1/(n-1)`;
/// the alternating triangulation's diagonals `√2` times that).
fn max_edge_strain(cloth: &Cloth, n: usize) -> f64 {
    let x = cloth.positions();
    let h = 1.0 / (n - 1) as f64;
    let mut worst: f64 = 0.0;
    for t in cloth.triangles() {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            let diagonal = a % n != b % n && a / n != b / n;
            let rest = if diagonal { h * 2f64.sqrt() } else { h };
            worst = worst.max((x[a] - x[b]).length() / rest - 1.0);
        }
    }
    worst
}

/// An `n`² sheet of the default material, pinned at two corners, after 2 s of hanging at
/// dt = 1/60 with `options`: its largest edge strain.
fn hang(n: usize, options: SolveOptions) -> f64 {
    let mesh = Mesh::grid(n, n, 1.0, 1.0, Triangulation::Alternating).unwrap();
    let mut cloth = Cloth::new(mesh, Elasticity::BaraffWitkin, Material::default(), G).unwrap();
    cloth.pin(&[0, n - 1], None).unwrap();
    cloth.step(1.0 / 60.0, 120, Method::ImplicitEuler, options).unwrap();
    assert!(cloth.stats().converged);
    max_edge_strain(&cloth, n)
}

#[test]
fn the_default_material_is_cotton_like() {
    let m = Material::default();
    assert_eq!(
        [m.density, m.stretch, m.shear, m.bend, m.damping, m.air_damping],
        [1.0, 1e4, 1e3, 1e-3, 0.1, 0.0]
    );
    assert_eq!(SolveOptions::default().max_strain, 0.03);
}

#[test]
fn hanging_cloth_at_the_defaults_stretches_by_3_percent() {
    for n in [32, 64] {
        let limited = hang(n, SolveOptions::default());
        let free = hang(n, SolveOptions { max_strain: f64::INFINITY, ..SolveOptions::default() });
        println!(
            "{n}²: largest edge strain {limited:.4} at the defaults, {free:.4} without the limit"
        );
        assert!(limited <= 0.03 + 2e-3, "{n}²: {limited}");
        assert!(free > limited + 5e-3, "{n}²: the material alone holds it: {free}");
    }
}

/// Step subdivision measures a step's change of the stretch ratios on the positions it would
/// commit, after the strain limit: at the pinned corners of a 64² sheet swinging at the 3 %
/// limit the unlimited solve overshoots the limit by more than `max_strain_change` every step,
/// which halved every step from 0.5 s on when the change was measured before the limit (the
/// `bench/bench_cloth.py` scene: 2.00 substeps a step then, 1.67 now).
#[test]
fn a_sheet_swinging_at_the_strain_limit_is_not_halved_every_step() {
    let n = 64;
    let mesh = Mesh::grid(n, n, 1.0, 1.0, Triangulation::Alternating).unwrap();
    let mut cloth = Cloth::new(mesh, Elasticity::BaraffWitkin, Material::default(), G).unwrap();
    cloth.pin(&[0, n - 1], None).unwrap();
    let options = SolveOptions::default();
    cloth.step(1.0 / 60.0, 30, Method::ImplicitEuler, options).unwrap();
    let mut whole = 0;
    for _ in 0..6 {
        cloth.step(1.0 / 60.0, 1, Method::ImplicitEuler, options).unwrap();
        whole += usize::from(cloth.stats().substeps == 1);
    }
    assert!(max_edge_strain(&cloth, n) > 0.029, "not at the limit");
    assert!(whole >= 2, "{whole} of 6 steps taken whole");
}

#[test]
fn strain_limit_must_be_positive() {
    let mesh = Mesh::grid(3, 3, 1.0, 1.0, Triangulation::Alternating).unwrap();
    let mut cloth = Cloth::new(mesh, Elasticity::BaraffWitkin, Material::default(), G).unwrap();
    let before = cloth.positions().to_vec();
    for bad in [0.0, -1.0, f64::NAN] {
        let options = SolveOptions { max_strain: bad, ..SolveOptions::default() };
        let e = cloth.step(1.0 / 60.0, 1, Method::ImplicitEuler, options).unwrap_err();
        assert!(e.to_string().contains("max_strain"), "{e}");
    }
    assert_eq!(cloth.positions(), &before[..]);
}

/// The substeps of a step of `dt` of a 9² sheet of 1 m of the default material: lying on the
/// ground at its contact distance with its centre vertex `depth` m below the ground, or, with
/// `depth` `None`, flat and pinned at two corners.
fn substeps(depth: Option<f64>, dt: f64) -> usize {
    let n = 9;
    let mesh = Mesh::grid(n, n, 1.0, 1.0, Triangulation::Alternating).unwrap();
    let mut cloth = Cloth::new(mesh, Elasticity::BaraffWitkin, Material::default(), G).unwrap();
    if let Some(depth) = depth {
        let ground = Shape::Plane(Plane { point: DVec3::ZERO, normal: DVec3::Y });
        let ground = Collider { shape: ground, velocity: DVec3::ZERO, friction: 0.5 };
        cloth.add_collider(ground).unwrap();
        let mut x: Vec<DVec3> =
            cloth.positions().iter().map(|p| *p + DVec3::Y * cloth.thickness()).collect();
        x[n * n / 2].y = -depth;
        cloth.set_state(&x, &vec![DVec3::ZERO; x.len()]).unwrap();
    } else {
        cloth.pin(&[0, n - 1], None).unwrap();
    }
    cloth.step(dt, 1, Method::ImplicitEuler, SolveOptions::default()).unwrap();
    cloth.stats().substeps
}

/// Step subdivision halves a step whose change of the stretch ratios shrinks with the step, and
/// not one whose change is a jump: a vertex 5 cm below the ground is lifted out by the contact's
/// position correction within one substep however short (its triangles' stretch changes by
/// about 10 % at once), so halving cannot bring the change under `max_strain_change`. Until
/// session 23 that step was halved to `h/32` regardless; now the first half of the refused step
/// is taken, as it changes the shape nearly as much as the whole step. A sheet hanging from
/// two corners, released flat, at `dt = 0.1 s` (its fall changes the stretch smoothly) is
/// halved as before. Measured with the same scenes from Python: main at 1379751 (before this
/// rule) took 6 and 3 substeps, this branch 2 and 3; the first assertion fails on the former.
#[test]
fn a_jump_is_not_halved_but_a_large_step_is() {
    let jump = substeps(Some(0.05), 1.0 / 60.0);
    let smooth = substeps(None, 0.1);
    println!("substeps: lifting a vertex out {jump}, a hanging sheet's first 0.1 s {smooth}");
    assert!(jump <= 3, "a jump halved to {jump} substeps");
    assert!(smooth >= 3, "a large step taken in {smooth} substeps");
}
