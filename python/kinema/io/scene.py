"""A scene's recorded animation written as glTF or USD (:meth:`kinema.Scene.export`).

``scene.record("animation")`` makes the scene keep, after every frame, its time and the state
of every system it holds. What has a fixed size goes in the record ``"animation"`` (one row
per frame, like any other record): every cloth's vertex positions, every rigid body's position
and orientation, every animated sphere's centre, every rod's and hair's vertices, every crowd's
and flock's agents, every biped's, ragdoll's (any articulated body's) and tracker's body
frames (positions and orientations) and the frames of a ragdoll's colliders, every
motion-captured character's joints. What
changes size is kept beside it, one entry per frame: the live particles of a particle or
constrained system, a fluid's particles and its surface mesh (``Fluid.surface_mesh()`` at its
default resolution, computed every frame while recording).

``scene.export(path)`` writes them in metres and seconds (see :mod:`kinema.io.gltf` and
:mod:`kinema.io.usd`): a cloth as a deforming mesh; a rigid body (its shape's mesh, as
:mod:`kinema.plot` draws it), an animated sphere, each link of a biped (its box,
:meth:`kinema.character.Biped.link_boxes`), each body of an articulated body or a tracker
(its capsule, :meth:`kinema.character.ArticulatedBody.capsules`) and each of an articulated
body's colliders (:func:`kinema._geometry.shape_mesh`; a plane as a square of 10 m) as rigid
tracks; rods and hair as
polylines; a character's bones as line segments; crowds (on the ground, ``(x, 0, z)``) and
flocks (2-D ones at ``z = 0``) as points; particles and fluids as points
and a fluid's surface as a mesh, all of whose sizes change from frame to frame.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from kinema.io._tracks import FrameMeshes, MeshSequence, RigidTrack

__all__ = ["SceneTracks", "export_scene", "frame_state", "scene_tracks"]

RECORD = "animation"
"""The name of the scene record that :func:`export_scene` reads."""

SceneTracks = tuple[list[RigidTrack], list[MeshSequence], list[FrameMeshes]]
"""What a scene recorded: rigid tracks, sequences of a fixed size, sequences that change size."""


def _width(s: Any) -> int | None:
    """The size of system ``s``'s state in a record row, or None if it changes size (kept
    beside the record) or is not exported."""
    from kinema import character, cloth, crowd, flock, rigid, rods
    from kinema.scene import AnimatedSphere, Character

    if isinstance(s, (cloth.Cloth, rods.Rod, rods.Hair)):
        return int(np.asarray(s.positions).size)
    if isinstance(s, rigid.World):
        return 7 * len(s.positions)
    if isinstance(s, AnimatedSphere):
        return 3
    if isinstance(s, (crowd.Crowd, flock.Flock)):
        return 3 * len(s.positions)
    if isinstance(s, character.Biped):
        return 7 * len(s.names)
    if isinstance(s, (character.ArticulatedBody, character.Tracker)):
        return 7 * (len(s.names) + len(_colliders(s)))
    if isinstance(s, Character):
        return 3 * len(s.joints(0.0))
    return None


def _colliders(s: Any) -> list[Any]:
    """The colliders of an articulated body (:meth:`kinema.character.ArticulatedBody.colliders`;
    a tracker has none)."""
    from kinema import character

    return s.colliders() if isinstance(s, character.ArticulatedBody) else []


def _lifted(s: Any) -> np.ndarray:
    """A crowd's or flock's agents in 3-D (m): a crowd's ``(x, z)`` at ``y = 0``, a 2-D flock's
    ``(x, y)`` at ``z = 0``."""
    from kinema import crowd

    p = np.asarray(s.positions, dtype=np.float64)
    out = np.zeros((len(p), 3))
    if isinstance(s, crowd.Crowd):
        out[:, [0, 2]] = p
    else:
        out[:, : p.shape[1]] = p
    return out


def _row_part(scene: Any, s: Any) -> np.ndarray:
    """System ``s``'s part of a record row (see :func:`_width`)."""
    from kinema import _geometry, character, crowd, flock, rigid
    from kinema.scene import AnimatedSphere, Character

    if isinstance(s, rigid.World):
        return np.c_[s.positions, s.orientations].ravel()
    if isinstance(s, AnimatedSphere):
        return np.asarray(s.position(scene.time), dtype=np.float64)
    if isinstance(s, (crowd.Crowd, flock.Flock)):
        return _lifted(s).ravel()
    if isinstance(s, character.Biped):
        return np.c_[s.positions(), s.orientations()].ravel()
    if isinstance(s, (character.ArticulatedBody, character.Tracker)):
        frames = [np.concatenate(_geometry.shape_frame(c)) for c in _colliders(s)]
        return np.concatenate([np.c_[s.positions(), s.orientations()].ravel(), *frames])
    if isinstance(s, Character):
        return np.asarray(s.joints(scene.time)).ravel()
    return np.asarray(s.positions).ravel()


