"""An ensemble of 100 particle fountains that differ only in their emitter's random seed.

Each task builds a fountain (an emitter of 300 particles/s with a random velocity spread, gravity,
drag, a ground plane), runs it for 1.5 s and returns the particles' mean height, the highest one
and their mean distance from the fountain's axis. Over the ensemble, the mean and the spread (standard deviation) of
each quantity, and the standard error of the mean, say how much one run's numbers can be
trusted; sweep_fountain_ensemble.png shows the distribution of the mean height. The seeds are
the design, so every run is reproducible on its own (kinema.sweep gives the same bits
serially or on any cluster).

Run: python examples/sweep_fountain_ensemble.py
"""

import os

import numpy as np

from kinema.particles import Drag, Emitter, Gravity, ParticleSystem, Plane
from kinema.sweep import sweep


def build(seed: int) -> ParticleSystem:
    ps = ParticleSystem(np.zeros((0, 3)), capacity=1000)
    ps.add(
        Emitter(
            rate=300, velocity=[0, 5, 0], velocity_spread=1.5, lifespan=2.0, mass=0.01, seed=seed
        )
    )
    ps.add(Gravity())
    ps.add(Drag(quadratic=1e-4))
    ps.add(Plane(restitution=0.4, friction=0.3))
    return ps


def run(ps: ParticleSystem) -> dict[str, float]:
    ps.step(1 / 240, steps=360)  # 1.5 s
    x = ps.positions[ps.alive]
    return {
        "mean_height": x[:, 1].mean(),
        "highest": x[:, 1].max(),
        "radius": np.hypot(x[:, 0], x[:, 2]).mean(),
    }


if __name__ == "__main__":  # Dask's worker processes import this file: keep the sweep here
    quick = bool(os.environ.get("KINEMA_QUICK"))
    seeds = 20 if quick else 100
    table = sweep(build, [{"seed": s} for s in range(seeds)], run, progress=not quick)
    assert (table["status"] == "ok").all()
    for name in ["mean_height", "highest", "radius"]:
        values = table[name].to_numpy(dtype=float)
        mean, spread = values.mean(), values.std(ddof=1)
        print(
            f"{name:>12}: mean {mean:8.4f}, spread {spread:.4f} "
            f"(standard error of the mean {spread / np.sqrt(seeds):.4f}, {seeds} seeds)"
        )
    heights = table["mean_height"].to_numpy()
    assert heights.std() > 0  # the seeds matter
    assert (heights > 0).all()  # above the ground plane

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    ax.hist(heights, bins=15, color="tab:blue", alpha=0.8)
    ax.axvline(heights.mean(), color="k", label=f"mean {heights.mean():.3f} m")
    ax.set(xlabel="mean particle height at t = 1.5 s (m)", ylabel="runs")
    ax.set_title(f"{seeds} fountains, one seed each")
    ax.legend()
    fig.savefig("sweep_fountain_ensemble.png", dpi=100)
    print("wrote sweep_fountain_ensemble.png")
