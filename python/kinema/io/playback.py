"""What a recorded animation looks like frame by frame: the meshes, line segments and points
that :mod:`kinema.view` draws, from a scene's recording, a ``(skin, motion)`` pair or a
``.glb`` file.

A ``.glb`` file is evaluated as a glTF viewer plays it: at every key time of its animations
(the union of their samplers' inputs), every node's translation, rotation, scale and morph
weights are sampled (``LINEAR``, ``STEP``; rotations normalised), world transforms composed
down the node hierarchy, skinned meshes blended linearly from their joints' world transforms
and inverse bind matrices (glTF skinning, §3.7.3 of the glTF 2.0 specification), morph targets
added to their base positions, and a node whose world transform has scale 0 is hidden. It reads
the files kinema writes (:mod:`kinema.io.gltf`) and other tightly packed ``.glb`` files of
triangles, lines and points; textures and materials are ignored.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["Drawn", "glb_frames", "scene_frames", "skin_frames"]

_TRIANGLES, _LINES, _POINTS = 4, 1, 0
_DTYPES = {5121: np.uint8, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


@dataclass
class Drawn:
    """One thing drawn: ``kind`` (``"mesh"``, ``"lines"`` or ``"points"``) and, for every
    frame, ``(vertices (V, 3) m, indices)`` (triangles ``(T, 3)``, segments ``(L, 2)``, or
    None for points) or None where it is hidden. Frames sharing one topology share the
    indices array."""

    kind: str
    frames: list[tuple[np.ndarray, np.ndarray | None] | None]


def _fixed(kind: str, frames: np.ndarray, indices: np.ndarray | None) -> Drawn:
    return Drawn(kind, [(f, indices) for f in np.asarray(frames, dtype=np.float64)])


def scene_frames(scene: Any) -> tuple[np.ndarray, dict[str, Drawn]]:
    """The animation ``scene`` recorded (:mod:`kinema.io.scene`): times ``(F,)`` s and what is
    drawn, by name."""
    from kinema.io._tracks import frame_meshes_of, strand_segments
    from kinema.io.scene import scene_tracks
    from kinema.rotation import Rotation

    rigid, sequences, varying = scene_tracks(scene)
    out: dict[str, Drawn] = {}
    for s in sequences:
        if s.triangles is not None:
            out[s.name] = _fixed("mesh", s.frames, np.asarray(s.triangles, dtype=np.int64))
        elif s.strands is not None:
            out[s.name] = _fixed("lines", s.frames, strand_segments(s.strands))
        else:
            out[s.name] = _fixed("points", s.frames, None)
    for r in rigid:
        v = np.asarray(r.vertices, dtype=np.float64)
        q = Rotation.from_quat(np.asarray(r.orientations))
        moved = np.stack([q[k].apply(v) for k in range(len(q))]) + np.asarray(r.positions)[:, None]
        out[r.name] = _fixed("mesh", moved, np.asarray(r.triangles, dtype=np.int64))
    for f in varying:
        _, vertices, triangles = frame_meshes_of(f)
        kind = "points" if f.triangles is None else "mesh"
        out[f.name] = Drawn(kind, list(zip(vertices, triangles, strict=True)))
    return np.asarray(scene.records["animation"])[:, 0], out


def skin_frames(skin: Any, motion: Any) -> tuple[np.ndarray, dict[str, Drawn]]:
    """A :class:`kinema.skin.Skin` played by ``motion``, in metres (the skeleton's
    ``metres_per_unit``): times ``(F,)`` s and the skinned mesh."""
    unit = float(getattr(skin.skeleton, "metres_per_unit", 1.0))
    frames = skin.deform(motion) * unit
    times = np.arange(len(frames)) / float(motion.frame_rate)
    return times, {"skin": _fixed("mesh", frames, np.asarray(skin.triangles, dtype=np.int64))}


class _Glb:
    """A loaded ``.glb`` file: its document and accessors as numpy arrays."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        from kinema.io.gltf import _pygltflib

        g = _pygltflib()
        try:
            self.doc = g.GLTF2().load_binary(os.fspath(path))
        except (OSError, ValueError, KeyError, TypeError) as e:
            raise ValueError(f"path: not a readable .glb file ({type(e).__name__})") from None
        self.blob = self.doc.binary_blob() or b""

    def read(self, index: int) -> np.ndarray:
        """Accessor ``index`` as ``(count, width)`` (float64 for floats)."""
        a = self.doc.accessors[index]
        view = self.doc.bufferViews[a.bufferView]
        dtype = np.dtype(_DTYPES[a.componentType])
        width = _WIDTH[a.type]
        if view.byteStride not in (None, 0, width * dtype.itemsize):
            raise ValueError("path: interleaved buffer views are not supported")
        start = (view.byteOffset or 0) + (a.byteOffset or 0)
        data = np.frombuffer(self.blob, dtype, a.count * width, start).reshape(a.count, width)
        return data.astype(np.float64) if dtype.kind == "f" else data.astype(np.int64)


def _sample(keys: np.ndarray, values: np.ndarray, t: float, step: bool) -> np.ndarray:
    """The sampler's value at time ``t`` (clamped to its keys)."""
    i = int(np.searchsorted(keys, t, side="right")) - 1
    if i < 0:
        return values[0]
    if i >= len(keys) - 1 or step:
        return values[i]
    u = (t - keys[i]) / (keys[i + 1] - keys[i])
    return (1.0 - u) * values[i] + u * values[i + 1]


