//! Integrators: observed convergence orders, stability limits against `max_stable_dt`,
//! stiff problems, long-run energy behaviour, failures that leave the state unchanged.

use kinema::ode::{
    bdf2_weights, max_stable_dt, max_stable_dt_oscillator, solve_adaptive, stability_function,
    Adaptive, History, Method, OdeSystem, SparseJacobian, Stepper,
};
use kinema::Error;
use nalgebra::{Complex, DMatrix};

/// `x'' = -ω² x` as `y = [x; v]`.
struct Oscillator(f64);
impl OdeSystem for Oscillator {
    fn dim(&self) -> usize {
        2
    }
    fn rhs(&mut self, _t: f64, y: &[f64], f: &mut [f64]) -> kinema::Result<()> {
        f[0] = y[1];
        f[1] = -self.0 * self.0 * y[0];
        Ok(())
    }
}

/// `y' = λ y` (real λ).
struct Decay(f64);
impl OdeSystem for Decay {
    fn dim(&self) -> usize {
        1
    }
    fn rhs(&mut self, _t: f64, y: &[f64], f: &mut [f64]) -> kinema::Result<()> {
        f[0] = self.0 * y[0];
        Ok(())
    }
    fn jacobian(&mut self, _t: f64, _y: &[f64], j: &mut DMatrix<f64>) -> kinema::Result<bool> {
        j[(0, 0)] = self.0;
        Ok(true)
    }
}

/// A chain of `n` unit masses joined by springs of stiffness `k`, the first spring tied to a
/// wall, as `y = [x; v]` (displacements along the chain). No analytic Jacobian: the implicit
/// methods difference it.
struct SpringChain {
    n: usize,
    k: f64,
}
impl OdeSystem for SpringChain {
    fn dim(&self) -> usize {
        2 * self.n
    }
    fn rhs(&mut self, _t: f64, y: &[f64], f: &mut [f64]) -> kinema::Result<()> {
        let n = self.n;
        for i in 0..n {
            let left = if i == 0 { 0.0 } else { y[i - 1] };
            let right = if i + 1 < n { self.k * (y[i + 1] - y[i]) } else { 0.0 };
            f[i] = y[n + i];
            f[n + i] = -self.k * (y[i] - left) + right;
        }
        Ok(())
    }
}

fn run<S: OdeSystem>(
    sys: &mut S,
    method: Method,
    y0: &[f64],
    t1: f64,
    steps: usize,
) -> kinema::Result<Vec<f64>> {
    let mut stepper = Stepper::new(method, y0.len())?;
    let h = t1 / steps as f64;
    let mut y = y0.to_vec();
    for s in 0..steps {
        stepper.step(sys, s as f64 * h, &mut y, h)?;
    }
    Ok(y)
}

#[test]
fn observed_convergence_orders() {
    for method in Method::ALL {
        let error = |steps: usize| {
            let y = run(&mut Oscillator(1.0), method, &[1.0, 0.0], 2.0, steps).unwrap();
            ((y[0] - 2f64.cos()).powi(2) + (y[1] + 2f64.sin()).powi(2)).sqrt()
        };
        let (coarse, fine) = if method == Method::Rk4 { (50, 100) } else { (400, 800) };
        let observed = (error(coarse) / error(fine)).log2();
        assert!(
            (observed - f64::from(method.order())).abs() < 0.1,
            "{}: observed order {observed}",
            method.name()
        );
    }
}

/// Each adaptive pair keeps the error of the oscillator within a small multiple of its
/// tolerance and converges at its order: error ~ steps^-order over three decades of tolerance.
#[test]
fn adaptive_pairs_converge_at_their_order() {
    for (method, tols) in
        [(Adaptive::Dopri5, [1e-7, 1e-9, 1e-11]), (Adaptive::Dop853, [1e-8, 1e-10, 1e-12])]
    {
        let mut points = Vec::new();
        for tol in tols {
            let sol = solve_adaptive(
                &mut Oscillator(1.0),
                method,
                &[1.0, 0.0],
                0.0,
                10.0,
                tol,
                tol * 1e-3,
                100_000,
                None,
                &[],
            )
            .unwrap();
            let y = &sol.y[sol.y.len() - 2..];
            let err = ((y[0] - 10f64.cos()).powi(2) + (y[1] + 10f64.sin()).powi(2)).sqrt();
            points.push(((sol.t.len() - 1) as f64, err));
            assert!(err < 200.0 * tol, "{method:?} tol {tol}: error {err}");
        }
        let slope = (points[2].1 / points[0].1).ln() / (points[2].0 / points[0].0).ln();
        let order = f64::from(method.order());
        // Measured: -5.0 and -9.7 (DOP853 takes 15 to 60 steps here, few enough to steepen).
        assert!((slope + order).abs() < 0.25 * order, "{method:?}: error ~ steps^{slope}");
    }
}

