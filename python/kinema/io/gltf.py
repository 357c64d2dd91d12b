"""glTF 2.0 binary (``.glb``) files of kinema results, written with ``pygltflib``.

Three kinds of content, each in metres and seconds (glTF's units), Y up as kinema's scenes:

- a :class:`kinema.skin.Skin` played by a motion: the skeleton as a hierarchy of joint nodes
  (one per bone, parented as the skeleton's joints), the mesh with ``JOINTS_n``/``WEIGHTS_n``
  (sets of four influences) and the inverse bind matrices, and one animation channel of
  ``translation`` and one of ``rotation`` per joint, ``LINEAR``, one key per frame. A glTF
  viewer blends the bones linearly (glTF skinning is linear blend skinning): the file shows
  ``method="lbs"`` whatever the skin's method;
- :class:`RigidTrack`: a rigid mesh moved by node animation (translation and rotation keys);
- :class:`MeshSequence`: vertices of a fixed number moving (cloth, rods and hair, crowds and
  flocks) as **morph targets** of one primitive (``TRIANGLES``, ``LINES`` for polylines,
  ``POINTS``): the first frame is the mesh, every frame ``k`` a target holding its
  displacement from the first, and a ``weights`` channel that is 1 on target ``k`` at time
  ``t_k`` and 0 on the others, ``LINEAR``, so that between keys the vertices move on straight
  lines. One mesh with morph targets rather than one mesh per frame: viewers play it as an
  animation (Blender imports the targets as shape keys) and the topology is stored once;
- :class:`FrameMeshes`: a mesh or point cloud whose size changes (particles, fluids and their
  surfaces) as **one node per frame** under a parent node, each with its own mesh and a
  ``scale`` channel, ``STEP``, that is 1 from its time to the next frame's and 0 otherwise
  (morph targets need one vertex count for all frames). A frame with no vertices is a node
  without a mesh.

Rotations are written ``(x, y, z, w)`` (glTF's order; kinema's is ``(w, x, y, z)``), each key in
the hemisphere of the one before so that interpolation takes the short way. Every accessor
carries its ``min``/``max``; weights are normalised in single precision.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from kinema.io._tracks import (
    FrameMeshes,
    MeshSequence,
    RigidTrack,
    frame_meshes_of,
    frames_of,
    skeleton_frames,
    strand_segments,
    times_of,
)

__all__ = ["write_glb"]


def _pygltflib() -> Any:
    try:
        import pygltflib
    except ImportError:
        raise ImportError(
            "kinema.io.write_glb needs pygltflib: pip install 'kinema[export]'"
        ) from None
    return pygltflib


class _Builder:
    """A glTF document and its one binary buffer, grown accessor by accessor."""

    def __init__(self) -> None:
        g = _pygltflib()
        self.g = g
        self.doc = g.GLTF2(asset=g.Asset(generator="kinema"), scenes=[g.Scene(nodes=[])], scene=0)
        self.doc.materials.append(
            g.Material(
                pbrMetallicRoughness=g.PbrMetallicRoughness(
                    baseColorFactor=[0.8, 0.6, 0.5, 1.0], metallicFactor=0.0
                ),
                doubleSided=True,
            )
        )
        self.blob = bytearray()

    def accessor(self, data: np.ndarray, kind: str, target: int | None = None) -> int:
        """Append ``data`` (float32, uint16 or uint32 rows of ``kind``) with its bounds."""
        g = self.g
        component = {
            np.dtype(np.float32): g.FLOAT,
            np.dtype(np.uint16): g.UNSIGNED_SHORT,
            np.dtype(np.uint32): g.UNSIGNED_INT,
        }[data.dtype]
        rows = data.reshape(len(data), -1)
        self.blob += b"\0" * (-len(self.blob) % 4)
        offset = len(self.blob)
        self.blob += np.ascontiguousarray(rows).tobytes()
        self.doc.bufferViews.append(
            g.BufferView(buffer=0, byteOffset=offset, byteLength=rows.nbytes, target=target)
        )
        as_number = float if component == g.FLOAT else int
        self.doc.accessors.append(
            g.Accessor(
                bufferView=len(self.doc.bufferViews) - 1,
                componentType=component,
                count=len(rows),
                type=kind,
                min=[as_number(x) for x in rows.min(axis=0)] if len(rows) else None,
                max=[as_number(x) for x in rows.max(axis=0)] if len(rows) else None,
            )
        )
        return len(self.doc.accessors) - 1

    def node(self, top: bool = True, **fields: Any) -> int:
        self.doc.nodes.append(self.g.Node(**fields))
        index = len(self.doc.nodes) - 1
        if top:
            self.doc.scenes[0].nodes.append(index)
        return index

    def mesh(self, vertices: np.ndarray, elements: Any, mode: int = 4, **attributes: int) -> int:
        """A mesh of one primitive: ``vertices`` joined by ``elements`` (index rows) drawn as
        ``mode`` (4 triangles, 1 lines), or ``elements=None``: points (mode 0)."""
        g = self.g
        position = self.accessor(vertices.astype(np.float32), g.VEC3, g.ARRAY_BUFFER)
        indices = None
        if elements is not None:
            flat = np.asarray(elements, dtype=np.uint32).reshape(-1)
            indices = self.accessor(flat, g.SCALAR, g.ELEMENT_ARRAY_BUFFER)
        primitive = g.Primitive(
            attributes=g.Attributes(POSITION=position, **attributes),
            indices=indices,
            material=0,
            mode=g.POINTS if elements is None else mode,
        )
        self.doc.meshes.append(g.Mesh(primitives=[primitive]))
        return len(self.doc.meshes) - 1

    def animate(
        self, name: str, times: Any, channels: list[tuple[Any, ...]], step: bool = False
    ) -> None:
        """One animation of ``(node, path, values)`` channels keyed at ``times`` (s), or of
        ``(node, path, values, times)`` channels keyed at their own; ``LINEAR``, or ``STEP``
        with ``step``."""
        g = self.g
        if not channels:
            return
        shared = self.accessor(np.asarray(times, dtype=np.float32), g.SCALAR)
        interpolation = g.ANIM_STEP if step else g.ANIM_LINEAR
        samplers, targets = [], []
        for node, path, values, *own in channels:  # own: the channel's key times, if any
            kind = {"translation": g.VEC3, "rotation": g.VEC4, "scale": g.VEC3}.get(path, g.SCALAR)
            data = np.asarray(values, dtype=np.float32)
            out = self.accessor(data.reshape(-1) if kind == g.SCALAR else data, kind)
            t = self.accessor(np.asarray(own[0], np.float32), g.SCALAR) if own else shared
            samplers.append(g.AnimationSampler(input=t, output=out, interpolation=interpolation))
            targets.append(
                g.AnimationChannel(
                    sampler=len(samplers) - 1, target=g.AnimationChannelTarget(node=node, path=path)
                )
            )
        self.doc.animations.append(g.Animation(name=name, samplers=samplers, channels=targets))

    def save(self, path: str | os.PathLike[str]) -> None:
        self.blob += b"\0" * (-len(self.blob) % 4)
        self.doc.buffers.append(self.g.Buffer(byteLength=len(self.blob)))
        self.doc.set_binary_blob(bytes(self.blob))
        self.doc.save_binary(os.fspath(path))


def _xyzw(q: np.ndarray) -> np.ndarray:
    """``(w, x, y, z)`` keys ``(F, 4)`` as glTF's ``(x, y, z, w)``, normalised, each in the
    hemisphere of the key before."""
    q = np.array(q, dtype=np.float64)
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    for f in range(1, len(q)):
        if np.dot(q[f], q[f - 1]) < 0:
            q[f] = -q[f]
    return q[:, [1, 2, 3, 0]]


def _add_rigid(b: _Builder, track: RigidTrack) -> None:
    x = np.asarray(track.positions, dtype=np.float64).reshape(-1, 3)
    t = times_of(track.times, len(x))
    q = np.asarray(track.orientations, dtype=np.float64).reshape(len(x), 4)
    mesh = b.mesh(np.asarray(track.vertices, dtype=np.float64), np.asarray(track.triangles))
    rotation = _xyzw(q)
    node = b.node(
        name=track.name, mesh=mesh, translation=x[0].tolist(), rotation=rotation[0].tolist()
    )
    b.animate(track.name, t, [(node, "translation", x), (node, "rotation", rotation)])


def _add_sequence(b: _Builder, seq: MeshSequence) -> None:
    g = b.g
    frames = frames_of(seq)
    t = times_of(seq.times, len(frames))
    base = frames[0].astype(np.float32)
    if seq.triangles is not None:
        mesh = b.mesh(base, np.asarray(seq.triangles))
    elif seq.strands is not None:
        mesh = b.mesh(base, strand_segments(seq.strands), g.LINES)
    else:
        mesh = b.mesh(base, None)
    primitive = b.doc.meshes[mesh].primitives[0]
    for f in frames:
        displacement = f.astype(np.float32) - base
        primitive.targets.append(
            g.Attributes(POSITION=b.accessor(displacement, g.VEC3, g.ARRAY_BUFFER))
        )
    b.doc.meshes[mesh].weights = [0.0] * len(frames)
    node = b.node(name=seq.name, mesh=mesh)
    b.animate(seq.name, t, [(node, "weights", np.eye(len(frames)))])


def _add_frames(b: _Builder, seq: FrameMeshes) -> None:
    t, vertices, triangles = frame_meshes_of(seq)
    children, channels = [], []
    for k, (v, tri) in enumerate(zip(vertices, triangles, strict=True)):
        mesh = b.mesh(v, tri) if len(v) else None
        shown = [1.0] * 3 if k == 0 else [0.0] * 3
        children.append(b.node(top=False, name=f"{seq.name}_{k}", mesh=mesh, scale=shown))
        keys = sorted({t[0], t[k], t[min(k + 1, len(t) - 1)]})
        values = [[1.0] * 3 if key == t[k] else [0.0] * 3 for key in keys]
        channels.append((children[-1], "scale", values, keys))
    b.node(name=seq.name, children=children)
    b.animate(seq.name, t, channels, step=True)


def _inverse_bind(rotation: np.ndarray, translation: np.ndarray) -> np.ndarray:
    """The inverse of each frame ``(J, 4)``, ``(J, 3)`` as glTF's column-major 4×4 ``(J, 16)``."""
    from kinema.rotation import Rotation

    r = Rotation.from_quat(rotation).inv().as_matrix()
    m = np.zeros((len(r), 4, 4))
    m[:, :3, :3] = r
    m[:, :3, 3] = -np.einsum("jab,jb->ja", r, translation)
    m[:, 3, 3] = 1.0
    return m.transpose(0, 2, 1).reshape(-1, 16)


