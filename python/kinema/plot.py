"""Plotting helpers (matplotlib, imported only when a function is called).

- :func:`stability_regions`: where ``|R(z)| ≤ 1`` in the complex ``z = hλ`` plane;
- :func:`work_precision`: error against cost from :func:`kinema.ode.work_precision`;
- :func:`scene`: the current state of a :class:`kinema.Scene` in 3D;
- :func:`render`: run a scene and write it as a GIF or MP4.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from kinema import ode

__all__ = ["render", "scene", "stability_regions", "work_precision"]


def stability_regions(
    methods: Sequence[str] = (
        "explicit_euler",
        "heun",
        "rk4",
        "implicit_euler",
        "trapezoidal",
        "bdf2",
    ),
    extent: float = 4.0,
    resolution: int = 301,
    ax: Any = None,
) -> Any:
    """Draw the boundary ``|R(z)| = 1`` of each method over ``[-extent, extent]²`` (stable
    side shaded for explicit methods); returns the matplotlib Axes."""
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(6, 6))
    x = np.linspace(-extent, extent, resolution)
    zr, zi = np.meshgrid(x, x)
    z = zr + 1j * zi
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for k, method in enumerate(methods):
        r = np.abs(ode.stability_function(method, z))
        color = colors[k % len(colors)]
        ax.contour(zr, zi, r, levels=[1.0], colors=[color], linewidths=1.5)
        ax.plot([], [], color=color, label=method)
    ax.axhline(0, color="0.6", lw=0.5)
    ax.axvline(0, color="0.6", lw=0.5)
    ax.set_xlabel("Re(hλ)")
    ax.set_ylabel("Im(hλ)")
    ax.set_title("stability boundaries |R(hλ)| = 1")
    ax.set_aspect("equal")
    ax.legend(fontsize=8, loc="upper left")
    return ax


def work_precision(rows: Sequence[ode.WorkPrecisionRow], cost: str = "nfev", ax: Any = None) -> Any:
    """Log-log error against cost (``"nfev"`` or ``"seconds"``) per method; returns the Axes."""
    import matplotlib.pyplot as plt

    if cost not in ("nfev", "seconds"):
        raise ValueError(f"cost: expected 'nfev' or 'seconds', got {cost!r}")
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 5))
    for method in dict.fromkeys(r.method for r in rows):
        sel = [r for r in rows if r.method == method]
        ax.loglog(
            [getattr(r, cost) for r in sel],
            [max(r.error, 1e-17) for r in sel],
            marker="o",
            label=method,
        )
    ax.set_xlabel("f evaluations" if cost == "nfev" else "wall time (s)")
    ax.set_ylabel("error at the final time")
    if rows:
        ax.set_title(f"work-precision: {rows[0].problem}")
    ax.legend(fontsize=8)
    return ax


def _bounds(frames: Sequence[Any]) -> tuple[np.ndarray, np.ndarray]:
    pts = [np.zeros((1, 3))]
    for g in frames:
        pts += [v for v, _ in g.meshes.values()] + list(g.points.values())
        pts += [s.reshape(-1, 3) for s in g.segments.values()]
    allp = np.vstack([p for p in pts if len(p)])
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    pad = 0.05 * float((hi - lo).max() or 1.0)
    return lo - pad, hi + pad


def _draw(ax: Any, g: Any, lo: np.ndarray, hi: np.ndarray, title: str) -> None:
    """Draw one frame's geometry with +Y up (matplotlib's z axis is the scene's y)."""
    ax.clear()
    for name, (v, t) in g.meshes.items():
        color = "tab:red" if name.startswith("cloth") else "0.65"
        ax.plot_trisurf(
            v[:, 0],
            v[:, 2],
            v[:, 1],
            triangles=t,
            color=color,
            alpha=0.85,
            linewidth=0.05,
            edgecolor="0.3",
        )
    for p in g.points.values():
        ax.scatter(p[:, 0], p[:, 2], p[:, 1], s=2, color="tab:blue", depthshade=False)
    for segs in g.segments.values():
        for a, b in segs:
            ax.plot([a[0], b[0]], [a[2], b[2]], [a[1], b[1]], color="k", lw=1.5)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[2], hi[2])
    ax.set_zlim(lo[1], hi[1])
    ax.set_box_aspect(tuple(np.maximum(hi - lo, 1e-3)[[0, 2, 1]]))
    ax.set_title(title, fontsize=9)
    ax.set_axis_off()


def scene(scene: Any, ax: Any = None) -> Any:
    """Draw the current state of a :class:`kinema.Scene` in 3D (cloth meshes, rigid bodies,
    particles, animated spheres, characters' bones; +Y up); returns the matplotlib Axes.
    Save a PNG with ``ax.figure.savefig(path)``."""
    import matplotlib.pyplot as plt

    from kinema import _geometry

    if ax is None:
        ax = plt.figure(figsize=(6, 5)).add_subplot(projection="3d")
    g = _geometry.of_scene(scene)
    _draw(ax, g, *_bounds([g]), f"t = {scene.time:.3f} s")
    return ax


def render(
    scene: Any,
    path: Any,
    frames: int,
    *,
    fps: float | None = None,
    every: int = 1,
    progress: bool = False,
    on_frame: Any = None,
) -> int:
    """Run ``scene`` for ``frames`` frames and write every ``every``-th frame (and the first) as
    an animation: ``.gif`` (Pillow) or ``.mp4`` (needs ffmpeg on the PATH). ``fps`` defaults to
    the scene's frame rate divided by ``every``; ``on_frame`` is passed on to
    :meth:`kinema.Scene.run`. Returns the frames written."""
    import matplotlib.pyplot as plt
    from matplotlib.animation import FFMpegWriter, FuncAnimation, PillowWriter

    from kinema import _geometry

    suffix = str(path).rsplit(".", 1)[-1].lower()
    if suffix not in ("gif", "mp4"):
        raise ValueError(f"path: expected a .gif or .mp4 file, got {path!r}")
    if suffix == "mp4" and not FFMpegWriter.isAvailable():
        raise RuntimeError("path: writing .mp4 needs ffmpeg on the PATH; write a .gif instead")
    if int(every) < 1:
        raise ValueError(f"every: must be >= 1, got {every}")
    shots = [(_geometry.of_scene(scene), scene.time)]

    def capture(s: Any) -> None:
        if on_frame is not None:
            on_frame(s)
        if s.frame % every == 0:
            shots.append((_geometry.of_scene(s), s.time))

    scene.run(frames=frames, progress=progress, on_frame=capture)
    lo, hi = _bounds([g for g, _ in shots])
    fig = plt.figure(figsize=(6, 5))
    ax = fig.add_subplot(projection="3d")
    rate = max(1, round(fps if fps is not None else 1.0 / (scene.dt * every)))
    writer = PillowWriter(fps=rate) if suffix == "gif" else FFMpegWriter(fps=rate)
    anim = FuncAnimation(
        fig, lambda k: _draw(ax, shots[k][0], lo, hi, f"t = {shots[k][1]:.2f} s"), frames=len(shots)
    )
    anim.save(str(path), writer=writer)
    plt.close(fig)
    return len(shots)