/// Whether `steps` steps of size h on `sys` keep |y| from growing.
fn bounded<S: OdeSystem>(sys: &mut S, method: Method, y0: &[f64], h: f64) -> bool {
    let y = run(sys, method, y0, h * 2000.0, 2000).unwrap();
    y.iter().map(|v| v * v).sum::<f64>() <= y0.iter().map(|v| v * v).sum::<f64>()
}

#[test]
fn measured_stability_limits_match_max_stable_dt() {
    let lambda = -3.0;
    for (method, closed_form) in [
        (Method::ExplicitEuler, 2.0),
        (Method::Midpoint, 2.0),
        (Method::Heun, 2.0),
        (Method::Rk4, 2.785_293_563_4),
    ] {
        let h = max_stable_dt(method, &[Complex::new(lambda, 0.0)]).unwrap();
        assert!((h * -lambda - closed_form).abs() < 1e-8, "{}: {h}", method.name());
        assert!(bounded(&mut Decay(lambda), method, &[1.0], 0.99 * h), "{}", method.name());
        assert!(!bounded(&mut Decay(lambda), method, &[1.0], 1.01 * h), "{}", method.name());
    }
    // The spring x'' = -ω² x: eigenvalues ±iω.
    let omega = 5.0;
    let eig = [Complex::new(0.0, omega), Complex::new(0.0, -omega)];
    for (method, closed_form) in
        [(Method::Rk4, 8f64.sqrt()), (Method::SymplecticEuler, 2.0), (Method::VelocityVerlet, 2.0)]
    {
        let h = max_stable_dt(method, &eig).unwrap();
        assert!((h * omega - closed_form).abs() < 1e-6, "{}: {}", method.name(), h * omega);
        let energy = |y: &[f64]| y[1] * y[1] + omega * omega * y[0] * y[0];
        let y = run(&mut Oscillator(omega), method, &[1.0, 0.0], 0.99 * h * 2000.0, 2000).unwrap();
        // Below the limit the amplitude stays bounded (near the limit the eigenvectors of the
        // amplification matrix are nearly parallel, so the energy oscillates widely but does
        // not grow); above it the energy grows like |R|^(2 steps).
        let e0 = omega * omega;
        assert!(energy(&y) < 1e4 * e0, "{} unstable below the limit", method.name());
        let y = run(&mut Oscillator(omega), method, &[1.0, 0.0], 1.01 * h * 2000.0, 2000).unwrap();
        assert!(energy(&y) > 1e10 * e0, "{} stable above the limit", method.name());
    }
    // Explicit Euler and midpoint are unstable on the imaginary axis for every step.
    assert_eq!(max_stable_dt(Method::ExplicitEuler, &eig).unwrap(), 0.0);
    assert_eq!(max_stable_dt(Method::Midpoint, &eig).unwrap(), 0.0);
    for method in [Method::ImplicitEuler, Method::Trapezoidal, Method::Bdf2] {
        assert_eq!(
            max_stable_dt(method, &[Complex::new(-1e6, 3.0), eig[0]]).unwrap(),
            f64::INFINITY
        );
    }
    assert!(max_stable_dt(Method::Rk4, &[Complex::new(1.0, 0.0)]).is_err());
}

#[test]
fn stability_functions_at_known_points() {
    let z = |re: f64, im: f64| Complex::new(re, im);
    assert!((stability_function(Method::ImplicitEuler, z(-1e12, 0.0))).norm() < 1e-11);
    assert!((stability_function(Method::Trapezoidal, z(-1e12, 0.0)) + 1.0).norm() < 1e-11);
    assert!(((stability_function(Method::Trapezoidal, z(0.0, 7.0))).norm() - 1.0).abs() < 1e-15);
    // BDF2 is L-stable: its dominant root vanishes at -inf, and at z = 0 it is 1.
    assert!(stability_function(Method::Bdf2, z(-1e12, 0.0)).norm() < 1e-5);
    assert!((stability_function(Method::Bdf2, z(0.0, 0.0)) - 1.0).norm() < 1e-15);
    assert!((stability_function(Method::Rk4, z(-1.0, 0.0)).re - 0.375).abs() < 1e-15);
}