def _particles_of(s: Any) -> Any:
    """The particle system of ``s`` (itself, or a constrained system's), else None."""
    from kinema import particles

    p = getattr(s, "_particles", s)
    return p if isinstance(p, particles.ParticleSystem) else None


def _varying_part(s: Any) -> list[np.ndarray] | None:
    """The state of ``s`` whose size changes: the live particles of a particle or constrained
    system; a fluid's particles, surface vertices and surface triangles. None for others."""
    from kinema import fluid

    if isinstance(s, fluid.Fluid):
        v, t = s.surface_mesh()
        return [np.array(s.positions, dtype=np.float64), v, np.asarray(t, dtype=np.int64)]
    p = _particles_of(s)
    return None if p is None else [np.array(p.positions[p.alive], dtype=np.float64)]


def frame_state(scene: Any) -> np.ndarray:
    """One row of the animation record: the scene's time, then each fixed-size system's state;
    the state that changes size is appended to the scene's list beside the record."""
    row = [np.array([scene.time])]
    varying = []
    for s in scene.systems:
        if _width(s) is not None:
            row.append(_row_part(scene, s))
        elif (part := _varying_part(s)) is not None:
            varying.append(part)
    vars(scene).setdefault("_animation_varying", []).append(varying)
    return np.concatenate(row)


def _fixed_tracks(scene: Any, rows: np.ndarray, out: SceneTracks) -> None:
    """The rigid tracks and fixed-size sequences of the record ``rows`` into ``out``."""
    from kinema import _geometry, character, cloth, rigid, rods
    from kinema.scene import AnimatedSphere, Character

    rigid_tracks, sequences, _ = out
    times, offset, f = rows[:, 0], 1, len(rows)
    for i, s in enumerate(scene.systems):
        n = _width(s)
        if n is None:
            continue
        block = rows[:, offset : offset + n]
        offset += n
        if isinstance(s, cloth.Cloth):
            sequences.append(MeshSequence(s.triangles, times, block.reshape(f, -1, 3), f"cloth{i}"))
        elif isinstance(s, rigid.World):
            states = block.reshape(f, -1, 7)
            for b, shape in enumerate(s.shapes):
                v, t = _geometry.body_mesh(shape)
                x, q = states[:, b, :3], states[:, b, 3:]
                rigid_tracks.append(RigidTrack(v, t, times, x, q, f"body{i}_{b}"))
        elif isinstance(s, character.Biped):
            states = block.reshape(f, -1, 7)
            for b, (name, (centre, half)) in enumerate(zip(s.names, s.link_boxes(), strict=True)):
                v, t = _geometry.box(half)
                x, q = states[:, b, :3], states[:, b, 3:]
                rigid_tracks.append(RigidTrack(v + centre, t, times, x, q, f"biped{i}_{name}"))
        elif isinstance(s, (character.ArticulatedBody, character.Tracker)):
            states = block.reshape(f, -1, 7)
            for b, (name, c) in enumerate(zip(s.names, s.capsules(), strict=True)):
                if c is not None:
                    v, t = _geometry.capsule(*c)
                    x, q = states[:, b, :3], states[:, b, 3:]
                    rigid_tracks.append(RigidTrack(v, t, times, x, q, f"ragdoll{i}_{b}_{name}"))
            for k, c in enumerate(_colliders(s)):
                v, t = _geometry.shape_mesh(c)
                x, q = states[:, len(s.names) + k, :3], states[:, len(s.names) + k, 3:]
                rigid_tracks.append(RigidTrack(v, t, times, x, q, f"ragdoll{i}_collider{k}"))
        elif isinstance(s, AnimatedSphere):
            v, t = _geometry.uv_sphere(float(s.radius))
            q = np.tile([1.0, 0.0, 0.0, 0.0], (f, 1))
            rigid_tracks.append(RigidTrack(v, t, times, block, q, f"sphere{i}"))
        elif isinstance(s, (rods.Rod, rods.Hair)):
            dims = np.asarray(s.positions).shape  # (N, 3) for a rod, (S, N, 3) for hair
            strands = np.full(int(np.prod(dims[:-2])), dims[-2])
            frames = block.reshape(f, -1, 3)
            sequences.append(MeshSequence(None, times, frames, f"rods{i}", strands))
        elif isinstance(s, Character):
            bones = s._bones.reshape(-1)
            frames = block.reshape(f, -1, 3)[:, bones]
            strands = np.full(len(s._bones), 2)
            sequences.append(MeshSequence(None, times, frames, f"character{i}", strands))
        else:
            sequences.append(MeshSequence(None, times, block.reshape(f, -1, 3), f"agents{i}"))


