"""Integrators: work-precision tables of every kinema method on the built-in problems, and
kinema's Dormand–Prince 5(4) against scipy.integrate.solve_ivp (RK45, DOP853, Radau) at the
same tolerances, in one process. Both call the same Python right-hand side, so f-evaluations
(nfev) are the fair cost measure; wall times are printed too.

Run: python bench/bench_ode.py [--quick]
(--quick changes nothing: the whole run takes about 2 s.)
"""

from __future__ import annotations

import argparse
import time

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


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="accepted; the run is already quick")
    parser.parse_args()
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