#[test]
fn implicit_methods_stay_bounded_at_huge_stiffness() {
    for method in [Method::ImplicitEuler, Method::Bdf2, Method::Trapezoidal] {
        let y = run(&mut Decay(-1e6), method, &[1.0], 1.0, 1).unwrap(); // h|λ| = 1e6
        assert!(y[0].abs() <= 1.0, "{}", method.name());
        let y = run(&mut Decay(-1e6), method, &[1.0], 100.0, 100).unwrap();
        assert!(y[0].abs() <= 1.0 && y[0].is_finite(), "{}", method.name());
    }
    for k in [1.0, 1e3, 1e6, 1e9] {
        let n = 10;
        let mut y0 = vec![0.0; 2 * n];
        y0[n - 1] = 0.1; // stretch the free end
        let energy = |y: &[f64]| {
            let mut e = 0.5 * k * y[0] * y[0];
            for i in 1..n {
                e += 0.5 * k * (y[i] - y[i - 1]).powi(2);
            }
            e + y[n..].iter().map(|v| 0.5 * v * v).sum::<f64>()
        };
        for method in [Method::ImplicitEuler, Method::Bdf2] {
            let y = run(&mut SpringChain { n, k }, method, &y0, 2.0, 120).unwrap(); // dt = 1/60
            assert!(energy(&y) <= energy(&y0) * (1.0 + 1e-6), "{} k={k}", method.name());
        }
    }
}

#[test]
fn symplectic_methods_keep_oscillator_energy_bounded_over_a_million_steps() {
    let energy = |y: &[f64]| 0.5 * (y[0] * y[0] + y[1] * y[1]);
    for (method, bound) in [(Method::SymplecticEuler, 0.01), (Method::VelocityVerlet, 1e-4)] {
        let mut stepper = Stepper::new(method, 2).unwrap();
        let mut y = [1.0, 0.0];
        let mut worst: f64 = 0.0;
        for s in 0..1_000_000 {
            stepper.step(&mut Oscillator(1.0), s as f64 * 0.01, &mut y, 0.01).unwrap();
            worst = worst.max((energy(&y) - 0.5).abs() / 0.5);
        }
        assert!(worst < bound, "{}: {worst}", method.name());
    }
    let y =
        run(&mut Oscillator(1.0), Method::ExplicitEuler, &[1.0, 0.0], 10_000.0, 1_000_000).unwrap();
    assert!(energy(&y) > 1e10);
}

#[test]
fn failures_leave_the_state_unchanged() {
    struct Blowup;
    impl OdeSystem for Blowup {
        fn dim(&self) -> usize {
            1
        }
        fn rhs(&mut self, _t: f64, y: &[f64], f: &mut [f64]) -> kinema::Result<()> {
            f[0] = 1e300 * y[0];
            Ok(())
        }
    }
    let mut stepper = Stepper::new(Method::Rk4, 1).unwrap();
    let mut y = [1e10];
    assert!(matches!(
        stepper.step(&mut Blowup, 0.0, &mut y, 1.0),
        Err(Error::Diverged { index: 0, .. })
    ));
    assert_eq!(y, [1e10]);

    struct Cubic;
    impl OdeSystem for Cubic {
        fn dim(&self) -> usize {
            1
        }
        fn rhs(&mut self, _t: f64, y: &[f64], f: &mut [f64]) -> kinema::Result<()> {
            f[0] = -y[0].powi(3);
            Ok(())
        }
    }
    let mut stepper = Stepper::new(Method::ImplicitEuler, 1).unwrap();
    stepper.history.max_newton = 1;
    let mut y = [1.0];
    assert!(matches!(stepper.step(&mut Cubic, 0.0, &mut y, 1.0), Err(Error::SolverFailed { .. })));
    assert_eq!(y, [1.0]);
    stepper.history.max_newton = 50;
    stepper.step(&mut Cubic, 0.0, &mut y, 1.0).unwrap();
    assert!((y[0] + y[0].powi(3) - 1.0).abs() < 1e-9); // y₁ = y₀ - h y₁³
    assert!(stepper.step(&mut Cubic, 0.0, &mut y, -1.0).is_err());
    assert!(Stepper::new(Method::VelocityVerlet, 3).is_err());
    assert!(Method::parse("rk45").is_err());
}

#[test]
fn symplectic_stability_accounts_for_damping() {
    // x'' + c x' + ω² x = 0 with ω = 10, c = 4: eigenvalues -2 ± i √96. Step the actual
    // integrator just below and above the predicted limit and watch the amplitude.
    struct Damped;
    impl OdeSystem for Damped {
        fn dim(&self) -> usize {
            2
        }
        fn rhs(&mut self, _t: f64, y: &[f64], dydt: &mut [f64]) -> kinema::Result<()> {
            dydt[0] = y[1];
            dydt[1] = -100.0 * y[0] - 4.0 * y[1];
            Ok(())
        }
    }
    let lambda = nalgebra::Complex::new(-2.0, 96f64.sqrt());
    for method in [Method::SymplecticEuler, Method::VelocityVerlet] {
        let limit = max_stable_dt(method, &[lambda, lambda.conj()]).unwrap();
        let undamped = max_stable_dt(method, &[nalgebra::Complex::new(0.0, 10.0)]).unwrap();
        assert!(limit < undamped, "{method:?}: damping lowers the limit ({limit} vs {undamped})");
        let grows = |h: f64| {
            let mut stepper = Stepper::new(method, 2).unwrap();
            let mut y = [1.0, 0.0];
            for _ in 0..2000 {
                stepper.step(&mut Damped, 0.0, &mut y, h).unwrap();
            }
            y[0].abs() + y[1].abs() * h > 1.0
        };
        assert!(!grows(0.99 * limit), "{method:?} unstable below {limit}");
        assert!(grows(1.01 * limit), "{method:?} stable above {limit}");
    }
}

