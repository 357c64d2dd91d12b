"""Saving a demo's animation: the GIF of every frame, then its last frame as a PNG."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any


def save_gif_and_last_frame(
    fig: Any, draw: Callable[[int], None], frames: Sequence[int], stem: Path, fps: int
) -> tuple[Path, Path]:
    """Write ``stem.gif`` (``draw(k)`` for every ``k`` of ``frames`` at ``fps``) and
    ``stem.png`` (the last of ``frames``, at 100 dpi), close ``fig`` and return both paths."""
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation, PillowWriter

    gif, png = stem.with_suffix(".gif"), stem.with_suffix(".png")
    FuncAnimation(fig, draw, frames=frames).save(gif, writer=PillowWriter(fps=fps))
    draw(frames[-1])
    fig.savefig(png, dpi=100)
    plt.close(fig)
    return gif, png
