"""Hair demo: a sphere head (10 cm radius) with groomed, slightly curly strands, turned and
nodded by a keyframed rotation; the strands are discrete elastic rods stepped together at
dt = 1/60 s with the rod–rod repulsion, the head a moving collider. Drawn from the front and
the side into ``hair.gif`` and ``hair.png``, with numbers: time per step, the largest stretch,
and the penetrations (vertices inside the head; vertex pairs of different strands closer than
the thickness)."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from kinema import Rotation
from kinema.demos._gif import save_gif_and_last_frame
from kinema.geometry import Sphere
from kinema.rods import groom, sphere_cap

HEAD = 0.1  # head radius (m)


def pose(t: float) -> Rotation:
    """The head's keyframed rotation at ``t`` (s): a turn (yaw, about y) and a nod (pitch,
    about x)."""
    yaw = 0.7 * np.sin(2 * np.pi * t / 2.0)
    pitch = 0.3 * np.sin(2 * np.pi * t / 1.3)
    return Rotation.from_rotvec([0.0, yaw, 0.0]) * Rotation.from_rotvec([pitch, 0.0, 0.0])


def penetrations(x: np.ndarray, thickness: float) -> tuple[int, int]:
    """Vertices inside the head, and vertex pairs of different strands closer than
    ``thickness`` (m)."""
    from scipy.spatial import cKDTree

    inside = int(np.sum(np.linalg.norm(x[:, 1:], axis=2) < HEAD - 1e-9))
    flat = x.reshape(-1, 3)
    strand = np.repeat(np.arange(x.shape[0]), x.shape[1])
    pairs = cKDTree(flat).query_pairs(thickness, output_type="ndarray")
    return inside, int(np.sum(strand[pairs[:, 0]] != strand[pairs[:, 1]]))


def run(out_dir: Path, quick: bool) -> dict[str, object]:
    """Simulate the hair, write the GIF and a still, and return the numbers."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection

    count, fps, seconds, substeps = (200, 30, 0.5, 2) if quick else (600, 30, 2.0, 2)
    radius, segments, length = 1e-4, 16, 0.12
    thickness = 2 * radius
    points, normals = sphere_cap(count, radius=HEAD, angle=1.4)
    hair = groom(
        points, normals, length=length, segments=segments, curl=0.01, radius=radius,
        youngs_modulus=1e9, density=1300.0, tolerance=1e-8, repulsion_stiffness=10.0,
        thickness=thickness,
    )  # fmt: skip
    hair.set_head_collider(Sphere((0.0, 0.0, 0.0), HEAD))
    rest = np.linalg.norm(np.diff(hair.positions[0], axis=0), axis=1)
    frames, stretch, elapsed, steps = [], 0.0, 0.0, 0
    for k in range(int(fps * seconds)):
        hair.set_head(pose((k + 1) / fps))
        start = time.perf_counter()
        hair.step(1 / (fps * substeps), substeps)
        elapsed += time.perf_counter() - start
        steps += substeps
        x = hair.positions
        edges = np.linalg.norm(np.diff(x, axis=1), axis=2)
        stretch = max(stretch, float(np.max(np.abs(edges / rest - 1.0))))
        frames.append(x)
    inside, close = penetrations(frames[-1], thickness)

    fig, axes = plt.subplots(1, 2, figsize=(8.0, 4.2))

    def draw(k: int) -> None:
        for ax, (a, b), name in zip(axes, ((0, 1), (2, 1)), ("front", "side"), strict=True):
            ax.cla()
            ax.add_patch(plt.Circle((0, 0), HEAD, color="0.85"))
            lines = LineCollection(
                list(frames[k][:, :, [a, b]]), linewidths=0.3, colors="saddlebrown"
            )
            ax.add_collection(lines)
            ax.set_xlim(-0.25, 0.25)
            ax.set_ylim(-0.25, 0.25)
            ax.set_aspect("equal")
            ax.set_title(f"{name}, t = {(k + 1) / fps:.2f} s")
        fig.suptitle(f"{count} strands × {segments} segments, implicit DER at dt = 1/60 s")

    gif, png = save_gif_and_last_frame(fig, draw, range(len(frames)), out_dir / "hair", fps)
    return {
        "strands": count,
        "segments": segments,
        "steps": steps,
        "time per step (ms)": round(1e3 * elapsed / steps, 2),
        "largest stretch (%)": round(100 * stretch, 4),
        "vertices inside the head": inside,
        "vertex pairs of different strands closer than the thickness": close,
        "animation": str(gif),
        "picture": str(png),
    }
