"""kinema.ode through Python: orders on the built-in problems, stability analysis against the
closed forms, agreement with scipy.integrate.solve_ivp, and bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import kinema
from kinema import ode


@pytest.mark.parametrize("method", sorted(ode.METHODS))
def test_observed_order_on_the_damped_spring(method):
    rows = ode.work_precision("damped_spring", [method], [0.01, 0.005])
    observed = math.log2(rows[0].error / rows[1].error)
    assert abs(observed - ode.METHODS[method]) < 0.15, observed


def _manufactured(t: float, y: np.ndarray) -> list[float]:
    """``x'' = -x³ - x x' + g(t)`` solved by ``x = sin t``: nonlinear and time-dependent, so the
    midpoint rule and Heun differ and a stage taken at the wrong time loses an order."""
    s, c = math.sin(t), math.cos(t)
    return [y[1], -(y[0] ** 3) - y[0] * y[1] - s + s**3 + s * c]


@pytest.mark.parametrize("method", sorted(ode.METHODS))
def test_observed_order_on_a_nonlinear_time_dependent_problem(method):
    def error(dt: float) -> float:
        _, y = ode.solve(_manufactured, [0.0, 1.0], (0, 2), dt=dt, method=method)
        return float(np.hypot(y[-1, 0] - math.sin(2), y[-1, 1] - math.cos(2)))

    dt = 0.05 if method == "rk4" else 0.005
    observed = math.log2(error(dt) / error(dt / 2))
    assert abs(observed - ode.METHODS[method]) < 0.1, observed


def test_dopri5_agrees_with_scipy_on_kepler():
    prob = ode.PROBLEMS["kepler"]()
    t, y = ode.solve(prob.f, prob.y0, prob.t_span, method="dopri5", rtol=1e-10, atol=1e-12)
    ref = solve_ivp(prob.f, prob.t_span, prob.y0, method="DOP853", rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(y[-1], ref.y[:, -1], atol=1e-8)
    np.testing.assert_allclose(y[-1], prob.exact(prob.t_span[1]), atol=1e-8)
    assert t[0] == 0.0 and t[-1] == prob.t_span[1]


@pytest.mark.parametrize(("method", "peer"), [("dopri5", "RK45"), ("dop853", "DOP853")])
@pytest.mark.parametrize("rtol", [1e-5, 1e-8])
def test_adaptive_pairs_match_scipy_in_error_and_evaluations(method, peer, rtol):
    """At equal tolerances the error on Kepler's orbit is of scipy's order of magnitude, and
    ``f`` is called about as often as scipy calls it (the same pair, the same controller)."""
    prob = ode.PROBLEMS["kepler"]()
    exact = prob.exact(prob.t_span[1])
    calls = [0]

    def f(t: float, y: np.ndarray) -> np.ndarray:
        calls[0] += 1
        return prob.f(t, y)

    _, y = ode.solve(f, prob.y0, prob.t_span, method=method, rtol=rtol, atol=rtol * 1e-3)
    ref = solve_ivp(prob.f, prob.t_span, prob.y0, method=peer, rtol=rtol, atol=rtol * 1e-3)
    ours, theirs = np.max(np.abs(y[-1] - exact)), np.max(np.abs(ref.y[:, -1] - exact))
    assert 0.1 < ours / theirs < 10, (ours, theirs)
    assert 0.5 < calls[0] / ref.nfev < 2, (calls[0], ref.nfev)


def test_dop853_reaches_tight_tolerances_with_fewer_evaluations_than_dopri5():
    prob = ode.PROBLEMS["kepler"]()
    counts = {}
    for method in ode.ADAPTIVE:
        calls = [0]

        def f(t: float, y: np.ndarray, calls: list[int] = calls) -> np.ndarray:
            calls[0] += 1
            return prob.f(t, y)

        _, y = ode.solve(f, prob.y0, prob.t_span, method=method, rtol=1e-11, atol=1e-14)
        assert np.max(np.abs(y[-1] - prob.exact(prob.t_span[1]))) < 1e-7
        counts[method] = calls[0]
    assert counts["dop853"] < 0.5 * counts["dopri5"], counts


def test_right_hand_sides_of_any_array_like_are_read():
    """A list, a column or a strided array from ``f`` give the same steps as a flat array."""
    flat = ode.solve(lambda t, y: -y, [1.0, 2.0], (0, 1), method="dop853")[1]
    for f in [
        lambda t, y: [-y[0], -y[1]],
        lambda t, y: (-y).reshape(2, 1),
        lambda t, y: np.stack([-y, y])[0],
        lambda t, y: np.asfortranarray(-np.stack([y, y]).T)[:, 0],
    ]:
        np.testing.assert_array_equal(ode.solve(f, [1.0, 2.0], (0, 1), method="dop853")[1], flat)
    with pytest.raises(ValueError, match="f: returned 3 values"):
        ode.solve(lambda t, y: [1.0, 2.0, 3.0], [1.0, 2.0], (0, 1), method="dop853")


def test_implicit_methods_on_the_stiff_chain_with_and_without_jacobian():
    prob = ode.PROBLEMS["spring_chain"]()
    exact = prob.exact(prob.t_span[1])
    # Accuracy at h ω_max = 0.2: first-order implicit Euler damps the fast modes most.
    for method, bound in [("implicit_euler", 0.5), ("trapezoidal", 0.05), ("bdf2", 0.1)]:
        _, with_jac = ode.solve(prob.f, prob.y0, prob.t_span, dt=1e-3, method=method, jac=prob.jac)
        _, no_jac = ode.solve(prob.f, prob.y0, prob.t_span, dt=1e-3, method=method)
        np.testing.assert_allclose(with_jac[-1], no_jac[-1], atol=1e-6)
        assert np.max(np.abs(with_jac[-1] - exact)) < bound


def _steps_of_decay(method: str, z: complex, steps: int) -> np.ndarray:
    """``steps`` steps of 1 of the real stepper on ``y' = z y`` from ``y = 1``, as complex."""
    a, b = z.real, z.imag
    _, y = ode.solve(
        lambda t, y: [a * y[0] - b * y[1], b * y[0] + a * y[1]],
        [1.0, 0.0],
        (0, steps),
        dt=1.0,
        method=method,
        jac=lambda t, y: [[a, -b], [b, a]],
    )
    return y[:, 0] + 1j * y[:, 1]


