"""Particles demo: a fountain with an emitter, a vortex, curl-noise turbulence and a ground
plane with restitution and friction, rendered to ``particles.gif`` and ``particles.png``; each
particle is drawn in the colour and size its emitter gave it, fading with age."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kinema.demos._gif import save_gif_and_last_frame
from kinema.particles import Drag, Emitter, Gravity, ParticleSystem, Plane, Turbulence, Vortex


def run(out_dir: Path, quick: bool) -> dict[str, object]:
    """Simulate the fountain, write the GIF and a still, and return counts and energies."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fps, seconds = 30, (2.0 if quick else 6.0)
    substeps = 4
    ps = ParticleSystem(np.zeros((0, 3)), capacity=3000)
    ps.add(
        Emitter(
            rate=600,
            position=[0, 0.05, 0],
            position_spread=0.05,
            velocity=[0, 7.0, 0],
            velocity_spread=1.2,
            lifespan=2.5,
            mass=0.01,
            seed=7,
            color=(0.15, 0.45, 1.0),
            color_spread=0.15,
            size=0.03,
            size_spread=0.015,
        )
    )
    ps.add(Gravity())
    ps.add(Drag(quadratic=2e-4))
    ps.add(Vortex(center=[0, 0, 0], strength=3.0, core=0.3))
    ps.add(Turbulence(strength=4.0, scale=0.7, seed=1))
    ps.add(Plane(restitution=0.3, friction=0.4))

    frames, contacts = [], 0
    for _ in range(int(fps * seconds)):
        for _ in range(substeps):
            ps.step(1.0 / (fps * substeps))
            contacts += ps.stats["contacts"]
        alive = ps.alive
        rgba = ps.colors[alive].copy()
        rgba[:, 3] *= np.clip(1.0 - ps.ages[alive] / 2.5, 0.1, 1.0)  # fade with age
        frames.append((ps.positions[alive].copy(), rgba, ps.sizes[alive].copy()))

    fig = plt.figure(figsize=(5.5, 5.5))
    ax = fig.add_subplot(projection="3d")

    def draw(k: int) -> None:
        ax.cla()
        pts, rgba, sizes = frames[k]
        # Marker area in points² grows with the square of the diameter (3 pt² at 3 cm).
        ax.scatter(pts[:, 0], pts[:, 2], pts[:, 1], c=rgba, s=3 * (sizes / 0.03) ** 2)
        ax.set_xlim(-2.5, 2.5)
        ax.set_ylim(-2.5, 2.5)
        ax.set_zlim(0, 4)
        ax.set_xlabel("x")
        ax.set_ylabel("z")
        ax.set_zlabel("y (up)")
        ax.set_title(f"fountain, t = {(k + 1) / fps:.2f} s, {len(pts)} particles")

    step = 3 if quick else 1
    shown = range((len(frames) - 1) % step, len(frames), step)  # ends on the last frame
    gif, png = save_gif_and_last_frame(fig, draw, shown, out_dir / "particles", fps // step)
    return {
        "animation": str(gif),
        "picture": str(png),
        "particles alive at the end": int(ps.alive.sum()),
        "ground contacts resolved": contacts,
        "kinetic energy at the end (J)": f"{ps.kinetic_energy():.4f}",
    }
