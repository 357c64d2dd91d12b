"""A stiffness x time-step stability map of a hanging cloth stepped explicitly, as a sweep.

Every (stretch stiffness, dt) pair is one task: build a 10x10 Baraff–Witkin cloth pinned at two
corners, step it for 0.25 s with symplectic Euler, and record its lowest point, or the divergence
(kinema.SimulationError) as a failed task. The sweep runs on a Dask LocalCluster of one worker
process per core. The map is compared with the method's stability limit on the cloth's fastest
vibration (Cloth.fastest_mode, kinema.ode.max_stable_dt_oscillator) and drawn into
sweep_stability_map.png: which combinations diverge, and where the theory puts the border.

Run: python examples/sweep_stability_map.py
"""

import os

import numpy as np

from kinema.cloth import Cloth
from kinema.ode import max_stable_dt_oscillator
from kinema.sweep import grid, sweep

N, T = 10, 0.25  # vertices per side, seconds simulated


def build(stretch: float, dt: float) -> tuple[Cloth, float]:
    cloth = Cloth.grid(N, N, 1.0, 1.0, stretch=stretch, shear=stretch / 10, damping=1e-3)
    cloth.pin([0, N - 1])
    return cloth, dt


def run(system: tuple[Cloth, float]) -> dict[str, float]:
    cloth, dt = system
    cloth.step(dt, round(T / dt), integrator="symplectic_euler")
    return {"lowest": cloth.positions[:, 1].min()}


def limit(stretch: float) -> float:
    """Symplectic Euler's largest stable step on the flat cloth's fastest mode (s)."""
    cloth, _ = build(stretch, 1.0)
    omega, c = cloth.fastest_mode()
    return max_stable_dt_oscillator("symplectic_euler", omega, c)


if __name__ == "__main__":  # Dask's worker processes import this file: keep the sweep here
    quick = bool(os.environ.get("KINEMA_QUICK"))
    stretch = np.geomspace(1e2, 1e4, 3 if quick else 8)
    dts = np.geomspace(2e-5, 5e-3, 5 if quick else 12)
    table = sweep(build, grid(stretch=stretch, dt=dts), run, progress=not quick)

    stable = (table["status"] == "ok").to_numpy().reshape(len(stretch), len(dts))
    limits = np.array([limit(k) for k in stretch])
    for k, row, dt_max in zip(stretch, stable, limits, strict=True):
        print(
            f"stretch {k:8.1f} N/m: {''.join('.' if s else 'x' for s in row)}  dt < {dt_max:.2e} s"
        )
        # Below the bound every run is stable; far beyond it every run diverges.
        assert row[dts < 0.9 * dt_max].all() and not row[dts > 2.0 * dt_max].any()
    failed = table[table["status"] == "failed"]
    print(f"{len(failed)} of {len(table)} runs diverged, e.g.: {failed['error'].iloc[0][:60]}")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4.5))
    ax.pcolormesh(dts, stretch, stable, cmap="RdYlGn", shading="nearest")
    ax.plot(limits, stretch, "k--", label="limit on the fastest mode")
    ax.set(xscale="log", yscale="log", xlabel="dt (s)", ylabel="stretch stiffness (N/m)")
    ax.set_title("cloth, symplectic Euler: stable (green) or diverged (red)")
    ax.legend(loc="lower left")
    fig.savefig("sweep_stability_map.png", dpi=100)
    print("wrote sweep_stability_map.png")