#[test]
fn oscillator_limits_hold_for_overdamped_and_undamped_modes() {
    // x'' + c x' + ω² x = 0 stepped by the real integrator just below and above the limit.
    struct Mode(f64, f64);
    impl OdeSystem for Mode {
        fn dim(&self) -> usize {
            2
        }
        fn rhs(&mut self, _t: f64, y: &[f64], dydt: &mut [f64]) -> kinema::Result<()> {
            dydt[0] = y[1];
            dydt[1] = -self.0 * self.0 * y[0] - self.1 * y[1];
            Ok(())
        }
    }
    for (omega, c) in [(10.0, 0.0), (10.0, 4.0), (10.0, 100.0), (1.0, 1000.0)] {
        for method in [Method::SymplecticEuler, Method::VelocityVerlet, Method::Rk4, Method::Heun] {
            let limit = max_stable_dt_oscillator(method, omega, c).unwrap();
            if method == Method::Heun && c == 0.0 {
                assert_eq!(limit, 0.0, "Heun never keeps an undamped oscillator bounded");
                continue;
            }
            assert!(limit > 0.0 && limit.is_finite(), "{method:?} {omega} {c}: {limit}");
            // Unstable: the amplitude over the last thousand steps dwarfs that of the first
            // (near the limit a stable symplectic map swings wide but does not grow).
            let grows = |h: f64| {
                let mut stepper = Stepper::new(method, 2).unwrap();
                let (mut y, mut first, mut last) = ([1.0, 1.0], 0.0_f64, 0.0_f64);
                for k in 0..4000 {
                    if stepper.step(&mut Mode(omega, c), 0.0, &mut y, h).is_err() {
                        return true; // overflowed to infinity
                    }
                    let size = y[0].abs() + h * y[1].abs();
                    if k < 1000 {
                        first = first.max(size);
                    } else if k >= 3000 {
                        last = last.max(size);
                    }
                }
                last > 10.0 * first
            };
            assert!(!grows(0.98 * limit), "{method:?} ω {omega} c {c}: unstable below {limit}");
            assert!(grows(1.05 * limit), "{method:?} ω {omega} c {c}: stable above {limit}");
        }
    }
    assert!(max_stable_dt_oscillator(Method::ImplicitEuler, 1e9, 0.0).unwrap().is_infinite());
    assert!(max_stable_dt_oscillator(Method::Rk4, -1.0, 0.0).is_err());
    assert!(max_stable_dt_oscillator(Method::Rk4, 1.0, f64::NAN).is_err());
}

/// [`SpringChain`] with its analytic Jacobian in compressed sparse columns: `∂x'/∂v = I` and
/// the tridiagonal `∂v'/∂x`. With `padded`, every other call also stores explicit zeros in
/// the velocity block (a pattern that changes between calls).
struct SparseChain {
    chain: SpringChain,
    padded: bool,
    calls: usize,
}
impl OdeSystem for SparseChain {
    fn dim(&self) -> usize {
        self.chain.dim()
    }
    fn rhs(&mut self, t: f64, y: &[f64], f: &mut [f64]) -> kinema::Result<()> {
        self.chain.rhs(t, y, f)
    }
    fn sparse_jacobian(
        &mut self,
        _t: f64,
        _y: &[f64],
        jac: &mut SparseJacobian,
    ) -> kinema::Result<bool> {
        let (n, k) = (self.chain.n, self.chain.k);
        self.calls += 1;
        let pad = self.padded && self.calls.is_multiple_of(2);
        jac.col_ptr.clear();
        jac.row_idx.clear();
        jac.values.clear();
        jac.col_ptr.push(0);
        for c in 0..n {
            // Column of x_c: rows of v_{c-1}, v_c, v_{c+1}.
            for r in c.saturating_sub(1)..(c + 2).min(n) {
                let value = if r == c { -2.0 * k + if c + 1 == n { k } else { 0.0 } } else { k };
                jac.row_idx.push(n + r);
                jac.values.push(value);
            }
            jac.col_ptr.push(jac.row_idx.len());
        }
        for c in 0..n {
            jac.row_idx.push(c);
            jac.values.push(1.0);
            if pad {
                jac.row_idx.push(n + c);
                jac.values.push(0.0);
            }
            jac.col_ptr.push(jac.row_idx.len());
        }
        Ok(true)
    }
}

