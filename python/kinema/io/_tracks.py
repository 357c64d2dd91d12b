"""What the exporters write, independent of the file format: rigid tracks, mesh sequences,
and a skeleton's joint frames (bind pose and animation) in metres and seconds."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "FrameMeshes",
    "MeshSequence",
    "RigidTrack",
    "SkeletonFrames",
    "frame_meshes_of",
    "frames_of",
    "skeleton_frames",
    "strand_segments",
    "times_of",
]


@dataclass
class RigidTrack:
    """A rigid mesh (``vertices (V, 3)`` m in its body frame, ``triangles (T, 3)``) placed at
    ``positions (F, 3)`` m and ``orientations (F, 4)`` ``(w, x, y, z)`` at ``times (F,)`` s."""

    vertices: Any
    triangles: Any
    times: Any
    positions: Any
    orientations: Any
    name: str = "body"


@dataclass
class MeshSequence:
    """Vertices of a fixed number moving: ``frames (F, V, 3)`` m at ``times (F,)`` s, joined by
    ``triangles (T, 3)`` (a deforming mesh: cloth), or with ``triangles=None`` by ``strands``,
    the vertex counts ``(S,)`` of polylines laid end to end (rods, hair), or by nothing (points:
    crowds, flocks). Written as morph targets in glTF, time-sampled points in USD."""

    triangles: Any
    times: Any
    frames: Any
    name: str = "mesh"
    strands: Any = None


@dataclass
class FrameMeshes:
    """A mesh or point cloud whose size changes from frame to frame (particles born and dying,
    a fluid and its surface): ``vertices[k] (V_k, 3)`` m at ``times[k]`` s, joined by
    ``triangles[k] (T_k, 3)``, or points with ``triangles=None``. Written as one node per frame
    shown only at its time in glTF, time-sampled points and topology in USD."""

    times: Any
    vertices: list[Any]
    triangles: list[Any] | None = None
    name: str = "frames"


def frames_of(seq: MeshSequence) -> np.ndarray:
    """``seq.frames`` as ``(F, V, 3)`` float64, checked (with its elements) against ``V``."""
    frames = np.asarray(seq.frames, dtype=np.float64)
    if frames.ndim != 3 or frames.shape[2] != 3 or len(frames) == 0:
        raise ValueError("frames: expected an (F, V, 3) array of F >= 1 frames")
    if seq.triangles is None and seq.strands is not None:
        counts = np.asarray(seq.strands, dtype=np.int64).reshape(-1)
        if np.any(counts < 2) or counts.sum() != frames.shape[1]:
            raise ValueError("strands: expected vertex counts >= 2 that sum to the vertices")
    return frames


def strand_segments(strands: Any) -> np.ndarray:
    """The segments ``(L, 2)`` (vertex index pairs) of polylines of ``strands`` vertices each,
    laid end to end."""
    counts = np.asarray(strands, dtype=np.int64).reshape(-1)
    starts = np.cumsum(counts) - counts
    return np.concatenate(
        [
            np.c_[s + np.arange(n - 1), s + np.arange(1, n)]
            for s, n in zip(starts, counts, strict=True)
        ]
    )


def frame_meshes_of(seq: FrameMeshes) -> tuple[np.ndarray, list[np.ndarray], list[Any]]:
    """``seq``'s times, vertices ``(V_k, 3)`` and triangles (``None`` for points), checked."""
    vertices = [np.asarray(v, dtype=np.float64).reshape(-1, 3) for v in seq.vertices]
    t = times_of(seq.times, len(vertices))
    if seq.triangles is None:
        return t, vertices, [None] * len(vertices)
    if len(seq.triangles) != len(vertices):
        raise ValueError("triangles: expected one array per frame")
    triangles = [np.asarray(x, dtype=np.int64).reshape(-1, 3) for x in seq.triangles]
    for v, x in zip(vertices, triangles, strict=True):
        if len(x) and (x.min() < 0 or x.max() >= len(v)):
            raise ValueError("triangles: names a vertex beyond its frame's vertices")
    return t, vertices, triangles


