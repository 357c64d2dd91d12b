"""Time integration: fixed-step methods, adaptive Dormand–Prince pairs and Radau IIA with
dense output, and their stability analysis.

Methods (``method=``), each with its order and stability function ``R(z)`` on ``y' = λy``:

============================  =====  =============================================
name                          order  notes
============================  =====  =============================================
``explicit_euler``            1      ``R = 1 + z``
``midpoint``, ``heun``        2      ``R = 1 + z + z²/2``
``rk4``                       4      classic Runge–Kutta
``symplectic_euler``          1      second-order systems ``[x; v]``; symplectic
``velocity_verlet``           2      second-order systems; symplectic, reversible
``implicit_euler``            1      L-stable; Newton with ``jac`` or differences
``trapezoidal``               2      A-stable (Crank–Nicolson)
``bdf2``                      2      A-stable two-step BDF (variable step)
``dopri5``                    5(4)   adaptive, ``rtol``/``atol`` instead of ``dt``
``dop853``                    8(5,3) adaptive (Hairer's DOP853), for tight tolerances
``radau``                     5      adaptive, implicit (Hairer's RADAU5), for stiff problems
============================  =====  =============================================

Sources: Hairer, Nørsett & Wanner, *Solving ODEs I* (explicit RK, Dormand & Prince 1980,
Prince & Dormand 1981, §II.10 for DOP853);
Hairer & Wanner, *Solving ODEs II* (implicit methods, §IV.8 for Radau IIA); Hairer, Lubich & Wanner, *Geometric
Numerical Integration* (symplectic methods). The integrators run in Rust; ``f`` is called from
Rust once per stage, so for small systems the cost is dominated by the Python call.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from kinema import _kinema
from kinema._array import real

__all__ = [
    "ADAPTIVE",
    "METHODS",
    "PROBLEMS",
    "Problem",
    "WorkPrecisionRow",
    "max_stable_dt",
    "max_stable_dt_oscillator",
    "solve",
    "solve_second_order",
    "stability_function",
    "work_precision",
]

METHODS: dict[str, int] = {name: order for name, order, _, _ in _kinema.ode_methods()}
"""Fixed-step method names and their orders (see :data:`ADAPTIVE` for the adaptive ones)."""
ADAPTIVE: dict[str, int] = {"dopri5": 5, "dop853": 8, "radau": 5}
"""Adaptive method names (the embedded Runge–Kutta pairs and Radau IIA) and the orders of
their solutions."""
METHODS_SECOND_ORDER = {name for name, _, _, second in _kinema.ode_methods() if second}


def _span(t_span: Any) -> tuple[float, float]:
    try:
        t0, t1 = (float(t) for t in t_span)
    except (TypeError, ValueError):
        raise ValueError(f"t_span: expected (t0, t1), got {t_span!r}") from None
    if not (math.isfinite(t0) and math.isfinite(t1) and t1 > t0):
        raise ValueError(f"t_span: expected finite t0 < t1, got ({t0}, {t1})")
    return t0, t1


def _state(y0: Any, name: str = "y0") -> np.ndarray:
    try:
        y = np.ascontiguousarray(np.asarray(y0, dtype=np.float64).ravel())
    except (TypeError, ValueError) as e:
        raise ValueError(f"{name}: cannot convert to a float64 array ({e})") from None
    if not np.isfinite(y).all():
        raise ValueError(f"{name}: contains NaN or infinity")
    return y


def solve(
    f: Callable[[float, np.ndarray], Any],
    y0: Any,
    t_span: Sequence[float],
    dt: float | None = None,
    method: str = "rk4",
    jac: Callable[[float, np.ndarray], Any] | None = None,
    rtol: float = 1e-6,
    atol: float = 1e-9,
    max_steps: int = 1_000_000,
    t_eval: Any = None,
    events: Sequence[Callable[[float, np.ndarray], float]] | None = None,
    vectorized: bool = False,
) -> tuple[Any, ...]:
    """Integrate ``y' = f(t, y)`` over ``t_span = (t0, t1)``; returns ``(t, y)``.

    Fixed-step methods need ``dt`` (s): ``ceil((t1 - t0) / dt)`` equal steps are taken so
    that the last lands on ``t1``; ``t`` is ``(M,)`` and ``y`` is ``(M, n)``. The adaptive
    methods ``"dopri5"`` (scipy's ``RK45``), ``"dop853"`` (scipy's ``DOP853``) and
    ``"radau"`` (scipy's ``Radau``, implicit, for stiff problems) adapt the step to keep the
    local error below ``atol + rtol |y|`` and return the accepted steps, or, with ``t_eval``
    (non-decreasing times within ``t_span``), the solution at those times from the method's
    dense output (orders 4, 7 and 3). Either way at most ``max_steps`` steps are taken: a
    ``dt`` that needs more raises ValueError naming ``dt`` before anything is allocated, the
    adaptive methods raise ``kinema.SimulationError`` when it runs out. Implicit methods
    (fixed-step ones and ``radau``) use ``jac(t, y) -> (n, n)`` when given, else finite
    differences. With ``vectorized=True`` (scipy's meaning) ``f`` also accepts ``y`` of shape
    ``(n, k)``, k states as columns, and returns ``(n, k)``: the finite differences then
    evaluate all ``n`` columns of the Jacobian in one call of ``f`` instead of ``n`` (the
    stages of the Runge–Kutta methods depend on each other and are called one by one).

    ``events`` (adaptive methods only), as scipy's: functions ``g(t, y) -> float`` whose zeros
    are located on the dense output to 1e-12 relative in ``t``; an attribute ``terminal``
    (true: stop at the first zero, which becomes the last time returned) and ``direction``
    (``> 0`` counts only zeros where ``g`` rises, ``< 0`` where it falls, ``0`` both). With
    events the result is ``(t, y, t_events, y_events)``: per event the times ``(k,)`` and
    states ``(k, n)`` of its zeros.

    Raises ValueError for bad arguments, ``kinema.SimulationError`` when the state diverges
    (naming the step and component) or Newton fails; exceptions raised by ``f`` propagate.
    """
    t0, t1 = _span(t_span)
    y = _state(y0)
    if not callable(f):
        raise ValueError("f: expected a callable f(t, y)")
    if isinstance(max_steps, bool) or not isinstance(max_steps, int | np.integer) or max_steps < 1:
        raise ValueError(f"max_steps: expected a positive integer, got {max_steps!r}")
    if not isinstance(vectorized, bool | np.bool_):
        raise ValueError(f"vectorized: expected a bool, got {vectorized!r}")
    if jac is not None and not callable(jac):
        raise ValueError("jac: expected a callable jac(t, y) -> (n, n) or None")
    specs = []
    if callable(events) or isinstance(events, str):
        raise ValueError("events: expected a list of callables g(t, y) -> float")
    for g in events or ():
        if not callable(g):
            raise ValueError(f"events: expected callables g(t, y) -> float, got {g!r}")
        direction = real(getattr(g, "direction", 0.0), "events: direction")
        specs.append((g, bool(getattr(g, "terminal", False)), direction))
    if method in ADAPTIVE:
        times = None if t_eval is None else _state(t_eval, "t_eval")
        t, states, _, t_ev, y_ev, _ = _kinema.ode_solve_adaptive(
            f,
            method,
            y,
            t0,
            t1,
            real(rtol, "rtol"),
            real(atol, "atol"),
            max_steps,
            jac,
            times,
            specs,
            bool(vectorized),
        )
        return (t, states) if events is None else (t, states, t_ev, y_ev)
    for name, value in [("t_eval", t_eval), ("events", events)]:
        if value is not None:
            raise ValueError(f"{name}: only the adaptive methods ({', '.join(ADAPTIVE)}) take it")
    if method not in METHODS:
        raise ValueError(f"method: {method!r} is not one of {', '.join([*METHODS, *ADAPTIVE])}")
    if dt is None or not (real(dt, "dt") > 0 and math.isfinite(real(dt, "dt"))):
        raise ValueError(f"dt: fixed-step method {method!r} needs a positive finite dt, got {dt!r}")
    count = (t1 - t0) / real(dt, "dt")
    if not count - 1e-9 <= max_steps:
        raise ValueError(
            f"dt: {dt!r} over t_span ({t0}, {t1}) needs {count:.3g} steps, more than "
            f"max_steps={max_steps}; raise dt or max_steps"
        )
    steps = max(1, math.ceil(count - 1e-9))
    states, _, _ = _kinema.ode_solve_fixed(f, y, t0, t1, steps, method, jac, bool(vectorized))
    return np.linspace(t0, t1, steps + 1), states


def solve_second_order(
    accel: Callable[[float, np.ndarray, np.ndarray], Any],
    x0: Any,
    v0: Any,
    t_span: Sequence[float],
    dt: float,
    method: str = "velocity_verlet",
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Integrate ``x'' = accel(t, x, v)``; returns ``(t, x, v)`` with ``x``, ``v`` ``(M, n)``.

    Any fixed-step method works; ``symplectic_euler`` and ``velocity_verlet`` use the
    structure (they keep the energy of conservative systems bounded for all time).
    """
    x, v = _state(x0, "x0"), _state(v0, "v0")
    if x.shape != v.shape:
        raise ValueError(f"v0: expected the shape of x0 {x.shape}, got {v.shape}")
    n = len(x)

    def f(t: float, y: np.ndarray) -> np.ndarray:
        return np.concatenate([y[n:], np.asarray(accel(t, y[:n], y[n:]), dtype=np.float64).ravel()])

    t, y = solve(f, np.concatenate([x, v]), t_span, dt=dt, method=method)
    return t, y[:, :n], y[:, n:]


def stability_function(method: str, z: Any) -> Any:
    """``R(z)`` of ``method``: the growth factor per step on ``y' = λy`` at ``z = hλ``.

    ``z`` is a complex scalar or array; the result has its shape. For ``bdf2`` it is the root
    of largest modulus of the characteristic polynomial; for the second-order methods the
    dominant eigenvalue of the amplification matrix on ``x'' = (z/h)² x`` (see the Rust docs).
    """
    zz = np.asarray(z, dtype=np.complex128)
    pairs = np.ascontiguousarray(np.stack([zz.real.ravel(), zz.imag.ravel()], axis=1))
    if method not in METHODS:
        raise ValueError(f"method: {method!r} is not one of {', '.join(METHODS)}")
    out = _kinema.ode_stability_function(method, pairs)
    r = (out[:, 0] + 1j * out[:, 1]).reshape(zz.shape)
    return complex(r) if zz.ndim == 0 else r


def max_stable_dt(method: str, eigenvalues: Any) -> float:
    """The largest step ``h`` with ``|R(hλ)| ≤ 1`` for every eigenvalue ``λ`` and every smaller
    step; ``inf`` for A-stable methods, ``0`` where no positive step is stable (explicit Euler
    on an undamped oscillator). Eigenvalues must have non-positive real part."""
    lam = np.atleast_1d(np.asarray(eigenvalues, dtype=np.complex128)).ravel()
    if method not in METHODS:
        raise ValueError(f"method: {method!r} is not one of {', '.join(METHODS)}")
    return _kinema.ode_max_stable_dt(
        method, np.ascontiguousarray(np.stack([lam.real, lam.imag], axis=1))
    )


def max_stable_dt_oscillator(method: str, omega: float, damping: float = 0.0) -> float:
    """The largest stable step of ``method`` on the mode ``x'' + c x' + ω² x = 0`` (``omega``
    rad/s, ``damping`` = ``c`` 1/s): a spring, or the fastest vibration of a cloth
    (:meth:`kinema.cloth.Cloth.fastest_mode`). First-order methods are judged on the mode's two
    eigenvalues (as :func:`max_stable_dt`); symplectic Euler and velocity Verlet on the spectral
    radius of their amplification matrix on the mode, which for an overdamped mode depends on
    both eigenvalues at once. ``inf`` for A-stable methods."""
    if method not in METHODS:
        raise ValueError(f"method: {method!r} is not one of {', '.join(METHODS)}")
    return _kinema.ode_max_stable_dt_oscillator(
        method, real(omega, "omega"), real(damping, "damping")
    )


# ----------------------------------------------------------------------------- problems
@dataclass(frozen=True)
class Problem:
    """An initial-value problem with a known solution, for measuring accuracy."""

    name: str
    f: Callable[[float, np.ndarray], np.ndarray]
    y0: np.ndarray
    t_span: tuple[float, float]
    exact: Callable[[float], np.ndarray]
    second_order: bool = False
    jac: Callable[[float, np.ndarray], np.ndarray] | None = None


def _kepler(e: float = 0.5) -> Problem:
    # Unit semi-major axis, GM = 1, period 2π, start at pericentre.
    def f(t: float, y: np.ndarray) -> np.ndarray:
        r3 = (y[0] ** 2 + y[1] ** 2) ** 1.5
        return np.array([y[2], y[3], -y[0] / r3, -y[1] / r3])

    def exact(t: float) -> np.ndarray:
        m = t  # mean anomaly
        ecc = m
        for _ in range(50):  # Newton on Kepler's equation E - e sin E = M
            ecc -= (ecc - e * math.sin(ecc) - m) / (1 - e * math.cos(ecc))
        c, s = math.cos(ecc), math.sin(ecc)
        b = math.sqrt(1 - e * e)
        edot = 1 / (1 - e * c)
        return np.array([c - e, b * s, -s * edot, b * c * edot])

    return Problem("kepler", f, exact(0.0), (0.0, 2 * math.pi), exact, second_order=True)


def _spring_chain(n: int = 8, k: float = 1e4) -> Problem:
    # Unit masses, springs of stiffness k, first spring to a wall; linear, exact via eigenvectors.
    lap = 2 * np.eye(n) - np.eye(n, k=1) - np.eye(n, k=-1)
    lap[-1, -1] = 1.0
    a = np.block([[np.zeros((n, n)), np.eye(n)], [-k * lap, np.zeros((n, n))]])
    y0 = np.concatenate([np.linspace(0, 0.1, n), np.zeros(n)])
    w, v = np.linalg.eig(a)
    c = np.linalg.solve(v, y0)

    def exact(t: float) -> np.ndarray:
        return np.real(v @ (c * np.exp(w * t)))

    return Problem("spring_chain", lambda t, y: a @ y, y0, (0.0, 0.1), exact, True, lambda t, y: a)


def _pendulum() -> Problem:
    # θ'' = -sin θ from θ = 2 rad at rest; reference from Dormand–Prince at rtol 1e-13.
    def f(t: float, y: np.ndarray) -> np.ndarray:
        return np.array([y[1], -math.sin(y[0])])

    cache: dict[float, np.ndarray] = {}

    def exact(t: float) -> np.ndarray:
        if t not in cache:
            cache[t] = solve(f, [2.0, 0.0], (0.0, t), method="dopri5", rtol=1e-13, atol=1e-15)[1][
                -1
            ]
        return cache[t]

    return Problem("pendulum", f, np.array([2.0, 0.0]), (0.0, 10.0), exact, True)


def _linear(name: str, a: np.ndarray, y0: np.ndarray, t1: float, second: bool) -> Problem:
    w, v = np.linalg.eig(a)
    c = np.linalg.solve(v, y0)
    return Problem(
        name,
        lambda t, y: a @ y,
        y0,
        (0.0, t1),
        lambda t: np.real(v @ (c * np.exp(w * t))),
        second,
        lambda t, y: a,
    )


PROBLEMS: dict[str, Callable[[], Problem]] = {
    "decay": lambda: _linear("decay", np.array([[-2.0]]), np.array([1.0]), 2.0, False),
    "oscillator": lambda: _linear(
        "oscillator", np.array([[0.0, 1.0], [-1.0, 0.0]]), np.array([1.0, 0.0]), 10.0, True
    ),
    "damped_spring": lambda: _linear(
        "damped_spring", np.array([[0.0, 1.0], [-4.0, -0.4]]), np.array([1.0, 0.0]), 10.0, True
    ),
    "pendulum": _pendulum,
    "kepler": _kepler,
    "spring_chain": _spring_chain,
}
"""Built-in problems with known solutions: ``x' = λx``, harmonic oscillator, damped spring,
pendulum, Kepler orbit (eccentricity 0.5, one period), a stiff spring chain (k = 1e4)."""


@dataclass(frozen=True)
class WorkPrecisionRow:
    """One run of :func:`work_precision`: final-state error, wall time and f-evaluations."""

    problem: str
    method: str
    dt: float
    error: float
    seconds: float
    nfev: int


def work_precision(
    problem: str | Problem, methods: Sequence[str], dts: Sequence[float]
) -> list[WorkPrecisionRow]:
    """Error against cost for each method and step on a problem with a known solution.

    The error is the max-norm of the difference from the exact final state; for the adaptive
    methods (:data:`ADAPTIVE`) the ``dts`` are read as tolerances (``rtol = dt``, ``atol = dt * 1e-3``). Second-order methods
    are skipped on first-order problems. Wall time includes the Python callback of ``f``;
    ``nfev`` is the cost measure that does not depend on the machine.
    """
    if isinstance(problem, str):
        if problem not in PROBLEMS:
            raise ValueError(f"problem: {problem!r} is not one of {', '.join(PROBLEMS)}")
        prob = PROBLEMS[problem]()
    elif isinstance(problem, Problem):
        prob = problem
    else:
        raise ValueError(f"problem: expected a name or a Problem, got {type(problem).__name__}")
    exact = prob.exact(prob.t_span[1])
    calls = [0]

    def f(t: float, y: np.ndarray) -> np.ndarray:
        calls[0] += 1
        return prob.f(t, y)

    rows = []
    for method in methods:
        if method in METHODS_SECOND_ORDER and not prob.second_order:
            continue
        for dt in dts:
            calls[0] = 0
            start = time.perf_counter()
            if method in ADAPTIVE:
                _, y = solve(f, prob.y0, prob.t_span, method=method, rtol=dt, atol=dt * 1e-3)
            else:
                _, y = solve(f, prob.y0, prob.t_span, dt=dt, method=method, jac=prob.jac)
            elapsed = time.perf_counter() - start
            err = float(np.max(np.abs(y[-1] - exact)))
            rows.append(WorkPrecisionRow(prob.name, method, real(dt, "dt"), err, elapsed, calls[0]))
    return rows
