"""Particles with the implicit methods: the cost of one implicit Euler step (dt = 1/60) with the
sparse Newton matrix (analytic sparse Jacobian, faer sparse LU) against the dense one
(Jacobian by forward differences over all 6N columns, dense LU), on two spring systems of N
particles:

- ``chain``: a hanging chain of 1 g particles, 1 cm links, k = 1e6 N/m, swinging;
- ``net``: a vertical square net of 10 g particles 2 cm apart (structural and shear springs),
  k = 100 N/m, pinned at its top corners and swinging out of its plane (cloth-like).

The Newton matrix is 6N x 6N. The dense path costs O(N³) per Jacobian update (and 6N right-hand
sides for the differences), so it is run only up to ``--dense-max`` particles. The last column
fits the growth exponent of the sparse path's cost, ms ∝ N^p, between consecutive sizes.

Run: python bench/bench_implicit_particles.py [--chain 100 1000 10000] [--net 100 1600]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from kinema.particles import Drag, Gravity, ParticleSystem, Springs

DT = 1.0 / 60.0


def chain(n: int) -> ParticleSystem:
    """A chain of ``n`` particles of 1 g hanging from a pinned first one, pushed sideways."""
    x = np.zeros((n, 3))
    x[:, 1] = -0.01 * np.arange(n)
    v = np.zeros((n, 3))
    v[:, 0] = 0.5 * np.arange(n) / n
    masses = np.full(n, 1e-3)
    masses[0] = np.inf
    ps = ParticleSystem(x, v, masses=masses)
    pairs = np.stack([np.arange(n - 1), np.arange(1, n)], axis=1)
    ps.add(Springs(pairs, stiffness=1e6, damping=1e-4))
    ps.add(Gravity())
    return ps


def net(n: int) -> ParticleSystem:
    """A vertical side x side net (side = round(sqrt(n))) pinned at its top corners."""
    side = round(math.sqrt(n))
    i, j = np.meshgrid(np.arange(side), np.arange(side), indexing="ij")
    x = np.stack([0.02 * j.ravel(), -0.02 * i.ravel(), np.zeros(side * side)], axis=1)
    v = np.zeros_like(x)
    v[:, 2] = 0.5 * i.ravel() / side
    idx = (i * side + j).ravel()
    pairs = []
    for di, dj in [(1, 0), (0, 1), (1, 1), (1, -1)]:
        ok = ((i + di < side) & (j + dj >= 0) & (j + dj < side)).ravel()
        pairs.append(np.stack([idx[ok], idx[ok] + di * side + dj], axis=1))
    masses = np.full(side * side, 0.01)
    masses[[0, side - 1]] = np.inf
    ps = ParticleSystem(x, v, masses=masses)
    ps.add(Springs(np.concatenate(pairs), stiffness=100.0, damping=0.01))
    ps.add(Gravity())
    ps.add(Drag(linear=1e-3))
    return ps


def ms_per_step(ps: ParticleSystem, steps: int, sparse: bool) -> float:
    """Wall time per step over ``steps`` steps after one warm-up step (symbolic analysis)."""
    ps.step(DT, 1, method="implicit_euler", sparse_jacobian=sparse)
    start = time.perf_counter()
    ps.step(DT, steps, method="implicit_euler", sparse_jacobian=sparse)
    return 1e3 * (time.perf_counter() - start) / steps


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--chain", type=int, nargs="+", default=[100, 300, 1000, 3000, 10000])
    parser.add_argument("--net", type=int, nargs="+", default=[100, 400, 1600, 6400])
    parser.add_argument("--steps", type=int, default=5, help="steps timed after a warm-up step")
    parser.add_argument("--dense-max", type=int, default=400, help="largest N for the dense path")
    args = parser.parse_args()
    print(f"implicit Euler, dt = 1/60, {args.steps} steps timed after one\n")
    print("| system | N | unknowns | sparse (ms/step) | dense (ms/step) | dense / sparse | p |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for name, build, sizes in [("chain", chain, args.chain), ("net", net, args.net)]:
        previous = None
        for n in sizes:
            ps = build(n)
            n = ps.positions.shape[0]
            sparse = ms_per_step(ps, args.steps, True)
            if n <= args.dense_max:
                dense = ms_per_step(build(n), max(1, args.steps // 5), False)
                dense_cols = f"{dense:.1f} | {dense / sparse:.0f}x"
            else:
                dense_cols = "– | –"
            slope = "–"
            if previous is not None:
                slope = f"{math.log(sparse / previous[1]) / math.log(n / previous[0]):.2f}"
            previous = (n, sparse)
            print(f"| {name} | {n} | {6 * n} | {sparse:.2f} | {dense_cols} | {slope} |")


if __name__ == "__main__":
    main()