#[test]
fn sparse_newton_matches_the_dense_solve_and_the_exact_linear_step() {
    let (n, k, h) = (40, 1e6, 1.0 / 60.0);
    let mut y0 = vec![0.0; 2 * n];
    for i in 0..n {
        y0[i] = 0.01 * ((i * 7 % 11) as f64 - 5.0);
        y0[n + i] = 0.1 * ((i * 3 % 5) as f64 - 2.0);
    }
    // Implicit Euler on the linear chain: y₁ = (I - h A)⁻¹ y₀ exactly, A dense as an oracle.
    let mut a = DMatrix::zeros(2 * n, 2 * n);
    let mut probe = SpringChain { n, k };
    let (mut e, mut col) = (vec![0.0; 2 * n], vec![0.0; 2 * n]);
    for c in 0..2 * n {
        e[c] = 1.0;
        probe.rhs(0.0, &e, &mut col).unwrap();
        a.set_column(c, &nalgebra::DVector::from_column_slice(&col));
        e[c] = 0.0;
    }
    let exact = (DMatrix::identity(2 * n, 2 * n) - h * &a)
        .lu()
        .solve(&nalgebra::DVector::from_column_slice(&y0))
        .unwrap();
    let mut sys = SparseChain { chain: SpringChain { n, k }, padded: false, calls: 0 };
    let mut stepper = Stepper::new(Method::ImplicitEuler, 2 * n).unwrap();
    let mut y = y0.clone();
    stepper.step(&mut sys, 0.0, &mut y, h).unwrap();
    let scale = exact.amax();
    let err = y.iter().zip(exact.iter()).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    assert!(err <= 1e-10 * scale, "implicit Euler vs (I - hA)⁻¹ y₀: {err:e}");
    // A linear system: the exact Jacobian converges at once, no Jacobian update.
    assert_eq!((sys.calls, stepper.history.njev), (1, 1));

    for method in [Method::ImplicitEuler, Method::Trapezoidal, Method::Bdf2] {
        let dense = run(&mut SpringChain { n, k }, method, &y0, 1.0, 60).unwrap();
        for padded in [false, true] {
            let mut sys = SparseChain { chain: SpringChain { n, k }, padded, calls: 0 };
            let sparse = run(&mut sys, method, &y0, 1.0, 60).unwrap();
            let scale = dense.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
            let err = sparse.iter().zip(&dense).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            // The differenced Jacobian is good to ~1e-8 relative; Newton removes its error
            // down to the tolerance.
            assert!(err <= 1e-8 * scale, "{} padded {padded}: {err:e}", method.name());
        }
    }
}

#[test]
fn invalid_sparse_jacobians_are_refused_with_the_state_unchanged() {
    /// The chain's Jacobian spoiled by `spoil`.
    struct Spoiled(SparseChain, fn(&mut SparseJacobian));
    impl OdeSystem for Spoiled {
        fn dim(&self) -> usize {
            self.0.dim()
        }
        fn rhs(&mut self, t: f64, y: &[f64], f: &mut [f64]) -> kinema::Result<()> {
            self.0.rhs(t, y, f)
        }
        fn sparse_jacobian(
            &mut self,
            t: f64,
            y: &[f64],
            jac: &mut SparseJacobian,
        ) -> kinema::Result<bool> {
            self.0.sparse_jacobian(t, y, jac)?;
            (self.1)(jac);
            Ok(true)
        }
    }
    let spoilers: [fn(&mut SparseJacobian); 4] = [
        |j| j.col_ptr.truncate(3), // too few columns
        |j| j.row_idx.swap(0, 1),  // rows not increasing
        |j| {
            j.values.pop(); // a value missing
        },
        |j| j.row_idx[0] = 10_000, // row out of range
    ];
    for spoil in spoilers {
        let n = 5;
        let chain = SparseChain { chain: SpringChain { n, k: 1.0 }, padded: false, calls: 0 };
        let mut stepper = Stepper::new(Method::ImplicitEuler, 2 * n).unwrap();
        let mut y = vec![0.5; 2 * n];
        let result = stepper.step(&mut Spoiled(chain, spoil), 0.0, &mut y, 0.1);
        assert!(
            matches!(&result, Err(Error::InvalidInput { arg, .. }) if arg == "jacobian"),
            "{result:?}"
        );
        assert_eq!(y, vec![0.5; 2 * n]);
    }
}

