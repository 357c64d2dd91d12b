"""Integrators: the spring chain stepped by ``ParticleSystem.step`` with every fixed-step method
against vectorised numpy (and implicit Euler against scipy's sparse LU factorised once) at
equal error; work-precision tables of every kinema method on the built-in problems;
kinema's Dormand–Prince 5(4) against scipy.integrate.solve_ivp (RK45, DOP853, Radau) at the
same tolerances; and the work-precision comparison at equal achieved error: kinema's dopri5,
dop853 and radau against scipy's RK45, DOP853 and Radau on the Arenstorf orbit, Van der Pol
at mu = 1000 and a 100-particle spring chain, CPU time against the error of the final state
(measured against a reference at rtol 1e-13), a sweep of rtol for each, all in one process and
on the same Python right-hand side.

Run: python bench/bench_ode.py [--quick] [--figure PATH] [--chain-only]
(--quick: fewer tolerances in the sweep; --figure writes the work-precision plot, matplotlib;
--chain-only: the fixed-step chain table alone.)
"""

from __future__ import annotations

import argparse
import math
import os
import time
from collections.abc import Callable
from functools import partial

# One thread for the reference: OpenBLAS's idle threads spin after numpy's and scipy's calls,
# and process CPU time counted their spinning against whatever ran next (kinema's explicit
# Euler at N = 1000 measured 24 µs a step after the N = 100 rows, 12.7 µs alone).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

from kinema import ode  # noqa: E402
from kinema.particles import ParticleSystem, Springs  # noqa: E402

try:
    from scipy.integrate import solve_ivp
    from scipy.sparse import bmat, diags, identity
    from scipy.sparse.linalg import splu
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


# The fixed-step chain: N unit masses on a line joined by springs of k = 1e4 N/m (rest length
# 0: linear), the first tied to a wall, displaced by linspace(0, 0.1, N) m at zero velocity
# and stepped over 0.1 s at dt = 1e-4 s (1000 steps): the linear chain of
# ode.PROBLEMS["spring_chain"] at the size of a rope. kinema steps it as a ParticleSystem in 3-D
# (a pinned particle for the wall, `Springs` between neighbours, positions = displacements; the
# motion stays on the line); numpy steps the displacements u (N,) with the same
# methods, vectorised; scipy's implicit Euler solves (I - h A) y1 = y0 with the sparse LU of
# I - h A factorised once (A is constant). Errors are of the final displacements against the
# exact solution (normal modes), so both sides' errors are shown at the same dt.
CHAIN_K, CHAIN_T, CHAIN_DT = 1e4, 0.1, 1e-4
CHAIN_METHODS = ["explicit_euler", "midpoint", "rk4", "symplectic_euler", "implicit_euler"]


def chain_laplacian(n: int):
    """The chain's stiffness pattern L (n x n, sparse): u'' = -k L u."""
    main = np.full(n, 2.0)
    main[-1] = 1.0
    return diags([main, -np.ones(n - 1), -np.ones(n - 1)], [0, 1, -1], format="csc")


def chain_exact(n: int) -> np.ndarray:
    """The displacements at CHAIN_T from the normal modes of the linear chain."""
    w2, modes = np.linalg.eigh(CHAIN_K * chain_laplacian(n).toarray())
    u0 = np.linspace(0.0, 0.1, n)
    return modes @ (np.cos(np.sqrt(w2) * CHAIN_T) * (modes.T @ u0))


def chain_acceleration(u: np.ndarray) -> np.ndarray:
    """-k L u, vectorised: the spring forces -k (u_i - u_(i-1)) with the wall at u_(-1) = 0."""
    s = CHAIN_K * np.diff(u, prepend=0.0)
    a = -s
    a[:-1] += s[1:]
    return a


