"""SIMBICON walkers: simulated seconds per CPU second (x real time), the 3-D biped and the
planar one, one process, one thread.

Settings (every figure): ``Biped(dims=3)`` and ``Biped()`` at their defaults (the paper's
gait; the 3-D walk with torso_kp = 1000, torso_kd = 100, coronal cv = 0.3; contact at
200 rad/s, stable PD at knees and ankles, symplectic Euler), dt = 1e-3 s (the 3-D walker's
step; the planar one walks at 1e-3 too; the 3-D one also at 2e-3 s: it walks 20 s at every
step of 1–3.5 ms, within 0.6 % of the same distance), 20 s simulated in one ``step`` call (no Python per
step), CPU time (``time.process_time``), best of three. No peer: no other package runs
SIMBICON; the planar walker is the reference. Run with KINEMA_NUM_THREADS=1.

``--pushes``: the largest push survived by the 3-D walker (0.2 s on the torso at t = 4.0,
4.1, …, 4.6 s, forces 50–1000 N by 50, walking on to t = 9 s without the hips below 0.7 m or
the torso beyond 0.8 rad), from the front (−x), behind (+x), the left (+z) and the right
(−z), and its walks of 20 s on flat ground and 10 s on ±5° slopes.

Run: KINEMA_NUM_THREADS=1 python bench/bench_biped.py [--quick: 2 s walks] [--pushes]
"""

from __future__ import annotations

import argparse
import math
import os
import time

import kinema
from kinema.character import Biped

DT = 1e-3


def rate(dims: int, seconds: float, dt: float = DT) -> tuple[float, float]:
    """(x real time, CPU µs per step) of ``seconds`` s of walking, best of three."""
    best = float("inf")
    for _ in range(3):
        b = Biped(dims=dims)
        t = time.process_time()
        b.step(dt, round(seconds / dt))
        best = min(best, time.process_time() - t)
        assert b.com[1] > 0.8, "the walker fell"
    return seconds / best, best / round(seconds / dt) * 1e6


def walk(seconds: float, push: tuple[float, tuple[float, float, float]] | None = None, **kw: float):
    """Walk the 3-D biped ``seconds`` s at dt = 1e-3; ``push``: (time, force) for 0.2 s.
    Returns (fell, COM per 0.1 s)."""
    b = Biped(dims=3, **kw)
    com = []
    for k in range(round(seconds * 10)):
        if push is not None and abs(k * 0.1 - push[0]) < 1e-9:
            b.push(push[1], 0.2)
        try:
            b.step(DT, 100)
        except kinema.SimulationError:
            return True, com
        com.append(b.com)
        _, x, _, z = b.q[3:7]
        if b.q[1] < 0.7 or 1.0 - 2.0 * (x * x + z * z) < math.cos(0.8):
            return True, com
    return False, com


def pushes() -> None:
    """The largest push survived each way at each phase, and the walks."""
    phases = [4.0 + 0.1 * k for k in range(7)]
    print("largest push survived (N), 0.2 s on the torso, 3-D walker, dt = 1e-3 s")
    print("| push at (s) | " + " | ".join(f"{p:.1f}" for p in phases) + " |")
    for name, d in (
        ("front (−x)", (-1, 0, 0)),
        ("behind (+x)", (1, 0, 0)),
        ("left (+z)", (0, 0, 1)),
        ("right (−z)", (0, 0, -1)),
    ):
        row = []
        for at in phases:
            best = 0
            for f in range(50, 1050, 50):
                if walk(9.0, (at, (f * d[0], 0.0, f * d[2])))[0]:
                    break
                best = f
            row.append(str(best))
        print(f"| {name} | " + " | ".join(row) + " |")
    fell, com = walk(20.0)
    print(
        f"flat, 20 s: fell {fell}, {(com[-1][0] - com[19][0]) / 18:.2f} m/s over 2–20 s, "
        f"largest |z| {max(abs(c[2]) for c in com):.2f} m"
    )
    for slope in (5.0, -5.0):
        fell, com = walk(10.0, slope=math.radians(slope))
        speed = (com[-1][0] - com[len(com) // 2][0]) / (len(com) / 20) if com else 0.0
        print(f"slope {slope:+.0f}°, 10 s: fell {fell} at {len(com) / 10:.1f} s, {speed:.2f} m/s")


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--pushes", action="store_true")
    args = parser.parse_args()
    if args.pushes:
        pushes()
        return
    seconds = 2.0 if args.quick else 20.0
    threads = os.environ.get("KINEMA_NUM_THREADS", "unset")
    print(f"dt = {DT} s, {seconds} s walked, KINEMA_NUM_THREADS={threads}, CPU time, best of 3")
    three, us3 = rate(3, seconds)
    two, us2 = rate(2, seconds)
    print(f"3-D walker (Biped(dims=3)): {three:7.0f}x real time, {us3:.2f} µs/step")
    print(f"planar walker (Biped()):    {two:7.0f}x real time, {us2:.2f} µs/step")
    print(f"3-D / planar cost per step: {us3 / us2:.2f}")
    wide, us = rate(3, seconds, 2e-3)
    print(
        f"3-D walker at dt = 2e-3 s (it walks 20 s at 1-3.5 ms, within 0.6 % of one distance): "
        f"{wide:.0f}x real time, {us:.2f} µs/step"
    )


if __name__ == "__main__":
    main()
