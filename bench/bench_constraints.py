"""Constraints: a hanging rope of rods (1 cm, 1 g particles, the top one pinned, pushed
sideways at up to 0.2 m/s) against its length (1k, 10k, 100k particles): step and project
(`method="projection"`, the implicit projection by Newton with the rods' geometric stiffness)
at dt = 1/60 s with post-stabilisation (the default) and without (no velocity projection),
time per step and the largest relative rod-length error |C|/L over 12 steps (or the step at
which a step fails); and one acceleration-level RK4 step of 0.1 ms (stabilised) through the
sparse Cholesky and through conjugate gradient. One thread (the solves are sequential).

Run: python bench/bench_constraints.py [--quick] [--sizes 1000 10000 100000]
(--quick: 1000 and 10000 particles.)
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from kinema import SimulationError
from kinema.constraints import ConstrainedSystem, Distance
from kinema.particles import Gravity, ParticleSystem

# CG needs about two iterations per rod on a chain (its condition number grows with the
# square of the length): beyond this size one RK4 step takes minutes, so it is not timed.
CG_LARGEST = 10_000


def rope(n: int, solver: str, stabilize: bool = True) -> tuple[ParticleSystem, ConstrainedSystem]:
    xs = np.column_stack([np.zeros(n), -0.01 * np.arange(n), np.zeros(n)])
    vs = np.column_stack([0.2 * np.arange(n) / n, np.zeros(n), np.zeros(n)])
    masses = np.full(n, 0.001)
    masses[0] = np.inf
    ps = ParticleSystem(xs, vs, masses)
    ps.add(Gravity())
    cs = ConstrainedSystem(ps, solver=solver, stabilize=stabilize)
    for i in range(n - 1):
        cs.add(Distance(i, i + 1, 0.01))
    return ps, cs


def timed(fn, repeat: int = 3) -> float:
    best = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def projection(n: int, stabilize: bool) -> tuple[float, str]:
    """(mean seconds per step after the first, which builds the pattern and the symbolic
    factorisation; largest |C|/L) over 12 steps of 1/60 s from the start."""
    _, cs = rope(n, "cholesky", stabilize)
    stretch, cost = 0.0, 0.0
    for k in range(12):
        start = time.perf_counter()
        try:
            cs.step(1 / 60, 1, method="projection")
        except SimulationError:
            return cost / max(k - 1, 1), f"fails at step {k}"
        cost += (time.perf_counter() - start) if k > 0 else 0.0
        stretch = max(stretch, cs.violation()[0] / 0.01)
    return cost / 11, f"{stretch:.1e}"


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="small sizes, for a fast check")
    parser.add_argument(
        "--sizes", type=int, nargs="+", help="default 1000 10000 100000 (1000 10000 with --quick)"
    )
    args = parser.parse_args()
    sizes = args.sizes or ([1000, 10000] if args.quick else [1000, 10000, 100000])
    print(
        "| particles | projection at 1/60 s + post-stabilisation (ms/step) | per particle (µs) "
        "| max \\|C\\|/L | without velocity projection (ms/step) | max \\|C\\|/L "
        "| RK4 step, Cholesky (ms) | RK4 step, CG (ms) |"
    )
    print("|---:|---:|---:|---:|---:|---:|---:|---:|")
    for n in sizes:
        t_proj, stretch = projection(n, True)
        t_bare, bare = projection(n, False)
        _, cs2 = rope(n, "cholesky")
        cs2.step(1e-4, 1)  # builds the pattern and the symbolic factorisation
        t_rk4 = timed(lambda cs2=cs2: cs2.step(1e-4, 1))
        cg = "–"
        if n <= CG_LARGEST:
            _, cs3 = rope(n, "cg")
            cs3.step(1e-4, 1)
            cg = f"{1e3 * timed(lambda cs3=cs3: cs3.step(1e-4, 1)):.2f}"
        print(
            f"| {n} | {1e3 * t_proj:.2f} | {1e6 * t_proj / n:.2f} | {stretch} "
            f"| {1e3 * t_bare:.2f} | {bare} | {1e3 * t_rk4:.2f} | {cg} |"
        )


if __name__ == "__main__":
    main()