/// `x'' = -x³ - x x' + g(t)` with `g` chosen so that `x = sin t` solves it, as `y = [x; v]`:
/// nonlinear in `x` and `v` and time-dependent, so the Runge–Kutta methods of one order (the
/// midpoint rule and Heun) differ, and a stage evaluated at the wrong time loses an order.
struct Manufactured;
impl Manufactured {
    fn exact(t: f64) -> [f64; 2] {
        [t.sin(), t.cos()]
    }
}
impl OdeSystem for Manufactured {
    fn dim(&self) -> usize {
        2
    }
    fn rhs(&mut self, t: f64, y: &[f64], f: &mut [f64]) -> kinema::Result<()> {
        let (s, c) = t.sin_cos();
        let g = -s + s.powi(3) + s * c;
        f[0] = y[1];
        f[1] = -y[0].powi(3) - y[0] * y[1] + g;
        Ok(())
    }
}

/// The error at `t1` of a run over `steps` whose step sizes repeat `pattern` (relative sizes),
/// started from the exact solution.
fn manufactured_error(method: Method, t1: f64, steps: usize, pattern: &[f64]) -> f64 {
    let total: f64 = (0..steps).map(|s| pattern[s % pattern.len()]).sum();
    let mut stepper = Stepper::new(method, 2).unwrap();
    let (mut t, mut y) = (0.0, Manufactured::exact(0.0));
    for s in 0..steps {
        let h = t1 * pattern[s % pattern.len()] / total;
        stepper.step(&mut Manufactured, t, &mut y, h).unwrap();
        t += h;
    }
    let e = Manufactured::exact(t1);
    (y[0] - e[0]).hypot(y[1] - e[1])
}

#[test]
fn observed_orders_on_a_nonlinear_time_dependent_problem() {
    for method in Method::ALL {
        let (coarse, fine) = if method == Method::Rk4 { (40, 80) } else { (400, 800) };
        let (e1, e2) = (
            manufactured_error(method, 2.0, coarse, &[1.0]),
            manufactured_error(method, 2.0, fine, &[1.0]),
        );
        let observed = (e1 / e2).log2();
        assert!(
            (observed - f64::from(method.order())).abs() < 0.1,
            "{}: observed order {observed} ({e1:.2e}, {e2:.2e})",
            method.name()
        );
    }
    // Midpoint and Heun are different methods here (on linear autonomous problems they agree).
    let (a, b) = (
        manufactured_error(Method::Midpoint, 2.0, 400, &[1.0]),
        manufactured_error(Method::Heun, 2.0, 400, &[1.0]),
    );
    assert!((a - b).abs() > 0.1 * a.max(b), "midpoint {a:e}, Heun {b:e}");
}

#[test]
fn bdf2_is_second_order_with_alternating_steps() {
    // Steps h, h/2, h, h/2, ...: every step changes the step size (ratio 1/2, then 2).
    for pattern in [[1.0, 0.5], [1.0, 2.0]] {
        let (e1, e2) = (
            manufactured_error(Method::Bdf2, 2.0, 400, &pattern),
            manufactured_error(Method::Bdf2, 2.0, 800, &pattern),
        );
        let observed = (e1 / e2).log2();
        assert!((observed - 2.0).abs() < 0.1, "{pattern:?}: observed order {observed}");
    }
}

#[test]
fn bdf2_weights_are_exact_on_quadratics() {
    // Second order: y = t² (f = 2t) is reproduced exactly from y(t - h₋) and y(t) for any
    // step ratio the formula takes; the constant-step weights are 1/3 and 2/3.
    assert_eq!(bdf2_weights(0.1, Some(0.1)), Some((1.0 / 3.0, 2.0 / 3.0)));
    let y = |t: f64| t * t;
    for (h, hp) in [(0.1, 0.1), (0.05, 0.1), (0.2, 0.1), (0.013, 0.02)] {
        let t = 0.7;
        let (c, gamma) = bdf2_weights(h, Some(hp)).unwrap();
        let next = y(t) + c * (y(t) - y(t - hp)) + gamma * h * 2.0 * (t + h);
        assert!((next - y(t + h)).abs() < 1e-15, "h {h}, h₋ {hp}: {next} vs {}", y(t + h));
    }
    // No history, or a step that grows beyond the zero-stable ratios: restart.
    assert_eq!(bdf2_weights(0.1, None), None);
    assert_eq!(bdf2_weights(0.3, Some(0.1)), None);
}

/// `y' = λ y` for complex `λ`, as `y = [Re y, Im y]`, with its Jacobian.
struct ComplexDecay(Complex<f64>);
impl OdeSystem for ComplexDecay {
    fn dim(&self) -> usize {
        2
    }
    fn rhs(&mut self, _t: f64, y: &[f64], f: &mut [f64]) -> kinema::Result<()> {
        let (a, b) = (self.0.re, self.0.im);
        f[0] = a * y[0] - b * y[1];
        f[1] = b * y[0] + a * y[1];
        Ok(())
    }
    fn jacobian(&mut self, _t: f64, _y: &[f64], j: &mut DMatrix<f64>) -> kinema::Result<bool> {
        let (a, b) = (self.0.re, self.0.im);
        j.copy_from_slice(&[a, b, -b, a]); // column-major
        Ok(true)
    }
}

