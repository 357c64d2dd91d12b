"""Crowds and flocks: kinema's ORCA against the RVO2 library's Python binding (`pyrvo`, the
`bench` extra) on RVO2's circle crossing — agents on a circle of radius 200 m going to their
antipodes, radius 1.5 m, max speed 2 m/s, preferred speed 1 m/s (RVO2's example clips the
goal vector to 1), neighbour distance 15 m, 10 neighbours, horizons 10 s / 10 s, dt 0.25 s —
from RVO2's exact starts (evenly on the circle) with its example's perturbation of every
preferred velocity by up to 10⁻⁴ m/s (pyrvo: uniform random, as the example; kinema: its
hashed `perturbation`), in one process, until every agent has arrived (first within one
radius) or `--steps` pass: steps per second, agents arrived, mean time to goal; then boids
steps per second. pyrvo's preferred velocities are set from Python each step, as its example
does (that loop is counted in its time).

Run: python bench/bench_crowd.py [--agents 250] [--steps 4000] [--boids 100000]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from kinema.crowd import Crowd
from kinema.flock import Flock


def starts(n: int) -> tuple[np.ndarray, np.ndarray]:
    a = np.arange(n) * 2 * np.pi / n
    p = 200.0 * np.stack([np.cos(a), np.sin(a)], axis=1)
    return p, -p


def kinema_circle(n: int, steps: int) -> tuple[float, float, int]:
    """Steps/s, mean time to goal over the arrived, and the number arrived."""
    c = Crowd(
        "orca",
        radius=1.5,
        max_speed=2.0,
        preferred_speed=1.0,
        neighbour_distance=15.0,
        max_neighbours=10,
        time_horizon=10.0,
        obstacle_time_horizon=10.0,
        goal_tolerance=1.5,
        perturbation=1e-4,
    )
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

    sim = pyrvo.RVOSimulator(0.25, 15.0, 10, 10.0, 10.0, 1.5, 2.0)
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
            if np.isinf(arrival[i]) and np.hypot(*d) < 1.5:
                arrival[i] = k * 0.25
            length = np.hypot(*d)
            if length > 1.0:
                d = d / length
            angle, nudge = rng.uniform(0.0, 2 * np.pi), rng.uniform(0.0, 1e-4)
            d = d + nudge * np.array([np.cos(angle), np.sin(angle)])
            sim.set_agent_pref_velocity(i, (float(d[0]), float(d[1])))
        sim.do_step()
        k += 1
    rate = k / (time.perf_counter() - t0)
    done = np.isfinite(arrival)
    return rate, float(arrival[done].mean()) if done.any() else float("nan"), int(done.sum())


def boids(n: int, steps: int) -> float:
    rng = np.random.default_rng(0)
    side = (n / 0.5) ** 0.5  # 0.5 boids per m²
    f = Flock(rng.uniform(0, side, (n, 2)), rng.uniform(-1, 1, (n, 2)))
    f.step(0.05)
    t0 = time.perf_counter()
    f.step(0.05, steps)
    return steps / (time.perf_counter() - t0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--agents", type=int, default=250)
    ap.add_argument("--steps", type=int, default=4000)
    ap.add_argument("--boids", type=int, default=100_000)
    args = ap.parse_args()
    print(f"threads: {os.environ.get('RAYON_NUM_THREADS', 'all')}, load: {os.getloadavg()}")
    kr, kt, ka = kinema_circle(args.agents, args.steps)
    print(
        f"kinema ORCA, {args.agents} agents: {kr:.1f} steps/s, {ka} arrived, "
        f"mean time to goal {kt:.1f} s"
    )
    try:
        rr, rt, ra = rvo2_circle(args.agents, args.steps)
        print(
            f"RVO2 (pyrvo), {args.agents} agents: {rr:.1f} steps/s, {ra} arrived, "
            f"mean time to goal {rt:.1f} s; speed ratio kinema/RVO2 {kr / rr:.2f}, "
            f"time-to-goal ratio {kt / rt:.3f}"
        )
    except ImportError:
        print("pyrvo not installed (pip install pyrvo): no RVO2 comparison")
    print(f"kinema boids, {args.boids} in 2-D: {boids(args.boids, 20):.2f} steps/s")


if __name__ == "__main__":
    main()
