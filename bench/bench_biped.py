"""SIMBICON walkers: simulated seconds per CPU second (x real time), the 3-D biped and the
planar one, one process, one thread.

Settings (every figure): ``Biped(dims=3)`` and ``Biped()`` at their defaults (the paper's
gait; the 3-D walk with torso_kp = 1000, torso_kd = 100, coronal cv = 0.4; contact at
200 rad/s, stable PD at knees and ankles, symplectic Euler), dt = 1e-3 s (the 3-D walker's
step; the planar one walks at 1e-3 too), 20 s simulated in one ``step`` call (no Python per
step), CPU time (``time.process_time``), best of three. No peer: no other package runs
SIMBICON; the planar walker is the reference. Run with KINEMA_NUM_THREADS=1.

Run: KINEMA_NUM_THREADS=1 python bench/bench_biped.py [--quick: 2 s walks]
"""

from __future__ import annotations

import argparse
import os
import time

from kinema.character import Biped

DT = 1e-3


def rate(dims: int, seconds: float) -> tuple[float, float]:
    """(x real time, CPU µs per step) of ``seconds`` s of walking, best of three."""
    best = float("inf")
    for _ in range(3):
        b = Biped(dims=dims)
        t = time.process_time()
        b.step(DT, round(seconds / DT))
        best = min(best, time.process_time() - t)
        assert b.com[1] > 0.8, "the walker fell"
    return seconds / best, best / round(seconds / DT) * 1e6


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    seconds = 2.0 if args.quick else 20.0
    threads = os.environ.get("KINEMA_NUM_THREADS", "unset")
    print(f"dt = {DT} s, {seconds} s walked, KINEMA_NUM_THREADS={threads}, CPU time, best of 3")
    three, us3 = rate(3, seconds)
    two, us2 = rate(2, seconds)
    print(f"3-D walker (Biped(dims=3)): {three:7.0f}x real time, {us3:.2f} µs/step")
    print(f"planar walker (Biped()):    {two:7.0f}x real time, {us2:.2f} µs/step")
    print(f"3-D / planar cost per step: {us3 / us2:.2f}")


if __name__ == "__main__":
    main()