/// The growth factor of one step of `h` of the real stepper on `y' = λy` from `y = 1`.
fn measured_amplification(method: Method, lambda: Complex<f64>, h: f64) -> Complex<f64> {
    let mut y = [1.0, 0.0];
    Stepper::new(method, 2).unwrap().step(&mut ComplexDecay(lambda), 0.0, &mut y, h).unwrap();
    Complex::new(y[0], y[1])
}

#[test]
fn stability_functions_match_the_steppers_measured_amplification() {
    let points = [(-0.1, 0.0), (-0.5, 0.0), (0.0, 0.3), (-0.2, 0.4), (-3.0, 2.0), (-40.0, 0.0)];
    // One-step methods: one step from y = 1 multiplies it by R(z).
    for method in [
        Method::ExplicitEuler,
        Method::Midpoint,
        Method::Heun,
        Method::Rk4,
        Method::ImplicitEuler,
        Method::Trapezoidal,
    ] {
        for (re, im) in points {
            let z = Complex::new(re, im);
            let measured = measured_amplification(method, z, 1.0);
            let r = stability_function(method, z);
            assert!(
                (measured - r).norm() <= 1e-13 * r.norm().max(1.0),
                "{method:?} z {z}: {measured} vs {r}"
            );
        }
    }
    // BDF2: the ratio of successive steps tends to the dominant root (the other is at most
    // about half of it at these z; at z = -1/2 the two coincide).
    for (re, im) in [(-0.1, 0.0), (-0.3, 0.0), (0.0, 0.3), (-0.2, 0.4)] {
        let z = Complex::new(re, im);
        let mut stepper = Stepper::new(Method::Bdf2, 2).unwrap();
        let mut y = [1.0, 0.0];
        let mut last = Complex::new(1.0, 0.0);
        let mut ratio = last;
        for _ in 0..80 {
            stepper.step(&mut ComplexDecay(z), 0.0, &mut y, 1.0).unwrap();
            let now = Complex::new(y[0], y[1]);
            ratio = now / last;
            last = now;
        }
        let r = stability_function(Method::Bdf2, z);
        assert!((ratio - r).norm() <= 1e-12, "BDF2 z {z}: {ratio} vs {r}");
    }
    // Second-order methods on the oscillator with eigenvalues λ, conj(λ): the amplification
    // matrix measured by stepping the unit states, its dominant eigenvalue against R.
    for method in [Method::SymplecticEuler, Method::VelocityVerlet] {
        for (re, im) in [(0.0, 1.0), (-0.1, 0.5), (-0.3, 1.5), (-2.0, 0.0)] {
            let lambda = Complex::new(re, im);
            let (omega2, c) = (lambda.norm_sqr(), -2.0 * re);
            struct Mode(f64, f64);
            impl OdeSystem for Mode {
                fn dim(&self) -> usize {
                    2
                }
                fn rhs(&mut self, _t: f64, y: &[f64], f: &mut [f64]) -> kinema::Result<()> {
                    f[0] = y[1];
                    f[1] = -self.0 * y[0] - self.1 * y[1];
                    Ok(())
                }
            }
            let mut stepper = Stepper::new(method, 2).unwrap();
            let (mut a, mut b) = ([1.0, 0.0], [0.0, 1.0]);
            stepper.step(&mut Mode(omega2, c), 0.0, &mut a, 1.0).unwrap();
            stepper.step(&mut Mode(omega2, c), 0.0, &mut b, 1.0).unwrap();
            let (trace, det) = (a[0] + b[1], a[0] * b[1] - b[0] * a[1]);
            let disc = Complex::new(trace * trace - 4.0 * det, 0.0).sqrt();
            let roots = [(trace + disc) / 2.0, (trace - disc) / 2.0];
            let r = stability_function(method, lambda);
            let measured = roots.iter().map(|m| m.norm()).fold(0.0, f64::max);
            assert!(
                (measured - r.norm()).abs() <= 1e-13,
                "{method:?} λ {lambda}: {measured} vs {r}"
            );
        }
    }
}

