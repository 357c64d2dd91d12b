"""Fluids: the dam break of Martin & Moyce (1952) as in docs/fluid.md — a column `L × 2L`
(L = 0.146 m) in a tank `4L × 3L`, a slab `0.4 L` thick — at several particle spacings, one
frame of 1/60 s at a time: kinema's DFSPH (the default), PBF and WCSPH against a numpy/scipy
implementation of the same WCSPH (cubic spline of support 2 s, Akinci boundary particles and
volumes, Tait pressure clamped at 0, XSPH viscosity, symplectic Euler, neighbours by
`scipy.spatial.cKDTree.query_pairs`) taking the same number of substeps per frame as kinema's
WCSPH, in one process. Reported: ms per frame, substeps per frame, the mean compression of
the last frame (percent) and, for the reference, its time per substep against kinema's.

Run: python bench/bench_fluid.py [--spacings 10 20] [--frames 6]
(spacings as L / s; 10 is ~2,300 fluid particles, 20 ~14,000, 40 ~100,000.)
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from scipy.spatial import cKDTree

from kinema.fluid import Fluid

L = 0.146
FRAME = 1.0 / 60.0
G = np.array([0.0, -9.81, 0.0])


def dam(spacing: float, solver: str) -> Fluid:
    fluid = Fluid(spacing, solver=solver)
    fluid.add_boundary_box((0.0, 0.0, 0.0), (4 * L, 3 * L, 0.4 * L))
    fluid.add_block((0.0, 0.0, 0.0), (L, 2 * L, 0.4 * L))
    return fluid


def cubic(r: np.ndarray, h: float) -> np.ndarray:
    q = r / h
    s = 8.0 / (np.pi * h**3)
    t = np.clip(1.0 - q, 0.0, None)
    return np.where(q <= 0.5, s * (6.0 * q * q * (q - 1.0) + 1.0), s * 2.0 * t**3)


def cubic_derivative(r: np.ndarray, h: float) -> np.ndarray:
    q = r / h
    s = 48.0 / (np.pi * h**4)
    t = np.clip(1.0 - q, 0.0, None)
    return np.where(q <= 0.5, s * q * (3.0 * q - 2.0), -s * t * t)


class NumpyWcsph:
    """The WCSPH substep of kinema's `solver="wcsph"` (docs/fluid.md) written with numpy."""

    def __init__(self, fluid: Fluid, spacing: float, sound_speed: float = 30.0, nu: float = 0.01):
        self.x = np.array(fluid.positions, dtype=float)
        self.v = np.zeros_like(self.x)
        self.b = np.array(fluid.boundary_particles, dtype=float)
        self.h = 2.0 * spacing
        self.vol = spacing**3
        self.c2 = sound_speed**2 / 7.0
        self.nu = nu
        self.margin = 0.25 * spacing
        self.lo = np.zeros(3) + self.margin
        self.hi = np.array([4 * L, 3 * L, 0.4 * L]) - self.margin
        # Akinci's boundary volumes V_b = 1 / Σ_k W(x_b - x_k) (not timed: the setup).
        tree = cKDTree(self.b)
        pairs = tree.query_pairs(self.h, output_type="ndarray")
        w = cubic(np.linalg.norm(self.b[pairs[:, 0]] - self.b[pairs[:, 1]], axis=1), self.h)
        total = np.full(len(self.b), cubic(np.zeros(1), self.h)[0])
        total += np.bincount(pairs[:, 0], w, len(self.b)) + np.bincount(pairs[:, 1], w, len(self.b))
        self.vb = 1.0 / total

    def substep(self, dt: float) -> float:
        n, h = len(self.x), self.h
        points = np.concatenate([self.x, self.b])
        pairs = cKDTree(points).query_pairs(h, output_type="ndarray")
        pairs = pairs[pairs[:, 0] < n]  # fluid–fluid and fluid–boundary (i < j: i is fluid)
        i, j = pairs[:, 0], pairs[:, 1]
        fluid = j < n
        d = points[i] - points[j]
        r = np.linalg.norm(d, axis=1)
        w = cubic(r, h)
        grad = d * (cubic_derivative(r, h) / np.where(r > 0, r, 1.0))[:, None]
        mass_j = np.where(fluid, self.vol, self.vb[np.minimum(j - n, len(self.vb) - 1)])
        ff_i, ff_j = i[fluid], j[fluid]
        rho = self.vol * cubic(np.zeros(1), h)[0] + np.bincount(i, mass_j * w, n)
        rho += np.bincount(ff_j, self.vol * w[fluid], n)
        # Gravity and XSPH viscosity.
        dv = np.tile(G * dt, (n, 1))
        rel = (self.v[ff_j] - self.v[ff_i]) * w[fluid, None]
        for a in range(3):
            dv[:, a] += self.nu * self.vol * np.bincount(ff_i, rel[:, a] / rho[ff_j], n)
            dv[:, a] -= self.nu * self.vol * np.bincount(ff_j, rel[:, a] / rho[ff_i], n)
        self.v += dv
        # Tait pressure, clamped, and its acceleration.
        k = np.maximum(self.c2 * (rho**7 - 1.0), 0.0) / rho**2
        coef = np.where(fluid, self.vol * (k[i] + k[np.minimum(j, n - 1)]), mass_j * k[i])
        force = grad * coef[:, None]
        for a in range(3):
            self.v[:, a] -= dt * np.bincount(i, force[:, a], n)
            self.v[:, a] += dt * np.bincount(ff_j, force[fluid, a], n)
        # Symplectic Euler and the tank.
        self.x += dt * self.v
        below, above = self.x < self.lo, self.x > self.hi
        self.x = np.clip(self.x, self.lo, self.hi)
        self.v = np.where(below, np.maximum(self.v, 0.0), self.v)
        self.v = np.where(above, np.minimum(self.v, 0.0), self.v)
        return 100.0 * float(np.maximum(rho - 1.0, 0.0).mean())


