//! The adaptive methods beyond the explicit pairs' step control (tests/ode.rs): Radau IIA on
//! linear, stiff and failing problems, and the dense output of every adaptive method.

use kinema::ode::{solve_adaptive, Adaptive, AdaptiveSolution, Event, OdeSystem};
use kinema::Error;
use nalgebra::DMatrix;

/// `x'' = -x` as `y = [x; v]`, solution `(cos t, -sin t)` from `(1, 0)`.
struct Oscillator;
impl OdeSystem for Oscillator {
    fn dim(&self) -> usize {
        2
    }
    fn rhs(&mut self, _t: f64, y: &[f64], f: &mut [f64]) -> kinema::Result<()> {
        f[0] = y[1];
        f[1] = -y[0];
        Ok(())
    }
}

/// `y' = A y` with `A = [[-1, 1], [0, -λ]]` (stiff for large `λ`), with or without its
/// Jacobian; solution `y₂ = e^{-λt} y₂(0)`, `y₁ = e^{-t} (y₁(0) + y₂(0)/(λ-1)) - y₂/(λ-1)`.
struct Stiff {
    lambda: f64,
    analytic: bool,
}
impl Stiff {
    fn exact(&self, t: f64, y0: [f64; 2]) -> [f64; 2] {
        let l = self.lambda;
        let y2 = (-l * t).exp() * y0[1];
        [(-t).exp() * (y0[0] + y0[1] / (l - 1.0)) - y2 / (l - 1.0), y2]
    }
}
impl OdeSystem for Stiff {
    fn dim(&self) -> usize {
        2
    }
    fn rhs(&mut self, _t: f64, y: &[f64], f: &mut [f64]) -> kinema::Result<()> {
        f[0] = -y[0] + y[1];
        f[1] = -self.lambda * y[1];
        Ok(())
    }
    fn jacobian(&mut self, _t: f64, _y: &[f64], j: &mut DMatrix<f64>) -> kinema::Result<bool> {
        if self.analytic {
            j.copy_from_slice(&[-1.0, 0.0, 1.0, -self.lambda]);
        }
        Ok(self.analytic)
    }
}

/// Robertson's chemical kinetics (Hairer & Wanner II, §IV.1, eq. 1.4); `y₁ + y₂ + y₃` is
/// conserved.
struct Robertson;
impl OdeSystem for Robertson {
    fn dim(&self) -> usize {
        3
    }
    fn rhs(&mut self, _t: f64, y: &[f64], f: &mut [f64]) -> kinema::Result<()> {
        f[0] = -0.04 * y[0] + 1e4 * y[1] * y[2];
        f[2] = 3e7 * y[1] * y[1];
        f[1] = -f[0] - f[2];
        Ok(())
    }
}

/// Van der Pol's oscillator `x'' = μ (1 - x²) x' - x` as `y = [x; x']`.
struct VanDerPol(f64);
impl OdeSystem for VanDerPol {
    fn dim(&self) -> usize {
        2
    }
    fn rhs(&mut self, _t: f64, y: &[f64], f: &mut [f64]) -> kinema::Result<()> {
        f[0] = y[1];
        f[1] = self.0 * (1.0 - y[0] * y[0]) * y[1] - y[0];
        Ok(())
    }
}

fn last(sol: &AdaptiveSolution, n: usize) -> &[f64] {
    &sol.y[sol.y.len() - n..]
}

/// Slope of `ln error` against `ln steps` between the first and last points.
fn slope(points: &[(f64, f64)]) -> f64 {
    let (a, b) = (points[0], points[points.len() - 1]);
    (b.1 / a.1).ln() / (b.0 / a.0).ln()
}

/// On a linear stiff system Radau meets its tolerance with either Jacobian, keeps its
/// factorisations while the step is unchanged (far fewer LUs than steps), evaluates the exact
/// Jacobian once (Newton on a linear system converges at once), and takes few steps where an
/// explicit pair is bounded by stability.
#[test]
fn radau_solves_a_stiff_linear_system_and_reuses_its_factors() {
    let y0 = [1.0, 1.0];
    for analytic in [true, false] {
        let mut sys = Stiff { lambda: 1e4, analytic };
        let sol = solve_adaptive(
            &mut sys,
            Adaptive::Radau,
            &y0,
            0.0,
            10.0,
            1e-8,
            1e-10,
            10_000,
            None,
            &[],
        )
        .unwrap();
        let exact = sys.exact(10.0, y0);
        let err = (last(&sol, 2)[0] - exact[0]).abs().max((last(&sol, 2)[1] - exact[1]).abs());
        assert!(err < 1e-8, "analytic {analytic}: error {err}");
        assert!(sol.steps < 600, "{} steps", sol.steps);
        assert!(sol.nlu < sol.steps / 2, "{} factorisations for {} steps", sol.nlu, sol.steps);
        if analytic {
            assert_eq!(sol.njev, 1);
        }
        let explicit = solve_adaptive(
            &mut sys,
            Adaptive::Dopri5,
            &y0,
            0.0,
            10.0,
            1e-8,
            1e-10,
            1_000_000,
            None,
            &[],
        )
        .unwrap();
        assert!(explicit.steps > 50 * sol.steps, "{} against {}", explicit.steps, sol.steps);
    }
}

