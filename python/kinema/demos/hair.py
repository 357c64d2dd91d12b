"""Hair demo: a sphere head (10 cm radius) with groomed, slightly curly strands, turned, nodded
and carried by the head joint of a CMU motion capture (subject 07, clip 05, a slow walk,
shipped in ``kinema/data``); the strands are discrete elastic rods stepped together at
dt = 1/60 s with the rod–rod repulsion, the head a moving collider. Drawn from the front and
the side (in the head's frame of translation) into ``hair.gif`` and ``hair.png``, with
numbers: time per step, the largest stretch, the head's turn and nod, and the penetrations
(vertices inside the head; vertex pairs of different strands closer than the thickness)."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from kinema import Rotation, mocap
from kinema.demos._gif import save_gif_and_last_frame
from kinema.geometry import Sphere
from kinema.rods import groom, sphere_cap

HEAD = 0.1  # head radius (m)


def head_motion(times: np.ndarray) -> tuple[Rotation, np.ndarray]:
    """The head's poses at ``times`` (s) from the CMU walk's ``head`` joint (forward
    kinematics, at the capture frame nearest each time, 120 Hz): its rotation since the first
    frame (world axes, +y up) and its translation since the first frame (m) less the walk's
    mean horizontal velocity — the head seen from an inertial frame moving with the walker
    (the same dynamics: a constant velocity adds no force), so the walk's bob, sway and
    surges remain."""
    skeleton = mocap.read_asf(mocap.SAMPLE_DIR / "07-walk.asf")
    motion = mocap.read_amc(mocap.SAMPLE_DIR / "07_05-walk.amc", skeleton)
    positions, orientations = skeleton.forward_kinematics(motion)
    joint = skeleton.joint_names.index("head")
    p = positions[:, joint] * skeleton.metres_per_unit
    velocity = (p[-1] - p[0]) / ((motion.frames - 1) / motion.frame_rate)
    velocity[1] = 0.0
    frames = np.minimum(np.rint(times * motion.frame_rate).astype(int), motion.frames - 1)
    start = Rotation.from_quat(orientations[0, joint])
    rotations = Rotation.from_quat(orientations[frames, joint]) * start.inv()
    translations = p[frames] - p[0] - np.outer(frames / motion.frame_rate, velocity)
    return rotations, translations


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
    count_frames = int(fps * seconds)
    rotations, translations = head_motion(np.arange(1, count_frames + 1) / fps)
    frames, stretch, elapsed, steps = [], 0.0, 0.0, 0
    for k in range(count_frames):
        hair.set_head(rotations[k], translations[k])
        start = time.perf_counter()
        hair.step(1 / (fps * substeps), substeps)
        elapsed += time.perf_counter() - start
        steps += substeps
        x = hair.positions
        edges = np.linalg.norm(np.diff(x, axis=1), axis=2)
        stretch = max(stretch, float(np.max(np.abs(edges / rest - 1.0))))
        frames.append(x - translations[k])
    inside, close = penetrations(frames[-1], thickness)
    roots = rotations[-1].apply(points) + translations[-1]
    root_error = float(np.max(np.linalg.norm(hair.positions[:, 0] - roots, axis=1)))
    euler = rotations.as_euler("YXZ", degrees=True)  # turn about y, then nod about x

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
        fig.suptitle(
            f"{count} strands × {segments} segments, implicit DER at dt = 1/60 s, "
            "head moved by CMU 07_05"
        )

    gif, png = save_gif_and_last_frame(fig, draw, range(len(frames)), out_dir / "hair", fps)
    return {
        "strands": count,
        "segments": segments,
        "steps": steps,
        "time per step (ms)": round(1e3 * elapsed / steps, 2),
        "largest stretch (%)": round(100 * stretch, 4),
        "head turn range (deg)": round(float(np.ptp(euler[:, 0])), 2),
        "head nod range (deg)": round(float(np.ptp(euler[:, 1])), 2),
        "roots off the CMU head pose (m)": float(f"{root_error:.1e}"),
        "head travel (cm)": round(100 * float(np.ptp(translations, axis=0).max()), 2),
        "vertices inside the head": inside,
        "vertex pairs of different strands closer than the thickness": close,
        "animation": str(gif),
        "picture": str(png),
    }
