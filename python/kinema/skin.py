"""Skinning: a surface bound to a skeleton, deformed by its motion.

``Skin(vertices, skeleton)`` binds a mesh given in the skeleton's bind pose (by default the
pose whose values are all zero: an Acclaim skeleton's rest pose) to the skeleton's bones;
``skin.deform(motion)`` returns the vertices of every frame ``(frames, V, 3)`` (one pose:
``(V, 3)``), in the skeleton's length units like the vertices.

Each vertex follows up to ``influences`` bones with normalised weights: given as
``weights=(bones, weights)`` (two ``(V, k)`` arrays), or computed — ``"heat"``, by heat
diffusion over the surface (Baran & Popović 2007, "bone heat": smooth blends over the
surface, the default when ``triangles`` are given), or ``"proximity"``, by bone proximity
(the ``k`` nearest bones by distance to their segments, weights proportional to
``distance**-falloff``; the default without triangles).
Two blends (``method=``): ``"dqs"``, dual quaternion skinning (Kavan, Collins, Žára &
O'Sullivan 2008), the default, which keeps the volume of twisted joints; ``"lbs"``, linear
blend skinning, which collapses a joint twisted by 180° (the "candy wrapper"). Both are exact
for a vertex that follows one bone. Conventions and sources in docs/skin.md.

``body_mesh(skeleton)`` gives any skeleton a body: capsules around its bones merged into one
closed surface (the smooth union of their signed distances, polygonised in Rust), returned as a
``Skin`` with heat weights.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from kinema import _kinema
from kinema._array import as_batch, real
from kinema.mocap import BvhSkeleton, Skeleton

__all__ = ["Skin", "body_mesh", "bone_segments"]

_METHODS = ("dqs", "lbs")
_WEIGHTS = ("heat", "proximity")


def _check_skeleton(skeleton: Any) -> None:
    if not isinstance(skeleton, (Skeleton, BvhSkeleton)):
        raise TypeError(
            f"skeleton: expected a kinema.mocap Skeleton or BvhSkeleton, "
            f"got {type(skeleton).__name__}"
        )


def _origins(skeleton: Any) -> list[int]:
    """Joint whose position is each bone's origin: an Acclaim bone starts at its parent's tip;
    a BVH joint's frame is at the joint."""
    parents = skeleton.parents
    if isinstance(skeleton, BvhSkeleton):
        return list(range(len(parents)))
    return [max(p, 0) if j > 0 else 0 for j, p in enumerate(parents)]


def bone_segments(
    skeleton: Any, positions: np.ndarray, orientations: np.ndarray
) -> tuple[np.ndarray, list[int]]:
    """The segments ``(S, 2, 3)`` that each bone's surface surrounds at one pose (joint
    ``positions (J, 3)``, ``orientations (J, 4)``) and the bone owning each: an Acclaim bone
    from its parent's tip to its own; a BVH joint from itself to each child and to its End
    Site. Bones with no length own no segment."""
    _check_skeleton(skeleton)
    parents = skeleton.parents
    pos = np.asarray(positions, dtype=np.float64)
    segments: list[tuple[np.ndarray, np.ndarray]] = []
    owners: list[int] = []
    bvh = isinstance(skeleton, BvhSkeleton)
    for j, p in enumerate(parents):
        if p >= 0:
            segments.append((pos[p], pos[j]))
            owners.append(p if bvh else j)
    if bvh:
        from kinema.rotation import Rotation

        for j, end in enumerate(skeleton.end_sites):
            if end is not None:
                tip = pos[j] + Rotation.from_quat(orientations[j]).apply(np.asarray(end))
                segments.append((pos[j], tip))
                owners.append(j)
    keep = [i for i, (a, b) in enumerate(segments) if np.any(a != b)]
    array = np.array([segments[i] for i in keep], dtype=np.float64).reshape(-1, 2, 3)
    return array, [owners[i] for i in keep]


