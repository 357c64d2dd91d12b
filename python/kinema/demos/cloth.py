"""Cloth demo: a sheet of the default cotton-like cloth, held upright, drops onto the ground
and folds onto itself, with self-collision (Bridson, Fedkiw & Anderson 2002).

Writes ``cloth.gif`` (the fall and the folds, rendered with matplotlib) and ``cloth.png``
(snapshots; per step the triangle pairs that intersect by the exact all-pairs test, the step
time split into the cloth solve and self-collision, and the largest edge stretch). Implicit
Euler with the default settings (sparse Cholesky, strain limit 3 %), dt = 1/100 s.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from kinema.cloth import Cloth, Plane

DT = 0.01
"""Step (s)."""


def sheet(n: int) -> Cloth:
    """An ``n`` x ``n`` sheet of 1 m of the default material, upright in the y–z plane with its
    lower edge 2 cm above the ground and a slight wave (so that it buckles into folds as it
    lands), self-collision on at the default thickness (a tenth of the mean edge length)."""
    cloth = Cloth.grid(n, n, 1.0, 1.0, self_collision=True)
    x = cloth.positions.copy()
    z = x[:, 2].copy()
    x[:, 1] = 0.52 + z
    x[:, 2] = 0.02 * np.sin(9.0 * z)
    cloth.set_state(x)
    cloth.add_collider(Plane((0.0, 0.0, 0.0), (0.0, 1.0, 0.0), friction=0.5))
    return cloth


def _edges(cloth: Cloth) -> np.ndarray:
    t = cloth.triangles
    return np.unique(np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), 1), axis=0)


def simulate(n: int, steps: int) -> tuple[Cloth, list[np.ndarray], dict[str, np.ndarray]]:
    """Drop the sheet for ``steps`` steps; log per step the intersecting triangle pairs, the
    seconds of the whole step, of the cloth solve and of self-collision, the largest edge
    stretch (length over rest length) and the pairs closer than the thickness."""
    cloth = sheet(n)
    edges = _edges(cloth)
    x = cloth.positions
    rest = np.linalg.norm(x[edges[:, 0]] - x[edges[:, 1]], axis=1)
    shapes = [x.copy()]
    names = ("intersections", "seconds", "solve", "self", "stretch", "proximities")
    log: dict[str, list[float]] = {k: [] for k in names}
    for _ in range(steps):
        start = time.perf_counter()
        cloth.step(DT)
        log["seconds"].append(time.perf_counter() - start)
        s = cloth.stats
        log["solve"].append(s["assemble_seconds"] + s["solve_seconds"])
        log["self"].append(s["self_collision_seconds"])
        log["proximities"].append(s["proximities"])
        x = cloth.positions
        length = np.linalg.norm(x[edges[:, 0]] - x[edges[:, 1]], axis=1)
        log["stretch"].append(float((length / rest).max()))
        log["intersections"].append(len(cloth.self_intersections()))
        shapes.append(x.copy())
    return cloth, shapes, {k: np.array(v) for k, v in log.items()}


def _draw(ax: Any, cloth: Cloth, x: np.ndarray) -> None:
    ax.plot_trisurf(
        x[:, 0],
        x[:, 2],
        x[:, 1],
        triangles=cloth.triangles,
        color="tab:red",
        alpha=0.95,
        linewidth=0.1,
        edgecolor="0.3",
    )
    ax.set_xlim(-0.6, 0.6)
    ax.set_ylim(-0.6, 0.6)
    ax.set_zlim(0.0, 1.1)
    ax.set_box_aspect((1.2, 1.2, 1.1))
    ax.view_init(elev=20, azim=-60)
    ax.set_axis_off()


def run(out_dir: Path, quick: bool) -> dict[str, object]:
    """Simulate, render ``cloth.gif`` and ``cloth.png`` and return the numbers."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation, PillowWriter

    n, steps = (16, 60) if quick else (32, 150)
    cloth, shapes, log = simulate(n, steps)

    fig = plt.figure(figsize=(5, 5))
    ax = fig.add_subplot(projection="3d")
    every = 3

    def frame(k: int) -> None:
        ax.clear()
        _draw(ax, cloth, shapes[k * every])
        ax.set_title(f"t = {k * every * DT:.2f} s")

    gif = out_dir / "cloth.gif"
    FuncAnimation(fig, frame, frames=len(shapes[::every])).save(gif, writer=PillowWriter(fps=20))
    plt.close(fig)

    fig = plt.figure(figsize=(14, 4))
    for k, f in enumerate([0, steps // 2, steps]):
        axk = fig.add_subplot(1, 4, k + 1, projection="3d")
        _draw(axk, cloth, shapes[f])
        axk.set_title(f"t = {f * DT:.2f} s")
    t = np.arange(1, steps + 1) * DT
    ax4 = fig.add_subplot(1, 4, 4)
    ax4.plot(t, 1e3 * log["solve"], label="cloth solve (ms)")
    ax4.plot(t, 1e3 * log["self"], label="self-collision (ms)")
    ax4.plot(t, log["intersections"], "k.", label="intersecting pairs")
    ax4.set_xlabel("time (s)")
    ax5 = ax4.twinx()
    ax5.plot(t, 100 * (log["stretch"] - 1), color="tab:green", label="largest stretch (%)")
    ax4.legend(loc="upper left", fontsize=8)
    ax5.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    png = out_dir / "cloth.png"
    fig.savefig(png, dpi=100)
    plt.close(fig)

    return {
        "pictures": f"{gif}, {png}",
        "vertices, triangles": f"{len(cloth)}, {cloth.triangles.shape[0]}",
        "steps with intersecting triangles (exact all-pairs test)": int(
            np.count_nonzero(log["intersections"])
        ),
        "ms per step (mean; cloth solve, self-collision)": (
            f"{1e3 * log['seconds'].mean():.1f}; {1e3 * log['solve'].mean():.1f}, "
            f"{1e3 * log['self'].mean():.1f}"
        ),
        "largest edge stretch (%)": f"{100 * (log['stretch'].max() - 1):.2f}",
        "pairs closer than the thickness (last step)": int(log["proximities"][-1]),
        "lowest vertex (m)": f"{shapes[-1][:, 1].min():.2e}",
    }
