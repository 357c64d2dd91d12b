//! Tests of the PCG kernels: the substitutions against their definitions and a whole solve,
//! in the portable and the AVX builds, bit for bit.

use super::*;

/// A 5-vertex pattern with made-up blocks and its preconditioner (`ω = 1`, no filter).
fn system(elements: &[[usize; 3]]) -> (BlockMatrix, Preconditioner) {
    let mut m = BlockMatrix::from_elements(5, elements.iter().map(|e| &e[..]));
    for (k, b) in m.blocks.iter_mut().enumerate() {
        let f = k as f64;
        *b = DMat3::from_cols_array(&[4.0, 0.3, f, 0.1, 5.0 + f, 0.2, -f, 0.4, 6.0]) * 0.5;
    }
    let mut p = Preconditioner::default();
    let blocks = m.blocks.clone();
    p.update(&m, |i| (blocks[i].inverse(), blocks[i]));
    (m, p)
}

fn lanes(v: &[DVec3]) -> Vec<Lane> {
    v.iter().map(|&v| Lane::new(v)).collect()
}

/// The substitutions against their definitions, in both builds.
fn check_substitutions(elements: &[[usize; 3]]) {
    let (m, p) = system(elements);
    let z: Vec<DVec3> = (0..5).map(|i| DVec3::new(1.0, -2.0, 0.5) * (i as f64 + 1.0)).collect();
    let c0: Vec<DVec3> = (0..5).map(|i| DVec3::new(0.5, -1.0, i as f64)).collect();
    let (beta, kappa) = (0.7, 0.4);
    let y: Vec<DVec3> = (0..5).map(|i| z[i] + beta * c0[i]).collect();
    type Swept = (Vec<Lane>, Vec<Lane>, Vec<Lane>, Vec<Lane>, f64);
    fn sweeps<L: Arith>(
        l: L,
        m: &BlockMatrix,
        p: &Preconditioner,
        z: &[DVec3],
        c0: &[DVec3],
        y: &[DVec3],
    ) -> Swept {
        let (mut x, mut c, mut t, mut w) = (lanes(z), lanes(c0), vec![Lane::ZERO; 5], lanes(y));
        backward(l, m, p, &mut x, &mut c, 0.7, &mut t, 0.4);
        let mut norm = Norm { dhat: &p.dhat, sum: l.splat(0.0) };
        forward(l, m, p, &mut w, &mut norm);
        (x, c, t, w, l.sum(norm.sum))
    }
    let mut results = vec![sweeps(Portable, &m, &p, &z, &c0, &y)];
    #[cfg(target_arch = "x86_64")]
    if let Some(simd) = pulp::x86::V3::try_new() {
        results.push(sweeps(Avx(simd), &m, &p, &z, &c0, &y));
    }
    let (x, c, t, w, dot) = &results[0];
    // (D + U) x = y with y = z + β c: c = y and t = U x + κ D x.
    for i in 0..5 {
        assert!((c[i].vec3() - y[i]).length() < 1e-15);
        let mut ux = DVec3::ZERO;
        for s in m.row_ptr[i]..m.row_ptr[i + 1] {
            ux += m.blocks[s] * x[m.cols[s] as usize].vec3();
        }
        let dx = m.blocks[i] * x[i].vec3();
        assert!((dx + ux - y[i]).length() < 1e-12);
        assert!((ux + kappa * dx - t[i].vec3()).length() < 1e-12);
    }
    // (D + L) w = y with L = Uᵀ.
    let mut row: Vec<DVec3> = (0..5).map(|i| m.blocks[i] * w[i].vec3()).collect();
    for (i, wi) in w.iter().enumerate() {
        for s in m.row_ptr[i]..m.row_ptr[i + 1] {
            row[m.cols[s] as usize] += m.blocks[s].transpose() * wi.vec3();
        }
    }
    assert!(row.iter().zip(&y).all(|(a, b)| (*a - *b).length() < 1e-12));
    let expected: f64 = (0..5).map(|i| w[i].vec3().dot(m.blocks[i] * w[i].vec3())).sum();
    assert!((dot - expected).abs() < 1e-12 * expected);
    // Fourth lanes zero, and the AVX2 build equal bit for bit.
    assert!([x, c, t, w].iter().all(|v| v.iter().all(|l| l.0[3] == 0.0)));
    for other in &results[1..] {
        assert!(other.0 == *x && other.1 == *c && other.2 == *t && other.3 == *w);
        assert_eq!(other.4.to_bits(), dot.to_bits());
    }
}

#[test]
fn substitutions_invert_their_halves_in_both_builds() {
    // Every row linked to the next (the per-row products carry the chain).
    check_substitutions(&[[0, 1, 2], [1, 2, 3], [2, 3, 4]]);
    // Rows 0-2 not linked, row 3 linked, row 4 without upper blocks.
    let m = BlockMatrix::from_elements(5, [[0, 2, 4], [1, 3, 4]].iter().map(|e| &e[..]));
    assert_eq!((0..4).map(|h| m.linked(h)).collect::<Vec<_>>(), [false, false, false, true]);
    check_substitutions(&[[0, 2, 4], [1, 3, 4]]);
}

/// A whole solve on the matrix of a hanging cloth (two pinned corners filtered out) in
/// both builds: the same iterations and the same `Δv` bit for bit.
#[test]
fn both_builds_solve_alike() {
    use crate::cloth::{Cloth, Elasticity, Material, Mesh, SolveOptions, Triangulation};
    let n = 24;
    let mesh = Mesh::grid(n, n, 1.0, 1.0, Triangulation::Alternating).unwrap();
    let g = DVec3::new(0.0, -9.81, 0.0);
    let mut cloth = Cloth::new(mesh, Elasticity::BaraffWitkin, Material::default(), g).unwrap();
    cloth.pin(&[0, n - 1], None).unwrap();
    let options = SolveOptions { max_strain_change: f64::INFINITY, ..Default::default() };
    cloth.step(1.0 / 60.0, 5, crate::ode::Method::ImplicitEuler, options).unwrap();
    let (m, filter) = (&cloth.solver.matrix, &cloth.solver.scratch.filter);
    let omega = 1.4;
    let work = || {
        let mut w = Work::default();
        w.resize(n * n);
        w.precond.update(m, |i| {
            let (d, f) = (m.blocks[i], filter[i]);
            let inverse = f * (f * d * f + DMat3::IDENTITY - f).inverse() * f;
            (inverse * omega, f * d * (1.0 / omega))
        });
        for (i, f) in filter.iter().enumerate() {
            let b = *f * DVec3::new(0.3, -1.0 + (i as f64).sin(), 0.1);
            (w.r[i], w.t[i]) = (Lane::new(b), Lane::new(b));
        }
        w
    };
    let (mut a, mut b) = (work(), work());
    let one = solve(m, &mut a, 1e-6, 1000, 0.0, omega - 1.0).unwrap();
    let run =
        Run { m, work: &mut b, tol: 1e-6, max_iterations: 1000, floor: 0.0, kappa: omega - 1.0 };
    let other = run.iterate(Portable).unwrap();
    assert!(one.0 > 10 && one.2, "a real solve: {one:?}");
    assert_eq!((one.0, one.1.to_bits(), one.2), (other.0, other.1.to_bits(), other.2));
    assert!(a.dv == b.dv);
    assert!((0..n * n).all(|i| filter[i] == DMat3::IDENTITY || a.dv[i] == Lane::ZERO));
}
