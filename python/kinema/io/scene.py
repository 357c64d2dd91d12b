"""A scene's recorded animation written as glTF or USD (:meth:`kinema.Scene.export`).

``scene.record("animation")`` makes the scene keep, after every frame, its time and the state
of the systems it knows: every cloth's vertex positions, every rigid body's position and
orientation, every animated sphere's centre (a record of one row per frame, like any other
record). ``scene.export(path)`` writes them: a cloth as a deforming mesh, a rigid body (its
shape's mesh, as :mod:`kinema.plot` draws it) and an animated sphere as rigid tracks, in metres
and seconds. Particles, fluids, constrained systems and motion-captured characters are not
exported yet.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from kinema.io._tracks import MeshSequence, RigidTrack

__all__ = ["export_scene", "frame_state", "scene_tracks"]

RECORD = "animation"
"""The name of the scene record that :func:`export_scene` reads."""


def _parts(scene: Any) -> list[tuple[Any, int]]:
    """The exported systems of ``scene`` and the size of each one's state in a record row."""
    from kinema import cloth, rigid
    from kinema.scene import AnimatedSphere

    out: list[tuple[Any, int]] = []
    for s in scene.systems:
        if isinstance(s, cloth.Cloth):
            out.append((s, 3 * len(s.positions)))
        elif isinstance(s, rigid.World):
            out.append((s, 7 * len(s.positions)))
        elif isinstance(s, AnimatedSphere):
            out.append((s, 3))
    return out


def frame_state(scene: Any) -> np.ndarray:
    """One row of the animation record: the scene's time, then each exported system's state."""
    from kinema import cloth, rigid

    row = [np.array([scene.time])]
    for s, _ in _parts(scene):
        if isinstance(s, cloth.Cloth):
            row.append(np.asarray(s.positions).ravel())
        elif isinstance(s, rigid.World):
            row.append(np.c_[s.positions, s.orientations].ravel())
        else:
            row.append(s.position(scene.time))
    return np.concatenate(row)


def scene_tracks(scene: Any) -> tuple[list[RigidTrack], list[MeshSequence]]:
    """The animation ``scene`` recorded, as rigid tracks and mesh sequences."""
    from kinema import _geometry, cloth, rigid

    rows = scene.records.get(RECORD)
    if rows is None or len(rows) == 0:
        raise ValueError('scene: recorded no animation: call scene.record("animation") first')
    parts = _parts(scene)
    if rows.ndim != 2 or rows.shape[1] != 1 + sum(n for _, n in parts):
        raise ValueError("scene: its systems changed since the animation was recorded")
    times = rows[:, 0]
    rigid_tracks, sequences = [], []
    offset = 1
    for i, (s, n) in enumerate(parts):
        block = rows[:, offset : offset + n]
        offset += n
        if isinstance(s, cloth.Cloth):
            frames = block.reshape(len(rows), -1, 3)
            sequences.append(MeshSequence(s.triangles, times, frames, f"cloth{i}"))
        elif isinstance(s, rigid.World):
            states = block.reshape(len(rows), -1, 7)
            for b, shape in enumerate(s.shapes):
                v, t = _geometry.body_mesh(shape)
                x, q = states[:, b, :3], states[:, b, 3:]
                rigid_tracks.append(RigidTrack(v, t, times, x, q, f"body{i}_{b}"))
        else:
            v, t = _geometry.uv_sphere(float(s.radius))
            q = np.tile([1.0, 0.0, 0.0, 0.0], (len(rows), 1))
            rigid_tracks.append(RigidTrack(v, t, times, block, q, f"sphere{i}"))
    return rigid_tracks, sequences


def export_scene(scene: Any, path: str | os.PathLike[str]) -> None:
    """Write the animation ``scene`` recorded to ``path`` (``.glb``, or ``.usd``/``.usdc``/
    ``.usda``)."""
    from kinema import io

    suffix = Path(path).suffix.lower()
    if suffix not in (".glb", ".usd", ".usdc", ".usda"):
        raise ValueError("path: expected a .glb, .usd, .usdc or .usda file name")
    rigid_tracks, sequences = scene_tracks(scene)
    if suffix == ".glb":
        io.write_glb(path, rigid=rigid_tracks, sequences=sequences)
    else:
        io.write_usd(path, rigid=rigid_tracks, sequences=sequences, frame_rate=1.0 / scene.dt)
