//! Integrators: observed convergence orders, stability limits against `max_stable_dt`,
//! stiff problems, long-run energy behaviour, failures that leave the state unchanged.

use kinema::ode::{
    max_stable_dt, max_stable_dt_oscillator, solve_adaptive, stability_function, Method, OdeSystem,
    Stepper,
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

#[test]
fn dormand_prince_is_fifth_order_at_tight_tolerance() {
    let mut points = Vec::new();
    for tol in [1e-7, 1e-9, 1e-11] {
        let sol =
            solve_adaptive(&mut Oscillator(1.0), &[1.0, 0.0], 0.0, 10.0, tol, tol * 1e-3, 100_000)
                .unwrap();
        let y = &sol.y[sol.y.len() - 2..];
        let err = ((y[0] - 10f64.cos()).powi(2) + (y[1] + 10f64.sin()).powi(2)).sqrt();
        points.push(((sol.t.len() - 1) as f64, err));
        assert!(err < 200.0 * tol, "tol {tol}: error {err}");
    }
    let slope = (points[2].1 / points[0].1).ln() / (points[2].0 / points[0].0).ln();
    assert!((slope + 5.0).abs() < 0.5, "error ~ steps^{slope}");
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
    assert!((stability_function(Method::Trapezoidal, z(0.0, 7.0))).norm() - 1.0 < 1e-15);
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
    stepper.max_newton = 1;
    let mut y = [1.0];
    assert!(matches!(stepper.step(&mut Cubic, 0.0, &mut y, 1.0), Err(Error::SolverFailed { .. })));
    assert_eq!(y, [1.0]);
    stepper.max_newton = 50;
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
