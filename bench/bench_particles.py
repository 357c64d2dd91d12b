"""Particles: N particles under gravity and quadratic drag above a ground plane with
restitution and friction, stepped with symplectic Euler; kinema against the same update
written with vectorised numpy (float64), in one process. Prints steps per second and the ratio.

Run: python bench/bench_particles.py [--n 1000000] [--steps 20]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from kinema.particles import Drag, Gravity, ParticleSystem, Plane

G = np.array([0.0, -9.81, 0.0])
K, E, MU, DT = 1e-3, 0.5, 0.3, 1e-3


def numpy_step(x: np.ndarray, v: np.ndarray) -> None:
    """One symplectic-Euler step with drag and the same plane response as kinema."""
    speed = np.linalg.norm(v, axis=1, keepdims=True)
    v += DT * (G - K * speed * v)
    x_prev = x.copy()
    x += DT * v
    hit = x[:, 1] < 0.0
    if hit.any():
        depth = -x[hit, 1]
        x[hit, 1] = 0.0
        moved = x[hit] - x_prev[hit]
        moved[:, 1] = 0.0
        slip = np.linalg.norm(moved, axis=1)
        scale = np.where(slip > 0, np.minimum(MU * depth / np.where(slip > 0, slip, 1), 1.0), 0.0)
        x[hit] -= moved * scale[:, None]
        vh = v[hit]
        vn = vh[:, 1].copy()
        resting = -vn <= 2 * 9.81 * DT
        jn = -vn * (1 + np.where(resting, 0.0, E))
        vt = vh.copy()
        vt[:, 1] = 0.0
        st = np.linalg.norm(vt, axis=1)
        keep = np.where(st <= MU * jn, 0.0, 1 - MU * jn / np.where(st > 0, st, 1))
        vh = vt * keep[:, None]
        vh[:, 1] = vn + jn
        v[hit] = vh


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--n", type=int, default=1_000_000)
    parser.add_argument("--steps", type=int, default=20)
    args = parser.parse_args()
    n, steps = args.n, args.steps
    rng = np.random.default_rng(0)
    x0 = rng.uniform([-10, 0, -10], [10, 5, 10], (n, 3))
    v0 = rng.normal(size=(n, 3))

    ps = ParticleSystem(x0, v0)
    ps.add(Gravity())
    ps.add(Drag(quadratic=K))
    ps.add(Plane(restitution=E, friction=MU))
    ps.step(DT)  # warm-up
    start = time.perf_counter()
    ps.step(DT, steps)
    t_kinema = (time.perf_counter() - start) / steps

    x, v = x0.copy(), v0.copy()
    numpy_step(x, v)
    start = time.perf_counter()
    for _ in range(steps):
        numpy_step(x, v)
    t_numpy = (time.perf_counter() - start) / steps

    # Bytes a step must touch at least: read and write x and v (48 B per particle each way).
    floor = 2 * 48 * n
    print(f"N = {n}, {steps} steps, {os.cpu_count()} threads available\n")
    print("| implementation | ms / step | steps / s | speed-up | GB/s touched |")
    print("|---|---:|---:|---:|---:|")
    for name, t in [("kinema (Rust)", t_kinema), ("numpy (vectorised)", t_numpy)]:
        print(
            f"| {name} | {1e3 * t:.2f} | {1 / t:.1f} | {t_numpy / t:.1f}x | {floor / t / 1e9:.2f} |"
        )


if __name__ == "__main__":
    main()
