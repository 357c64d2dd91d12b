"""Radau IIA and the dense output (t_eval) of kinema.ode.solve, against analytic solutions
and scipy's solve_ivp."""

from __future__ import annotations

import numpy as np
import pytest

import kinema
from kinema import ode

scipy_integrate = pytest.importorskip("scipy.integrate")


def van_der_pol(mu: float):
    def f(t, y):
        return np.array([y[1], mu * (1 - y[0] ** 2) * y[1] - y[0]])

    def jac(t, y):
        return np.array([[0.0, 1.0], [-2 * mu * y[0] * y[1] - 1, mu * (1 - y[0] ** 2)]])

    return f, jac


@pytest.mark.parametrize("use_jac", [True, False])
def test_radau_matches_the_exact_solution_of_a_stiff_linear_system(use_jac):
    a = np.array([[-1.0, 1.0, 0.0], [0.0, -1e3, 1.0], [0.0, -1.0, -1e3]])
    y0 = np.array([1.0, 1.0, -1.0])
    w, v = np.linalg.eig(a)
    c = np.linalg.solve(v, y0)
    t, y = ode.solve(
        lambda t, y: a @ y,
        y0,
        (0.0, 5.0),
        method="radau",
        rtol=1e-9,
        atol=1e-12,
        jac=(lambda t, y: a) if use_jac else None,
    )
    exact = np.real(v @ (c * np.exp(w * 5.0)))
    np.testing.assert_allclose(y[-1], exact, rtol=1e-8, atol=1e-12)
    peer = scipy_integrate.solve_ivp(
        lambda t, y: a @ y, (0.0, 5.0), y0, method="Radau", rtol=1e-9, atol=1e-12, jac=a
    )
    assert abs(len(t) - len(peer.t)) < 0.05 * len(peer.t), (len(t), len(peer.t))


def test_radau_agrees_with_scipy_on_van_der_pol_mu_1000():
    # One relaxation period (~1614 s) and more; both at tight tolerance, then kinema's step
    # counts at scipy's default-like tolerance: the same algorithm, the same few hundred steps.
    f, jac = van_der_pol(1000.0)
    _, y = ode.solve(f, [2.0, 0.0], (0.0, 3000.0), method="radau", rtol=1e-10, atol=1e-10, jac=jac)
    ref = scipy_integrate.solve_ivp(
        f, (0.0, 3000.0), [2.0, 0.0], method="Radau", rtol=1e-10, atol=1e-10, jac=jac
    )
    np.testing.assert_allclose(y[-1], ref.y[:, -1], rtol=1e-6, atol=1e-8)
    t, _ = ode.solve(f, [2.0, 0.0], (0.0, 3000.0), method="radau", rtol=1e-6, atol=1e-6)
    peer = scipy_integrate.solve_ivp(
        f, (0.0, 3000.0), [2.0, 0.0], method="Radau", rtol=1e-6, atol=1e-6
    )
    assert 100 < len(t) < 1000
    assert abs(len(t) - len(peer.t)) < 0.1 * len(peer.t), (len(t), len(peer.t))


@pytest.mark.parametrize(
    ("method", "peer"), [("dopri5", "RK45"), ("dop853", "DOP853"), ("radau", "Radau")]
)
def test_t_eval_returns_the_dense_output_at_those_times(method, peer):
    times = np.linspace(0.0, 10.0, 77)
    f = lambda t, y: np.array([y[1], -y[0]])  # noqa: E731
    t, y = ode.solve(f, [1.0, 0.0], (0.0, 10.0), method=method, rtol=1e-8, atol=1e-10, t_eval=times)
    np.testing.assert_array_equal(t, times)
    assert y.shape == (77, 2)
    exact = np.stack([np.cos(times), -np.sin(times)], axis=1)
    err = np.max(np.abs(y - exact))
    ref = scipy_integrate.solve_ivp(
        f, (0.0, 10.0), [1.0, 0.0], method=peer, rtol=1e-8, atol=1e-10, t_eval=times
    )
    peer_err = np.max(np.abs(ref.y.T - exact))
    assert err < 1e-6 and err < 10 * peer_err, (err, peer_err)


def test_bad_input_is_refused_naming_the_argument():
    f = lambda t, y: -y  # noqa: E731
    with pytest.raises(ValueError, match="t_eval"):
        ode.solve(f, [1.0], (0.0, 1.0), method="radau", t_eval=[0.5, 0.2])
    with pytest.raises(ValueError, match="t_eval"):
        ode.solve(f, [1.0], (0.0, 1.0), method="dop853", t_eval=[2.0])
    with pytest.raises(ValueError, match="t_eval"):
        ode.solve(f, [1.0], (0.0, 1.0), method="dopri5", t_eval=[np.nan])
    with pytest.raises(ValueError, match="t_eval"):
        ode.solve(f, [1.0], (0.0, 1.0), dt=0.1, method="rk4", t_eval=[0.5])
    with pytest.raises(ValueError, match="jac"):
        ode.solve(f, [1.0, 2.0], (0.0, 1.0), method="radau", jac=lambda t, y: np.eye(3))
    with pytest.raises(ValueError, match="jac"):
        ode.solve(f, [1.0], (0.0, 1.0), method="radau", jac=np.eye(1))
    with pytest.raises(ZeroDivisionError):
        ode.solve(f, [1.0], (0.0, 1.0), method="radau", jac=lambda t, y: 1 / 0)