@pytest.mark.parametrize(
    "method", ["explicit_euler", "heun", "rk4", "implicit_euler", "trapezoidal"]
)
def test_stability_function_is_the_steppers_measured_amplification(method):
    for z in [-1.0, 0.3j, -2 + 1j, -0.2 + 0.4j, -40.0]:
        measured = _steps_of_decay(method, z, 1)[-1]
        assert abs(measured - ode.stability_function(method, z)) < 1e-13 * max(1, abs(measured))


def test_bdf2_stability_function_is_the_measured_growth_per_step():
    # After many steps the growth per step is the dominant root (the other is at most about
    # half of it at these z; at z = -1/2 the two roots coincide).
    for z in [-0.1, -0.3, 0.3j, -0.2 + 0.4j]:
        y = _steps_of_decay("bdf2", z, 80)
        assert abs(y[-1] / y[-2] - ode.stability_function("bdf2", z)) < 1e-12


def test_stability_function_and_limits():
    assert ode.stability_function("explicit_euler", -1.5) == pytest.approx(-0.5)
    z = np.array([-1.0, 1j, -2 + 1j])
    np.testing.assert_allclose(
        ode.stability_function("rk4", z), 1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24
    )
    # Explicit Euler near the imaginary axis: stable up to 2 |Re λ| / |λ|².
    lam = -1e-4 + 1j
    limit = ode.max_stable_dt("explicit_euler", [lam])
    assert limit == pytest.approx(2e-4 / abs(lam) ** 2, rel=1e-12)
    assert abs(_steps_of_decay("explicit_euler", lam * 0.99 * limit, 1)[-1]) <= 1.0
    assert abs(_steps_of_decay("explicit_euler", lam * 1.01 * limit, 1)[-1]) > 1.0
    assert ode.max_stable_dt("explicit_euler", [-4.0]) == pytest.approx(0.5, rel=1e-12)
    assert ode.max_stable_dt("rk4", [3j, -3j]) == pytest.approx(math.sqrt(8) / 3, rel=1e-10)
    assert ode.max_stable_dt("velocity_verlet", [10j]) == pytest.approx(0.2, rel=1e-10)
    assert ode.max_stable_dt("bdf2", [-1e9, 1e3j]) == math.inf
    assert ode.max_stable_dt("explicit_euler", [1j]) == 0.0


def test_measured_limit_matches_max_stable_dt():
    lam = -50.0
    h = ode.max_stable_dt("heun", [lam])
    for factor, grows in [(0.99, False), (1.01, True)]:
        _, y = ode.solve(
            lambda t, y: lam * y, [1.0], (0, 2000 * factor * h), dt=factor * h, method="heun"
        )
        assert (abs(y[-1, 0]) > 1.0) == grows


def test_second_order_and_energy():
    t, x, v = ode.solve_second_order(lambda t, x, v: -x, [1.0], [0.0], (0, 100), dt=0.05)
    energy = 0.5 * (x[:, 0] ** 2 + v[:, 0] ** 2)
    assert np.max(np.abs(energy - 0.5)) < 1e-3
    assert len(t) == 2001 and x.shape == (2001, 1)


def test_bad_input_and_errors():
    with pytest.raises(ValueError, match="dt"):
        ode.solve(lambda t, y: y, [1.0], (0, 1), method="rk4")
    with pytest.raises(ValueError, match="method"):
        ode.solve(lambda t, y: y, [1.0], (0, 1), dt=0.1, method="rk45")
    with pytest.raises(ValueError, match="t_span"):
        ode.solve(lambda t, y: y, [1.0], (1, 0), dt=0.1)
    with pytest.raises(ValueError, match="y0"):
        ode.solve(lambda t, y: y, [np.nan], (0, 1), dt=0.1)
    with pytest.raises(ValueError, match="f: returned 2 values"):
        ode.solve(lambda t, y: [1.0, 2.0], [1.0], (0, 1), dt=0.1)
    with pytest.raises(ZeroDivisionError):
        ode.solve(lambda t, y: 1 / 0, [1.0], (0, 1), dt=0.1)
    with pytest.raises(kinema.SimulationError, match="step 0"), np.errstate(over="ignore"):
        ode.solve(lambda t, y: 1e300 * y, [1e300], (0, 1), dt=1.0, method="explicit_euler")
    with pytest.raises(ValueError, match="eigenvalues"):
        ode.max_stable_dt("rk4", [1.0])
    with pytest.raises(ValueError, match="even length"):
        ode.solve(lambda t, y: y, [1.0], (0, 1), dt=0.1, method="symplectic_euler")
    with pytest.raises(ValueError, match="problem: 'harmonic' is not one of decay, oscillator"):
        ode.work_precision("harmonic", ["rk4"], [0.1])
    with pytest.raises(ValueError, match="problem: expected a name or a Problem"):
        ode.work_precision(3, ["rk4"], [0.1])
    with pytest.raises(ValueError, match="method"):
        ode.work_precision("decay", ["rk45"], [0.1])