def _influence_sets(bones: np.ndarray, weights: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """The influences ``(V, k)`` as sets of four (``JOINTS_n``, ``WEIGHTS_n``), padded with
    zero weights on joint 0, weights normalised in single precision."""
    v, k = bones.shape
    n = -(-k // 4) * 4
    j = np.zeros((v, n), dtype=np.uint16)
    w = np.zeros((v, n), dtype=np.float32)
    j[:, :k] = bones
    w[:, :k] = weights
    w /= w.sum(axis=1, keepdims=True, dtype=np.float32)
    top = np.argmax(w, axis=1)
    w[np.arange(v), top] += np.float32(1.0) - w.sum(axis=1, dtype=np.float32)
    return [(j[:, s : s + 4], w[:, s : s + 4]) for s in range(0, n, 4)]


def _add_skin(b: _Builder, skin: Any, motion: Any, scale: float | None) -> None:
    g = b.g
    sf = skeleton_frames(skin, motion, scale)
    joints = []
    for j, p in enumerate(sf.parents):
        joints.append(
            b.node(
                top=p < 0,
                name=sf.names[j],
                translation=sf.rest_translation[j].tolist(),
                rotation=_xyzw(sf.rest_rotation[j : j + 1])[0].tolist(),
            )
        )
    for j, p in enumerate(sf.parents):
        if p >= 0:
            b.doc.nodes[joints[p]].children.append(joints[j])
    inverse = _inverse_bind(sf.bind_rotation, sf.bind_translation).astype(np.float32)
    ibm = b.accessor(inverse, g.MAT4)
    b.doc.skins.append(g.Skin(inverseBindMatrices=ibm, joints=joints, skeleton=joints[0]))
    sets = {}
    for n, (jn, wn) in enumerate(_influence_sets(skin.bones, skin.weights)):
        sets[f"JOINTS_{n}"] = b.accessor(jn, g.VEC4, g.ARRAY_BUFFER)
        sets[f"WEIGHTS_{n}"] = b.accessor(wn, g.VEC4, g.ARRAY_BUFFER)
    mesh = b.mesh(sf.scale * np.asarray(skin.vertices), sf.triangles, **sets)
    b.node(name="skin", mesh=mesh, skin=len(b.doc.skins) - 1)
    channels: list[tuple[int, str, Any]] = []
    for j, node in enumerate(joints):
        channels += [
            (node, "translation", sf.translation[:, j]),
            (node, "rotation", _xyzw(sf.rotation[:, j])),
        ]
    b.animate("motion", sf.times, channels)


def write_glb(
    path: str | os.PathLike[str],
    *,
    skins: Any = (),
    rigid: Any = (),
    sequences: Any = (),
    frames: Any = (),
    scale: float | None = None,
) -> None:
    """Write a ``.glb`` file with ``skins`` (``(skin, motion)`` pairs: a
    :class:`kinema.skin.Skin` and a motion of its skeleton, lengths times ``scale``, default the
    skeleton's ``metres_per_unit`` for Acclaim and 1 for BVH), ``rigid`` (:class:`RigidTrack`),
    ``sequences`` (:class:`MeshSequence`) and ``frames`` (:class:`FrameMeshes`), one animation
    each; see the module docs."""
    b = _Builder()
    for skin, motion in skins:
        _add_skin(b, skin, motion, scale)
    for track in rigid:
        _add_rigid(b, track)
    for seq in sequences:
        _add_sequence(b, seq)
    for each in frames:
        _add_frames(b, each)
    b.save(path)