def chain_numpy(method: str, n: int, steps: int) -> np.ndarray:
    """`steps` steps of `method` on the chain in numpy (scipy's sparse LU for implicit Euler)."""
    h, acc = CHAIN_DT, chain_acceleration
    u, v = np.linspace(0.0, 0.1, n), np.zeros(n)
    if method == "implicit_euler":
        a = bmat([[None, identity(n)], [-CHAIN_K * chain_laplacian(n), None]], format="csc")
        lu = splu((identity(2 * n, format="csc") - h * a).tocsc())
        y = np.concatenate([u, v])
        for _ in range(steps):
            y = lu.solve(y)
        return y[:n]
    for _ in range(steps):
        if method == "explicit_euler":
            u, v = u + h * v, v + h * acc(u)
        elif method == "midpoint":
            um, vm = u + 0.5 * h * v, v + 0.5 * h * acc(u)
            u, v = u + h * vm, v + h * acc(um)
        elif method == "rk4":
            a1 = acc(u)
            u2, v2 = u + 0.5 * h * v, v + 0.5 * h * a1
            a2 = acc(u2)
            u3, v3 = u + 0.5 * h * v2, v + 0.5 * h * a2
            a3 = acc(u3)
            u4, v4 = u + h * v3, v + h * a3
            a4 = acc(u4)
            u = u + h / 6 * (v + 2 * v2 + 2 * v3 + v4)
            v = v + h / 6 * (a1 + 2 * a2 + 2 * a3 + a4)
        else:  # symplectic Euler
            v = v + h * acc(u)
            u = u + h * v
    return u


def chain_system(n: int) -> ParticleSystem:
    """The chain as a ParticleSystem: a pinned wall particle at the origin and n unit masses
    at x = u, joined by springs of rest length 0 (kinema's linear springs, f = -k d), so that
    the positions are the displacements and the equations those of the linear chain."""
    x = np.zeros((n + 1, 3))
    x[1:, 0] = np.linspace(0.0, 0.1, n)
    system = ParticleSystem(x, masses=np.r_[np.inf, np.ones(n)])
    pairs = np.stack([np.arange(n), np.arange(1, n + 1)], axis=1)
    system.add(Springs(pairs, stiffness=CHAIN_K, rest=np.zeros(n)))
    return system


def chain_kinema(method: str, n: int, steps: int, per_call: int) -> np.ndarray:
    """`steps` steps of `method` in calls of `per_call` steps; the final displacements."""
    system = chain_system(n)
    for _ in range(steps // per_call):
        system.step(CHAIN_DT, per_call, method)
    return system.positions[1:, 0].copy()


def chain_table() -> list[tuple[int, str, float, float, float, float, float, float]]:
    """(N, method, kinema error, numpy error, kinema µs/step in one call, in a call per step,
    numpy µs/step, CPU) for the chain of 100 and 1000 masses."""
    steps = round(CHAIN_T / CHAIN_DT)
    rows = []
    for n in [100, 1000]:
        exact = chain_exact(n)
        for method in CHAIN_METHODS:
            t_one, u_k = cpu(partial(chain_kinema, method, n, steps, steps))
            t_each, _ = cpu(partial(chain_kinema, method, n, steps, 1))
            t_np, u_np = cpu(partial(chain_numpy, method, n, steps))
            err_k, err_np = (float(np.max(np.abs(u - exact))) for u in (u_k, u_np))
            rows.append((n, method, err_k, err_np, t_one, t_each, t_np))
    return rows


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
    parser.add_argument("--chain-only", action="store_true", help="the chain table alone")
    args = parser.parse_args()
    if solve_ivp is not None:
        print(
            f"## The spring chain, fixed steps: kinema ParticleSystem against numpy "
            f"(k = {CHAIN_K:g} N/m, dt = {CHAIN_DT:g} s, {CHAIN_T:g} s, CPU time, one thread "
            f"for numpy; implicit Euler against scipy's sparse LU factorised once)\n"
        )
        print(
            "| N | method | kinema error | numpy error | kinema µs/step (one call) "
            "| kinema µs/step (a call per step) | numpy µs/step | ratio (one call) "
            "| ratio (a call per step) |"
        )
        print("|---:|---|---:|---:|---:|---:|---:|---:|---:|")
        steps = round(CHAIN_T / CHAIN_DT)
        for n, m, e_k, e_np, t_one, t_each, t_np in chain_table():
            print(
                f"| {n} | {m} | {e_k:.2e} | {e_np:.2e} | {1e6 * t_one / steps:.2f} "
                f"| {1e6 * t_each / steps:.2f} | {1e6 * t_np / steps:.2f} "
                f"| {t_np / t_one:.1f}x | {t_np / t_each:.1f}x |"
            )
        print()
    if args.chain_only:
        return
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
