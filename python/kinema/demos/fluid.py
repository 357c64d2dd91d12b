"""Fluid demo: a dam break (a water column collapsing in a tank, the set-up of Martin & Moyce
1952) with DFSPH, drawn from the side as particles coloured by speed into ``fluid.gif`` and
``fluid.png``."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kinema.demos._gif import save_gif_and_last_frame
from kinema.fluid import Fluid


def run(out_dir: Path, quick: bool) -> dict[str, object]:
    """Simulate the dam break, write the GIF and a still, and return counts and errors."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    width, height, depth = 0.6, 0.4, 0.05
    spacing = 0.025 if quick else 0.0125
    fps, seconds = 30, (0.6 if quick else 1.5)
    fluid = Fluid(spacing=spacing)
    fluid.add_boundary_box([0, 0, 0], [width, height, depth])
    fluid.add_block([0, 0, 0], [0.15, 0.3, depth])
    frames, worst = [], 0.0
    for _ in range(int(fps * seconds)):
        fluid.step(1 / fps)
        worst = max(worst, fluid.stats["max_density_error"])
        frames.append((fluid.positions.copy(), np.linalg.norm(fluid.velocities, axis=1)))

    fig, ax = plt.subplots(figsize=(6.0, 4.2))
    top = max(float(s.max()) for _, s in frames)

    def draw(k: int) -> None:
        ax.cla()
        x, speed = frames[k]
        ax.scatter(x[:, 0], x[:, 1], c=speed, cmap="viridis", vmin=0, vmax=top, s=4)
        ax.set_xlim(0, width)
        ax.set_ylim(0, height)
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.set_title(f"dam break, DFSPH, t = {(k + 1) / fps:.2f} s (colour: speed)")

    gif, png = save_gif_and_last_frame(fig, draw, range(len(frames)), out_dir / "fluid", fps)
    return {
        "particles": len(fluid),
        "frames": len(frames),
        "largest density error (%)": round(worst, 3),
        "fastest (m/s)": round(top, 3),
        "animation": str(gif),
        "picture": str(png),
    }