/// Radau's error on the oscillator falls as steps^-5 (order 2s - 1 = 5 at the step points)
/// over four decades of tolerance and stays within a small multiple of it.
#[test]
fn radau_converges_at_order_five() {
    let mut points = Vec::new();
    for tol in [1e-6, 1e-8, 1e-10] {
        let sol = solve_adaptive(
            &mut Oscillator,
            Adaptive::Radau,
            &[1.0, 0.0],
            0.0,
            10.0,
            tol,
            tol,
            100_000,
            None,
            &[],
        )
        .unwrap();
        let y = last(&sol, 2);
        let err = (y[0] - 10f64.cos()).hypot(y[1] + 10f64.sin());
        assert!(err < 100.0 * tol, "tol {tol}: error {err}");
        points.push((sol.steps as f64, err));
    }
    let s = slope(&points);
    assert!((s + 5.0).abs() < 1.0, "error ~ steps^{s}, {points:?}");
}

/// Robertson's kinetics to t = 1e5 (eigenvalues to -1e4, steps growing to 1e4): hundreds of
/// steps, the conserved mass kept, and the known solution at t = 40 (Hairer & Wanner II,
/// IV.10, 0.7158, 9.185e-6, 0.2842).
#[test]
fn radau_solves_robertson_in_hundreds_of_steps() {
    let y0 = [1.0, 0.0, 0.0];
    let sol = solve_adaptive(
        &mut Robertson,
        Adaptive::Radau,
        &y0,
        0.0,
        1e5,
        1e-8,
        1e-12,
        100_000,
        Some(&[40.0, 1e5]),
        &[],
    )
    .unwrap();
    assert!(sol.steps < 600, "{} steps", sol.steps);
    let at40 = &sol.y[..3];
    assert!((at40[0] - 0.7158).abs() < 1e-4 && (at40[1] - 9.185e-6).abs() < 1e-8, "{at40:?}");
    for row in sol.y.chunks(3) {
        assert!((row.iter().sum::<f64>() - 1.0).abs() < 1e-10, "{row:?}");
    }
}

/// Van der Pol at μ = 1000 over [0, 3000] (one relaxation period ≈ 1614): hundreds of steps,
/// not millions, and back near x = 2 after the first period's jumps (compared with scipy's
/// Radau at tight tolerance in tests/python/test_ode_adaptive.py).
#[test]
fn radau_steps_through_van_der_pol_at_mu_1000() {
    let sol = solve_adaptive(
        &mut VanDerPol(1000.0),
        Adaptive::Radau,
        &[2.0, 0.0],
        0.0,
        3000.0,
        1e-6,
        1e-6,
        100_000,
        None,
        &[],
    )
    .unwrap();
    assert!(sol.steps < 1000, "{} steps, {} rejected", sol.steps, sol.rejected);
    assert!(sol.y.iter().all(|v| v.is_finite()));
}

/// `y' = y²` from 1 blows up at t = 1: past it Newton fails at every step size and the solve
/// reports a solver failure instead of looping or returning NaN.
#[test]
fn radau_reports_newton_failure() {
    struct Blowup;
    impl OdeSystem for Blowup {
        fn dim(&self) -> usize {
            1
        }
        fn rhs(&mut self, _t: f64, y: &[f64], f: &mut [f64]) -> kinema::Result<()> {
            f[0] = y[0] * y[0];
            Ok(())
        }
    }
    let r = solve_adaptive(
        &mut Blowup,
        Adaptive::Radau,
        &[1.0],
        0.0,
        2.0,
        1e-6,
        1e-9,
        100_000,
        None,
        &[],
    );
    assert!(matches!(r, Err(Error::SolverFailed { .. } | Error::Diverged { .. })), "{r:?}");
}

