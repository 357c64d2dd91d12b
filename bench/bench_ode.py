"""Integrators: work-precision tables of every kinema method on the built-in problems;
kinema's Dormand–Prince 5(4) against scipy.integrate.solve_ivp (RK45, DOP853, Radau) at the
same tolerances; and the work-precision comparison at equal achieved error: kinema's dopri5,
dop853 and radau against scipy's RK45, DOP853 and Radau on the Arenstorf orbit, Van der Pol
at mu = 1000 and a 100-particle spring chain, CPU time against the error of the final state
(measured against a reference at rtol 1e-13), a sweep of rtol for each, all in one process and
on the same Python right-hand side.

Run: python bench/bench_ode.py [--quick] [--figure PATH]
(--quick: fewer tolerances in the sweep; --figure writes the work-precision plot, matplotlib.)
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable
from functools import partial

import numpy as np

from kinema import ode

try:
    from scipy.integrate import solve_ivp
except ImportError:
    solve_ivp = None

FIXED = [
    "explicit_euler",
    "midpoint",
    "heun",
    "rk4",
    "symplectic_euler",
    "velocity_verlet",
    "implicit_euler",
    "trapezoidal",
    "bdf2",
]


def arenstorf() -> tuple[Callable, np.ndarray, tuple[float, float], None]:
    """The Arenstorf orbit (Hairer, Nørsett & Wanner I, §II.0, eq. 0.1): one period."""
    mu = 0.012277471
    mu2 = 1 - mu

    def f(t: float, y: np.ndarray) -> np.ndarray:
        d1 = ((y[0] + mu) ** 2 + y[1] ** 2) ** 1.5
        d2 = ((y[0] - mu2) ** 2 + y[1] ** 2) ** 1.5
        return np.array(
            [
                y[2],
                y[3],
                y[0] + 2 * y[3] - mu2 * (y[0] + mu) / d1 - mu * (y[0] - mu2) / d2,
                y[1] - 2 * y[2] - mu2 * y[1] / d1 - mu * y[1] / d2,
            ]
        )

    y0 = np.array([0.994, 0.0, 0.0, -2.00158510637908252240537862224])
    return f, y0, (0.0, 17.0652165601579625588917206249), None


def van_der_pol() -> tuple[Callable, np.ndarray, tuple[float, float], Callable]:
    """Van der Pol's oscillator at mu = 1000 over [0, 3000] (about two relaxation periods)."""
    mu = 1000.0

    def f(t: float, y: np.ndarray) -> np.ndarray:
        return np.array([y[1], mu * (1 - y[0] ** 2) * y[1] - y[0]])

    def jac(t: float, y: np.ndarray) -> np.ndarray:
        return np.array([[0.0, 1.0], [-2 * mu * y[0] * y[1] - 1, mu * (1 - y[0] ** 2)]])

    return f, np.array([2.0, 0.0]), (0.0, 3000.0), jac


def chain() -> tuple[Callable, np.ndarray, tuple[float, float], Callable]:
    """100 unit masses joined by springs of k = 1e4 N/m, the first tied to a wall (linear,
    y = [x; v], 200 unknowns), over 0.1 s: the problem of ode.PROBLEMS["spring_chain"]."""
    prob = ode._spring_chain(n=100, k=1e4)
    return prob.f, prob.y0, prob.t_span, prob.jac


WP_PROBLEMS = {"arenstorf": arenstorf, "van_der_pol": van_der_pol, "chain": chain}
WP_METHODS = [("dopri5", "RK45"), ("dop853", "DOP853"), ("radau", "Radau")]


def cpu(run: Callable[[], np.ndarray]) -> tuple[float, np.ndarray]:
    """CPU seconds of `run()` (the best of up to 3 runs within 2 s) and its result."""
    best, out, total = math.inf, None, 0.0
    for _ in range(3):
        start = time.process_time()
        out = run()
        dt = time.process_time() - start
        best, total = min(best, dt), total + dt
        if total > 2.0:
            break
    return best, out


def final_kinema(method: str, f, y0, span, rtol, atol, kw) -> np.ndarray:
    """The final state of kinema's `method`."""
    return ode.solve(f, y0, span, method=method, rtol=rtol, atol=atol, **kw)[1][-1]


def final_scipy(method: str, f, y0, span, rtol, atol, kw) -> np.ndarray:
    """The final state of scipy's `method`."""
    return solve_ivp(f, span, y0, method=method, rtol=rtol, atol=atol, **kw).y[:, -1]