class Skin:
    """``vertices (V, 3)`` in the bind pose of ``skeleton`` (a ``kinema.mocap.Skeleton`` or
    ``BvhSkeleton``), bound to its bones.

    ``weights``: ``"heat"`` (heat diffusion over the surface, Baran & Popović 2007: bone ``i``'s
    weights solve ``−Δwⁱ + H wⁱ = H pⁱ`` with the cotangent Laplacian, ``H_jj = 1/d_j²`` for the
    distance ``d_j`` to the vertex's nearest bone and ``pⁱ_j = 1`` where bone ``i`` is nearest;
    the ``influences`` largest, normalised; needs ``triangles``), ``"proximity"`` (the
    ``influences`` nearest bones, weights ``∝ distance**-falloff``, normalised), ``None`` (heat
    with triangles, proximity without) or ``(bones, weights)``, two ``(V, k)`` arrays (bone =
    joint index; weights non-negative, normalised per vertex here). ``bind_pose``: the
    skeleton's values (``(stride,)``) at which the vertices were modelled; default all zero.
    ``triangles (M, 3)`` are kept for export and drawing. ``method``: ``"dqs"`` or ``"lbs"``.
    """

    def __init__(
        self,
        vertices: Any,
        skeleton: Any,
        weights: str | tuple[Any, Any] | None = None,
        *,
        triangles: Any = None,
        method: str = "dqs",
        influences: int = 4,
        falloff: float = 4.0,
        bind_pose: Any = None,
    ) -> None:
        _check_skeleton(skeleton)
        if method not in _METHODS:
            raise ValueError('method: must be "dqs" or "lbs"')
        rest, _ = as_batch(vertices, "vertices", (3,))
        if triangles is not None:
            tri = np.asarray(triangles)
            if tri.ndim != 2 or tri.shape[1] != 3 or not np.issubdtype(tri.dtype, np.integer):
                raise ValueError("triangles: expected an (M, 3) integer array")
            if tri.size and (tri.min() < 0 or tri.max() >= len(rest)):
                raise ValueError("triangles: index beyond the vertices")
            triangles = np.ascontiguousarray(tri, dtype=np.int64)
        pose = np.zeros(skeleton.stride) if bind_pose is None else bind_pose
        bind_p, bind_q = skeleton.forward_kinematics(pose)
        joints = len(skeleton.parents)
        if weights is None:
            weights = "proximity" if triangles is None else "heat"
        if isinstance(weights, str):
            if weights not in _WEIGHTS:
                raise ValueError('weights: must be "heat", "proximity", None or (bones, weights)')
            if weights == "heat" and triangles is None:
                raise ValueError('weights: "heat" needs the surface\'s triangles')
            segments, owners = bone_segments(skeleton, bind_p, bind_q)
            if weights == "heat":
                bones, w = _kinema.skin_heat_weights(
                    rest, triangles.tolist(), segments, owners, joints, influences
                )
            else:
                bones, w = _kinema.skin_proximity_weights(
                    rest, segments, owners, joints, influences, real(falloff, "falloff")
                )
            k = len(w) // max(len(rest), 1)
        else:
            bones, w, k = _influences(weights, len(rest), joints)
        self._skin = _kinema.Skin(rest, k, bones, w, _origins(skeleton), bind_p, bind_q)
        self.skeleton = skeleton
        self.bind_pose = np.asarray(pose, dtype=np.float64)
        self.method = method
        self.vertices = rest
        self.vertices.flags.writeable = False
        self.triangles = triangles
        self.bones = np.asarray(bones, dtype=np.int64).reshape(len(rest), k)
        self.weights = self._skin.weights.reshape(len(rest), k)

    def deform(self, motion: Any) -> np.ndarray:
        """The skinned vertices of every frame of ``motion`` ``(frames, V, 3)``, or of one pose
        (the skeleton's values, ``(stride,)``) ``(V, 3)``."""
        positions, orientations = self.skeleton.forward_kinematics(motion)
        single = positions.ndim == 2
        out = self._skin.deform(positions.reshape(-1, 3), orientations.reshape(-1, 4), self.method)
        v = len(self.vertices)
        return out.reshape(v, 3) if single else out.reshape(-1, v, 3)


def _influences(weights: Any, n: int, joints: int) -> tuple[np.ndarray, np.ndarray, int]:
    """``(bones, weights)`` given by the user as two ``(V, k)`` arrays, flattened."""
    if not (isinstance(weights, tuple) and len(weights) == 2):
        raise TypeError("weights: expected None or a (bones, weights) pair of (V, k) arrays")
    bones = np.asarray(weights[0])
    w = np.asarray(weights[1], dtype=np.float64)
    if bones.ndim != 2 or w.shape != bones.shape or bones.shape[0] != n:
        raise ValueError(f"weights: expected two ({n}, k) arrays, got {bones.shape} and {w.shape}")
    if not np.issubdtype(bones.dtype, np.integer):
        raise ValueError("weights: bones must be integers")
    if bones.size and (bones.min() < 0 or bones.max() >= joints):
        raise ValueError(f"weights: bones must be joint indices in [0, {joints})")
    flat = np.ascontiguousarray(bones, dtype=np.uint32).ravel()
    return flat, np.ascontiguousarray(w).ravel(), bones.shape[1]


def body_mesh(
    skeleton: Any,
    radius: Any = None,
    *,
    blend: float | None = None,
    cell: float | None = None,
    weights: str = "heat",
    method: str = "dqs",
    influences: int = 4,
    falloff: float = 4.0,
    bind_pose: Any = None,
) -> Skin:
    """A body for ``skeleton``: capsules of ``radius`` around its bones (``bone_segments`` at
    the bind pose) merged into one closed, manifold, outward-facing surface, bound to the bones
    with ``weights`` (``"heat"`` or ``"proximity"``, see :class:`Skin`; ``influences``,
    ``falloff``) and blended by ``method``.

    Lengths are in the skeleton's units. ``radius``: one for every bone or one per segment of
    ``bone_segments`` (default: 4 % of the bind pose's largest extent). The surface is the zero
    level set of the capsules' signed distances merged by a polynomial smooth minimum of width
    ``blend`` (default ``radius / 2``: joints are filleted and swell by at most ``blend / 4``;
    0 gives the plain union), sampled on a grid of spacing ``cell`` (default ``radius / 4``) and
    polygonised by marching tetrahedra (docs/skin.md)."""
    _check_skeleton(skeleton)
    pose = np.zeros(skeleton.stride) if bind_pose is None else bind_pose
    segments, _ = bone_segments(skeleton, *skeleton.forward_kinematics(pose))
    if len(segments) == 0:
        raise ValueError("skeleton: has no bone of non-zero length")
    if radius is None:
        extent = segments.reshape(-1, 3).max(axis=0) - segments.reshape(-1, 3).min(axis=0)
        radius = 0.04 * float(extent.max())
    radii = np.asarray(radius, dtype=np.float64).ravel()
    if radii.size == 1:
        radii = np.full(len(segments), radii[0])
    typical = float(np.min(radii)) if radii.size else 1.0
    blend = 0.5 * typical if blend is None else real(blend, "blend")
    cell = 0.25 * typical if cell is None else real(cell, "cell")
    vertices, triangles = _kinema.skin_capsule_union(segments, radii.tolist(), blend, cell)
    return Skin(
        vertices,
        skeleton,
        weights,
        triangles=triangles.astype(np.int64),
        method=method,
        influences=influences,
        falloff=falloff,
        bind_pose=bind_pose,
    )