/// The dense output at times between the steps converges at the interpolant's order: error
/// ~ steps^-(q+1) with q = 4 (dopri5), 7 (dop853), 3 (radau's collocation polynomial), and
/// where the times are step points the dense output is the step's solution. Also: times out
/// of order or outside the span are refused.
#[test]
fn dense_output_converges_at_the_interpolants_order() {
    let t_eval: Vec<f64> = (0..=200).map(|i| 0.05 * i as f64).collect();
    for (method, tols, order) in [
        (Adaptive::Dopri5, [1e-5, 1e-7, 1e-9], 5.0),
        (Adaptive::Dop853, [1e-6, 1e-8, 1e-10], 8.0),
        (Adaptive::Radau, [1e-5, 1e-7, 1e-9], 4.0),
    ] {
        let mut points = Vec::new();
        for tol in tols {
            let sol = solve_adaptive(
                &mut Oscillator,
                method,
                &[1.0, 0.0],
                0.0,
                10.0,
                tol,
                tol,
                100_000,
                Some(&t_eval),
                &[],
            )
            .unwrap();
            assert_eq!(sol.t, t_eval);
            let err = t_eval
                .iter()
                .zip(sol.y.chunks(2))
                .map(|(t, y)| (y[0] - t.cos()).hypot(y[1] + t.sin()))
                .fold(0.0, f64::max);
            points.push((sol.steps as f64, err));
        }
        let s = slope(&points);
        assert!(
            (s + order).abs() < 0.25 * order,
            "{method:?}: dense error ~ steps^{s}, {points:?}"
        );
        let full = solve_adaptive(
            &mut Oscillator,
            method,
            &[1.0, 0.0],
            0.0,
            10.0,
            1e-6,
            1e-6,
            100_000,
            None,
            &[],
        )
        .unwrap();
        let at_steps = solve_adaptive(
            &mut Oscillator,
            method,
            &[1.0, 0.0],
            0.0,
            10.0,
            1e-6,
            1e-6,
            100_000,
            Some(&full.t),
            &[],
        )
        .unwrap();
        assert_eq!(at_steps.y, full.y, "{method:?}");
    }
    for bad in [vec![1.0, 0.5], vec![-1.0], vec![11.0]] {
        let r = solve_adaptive(
            &mut Oscillator,
            Adaptive::Dopri5,
            &[1.0, 0.0],
            0.0,
            10.0,
            1e-6,
            1e-6,
            100,
            Some(&bad),
            &[],
        );
        assert!(matches!(&r, Err(Error::InvalidInput { arg, .. }) if arg == "t_eval"), "{r:?}");
    }
}

/// A ball dropped from `h` (`y = [x; v]`, `x'' = -g`) with the event `x = 0`.
struct Ball;
impl OdeSystem for Ball {
    fn dim(&self) -> usize {
        2
    }
    fn rhs(&mut self, _t: f64, y: &[f64], f: &mut [f64]) -> kinema::Result<()> {
        f[0] = y[1];
        f[1] = -9.81;
        Ok(())
    }
    fn events(&mut self, _t: f64, y: &[f64], g: &mut [f64]) -> kinema::Result<()> {
        g[0] = y[0];
        Ok(())
    }
}

/// The ball hits the ground at `√(2h/g)` to 1e-12 relative with every method (its path is
/// a parabola, which every dense output represents exactly, so what is measured is the root
/// finder), and the terminal event ends the run there, at height 0.
#[test]
fn a_terminal_event_stops_the_dropped_ball_at_the_ground() {
    let exact = (2.0 * 10.0 / 9.81f64).sqrt();
    for method in Adaptive::ALL {
        let terminal = [Event { terminal: true, direction: -1.0 }];
        let sol = solve_adaptive(
            &mut Ball,
            method,
            &[10.0, 0.0],
            0.0,
            5.0,
            1e-6,
            1e-9,
            1000,
            None,
            &terminal,
        )
        .unwrap();
        let hit = sol.t_events[0][0];
        assert!((hit - exact).abs() < 1e-12 * exact, "{method:?}: {hit} against {exact}");
        assert!(sol.terminated && *sol.t.last().unwrap() == hit, "{method:?}");
        assert!(last(&sol, 2)[0].abs() < 1e-10, "{method:?}: {:?}", last(&sol, 2));
        let on = [Event { terminal: false, direction: -1.0 }];
        let past =
            solve_adaptive(&mut Ball, method, &[10.0, 0.0], 0.0, 5.0, 1e-6, 1e-9, 1000, None, &on)
                .unwrap();
        assert!(!past.terminated && *past.t.last().unwrap() == 5.0 && past.t_events[0].len() == 1);
    }
}

/// `x = cos t` crosses zero at π/2 (falling), 3π/2 (rising) and 5π/2 (falling) in [0, 10]:
/// `direction` keeps the falling, the rising, or all of them, each within the tolerance.
#[test]
fn event_direction_filters_crossings() {
    struct Cos;
    impl OdeSystem for Cos {
        fn dim(&self) -> usize {
            2
        }
        fn rhs(&mut self, t: f64, y: &[f64], f: &mut [f64]) -> kinema::Result<()> {
            Oscillator.rhs(t, y, f)
        }
        fn events(&mut self, _t: f64, y: &[f64], g: &mut [f64]) -> kinema::Result<()> {
            g.fill(y[0]);
            Ok(())
        }
    }
    let pi = std::f64::consts::PI;
    let events = [-1.0, 1.0, 0.0].map(|direction| Event { terminal: false, direction });
    for method in Adaptive::ALL {
        let sol = solve_adaptive(
            &mut Cos,
            method,
            &[1.0, 0.0],
            0.0,
            10.0,
            1e-10,
            1e-12,
            100_000,
            None,
            &events,
        )
        .unwrap();
        for (found, want) in sol.t_events.iter().zip([
            vec![0.5 * pi, 2.5 * pi],
            vec![1.5 * pi],
            vec![0.5 * pi, 1.5 * pi, 2.5 * pi],
        ]) {
            assert_eq!(found.len(), want.len(), "{method:?}: {found:?}");
            for (a, b) in found.iter().zip(&want) {
                assert!((a - b).abs() < 1e-8, "{method:?}: {found:?}");
            }
        }
    }
}
