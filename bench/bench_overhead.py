"""Fixed costs of a call and of a step (issue #29): a step of an empty particle system, a call
of zero steps, and the cost per particle-step of a system without forces (``x += h v``,
symplectic Euler) from 10^3 to 10^6 particles, stepped one call per step and in one call of
many steps. Times are the best of five runs, wall clock, kinema on its default threads
(``--threads`` to change); the ideal is a flat cost per particle-step.

Run: python bench/bench_overhead.py [--quick] [--threads N] [--figure PATH]
(--quick: fewer calls, up to 10^5 particles.)
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable

import numpy as np

import kinema
from kinema.particles import ParticleSystem

DT = 1e-3


def best(fn: Callable[[], object], calls: int, repeat: int = 5) -> float:
    """Best time of ``calls`` calls of ``fn`` over ``repeat`` runs, in seconds per call."""
    fn()
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        for _ in range(calls):
            fn()
        times.append((time.perf_counter() - start) / calls)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="fewer calls, up to 10^5 particles")
    parser.add_argument("--threads", type=int, help="kinema threads (default: all cores)")
    parser.add_argument("--figure", help="write the cost per particle-step against N here")
    args = parser.parse_args()
    if args.threads:
        kinema.set_num_threads(args.threads)
    calls = 10_000 if args.quick else 100_000
    empty = ParticleSystem(np.zeros((0, 3)))
    some = ParticleSystem(np.zeros((1000, 3)))
    print(
        f"kinema {kinema.__version__}, threads {kinema.num_threads()}, dt = {DT} s, "
        f"symplectic Euler, no forces, best of 5"
    )
    print(f"- a step of an empty system: {best(lambda: empty.step(DT), calls) * 1e6:.2f} µs")
    print(
        f"- a call of zero steps (1000 particles): "
        f"{best(lambda: some.step(DT, steps=0), calls) * 1e6:.2f} µs"
    )
    sizes = [10**3, 10**4, 10**5] + ([] if args.quick else [10**6])
    print("\n| particles | one call per step (ns/particle-step) | one call of 100 steps |")
    print("|---:|---:|---:|")
    per_step, per_call = [], []
    for n in sizes:
        ps = ParticleSystem(np.zeros((n, 3)), velocities=np.ones((n, 3)))
        k = max(10, min(20_000, 10**7 // n))
        one = best(lambda ps=ps: ps.step(DT), k)
        many = best(lambda ps=ps: ps.step(DT, steps=100), max(1, k // 100))
        per_step.append(one / n * 1e9)
        per_call.append(many / (100 * n) * 1e9)
        print(f"| {n:,} | {per_step[-1]:.2f} | {per_call[-1]:.2f} |")
    print(f"\nload average (1, 5, 15 min): {os.getloadavg()}")
    if args.figure:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(5, 3.5))
        ax.loglog(sizes, per_step, "o-", label="one call per step")
        ax.loglog(sizes, per_call, "s-", label="one call of 100 steps")
        ax.set_xlabel("particles")
        ax.set_ylabel("ns per particle-step")
        ax.set_title(f"x += h v, symplectic Euler, {kinema.num_threads()} threads")
        ax.legend()
        fig.tight_layout()
        fig.savefig(args.figure, dpi=120)
        print(f"figure: {args.figure}")


if __name__ == "__main__":
    main()