def kinema_frames(fluid: Fluid, frames: int) -> tuple[float, float, float, float]:
    """(ms per frame, CPU ms per frame (all threads), substeps per frame, mean compression
    of the last frame in percent)."""
    fluid.step(FRAME)  # the first frame sizes the buffers
    start, cpu = time.perf_counter(), time.process_time()
    substeps = 0
    for _ in range(frames):
        fluid.step(FRAME)
        substeps += int(fluid.stats["substeps"])
    seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
    return (
        1e3 * seconds / frames,
        1e3 * cpu / frames,
        substeps / frames,
        float(fluid.stats["density_error"]),
    )


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--spacings", type=int, nargs="+", default=[10, 20])
    parser.add_argument("--frames", type=int, default=6)
    args = parser.parse_args()
    print(
        f"threads: kinema {os.environ.get('KINEMA_NUM_THREADS', 'all')}, numpy 1; load {os.getloadavg()[0]:.1f}"
    )
    print(
        "| L / s | fluid particles | boundary particles | DFSPH ms/frame, CPU ms (substeps) | PBF "
        "ms/frame (substeps) | WCSPH ms/frame, CPU ms (substeps) | numpy WCSPH ms/frame, CPU ms "
        "| numpy / kinema WCSPH, wall / CPU | compression % (DFSPH / WCSPH / numpy) |"
    )
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---|")
    for per_l in args.spacings:
        s = L / per_l
        results = {}
        for solver in ("dfsph", "pbf", "wcsph"):
            fluid = dam(s, solver)
            results[solver] = kinema_frames(fluid, args.frames)
        ref_fluid = dam(s, "wcsph")
        ref = NumpyWcsph(ref_fluid, s)
        per_frame = max(1, round(results["wcsph"][2]))
        for _ in range(per_frame):  # the first frame, as kinema's
            ref.substep(FRAME / per_frame)
        start, cpu = time.perf_counter(), time.process_time()
        for _ in range(args.frames):
            for _ in range(per_frame):
                err = ref.substep(FRAME / per_frame)
        ms_ref = 1e3 * (time.perf_counter() - start) / args.frames
        cpu_ref = 1e3 * (time.process_time() - cpu) / args.frames
        n = len(ref_fluid)
        nb = len(ref_fluid.boundary_particles)
        d, p, w = results["dfsph"], results["pbf"], results["wcsph"]
        print(
            f"| {per_l} | {n} | {nb} | {d[0]:.1f}, {d[1]:.1f} ({d[2]:.0f}) | {p[0]:.1f} ({p[2]:.0f}) "
            f"| {w[0]:.1f}, {w[1]:.1f} ({w[2]:.0f}) | {ms_ref:.1f}, {cpu_ref:.1f} "
            f"| {ms_ref / w[0]:.1f}x / {cpu_ref / w[1]:.1f}x "
            f"| {d[3]:.3f} / {w[3]:.3f} / {err:.3f} |"
        )


if __name__ == "__main__":
    main()