def _varying_tracks(scene: Any, times: np.ndarray, out: SceneTracks) -> None:
    """The sequences that change size, kept beside the record, into ``out``."""
    from kinema import fluid

    kept = vars(scene).get("_animation_varying", [])
    if len(kept) != len(times):
        raise ValueError("scene: its record of particles and fluids does not match its frames")
    j = 0
    for i, s in enumerate(scene.systems):
        is_fluid = isinstance(s, fluid.Fluid)
        if _width(s) is not None or not (is_fluid or _particles_of(s) is not None):
            continue
        name = f"{'fluid' if is_fluid else 'particles'}{i}"
        parts = [frame[j] for frame in kept]
        j += 1
        out[2].append(FrameMeshes(times, [p[0] for p in parts], None, name))
        if is_fluid:
            surface = [p[1] for p in parts], [p[2] for p in parts]
            out[2].append(FrameMeshes(times, *surface, f"{name}_surface"))


def scene_tracks(scene: Any) -> SceneTracks:
    """The animation ``scene`` recorded, as rigid tracks, fixed-size sequences and sequences
    that change size."""
    rows = scene.records.get(RECORD)
    if rows is None or len(rows) == 0:
        raise ValueError('scene: recorded no animation: call scene.record("animation") first')
    width = 1 + sum(_width(s) or 0 for s in scene.systems)
    if rows.ndim != 2 or rows.shape[1] != width:
        raise ValueError("scene: its systems changed since the animation was recorded")
    out: SceneTracks = ([], [], [])
    _fixed_tracks(scene, rows, out)
    _varying_tracks(scene, rows[:, 0], out)
    return out


def export_scene(scene: Any, path: str | os.PathLike[str]) -> None:
    """Write the animation ``scene`` recorded to ``path`` (``.glb``, or ``.usd``/``.usdc``/
    ``.usda``)."""
    from kinema import io

    suffix = Path(path).suffix.lower()
    if suffix not in (".glb", ".usd", ".usdc", ".usda"):
        raise ValueError("path: expected a .glb, .usd, .usdc or .usda file name")
    rigid_tracks, sequences, frames = scene_tracks(scene)
    if suffix == ".glb":
        io.write_glb(path, rigid=rigid_tracks, sequences=sequences, frames=frames)
    else:
        io.write_usd(
            path, rigid=rigid_tracks, sequences=sequences, frames=frames, frame_rate=1.0 / scene.dt
        )
