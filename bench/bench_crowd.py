"""Crowds and flocks: kinema's ORCA against the RVO2 library's Python binding (`pyrvo`, the
`bench` extra) on RVO2's circle crossing — agents on a circle of radius 200 m going to their
antipodes at the example's settings, `kinema.crowd.RVO2_CIRCLE` (radius 1.5 m, max speed
2 m/s, preferred speed 1 m/s: RVO2's example clips the goal vector to 1; neighbour distance
15 m, 10 neighbours, horizons 10 s / 10 s; dt 0.25 s), read by both simulators —
from RVO2's exact starts (evenly on the circle) with its example's perturbation of every
preferred velocity by up to 10⁻⁴ m/s (pyrvo: uniform random, as the example; kinema: its
hashed `perturbation`; kinema at its default planning margin 0.1), in one process, until
every agent has arrived (first within one radius) or `--steps` pass: steps per second,
agents arrived, mean time to goal (pyrvo's preferred velocities are set from Python each
step, as its example does, and that loop is counted in its time there).

Then speed, as time per step at equal settings (kinema's defaults): ORCA with `--orca`
agents crossing a square at 0.1 agents per m² against RVO2's `do_step` alone (the Python loop
setting its preferred velocities outside the timer), and 2-D boids at 0.5 per m² against a
numpy reference with scipy's cKDTree neighbours (`boids_reference`, the same rules).

Run: python bench/bench_crowd.py [--agents 250] [--steps 6000] [--orca 1000 10000]
[--boids 10000 100000 1000000]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from kinema.crowd import RVO2_CIRCLE, Crowd
from kinema.flock import Flock


def starts(n: int) -> tuple[np.ndarray, np.ndarray]:
    a = np.arange(n) * 2 * np.pi / n
    p = 200.0 * np.stack([np.cos(a), np.sin(a)], axis=1)
    return p, -p


def kinema_circle(n: int, steps: int) -> tuple[float, float, int]:
    """Steps/s, mean time to goal over the arrived, and the number arrived."""
    c = Crowd(**{**RVO2_CIRCLE, "perturbation": 1e-4})
    p, g = starts(n)
    c.add_agents(p, g)
    t0 = time.perf_counter()
    done = 0
    while done < steps and not np.isfinite(c.metrics()["arrival_times"]).all():
        c.step(0.25, 10)
        done += 10
    rate = done / (time.perf_counter() - t0)
    m = c.metrics()
    return rate, m["mean_time_to_goal"], m["arrived"]


def rvo2_circle(n: int, steps: int) -> tuple[float, float, int]:
    import pyrvo

    s = RVO2_CIRCLE
    keys = ("neighbour_distance", "max_neighbours", "time_horizon", "obstacle_time_horizon")
    sim = pyrvo.RVOSimulator(0.25, *(s[k] for k in keys), s["radius"], s["max_speed"])
    p, g = starts(n)
    for x in p:
        sim.add_agent((float(x[0]), float(x[1])))
    arrival = np.full(n, np.inf)
    rng = np.random.default_rng(0)
    t0 = time.perf_counter()
    k = 0
    while k < steps and not np.isfinite(arrival).all():
        for i in range(n):
            q = sim.get_agent_position(i)
            d = g[i] - (q.x, q.y)
            length = np.hypot(*d)
            if np.isinf(arrival[i]) and length < s["goal_tolerance"]:
                arrival[i] = k * 0.25
            if length > s["preferred_speed"]:
                d = d * s["preferred_speed"] / length
            angle, nudge = rng.uniform(0.0, 2 * np.pi), rng.uniform(0.0, 1e-4)
            d = d + nudge * np.array([np.cos(angle), np.sin(angle)])
            sim.set_agent_pref_velocity(i, (float(d[0]), float(d[1])))
        sim.do_step()
        k += 1
    rate = k / (time.perf_counter() - t0)
    done = np.isfinite(arrival)
    return rate, float(arrival[done].mean()) if done.any() else float("nan"), int(done.sum())


def boids_reference(
    p: np.ndarray, v: np.ndarray, dt: float, steps: int
) -> tuple[np.ndarray, np.ndarray]:
    """kinema's boids at their defaults (docs/crowd.md: separation 1.5, alignment 1, cohesion
    1, neighbour radius 2 m, separation distance 1 m, field of view 270°, max speed 2 m/s, max
    force 1 m/s²) in numpy, neighbours by scipy's cKDTree: the peer of the boids benchmark and
    the independent oracle of tests/python/test_flock.py."""
    from scipy.spatial import cKDTree

    sep_w, ali_w, coh_w, radius, sep_d = 1.5, 1.0, 1.0, 2.0, 1.0
    cos_half, max_speed, max_force = np.cos(0.75 * np.pi), 2.0, 1.0

    def clamp(x: np.ndarray, m: float) -> np.ndarray:
        length = np.linalg.norm(x, axis=1, keepdims=True)
        return np.where(length > m, x * (m / np.where(length > 0, length, 1.0)), x)

    def steer(desired: np.ndarray, v: np.ndarray) -> np.ndarray:
        length = np.linalg.norm(desired, axis=1, keepdims=True)
        out = desired * (max_speed / np.where(length > 0, length, 1.0)) - v
        return np.where(length > 0, clamp(out, max_force), 0.0)

    p, v = p.copy(), v.copy()
    n, dim = p.shape
    for _ in range(steps):
        pairs = cKDTree(p).query_pairs(radius, output_type="ndarray")
        i = np.concatenate([pairs[:, 0], pairs[:, 1]])
        j = np.concatenate([pairs[:, 1], pairs[:, 0]])
        d = p[j] - p[i]
        dist = np.linalg.norm(d, axis=1)
        speed = np.linalg.norm(v[i], axis=1)
        seen = (speed == 0) | (np.einsum("kd,kd->k", d, v[i]) >= cos_half * dist * speed)
        i, j, d, dist = i[seen], j[seen], d[seen], dist[seen]
        count = np.bincount(i, minlength=n)[:, None].astype(float)
        close = (dist > 0) & (dist < sep_d)
        push = np.where(close[:, None], -d / np.where(close, dist * dist, 1.0)[:, None], 0.0)
        away, velocity, offset = (np.zeros((n, dim)) for _ in range(3))
        for k in range(dim):
            away[:, k] = np.bincount(i, push[:, k], minlength=n)
            velocity[:, k] = np.bincount(i, v[j, k], minlength=n)
            offset[:, k] = np.bincount(i, d[:, k], minlength=n)
        inv = 1.0 / np.maximum(count, 1.0)
        a = (
            sep_w * steer(away, v)
            + ali_w * steer(velocity * inv, v)
            + coh_w * steer(offset * inv, v)
        )
        a = np.where(count > 0, clamp(a, max_force), 0.0)
        v = clamp(v + a * dt, max_speed)
        p = p + v * dt
    return p, v


def boid_field(n: int) -> tuple[np.ndarray, np.ndarray]:
    """`n` boids in 2-D at 0.5 per m² (random, seed 0), velocities in [-1, 1]² m/s."""
    rng = np.random.default_rng(0)
    side = (n / 0.5) ** 0.5
    return rng.uniform(0, side, (n, 2)), rng.uniform(-1, 1, (n, 2))


def boids(n: int, steps: int) -> tuple[float, float, float, float]:
    """Seconds per step of kinema's boids and of the numpy/cKDTree reference (defaults, dt
    0.05 s, 2-D, 0.5 boids per m²): wall time and CPU time of the process (all threads)."""
    import scipy.spatial  # noqa: F401 -- imported outside the timer

    p, v = boid_field(n)
    f = Flock(p, v)
    f.step(0.05)  # warm-up: buffers grow
    t0, c0 = time.perf_counter(), time.process_time()
    f.step(0.05, steps)
    kin = (time.perf_counter() - t0) / steps
    kin_cpu = (time.process_time() - c0) / steps
    t0, c0 = time.perf_counter(), time.process_time()
    boids_reference(p, v, 0.05, 1)
    return kin, time.perf_counter() - t0, kin_cpu, time.process_time() - c0


def orca_field(n: int) -> tuple[np.ndarray, np.ndarray]:
    """`n` agents at 0.1 per m² in a square (random, seed 1), goals the mirror images of the
    starts through the centre (everyone crosses)."""
    rng = np.random.default_rng(1)
    side = (n / 0.1) ** 0.5
    p = rng.uniform(-side / 2, side / 2, (n, 2))
    return p, -p


def orca_speed(n: int, steps: int) -> tuple[float, float | None]:
    """Seconds per ORCA step of kinema and of RVO2 (pyrvo's do_step alone; the preferred
    velocities are set outside the timer), both at kinema's defaults: radius 0.25 m, max
    speed 2 m/s, preferred speed 1.34 m/s, neighbour distance 5 m, 10 neighbours, horizons
    5 s / 2 s, dt 0.1 s."""
    p, g = orca_field(n)
    c = Crowd("orca")
    c.add_agents(p, g)
    c.step(0.1)  # warm-up
    t0 = time.perf_counter()
    c.step(0.1, steps)
    kin = (time.perf_counter() - t0) / steps
    try:
        import pyrvo
    except ImportError:
        return kin, None
    sim = pyrvo.RVOSimulator(0.1, 5.0, 10, 5.0, 2.0, 0.25, 2.0)
    for x in p:
        sim.add_agent((float(x[0]), float(x[1])))
    spent = 0.0
    for _ in range(steps + 1):
        for i in range(n):
            q = sim.get_agent_position(i)
            d = g[i] - (q.x, q.y)
            length = np.hypot(*d)
            d = d * (1.34 / length) if length > 0.134 else d / 0.1
            sim.set_agent_pref_velocity(i, (float(d[0]), float(d[1])))
        t0 = time.perf_counter()
        sim.do_step()
        spent += time.perf_counter() - t0
    return kin, spent / (steps + 1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--agents", type=int, default=250)
    ap.add_argument("--steps", type=int, default=6000)
    ap.add_argument("--orca", type=int, nargs="*", default=[1000, 10_000])
    ap.add_argument("--boids", type=int, nargs="*", default=[10_000, 100_000, 1_000_000])
    args = ap.parse_args()
    print(f"threads: {os.environ.get('RAYON_NUM_THREADS', 'all')}, load: {os.getloadavg()}")
    if args.agents:
        kr, kt, ka = kinema_circle(args.agents, args.steps)
        print(
            f"circle crossing, kinema ORCA, {args.agents} agents: {kr:.1f} steps/s, {ka} "
            f"arrived, mean time to goal {kt:.2f} s"
        )
        try:
            rr, rt, ra = rvo2_circle(args.agents, args.steps)
            print(
                f"circle crossing, RVO2 (pyrvo), {args.agents} agents: {rr:.1f} steps/s, {ra} "
                f"arrived, mean time to goal {rt:.2f} s; time-to-goal ratio {kt / rt:.3f}"
            )
        except ImportError:
            print("pyrvo not installed (pip install pyrvo): no RVO2 comparison")
    for n in args.orca:
        kin, rvo = orca_speed(n, 20)
        line = f"ORCA, {n} agents (kinema defaults, dt 0.1 s): kinema {kin * 1e3:.2f} ms/step"
        if rvo is not None:
            line += f", RVO2 {rvo * 1e3:.2f} ms/step, ratio RVO2/kinema {rvo / kin:.2f}"
        print(line)
    for n in args.boids:
        kin, ref, kin_cpu, ref_cpu = boids(n, 5)
        print(
            f"boids, {n} in 2-D (defaults, dt 0.05 s, 0.5 per m²): kinema "
            f"{kin * 1e3:.1f} ms/step (CPU {kin_cpu * 1e3:.1f} ms), numpy+cKDTree "
            f"{ref * 1e3:.1f} ms/step (CPU {ref_cpu * 1e3:.1f} ms), ratio {ref / kin:.1f} "
            f"(CPU {ref_cpu / kin_cpu:.1f})"
        )


if __name__ == "__main__":
    main()