def _matrix(translation: Any, rotation: Any, scale: Any) -> np.ndarray:
    from kinema.rotation import Rotation

    x, y, z, w = np.asarray(rotation, dtype=np.float64)
    m = np.eye(4)
    m[:3, :3] = Rotation.from_quat([w, x, y, z]).as_matrix() * np.asarray(scale, np.float64)
    m[:3, 3] = translation
    return m


class _Pose:
    """The nodes of a glTF document at one time: local TRS and morph weights sampled from the
    animations, world matrices composed from the scene's roots."""

    def __init__(self, glb: _Glb, channels: list[tuple[Any, Any]], t: float) -> None:
        doc = glb.doc
        trs: list[list[Any]] = [
            [n.translation or [0, 0, 0], n.rotation or [0, 0, 0, 1], n.scale or [1, 1, 1]]
            for n in doc.nodes
        ]
        self.weights: dict[int, np.ndarray] = {}
        for channel, sampler in channels:
            keys, values = glb.read(sampler.input)[:, 0], glb.read(sampler.output)
            node, path = channel.target.node, channel.target.path
            if path == "weights":
                values = values.reshape(len(keys), -1)
            value = _sample(keys, values, t, sampler.interpolation == "STEP")
            if path == "weights":
                self.weights[node] = value
            else:
                slot = ["translation", "rotation", "scale"].index(path)
                trs[node][slot] = value / np.linalg.norm(value) if slot == 1 else value
        self.world = [np.eye(4)] * len(doc.nodes)
        roots = doc.scenes[doc.scene or 0].nodes if doc.scenes else range(len(doc.nodes))
        stack = [(r, np.eye(4)) for r in roots]
        while stack:
            k, parent = stack.pop()
            node = doc.nodes[k]
            local = np.array(node.matrix).reshape(4, 4).T if node.matrix else _matrix(*trs[k])
            self.world[k] = parent @ local
            stack += [(c, self.world[k]) for c in node.children or []]


def _positions(glb: _Glb, pose: _Pose, k: int, p: int) -> np.ndarray | None:
    """The world positions of primitive ``p`` of node ``k``'s mesh at ``pose``; None when the
    node is hidden (its world transform has scale 0)."""
    doc, node = glb.doc, glb.doc.nodes[k]
    prim = doc.meshes[node.mesh].primitives[p]
    x = glb.read(prim.attributes.POSITION)
    weights = pose.weights.get(k, doc.meshes[node.mesh].weights or [])
    for target, w in zip(prim.targets or [], weights, strict=False):
        if w != 0.0:
            x = x + w * glb.read(target["POSITION"])
    if node.skin is None:
        m = pose.world[k]
        if abs(np.linalg.det(m[:3, :3])) < 1e-30:
            return None
        return x @ m[:3, :3].T + m[:3, 3]
    skin = doc.skins[node.skin]
    ibm = glb.read(skin.inverseBindMatrices).reshape(-1, 4, 4).transpose(0, 2, 1)
    joints = np.stack([pose.world[j] for j in skin.joints]) @ ibm
    out = np.zeros_like(x)
    n = 0
    while (j := getattr(prim.attributes, f"JOINTS_{n}", None)) is not None:
        js, ws = glb.read(j), glb.read(getattr(prim.attributes, f"WEIGHTS_{n}"))
        for c in range(js.shape[1]):
            m = joints[js[:, c]]
            out += ws[:, c : c + 1] * (np.einsum("vab,vb->va", m[:, :3, :3], x) + m[:, :3, 3])
        n += 1
    return out


def glb_frames(path: str | os.PathLike[str]) -> tuple[np.ndarray, dict[str, Drawn]]:
    """The ``.glb`` file at ``path`` evaluated at every key time of its animations (see the
    module docs; one frame at time 0 without animations): times ``(F,)`` s and what is drawn,
    by node name (and primitive index after the first)."""
    glb = _Glb(path)
    doc = glb.doc
    channels = [(c, a.samplers[c.sampler]) for a in doc.animations for c in a.channels]
    keys = [glb.read(s.input)[:, 0] for _, s in channels]
    times = np.unique(np.concatenate(keys)) if keys else np.zeros(1)
    meshes = [
        (k, p)
        for k, n in enumerate(doc.nodes)
        if n.mesh is not None
        for p in range(len(doc.meshes[n.mesh].primitives))
    ]
    out: dict[str, Drawn] = {}
    drawn: list[Drawn] = []
    indices: dict[tuple[int, int], np.ndarray | None] = {}
    for k, p in meshes:
        prim = doc.meshes[doc.nodes[k].mesh].primitives[p]
        mode = _TRIANGLES if prim.mode is None else prim.mode
        kind = {_TRIANGLES: "mesh", _LINES: "lines", _POINTS: "points"}.get(mode)
        if kind is None:
            raise ValueError("path: holds a primitive mode other than triangles, lines, points")
        flat = None if prim.indices is None else glb.read(prim.indices).ravel()
        if flat is None and kind != "points":
            flat = np.arange(len(glb.read(prim.attributes.POSITION)))
        indices[k, p] = None if flat is None else flat.reshape(-1, 3 if kind == "mesh" else 2)
        name = (doc.nodes[k].name or f"node{k}") + (f"_{p}" if p else "")
        drawn.append(Drawn(kind, []))
        out[name if name not in out else f"{name}_node{k}"] = drawn[-1]
    for t in times:
        pose = _Pose(glb, channels, float(t))
        for (k, p), d in zip(meshes, drawn, strict=True):
            x = _positions(glb, pose, k, p)
            d.frames.append(None if x is None else (x, indices[k, p]))
    return times, out
