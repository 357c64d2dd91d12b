"""Scenes: what the scene layer costs over calling the systems directly, in one process.

- an empty scene: time per step (goal: under 1 µs);
- a 64x64 Baraff–Witkin cloth: ``scene.run`` against ``cloth.step`` in a loop (goal: under 5 %);
- 100 000 particles without colliders: the scene adds no collision work;
- the same particles with a kinematic sphere, against moving the collider by hand: what the
  scene's coupling adds when it is asked for.

Each case steps fresh copies of one pickled system, alternating direct and scene runs, and
keeps the best of several; times are per step.

Run: python bench/bench_scene.py [--quick]
"""

from __future__ import annotations

import argparse
import pickle
import time
from collections.abc import Callable

import numpy as np

from kinema import anim, cloth, particles
from kinema.scene import AnimatedSphere, Scene

DT = 1 / 60


def best(fn: Callable[[], object], repeat: int) -> float:
    """Best wall time of ``repeat`` calls (s)."""
    out = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        out = min(out, time.perf_counter() - start)
    return out


def make_cloth(n: int) -> cloth.Cloth:
    c = cloth.Cloth.grid(n, n, 1.0, 1.0)
    c.pin([0, n - 1])
    return c


def make_particles(n: int) -> particles.ParticleSystem:
    rng = np.random.default_rng(0)
    p = particles.ParticleSystem(rng.uniform(-1, 1, (n, 3)) + np.array([0, 2, 0]))
    p.add(particles.Gravity())
    p.add(particles.Drag(quadratic=0.01))
    return p


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="small sizes, few repeats")
    args = parser.parse_args()
    n_cloth, n_particles, steps, repeat = (
        (24, 10_000, 10, 3) if args.quick else (64, 100_000, 30, 5)
    )
    empty_steps = 10_000 if args.quick else 1_000_000

    empty = Scene(dt=DT, substeps=10)
    t_empty = best(lambda: empty.run(frames=empty_steps // 10, progress=False), repeat)
    rows: list[tuple[str, float | None, float]] = [("empty scene", None, t_empty / empty_steps)]

    def trial(blob: bytes, via_scene: bool, coupled: bool = False) -> float:
        """Seconds for ``steps`` steps of a fresh copy of the pickled system."""
        system = pickle.loads(blob)
        if not via_scene:
            start = time.perf_counter()
            for k in range(steps):
                if coupled:  # what the scene does, by hand: move the collider each step
                    system.set_collider(0, particles.Sphere(path(k * DT), 0.5))
                system.step(DT)
            return time.perf_counter() - start
        scene = Scene(dt=DT)
        scene.add(system)
        if coupled:
            scene.add(AnimatedSphere(0.5, path))
        start = time.perf_counter()
        scene.run(frames=steps, progress=False)
        return time.perf_counter() - start

    def compare(name: str, blob: bytes, coupled: bool = False) -> None:
        # Alternate the two so that both see the same states and the same machine load.
        times = [(trial(blob, False, coupled), trial(blob, True, coupled)) for _ in range(repeat)]
        rows.append((name, min(t[0] for t in times) / steps, min(t[1] for t in times) / steps))

    path = anim.Track([0.0, 10.0], [[0.0, 0.5, 0.0], [1.0, 0.5, 0.0]], "linear")
    c = make_cloth(n_cloth)
    c.step(DT, 30)  # past the first large PCG solves of the fall
    compare(f"{n_cloth}x{n_cloth} cloth", pickle.dumps(c))
    p = make_particles(n_particles)
    compare(f"{n_particles} particles, no colliders", pickle.dumps(p))
    p.add(particles.Sphere(path(0.0), 0.5))
    compare(f"{n_particles} particles + animated sphere", pickle.dumps(p), coupled=True)

    print("| case (per step) | direct (µs) | scene (µs) | scene overhead |")
    print("|---|---:|---:|---:|")
    for name, d, s in rows:
        if d is None:
            print(f"| {name} | – | {1e6 * s:.3f} | – |")
        else:
            print(f"| {name} | {1e6 * d:.0f} | {1e6 * s:.0f} | {100 * (s / d - 1):+.1f}% |")


if __name__ == "__main__":
    main()