def test_newton_failure_raises_simulation_error_with_the_input_unchanged():
    # y' = y² from 1 blows up at t = 1; past it no step size lets Newton converge.
    y0 = np.array([1.0])
    with pytest.raises(kinema.SimulationError):
        ode.solve(lambda t, y: y**2, y0, (0.0, 2.0), method="radau")
    assert y0.tolist() == [1.0]


@pytest.mark.parametrize("method", ["dopri5", "dop853", "radau"])
def test_a_ball_dropped_from_a_height_hits_the_ground_at_sqrt_2h_over_g(method):
    h, g = 10.0, 9.81

    def ground(t, y):
        return y[0]

    ground.terminal = True  # type: ignore[attr-defined]
    ground.direction = -1  # type: ignore[attr-defined]
    t, y, t_ev, y_ev = ode.solve(
        lambda t, y: [y[1], -g], [h, 0.0], (0.0, 5.0), method=method, events=[ground]
    )
    exact = np.sqrt(2 * h / g)
    assert abs(t_ev[0][0] - exact) < 1e-12 * exact
    assert t[-1] == t_ev[0][0] and abs(y[-1, 0]) < 1e-10
    np.testing.assert_allclose(y_ev[0][0], [0.0, -g * exact], atol=1e-9)


def test_event_direction_and_scipy_agree():
    f = lambda t, y: np.array([y[1], -y[0]])  # noqa: E731

    def rising(t, y):
        return y[0]

    rising.direction = 1  # type: ignore[attr-defined]

    def any_crossing(t, y):
        return y[0]

    _, _, t_ev, _ = ode.solve(
        f,
        [1.0, 0.0],
        (0.0, 10.0),
        method="dop853",
        rtol=1e-10,
        atol=1e-12,
        events=[rising, any_crossing],
    )
    np.testing.assert_allclose(t_ev[0], [1.5 * np.pi], atol=1e-8)
    np.testing.assert_allclose(t_ev[1], [0.5 * np.pi, 1.5 * np.pi, 2.5 * np.pi], atol=1e-8)
    ref = scipy_integrate.solve_ivp(
        f,
        (0.0, 10.0),
        [1.0, 0.0],
        method="DOP853",
        rtol=1e-10,
        atol=1e-12,
        events=[rising, any_crossing],
    )
    for ours, theirs in zip(t_ev, ref.t_events, strict=True):
        np.testing.assert_allclose(ours, theirs, atol=1e-9)


def test_bad_events_are_refused():
    f = lambda t, y: -y  # noqa: E731
    with pytest.raises(ValueError, match="events"):
        ode.solve(f, [1.0], (0.0, 1.0), method="dopri5", events=[1.0])
    with pytest.raises(ValueError, match="events"):
        ode.solve(f, [1.0], (0.0, 1.0), method="dopri5", events=lambda t, y: y[0])
    with pytest.raises(ValueError, match="events"):
        ode.solve(f, [1.0], (0.0, 1.0), dt=0.1, method="rk4", events=[lambda t, y: y[0]])
    with pytest.raises(ValueError, match="events"):
        ode.solve(f, [1.0], (0.0, 1.0), method="radau", events=[lambda t, y: np.nan])
    with pytest.raises(ZeroDivisionError):
        ode.solve(f, [1.0], (0.0, 1.0), method="dop853", events=[lambda t, y: 1 / 0])


@pytest.mark.parametrize(
    ("method", "dt"), [("radau", None), ("implicit_euler", 1.0), ("bdf2", 1.0)]
)
def test_vectorized_differences_are_one_call_and_the_unvectorised_result(method, dt):
    # Van der Pol at mu = 1000 written elementwise, so that a column of (n, k) is computed with
    # the same operations as a state alone: the vectorised finite-difference Jacobian (one
    # call of f per Jacobian) gives bitwise the solution of the column-by-column one.
    mu, shapes = 1000.0, []

    def f(t, y):
        shapes.append(np.shape(y))
        return np.array([y[1], mu * (1 - y[0] ** 2) * y[1] - y[0]])

    kw = {"rtol": 1e-6, "atol": 1e-6} if dt is None else {"dt": dt}
    _, plain = ode.solve(f, [2.0, 0.0], (0.0, 30.0), method=method, **kw)
    calls_plain = len(shapes)
    shapes.clear()
    _, vec = ode.solve(f, [2.0, 0.0], (0.0, 30.0), method=method, vectorized=True, **kw)
    np.testing.assert_array_equal(vec, plain)
    columns = [s for s in shapes if s != (2,)]
    assert columns and all(s == (2, 2) for s in columns), set(shapes)
    # Each Jacobian took one call instead of two.
    assert len(shapes) == calls_plain - len(columns), (len(shapes), calls_plain, len(columns))


def test_vectorized_right_hand_sides_that_return_a_bad_shape_are_refused():
    with pytest.raises(ValueError, match="vectorized"):
        ode.solve(lambda t, y: np.zeros(2), [1.0, 0.0], (0.0, 1.0), method="radau", vectorized=True)
    with pytest.raises(ValueError, match="vectorized"):
        ode.solve(lambda t, y: -y, [1.0], (0.0, 1.0), method="radau", vectorized="yes")