/// The largest stable step along `λ`'s ray measured with the real stepper: `|R|` of one step
/// from `y = 1` on a geometric grid of ratio 1.001 from `|hλ| = 1e-9` (so no stable interval
/// longer than 0.1% is stepped over), then bisected between the last stable and first
/// unstable grid points.
fn measured_limit(method: Method, lambda: Complex<f64>) -> f64 {
    let grows = |h: f64| measured_amplification(method, lambda, h).norm() > 1.0;
    let mut h = 1e-9 / lambda.norm();
    if grows(h) {
        return 0.0;
    }
    while !grows(h * 1.001) {
        h *= 1.001;
    }
    let (mut lo, mut hi) = (h, h * 1.001);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if grows(mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    lo
}

#[test]
fn max_stable_dt_is_exact_near_the_imaginary_axis() {
    // Explicit Euler: |1 + hλ| ≤ 1 up to h = 2|Re λ| / |λ|².
    for (re, im) in
        [(-1e-4, 1.0), (-1e-4, -1.0), (-3.0, 0.0), (-1.0, 2.0), (-1e-12, 1e6), (-5.0, 1e-3)]
    {
        let lambda = Complex::new(re, im);
        let h = max_stable_dt(Method::ExplicitEuler, &[lambda]).unwrap();
        let exact = -2.0 * re / lambda.norm_sqr();
        assert!((h - exact).abs() <= 1e-12 * exact, "λ {lambda}: {h:e} vs {exact:e}");
    }
    assert_eq!(max_stable_dt(Method::ExplicitEuler, &[Complex::new(0.0, 3.0)]).unwrap(), 0.0);
    // RK2 and RK4 against the limit measured by stepping.
    for method in [Method::ExplicitEuler, Method::Midpoint, Method::Heun, Method::Rk4] {
        for (re, im) in
            [(-1e-4, 1.0), (-2e-3, 1.5), (-1e-3, 2.8), (-0.5, 2.0), (-2.0, 0.0), (-0.05, 40.0)]
        {
            let lambda = Complex::new(re, im);
            let h = max_stable_dt(method, &[lambda, lambda.conj()]).unwrap();
            let measured = measured_limit(method, lambda);
            assert!(
                (h - measured).abs() <= 1e-7 * measured,
                "{method:?} λ {lambda}: {h:e}, measured {measured:e}"
            );
        }
    }
}

/// A failed BDF2 step (Newton fails in every substep on `y' = y²` from `y = 1` over a step
/// beyond the blow-up at `t = 1`) leaves the state and the two-step history as they were:
/// the steps after it are bit for bit those of a stepper that never tried it.
#[test]
fn failed_bdf2_step_keeps_its_history() {
    struct Square;
    impl OdeSystem for Square {
        fn dim(&self) -> usize {
            1
        }
        fn rhs(&mut self, _t: f64, y: &[f64], f: &mut [f64]) -> kinema::Result<()> {
            f[0] = y[0] * y[0];
            Ok(())
        }
    }
    let run = |fail: bool| {
        let mut stepper = Stepper::new(Method::Bdf2, 1).unwrap();
        let mut y = [1.0];
        for k in 0..3 {
            stepper.step(&mut Square, 0.01 * k as f64, &mut y, 0.01).unwrap();
        }
        if fail {
            let before = y;
            assert!(stepper.step(&mut Square, 0.03, &mut y, 10.0).is_err());
            assert_eq!(y.map(f64::to_bits), before.map(f64::to_bits));
        }
        for k in 3..6 {
            stepper.step(&mut Square, 0.01 * k as f64, &mut y, 0.01).unwrap();
        }
        y[0].to_bits()
    };
    assert_eq!(run(true), run(false));
}

/// One workspace advances two histories of one system interleaved, with different initial
/// states and step lengths, each bitwise as a stepper of its own would, for every method (BDF2
/// reads its previous step from the history, the Newton iteration its settings): the workspace
/// carries nothing from one step to the next.
#[test]
fn one_workspace_steps_interleaved_histories_as_separate_steppers() {
    let mut sys = SpringChain { n: 3, k: 50.0 };
    let starts = [[0.1, -0.2, 0.3, 0.0, 0.5, -1.0], [-0.4, 0.0, 0.2, 1.0, 0.0, 0.3]];
    let hs = [0.01, 0.013];
    for method in Method::ALL {
        let mut work = kinema::ode::Workspace::default();
        let mut histories = [History::new(method, 6).unwrap(), History::new(method, 6).unwrap()];
        let mut ys = starts;
        let mut alone = [Stepper::new(method, 6).unwrap(), Stepper::new(method, 6).unwrap()];
        let mut ys_alone = starts;
        for s in 0..20 {
            for k in [1, 0] {
                let t = s as f64 * hs[k];
                let other = ys[1 - k];
                work.step(&mut histories[k], &mut sys, t, &mut ys[k], hs[k]).unwrap();
                assert_eq!(ys[1 - k].map(f64::to_bits), other.map(f64::to_bits));
                alone[k].step(&mut sys, t, &mut ys_alone[k], hs[k]).unwrap();
                assert_eq!(
                    ys[k].map(f64::to_bits),
                    ys_alone[k].map(f64::to_bits),
                    "{method:?} state {k} step {s}"
                );
                assert_eq!(histories[k], alone[k].history, "{method:?} history {k} step {s}");
            }
        }
    }
}
