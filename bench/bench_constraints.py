"""Constraints: step time of a hanging rope of rods against its length (1k, 10k, 100k
particles), at dt = 1/60 s with the velocity-level projection through the sparse Cholesky, and
one acceleration-level RK4 step through Cholesky and conjugate gradient for comparison.

Run: python bench/bench_constraints.py [--quick] [--sizes 1000 10000 100000]
(--quick: 1000 and 10000 particles.)
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from kinema.constraints import ConstrainedSystem, Distance
from kinema.particles import Gravity, ParticleSystem


def rope(n: int, solver: str) -> tuple[ParticleSystem, ConstrainedSystem]:
    xs = np.column_stack([np.zeros(n), -0.01 * np.arange(n), np.zeros(n)])
    vs = np.column_stack([0.2 * np.arange(n) / n, np.zeros(n), np.zeros(n)])
    masses = np.full(n, 0.001)
    masses[0] = np.inf
    ps = ParticleSystem(xs, vs, masses)
    ps.add(Gravity())
    cs = ConstrainedSystem(ps, solver=solver)
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


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="small sizes, for a fast check")
    parser.add_argument(
        "--sizes", type=int, nargs="+", help="default 1000 10000 100000 (1000 10000 with --quick)"
    )
    args = parser.parse_args()
    sizes = args.sizes or ([1000, 10000] if args.quick else [1000, 10000, 100000])
    print(
        "| particles | projection, Cholesky (ms/step) | per particle (µs) | RK4 step, Cholesky (ms) | RK4 step, CG (ms) |"
    )
    print("|---:|---:|---:|---:|---:|")
    for n in sizes:
        _, cs = rope(n, "cholesky")
        cs.step(1 / 60, 1, method="projection")  # builds the pattern and the symbolic factorisation
        t_proj = timed(lambda cs=cs: cs.step(1 / 60, 5, method="projection")) / 5
        _, cs2 = rope(n, "cholesky")
        cs2.step(1e-4, 1)
        t_rk4 = timed(lambda cs2=cs2: cs2.step(1e-4, 1))
        _, cs3 = rope(n, "cg")
        cs3.step(1e-4, 1)
        t_cg = timed(lambda cs3=cs3: cs3.step(1e-4, 1))
        print(
            f"| {n} | {1e3 * t_proj:.2f} | {1e6 * t_proj / n:.2f} | {1e3 * t_rk4:.2f} | {1e3 * t_cg:.2f} |"
        )


if __name__ == "__main__":
    main()
