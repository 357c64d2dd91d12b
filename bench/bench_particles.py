"""Particles: N particles under gravity and quadratic drag above a ground plane with
restitution and friction, stepped with symplectic Euler; kinema against the same update
written with vectorised numpy (float64), and as Taichi and Warp CPU kernels (float64) when
they are installed, in one process. Prints steps per second, the ratios, the CPU time per step
(all threads; on a shared machine the wall clock also counts waiting for the CPU), and the
rate at which the bytes a step must touch move, against the machine's memory bandwidth measured
with an in-place stream over as many bytes (numpy on one thread, and Taichi on all threads).
kinema is timed in one call of all the steps (the first row: without emitters it takes each
block of particles through every step while it is in the cache, so the state crosses memory
once per call) and in one call per step (the second row, the memory traffic of the peers).
Each implementation is timed in the fastest of five runs of the steps.

Run: python bench/bench_particles.py [--quick] [--n 1000000] [--steps 20]
(--quick: N = 10^5, 10 steps.)
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


def taichi_runner(x0: np.ndarray, v0: np.ndarray):
    """The same step as a Taichi kernel on the CPU in float64, or None if Taichi is missing."""
    try:
        import taichi as ti
    except ImportError:
        return None
    ti.init(arch=ti.cpu, default_fp=ti.f64, log_level=ti.ERROR)
    n = len(x0)
    x = ti.Vector.field(3, dtype=ti.f64, shape=n)
    v = ti.Vector.field(3, dtype=ti.f64, shape=n)
    x.from_numpy(x0)
    v.from_numpy(v0)

    @ti.kernel
    def step():
        for i in x:
            vi = v[i]
            vi += DT * (ti.Vector([0.0, -9.81, 0.0]) - K * vi.norm() * vi)
            prev = x[i]
            xi = prev + DT * vi
            if xi[1] < 0.0:
                depth = -xi[1]
                xi[1] = 0.0
                moved = xi - prev
                moved[1] = 0.0
                slip = moved.norm()
                if slip > 0.0:
                    xi -= moved * ti.min(MU * depth / slip, 1.0)
                vn = vi[1]
                if vn < 0.0:
                    e = E
                    if -vn <= 2.0 * 9.81 * DT:
                        e = 0.0
                    jn = -vn * (1.0 + e)
                    vt = ti.Vector([vi[0], 0.0, vi[2]])
                    st = vt.norm()
                    if st <= MU * jn:
                        vt = ti.Vector([0.0, 0.0, 0.0])
                    else:
                        vt = vt * (1.0 - MU * jn / st)
                    vi = vt + ti.Vector([0.0, vn + jn, 0.0])
            x[i] = xi
            v[i] = vi

    def run(steps: int) -> None:
        for _ in range(steps):
            step()
        ti.sync()

    return run


def warp_runner(x0: np.ndarray, v0: np.ndarray):
    """The same step as a Warp kernel on the CPU in float64, or None if Warp is missing."""
    try:
        import warp as wp
    except ImportError:
        return None
    wp.config.quiet = True
    wp.init()
    f64 = wp.float64

    @wp.kernel
    def step(x: wp.array(dtype=wp.vec3d), v: wp.array(dtype=wp.vec3d)):
        i = wp.tid()
        dt, k, e, mu = f64(DT), f64(K), f64(E), f64(MU)
        zero = f64(0.0)
        vi = v[i]
        vi = vi + dt * (wp.vec3d(zero, f64(-9.81), zero) - k * wp.length(vi) * vi)
        prev = x[i]
        xi = prev + dt * vi
        if xi[1] < zero:
            depth = -xi[1]
            xi = wp.vec3d(xi[0], zero, xi[2])
            moved = wp.vec3d(xi[0] - prev[0], zero, xi[2] - prev[2])
            slip = wp.length(moved)
            if slip > zero:
                xi = xi - moved * wp.min(mu * depth / slip, f64(1.0))
            vn = vi[1]
            if vn < zero:
                ee = e
                if -vn <= f64(2.0) * f64(9.81) * dt:
                    ee = zero
                jn = -vn * (f64(1.0) + ee)
                vt = wp.vec3d(vi[0], zero, vi[2])
                st = wp.length(vt)
                if st <= mu * jn:
                    vt = wp.vec3d(zero, zero, zero)
                else:
                    vt = vt * (f64(1.0) - mu * jn / st)
                vi = vt + wp.vec3d(zero, vn + jn, zero)
        x[i] = xi
        v[i] = vi

    x = wp.array(x0, dtype=wp.vec3d, device="cpu")
    v = wp.array(v0, dtype=wp.vec3d, device="cpu")

    def run(steps: int) -> None:
        for _ in range(steps):
            wp.launch(step, dim=len(x0), inputs=[x, v], device="cpu")
        wp.synchronize()

    return run


def stream_bandwidth(nbytes: int) -> list[tuple[str, float]]:
    """Read-modify-write bandwidth (B/s, best of 20) of an in-place pass over `nbytes` of
    float64: with numpy (one thread) and as a Taichi kernel (all threads) when installed."""
    a = np.ones(nbytes // 8)
    rates = []
    best = np.inf
    for _ in range(20):
        start = time.perf_counter()
        np.multiply(a, 0.999, out=a)
        best = min(best, time.perf_counter() - start)
    rates.append(("numpy, 1 thread", 2 * a.nbytes / best))
    try:
        import taichi as ti
    except ImportError:
        return rates
    ti.init(arch=ti.cpu, default_fp=ti.f64, log_level=ti.ERROR)
    field = ti.field(ti.f64, shape=len(a))
    field.from_numpy(a)

    @ti.kernel
    def scale():
        for i in field:
            field[i] = field[i] * 0.999

    scale()
    ti.sync()
    best = np.inf
    for _ in range(20):
        start = time.perf_counter()
        scale()
        ti.sync()
        best = min(best, time.perf_counter() - start)
    rates.append(("Taichi, all threads", 2 * a.nbytes / best))
    return rates


def timed(run, steps: int, repeats: int = 5) -> tuple[float, float]:
    """Wall-clock and CPU (all threads of the process) seconds per step of `run(steps)`, in
    the fastest of `repeats` runs (the same for every implementation: on a shared machine
    the slower runs measure the other processes)."""
    best = (np.inf, np.inf)
    for _ in range(repeats):
        wall, cpu = time.perf_counter(), time.process_time()
        run(steps)
        best = min(
            best, ((time.perf_counter() - wall) / steps, (time.process_time() - cpu) / steps)
        )
    return best


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="small sizes, for a fast check")
    parser.add_argument("--n", type=int, help="particles (default 10^6, 10^5 with --quick)")
    parser.add_argument("--steps", type=int, help="steps timed (default 20, 10 with --quick)")
    args = parser.parse_args()
    n = args.n or (100_000 if args.quick else 1_000_000)
    steps = args.steps or (10 if args.quick else 20)
    rng = np.random.default_rng(0)
    x0 = rng.uniform([-10, 0, -10], [10, 5, 10], (n, 3))
    v0 = rng.normal(size=(n, 3))

    ps = ParticleSystem(x0, v0)
    ps.add(Gravity())
    ps.add(Drag(quadratic=K))
    ps.add(Plane(restitution=E, friction=MU))
    ps.step(DT)  # warm-up
    timings = [("kinema (Rust)", *timed(lambda k: ps.step(DT, k), steps))]

    def kinema_one_by_one(k: int) -> None:
        for _ in range(k):
            ps.step(DT)

    # One call per step, as Taichi and Warp launch one kernel per step: kinema then reads and
    # writes the state every step (in one call of many steps it does so once per call).
    timings.append(("kinema, 1 step per call", *timed(kinema_one_by_one, steps)))

    x, v = x0.copy(), v0.copy()
    numpy_step(x, v)

    def numpy_run(k: int) -> None:
        for _ in range(k):
            numpy_step(x, v)

    timings.append(("numpy (vectorised)", *timed(numpy_run, steps)))
    for name, make in [("Taichi (CPU, f64)", taichi_runner), ("Warp (CPU, f64)", warp_runner)]:
        run = make(x0.copy(), v0.copy())
        if run is None:
            print(f"{name}: not installed")
            continue
        run(1)  # compile
        timings.append((name, *timed(run, steps)))

    # Bytes a step must touch at least: read and write x and v (48 B per particle each way).
    floor = 2 * 48 * n
    rates = stream_bandwidth(floor // 2)
    limit = max(rate for _, rate in rates)
    t_kinema = timings[0][1]
    print(f"N = {n}, {steps} steps, {os.cpu_count()} threads available\n")
    print(
        "| implementation | ms / step | steps / s | kinema speed-up | CPU ms / step "
        "| GB/s touched | x bandwidth limit |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|")
    for name, t, cpu in timings:
        print(
            f"| {name} | {1e3 * t:.2f} | {1 / t:.1f} | {t / t_kinema:.2f}x | {1e3 * cpu:.2f} "
            f"| {floor / t / 1e9:.2f} | {limit * t / floor:.1f} |"
        )
    for name, rate in rates:
        print(f"\nIn-place stream over {floor / 1e6:.0f} MB ({name}): {rate / 1e9:.1f} GB/s")


if __name__ == "__main__":
    main()
