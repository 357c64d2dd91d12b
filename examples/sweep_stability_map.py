"""A stiffness x time-step stability map of a hanging spring chain, as a parameter sweep.

Every (stiffness, dt) pair is one task: build a chain of 10 particles on springs, step it 400
times with symplectic Euler, and record the tip's height, or the divergence
(kinema.SimulationError) as a failed task. The sweep runs on a Dask LocalCluster of one
worker process per core; the map is compared with the method's stability limit
dt < 2 / omega_max, omega_max^2 < 4 k / m, and drawn into sweep_stability_map.png.

Run: python examples/sweep_stability_map.py
"""

import os

import numpy as np

from kinema.particles import Gravity, ParticleSystem, Springs
from kinema.sweep import grid, sweep

N, MASS = 10, 0.1  # particles, kg each


def build(stiffness: float, dt: float) -> tuple[ParticleSystem, float]:
    x = np.zeros((N, 3))
    x[:, 0] = np.arange(N) * 0.1
    masses = np.full(N, MASS)
    masses[0] = np.inf  # pinned
    chain = ParticleSystem(x, masses=masses)
    chain.add(Springs([[i, i + 1] for i in range(N - 1)], stiffness, damping=0.01))
    chain.add(Gravity())
    return chain, dt


def run(system: tuple[ParticleSystem, float]) -> dict[str, float]:
    chain, dt = system
    chain.step(dt, steps=400)
    return {"tip_y": chain.positions[-1, 1]}


if __name__ == "__main__":  # Dask's worker processes import this file: keep the sweep here
    quick = bool(os.environ.get("KINEMA_QUICK"))
    stiffness = np.geomspace(10.0, 1e4, 4 if quick else 10)
    dts = np.geomspace(1e-3, 0.1, 4 if quick else 10)
    table = sweep(build, grid(stiffness=stiffness, dt=dts), run, progress=not quick)

    stable = (table["status"] == "ok").to_numpy().reshape(len(stiffness), len(dts))
    limit = 2.0 / np.sqrt(4.0 * stiffness / MASS)  # symplectic Euler, fastest chain mode
    for k, row, dt_max in zip(stiffness, stable, limit, strict=True):
        print(f"k = {k:8.1f} N/m: {''.join('.' if s else 'x' for s in row)}  dt < {dt_max:.4f}")
        # Below the bound every run is stable; far beyond it every run diverges.
        assert row[dts < 0.9 * dt_max].all() and not row[dts > 1.5 * dt_max].any()
    failed = table[table["status"] == "failed"]
    print(f"{len(failed)} of {len(table)} runs diverged, e.g.: {failed['error'].iloc[0][:60]}")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4.5))
    ax.pcolormesh(dts, stiffness, stable, cmap="RdYlGn", shading="nearest")
    ax.plot(limit, stiffness, "k--", label="2 / ω_max")
    ax.set(xscale="log", yscale="log", xlabel="dt (s)", ylabel="stiffness (N/m)")
    ax.set_title("symplectic Euler: stable (green) or diverged (red)")
    ax.legend(loc="lower left")
    fig.savefig("sweep_stability_map.png", dpi=100)
    print("wrote sweep_stability_map.png")