def times_of(times: Any, frames: int) -> np.ndarray:
    """``times`` as ``frames`` increasing finite seconds."""
    t = np.asarray(times, dtype=np.float64).reshape(-1)
    if len(t) != frames or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise ValueError(f"times: expected {frames} increasing finite times (s)")
    return t


def _local(
    parents: list[int], rotation: np.ndarray, translation: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Joint frames relative to their parents' (``(..., J, 4)`` ``(w, x, y, z)`` and
    ``(..., J, 3)``): ``R_p⁻¹ R_j`` and ``R_p⁻¹ (t_j - t_p)``; roots keep theirs."""
    from kinema.rotation import Rotation

    r = Rotation.from_quat(rotation.reshape(-1, 4))
    shape = rotation.shape[:-1]
    p = np.array([max(x, 0) for x in parents])
    rp = Rotation.from_quat(rotation[..., p, :].reshape(-1, 4)).inv()
    dt = (translation - translation[..., p, :]).reshape(-1, 3)
    q = (rp * r).as_quat().reshape(*shape, 4)
    t = rp.apply(dt).reshape(*shape, 3)
    roots = np.array(parents) < 0
    q[..., roots, :] = rotation[..., roots, :]
    t[..., roots, :] = translation[..., roots, :]
    return q, t


@dataclass
class SkeletonFrames:
    """The bones of a skin as a joint hierarchy: bone ``j``'s frame is joint ``j``'s orientation
    at the position of its origin joint (``kinema.skin``), times ``scale`` (file units to m).
    Rotations ``(w, x, y, z)``; world frames at the bind pose, frames relative to the parent
    joint's at the bind pose (``rest_*``) and at every frame of the motion (``(F, J, ·)``)."""

    names: list[str]
    parents: list[int]
    scale: float
    triangles: np.ndarray
    bind_rotation: np.ndarray
    bind_translation: np.ndarray
    rest_rotation: np.ndarray
    rest_translation: np.ndarray
    rotation: np.ndarray
    translation: np.ndarray
    times: np.ndarray


def skeleton_frames(skin: Any, motion: Any, scale: float | None) -> SkeletonFrames:
    """The joint frames of ``skin``'s skeleton at its bind pose and over ``motion`` (keyed at
    ``frame / frame_rate`` s), lengths times ``scale`` (default the skeleton's
    ``metres_per_unit``, 1 for BVH)."""
    from kinema.skin import Skin, _origins

    if not isinstance(skin, Skin):
        raise TypeError(f"skins: expected (Skin, motion) pairs, got {type(skin).__name__}")
    skeleton = skin.skeleton
    if scale is None:
        scale = float(getattr(skeleton, "metres_per_unit", 1.0))
    if not (np.isfinite(scale) and scale > 0):
        raise ValueError("scale: must be positive and finite")
    origins = _origins(skeleton)
    parents = list(skeleton.parents)
    bind_p, bind_q = skeleton.forward_kinematics(skin.bind_pose)
    bind_t = scale * np.asarray(bind_p)[origins]
    rest_q, rest_t = _local(parents, np.asarray(bind_q), bind_t)
    positions, orientations = skeleton.forward_kinematics(motion)
    if np.ndim(positions) != 3:
        raise ValueError("skins: expected a motion of several frames, not one pose")
    q, t = _local(parents, np.asarray(orientations), scale * np.asarray(positions)[:, origins])
    triangles = skin.triangles if skin.triangles is not None else np.zeros((0, 3), np.int64)
    return SkeletonFrames(
        names=list(skeleton.joint_names),
        parents=parents,
        scale=scale,
        triangles=triangles,
        bind_rotation=np.asarray(bind_q),
        bind_translation=bind_t,
        rest_rotation=rest_q,
        rest_translation=rest_t,
        rotation=q,
        translation=t,
        times=np.arange(len(q)) / float(motion.frame_rate),
    )