def work_precision(quick: bool) -> list[tuple[str, str, float, float, float]]:
    """(problem, solver, rtol, error, CPU s) for every problem, method and rtol."""
    rows = []
    for name, make in WP_PROBLEMS.items():
        f, y0, span, jac = make()
        stiff = name == "van_der_pol"
        ref = solve_ivp(
            f,
            span,
            y0,
            method="Radau" if stiff else "DOP853",
            rtol=1e-13,
            atol=1e-13,
            **({"jac": jac} if stiff else {}),
        ).y[:, -1]
        rtols = [1e-4, 1e-7, 1e-10] if quick else [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10]
        for ours, peer in WP_METHODS:
            if stiff and ours != "radau":
                continue  # explicit methods need millions of steps here
            for rtol in rtols:
                atol = rtol * 1e-3 if not stiff else rtol
                kw = {"jac": jac} if ours == "radau" and jac is not None else {}
                args = (f, y0, span, rtol, atol, kw)
                t_k, y_k = cpu(partial(final_kinema, ours, *args))
                t_s, y_s = cpu(partial(final_scipy, peer, *args))
                scale = np.max(np.abs(ref))
                rows.append(
                    (name, f"kinema {ours}", rtol, float(np.max(np.abs(y_k - ref)) / scale), t_k)
                )
                rows.append(
                    (name, f"scipy {peer}", rtol, float(np.max(np.abs(y_s - ref)) / scale), t_s)
                )
    return rows


def plot(rows: list[tuple[str, str, float, float, float]], path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    problems = list(WP_PROBLEMS)
    fig, axes = plt.subplots(1, len(problems), figsize=(5 * len(problems), 4))
    for ax, name in zip(axes, problems, strict=True):
        for solver in dict.fromkeys(r[1] for r in rows if r[0] == name):
            sel = [r for r in rows if r[0] == name and r[1] == solver]
            ax.loglog(
                [r[3] for r in sel],
                [r[4] for r in sel],
                "o-" if "kinema" in solver else "s--",
                label=solver,
            )
        ax.set_title(name)
        ax.set_xlabel("relative error of the final state")
        ax.set_ylabel("CPU time (s)")
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="fewer tolerances in the sweep")
    parser.add_argument("--figure", help="write the work-precision figure (png) here")
    args = parser.parse_args()
    if solve_ivp is not None:
        rows = work_precision(args.quick)
        print("## Work-precision at equal achieved error (CPU s against relative error)\n")
        print("| problem | solver | rtol | error | CPU ms |")
        print("|---|---|---:|---:|---:|")
        for r in rows:
            print(f"| {r[0]} | {r[1]} | {r[2]:g} | {r[3]:.1e} | {1e3 * r[4]:.2f} |")
        print()
        if args.figure:
            plot(rows, args.figure)
    print("## Work-precision, fixed-step methods (error at the final time, f-evaluations)\n")
    for name, dts in [
        ("oscillator", [0.1, 0.01]),
        ("kepler", [0.01, 0.001]),
        ("spring_chain", [1e-3, 1e-4]),
    ]:
        rows = ode.work_precision(name, FIXED, dts)
        print(f"### {name}\n")
        print("| method | " + " | ".join(f"dt={dt:g}: error (nfev)" for dt in dts) + " |")
        print("|---|" + "---:|" * len(dts))
        for m in FIXED:
            sel = [r for r in rows if r.method == m]
            if sel:
                print(f"| {m} | " + " | ".join(f"{r.error:.2e} ({r.nfev})" for r in sel) + " |")
        print()

    print("## Adaptive: kinema dopri5 against scipy solve_ivp\n")
    peers = ["RK45", "DOP853", "Radau"]
    if solve_ivp is None:
        print("scipy: not installed, kinema alone\n")
        peers = []
    print("| problem | rtol | method | error | nfev | ms |")
    print("|---|---:|---|---:|---:|---:|")
    for name in ["kepler", "pendulum", "spring_chain"]:
        prob = ode.PROBLEMS[name]()
        exact = prob.exact(prob.t_span[1])
        for rtol in [1e-6, 1e-9]:
            atol = rtol * 1e-3
            calls = [0]

            def f(
                t: float, y: np.ndarray, prob: ode.Problem = prob, calls: list[int] = calls
            ) -> np.ndarray:
                calls[0] += 1
                return prob.f(t, y)

            runs = [
                (
                    "kinema dopri5",
                    lambda f=f, prob=prob, rtol=rtol, atol=atol: ode.solve(
                        f, prob.y0, prob.t_span, method="dopri5", rtol=rtol, atol=atol
                    )[1][-1],
                )
            ]
            for sm in peers:
                runs.append(
                    (
                        f"scipy {sm}",
                        lambda f=f, prob=prob, sm=sm, rtol=rtol, atol=atol: solve_ivp(
                            f,
                            prob.t_span,
                            prob.y0,
                            method=sm,
                            rtol=rtol,
                            atol=atol,
                            **({"jac": prob.jac} if sm == "Radau" and prob.jac is not None else {}),
                        ).y[:, -1],
                    )
                )
            for label, run in runs:
                calls[0] = 0
                start = time.perf_counter()
                y = run()
                ms = 1e3 * (time.perf_counter() - start)
                print(
                    f"| {name} | {rtol:g} | {label} | {np.max(np.abs(y - exact)):.2e} | {calls[0]} | {ms:.1f} |"
                )


if __name__ == "__main__":
    main()
