"""USD files (``.usd``, ``.usdc``, ``.usda``) of kinema results, written with Pixar's
``usd-core`` (``pxr``); metres (``metersPerUnit = 1``), Y up, time codes of ``frame_rate``
per second.

- a :class:`kinema.skin.Skin` played by a motion: a ``SkelRoot`` holding a ``Skeleton``
  (joint paths from the skeleton's hierarchy, world bind transforms, rest transforms), a
  ``SkelAnimation`` (joint translations and rotations relative to the parent, one time sample
  per frame) and the ``Mesh`` bound to it (``UsdSkelBindingAPI``: ``jointIndices`` and
  ``jointWeights`` of ``k`` influences per vertex, and ``skel:skinningMethod`` set to the skin's
  method: ``dualQuaternion`` or ``classicLinear``, so USD shows what kinema computed);
- :class:`kinema.io.RigidTrack`: an ``Xform`` with time-sampled translate and orient (both
  double precision), holding the mesh;
- :class:`kinema.io.MeshSequence`: a ``Mesh`` (triangles), ``BasisCurves`` (``linear``, one
  curve per strand: rods, hair) or ``Points`` (crowds, flocks) whose ``points`` are
  time-sampled (one sample per frame);
- :class:`kinema.io.FrameMeshes`: a ``Mesh`` or ``Points`` whose ``points`` (and a mesh's
  ``faceVertexCounts`` and ``faceVertexIndices``) are time-sampled, their size changing from
  sample to sample (particles, fluids and their surfaces).
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
    times_of,
)

__all__ = ["write_usd"]


def _pxr() -> Any:
    try:
        import pxr
        import pxr.Gf
        import pxr.Usd
        import pxr.UsdGeom
        import pxr.UsdSkel
        import pxr.Vt
    except ImportError:
        raise ImportError(
            "kinema.io.write_usd needs usd-core: pip install 'kinema[export]'"
        ) from None
    return pxr


def _matrix(pxr: Any, rotation: np.ndarray, translation: np.ndarray) -> Any:
    """The frame ``(w, x, y, z)``, ``(3,)`` as a USD matrix (row vectors: ``p' = p M``)."""
    from kinema.rotation import Rotation

    m = np.eye(4)
    m[:3, :3] = Rotation.from_quat(rotation).as_matrix().T
    m[3, :3] = translation
    return pxr.Gf.Matrix4d(m.tolist())


def _codes(times: np.ndarray, rate: float) -> np.ndarray:
    """The time codes of ``times`` (s): ``t · rate`` frames, rounded to 10⁻⁶ frame so that
    frame ``k`` recorded at ``k dt`` is the code ``k`` exactly (time samples whose size
    changes are held, not interpolated, so a code a rounding error early shows the frame
    before)."""
    return np.round(np.asarray(times, dtype=np.float64) * rate, 6)


def _joint_paths(names: list[str], parents: list[int]) -> list[str]:
    paths: list[str] = []
    for name, p in zip(names, parents, strict=True):
        paths.append(name if p < 0 else f"{paths[p]}/{name}")
    return paths


def _mesh(pxr: Any, stage: Any, path: str, vertices: np.ndarray, triangles: Any) -> Any:
    mesh = pxr.UsdGeom.Mesh.Define(stage, path)
    tri = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    mesh.CreateFaceVertexCountsAttr(pxr.Vt.IntArray([3] * len(tri)))
    mesh.CreateFaceVertexIndicesAttr(pxr.Vt.IntArray(tri.ravel().tolist()))
    mesh.CreatePointsAttr(pxr.Vt.Vec3fArray.FromNumpy(vertices.astype(np.float32)))
    mesh.CreateDoubleSidedAttr(True)
    return mesh


def _quats(pxr: Any, q: np.ndarray) -> Any:
    return pxr.Vt.QuatfArray([pxr.Gf.Quatf(*map(float, r)) for r in q])


def _add_skin(pxr: Any, stage: Any, path: str, skin: Any, motion: Any, rate: float) -> None:
    sf = skeleton_frames(skin, motion, None)
    UsdSkel, Vt = pxr.UsdSkel, pxr.Vt
    root = UsdSkel.Root.Define(stage, path)
    skel = UsdSkel.Skeleton.Define(stage, f"{path}/skeleton")
    joints = Vt.TokenArray(_joint_paths(sf.names, sf.parents))
    skel.CreateJointsAttr(joints)
    skel.CreateJointNamesAttr(Vt.TokenArray(sf.names))
    bind = [_matrix(pxr, q, t) for q, t in zip(sf.bind_rotation, sf.bind_translation, strict=True)]
    rest = [_matrix(pxr, q, t) for q, t in zip(sf.rest_rotation, sf.rest_translation, strict=True)]
    skel.CreateBindTransformsAttr(Vt.Matrix4dArray(bind))
    skel.CreateRestTransformsAttr(Vt.Matrix4dArray(rest))
    anim = UsdSkel.Animation.Define(stage, f"{path}/skeleton/motion")
    anim.CreateJointsAttr(joints)
    translations, rotations = anim.CreateTranslationsAttr(), anim.CreateRotationsAttr()
    anim.CreateScalesAttr(Vt.Vec3hArray([pxr.Gf.Vec3h(1, 1, 1)] * len(sf.names)))
    for k, time in enumerate(_codes(sf.times, rate)):
        translations.Set(Vt.Vec3fArray.FromNumpy(sf.translation[k].astype(np.float32)), time)
        rotations.Set(_quats(pxr, sf.rotation[k]), time)
    UsdSkel.BindingAPI.Apply(skel.GetPrim()).CreateAnimationSourceRel().SetTargets([anim.GetPath()])
    mesh = _mesh(pxr, stage, f"{path}/body", sf.scale * np.asarray(skin.vertices), sf.triangles)
    binding = UsdSkel.BindingAPI.Apply(mesh.GetPrim())
    binding.CreateSkeletonRel().SetTargets([skel.GetPath()])
    k = skin.bones.shape[1]
    binding.CreateJointIndicesPrimvar(False, k).Set(Vt.IntArray(skin.bones.ravel().tolist()))
    binding.CreateJointWeightsPrimvar(False, k).Set(Vt.FloatArray(skin.weights.ravel().tolist()))
    binding.CreateGeomBindTransformAttr(pxr.Gf.Matrix4d(1.0))
    method = "dualQuaternion" if skin.method == "dqs" else "classicLinear"
    binding.CreateSkinningMethodAttr(method)
    UsdSkel.BindingAPI.Apply(root.GetPrim())


def _add_rigid(pxr: Any, stage: Any, path: str, track: RigidTrack, rate: float) -> None:
    x = np.asarray(track.positions, dtype=np.float64).reshape(-1, 3)
    t = _codes(times_of(track.times, len(x)), rate)
    q = np.asarray(track.orientations, dtype=np.float64).reshape(len(x), 4)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    xform = pxr.UsdGeom.Xform.Define(stage, path)
    # Double precision: a float orient of a small turn loses ~1e-5 (USD takes its angle by acos).
    translate = xform.AddTranslateOp()
    orient = xform.AddOrientOp(pxr.UsdGeom.XformOp.PrecisionDouble)
    for k, time in enumerate(t):
        translate.Set(pxr.Gf.Vec3d(*x[k]), time)
        orient.Set(pxr.Gf.Quatd(*map(float, q[k])), time)
    _mesh(pxr, stage, f"{path}/mesh", np.asarray(track.vertices, np.float64), track.triangles)


def _add_sequence(pxr: Any, stage: Any, path: str, seq: MeshSequence, rate: float) -> None:
    frames = frames_of(seq)
    t = _codes(times_of(seq.times, len(frames)), rate)
    if seq.triangles is not None:
        points = _mesh(pxr, stage, path, frames[0], seq.triangles).GetPointsAttr()
    elif seq.strands is not None:
        curves = pxr.UsdGeom.BasisCurves.Define(stage, path)
        curves.CreateTypeAttr(pxr.UsdGeom.Tokens.linear)
        counts = np.asarray(seq.strands, dtype=np.int64).reshape(-1)
        curves.CreateCurveVertexCountsAttr(pxr.Vt.IntArray(counts.tolist()))
        points = curves.CreatePointsAttr()
    else:
        points = pxr.UsdGeom.Points.Define(stage, path).CreatePointsAttr()
    for k, time in enumerate(t):
        points.Set(pxr.Vt.Vec3fArray.FromNumpy(frames[k].astype(np.float32)), time)


def _add_frames(pxr: Any, stage: Any, path: str, seq: FrameMeshes, rate: float) -> None:
    t, vertices, triangles = frame_meshes_of(seq)
    Vt = pxr.Vt
    if seq.triangles is None:
        points = pxr.UsdGeom.Points.Define(stage, path).CreatePointsAttr()
    else:
        mesh = pxr.UsdGeom.Mesh.Define(stage, path)
        mesh.CreateDoubleSidedAttr(True)
        points = mesh.CreatePointsAttr()
        counts, indices = mesh.CreateFaceVertexCountsAttr(), mesh.CreateFaceVertexIndicesAttr()
    for k, time in enumerate(_codes(t, rate)):
        points.Set(Vt.Vec3fArray.FromNumpy(vertices[k].astype(np.float32)), time)
        if seq.triangles is not None:
            counts.Set(Vt.IntArray([3] * len(triangles[k])), time)
            indices.Set(Vt.IntArray(triangles[k].ravel().tolist()), time)


def write_usd(
    path: str | os.PathLike[str],
    *,
    skins: Any = (),
    rigid: Any = (),
    sequences: Any = (),
    frames: Any = (),
    frame_rate: float = 60.0,
) -> None:
    """Write a USD stage (format from the extension: ``.usda`` text, ``.usd``/``.usdc``
    binary) with ``skins`` (``(skin, motion)`` pairs, lengths times the skeleton's
    ``metres_per_unit``), ``rigid`` (:class:`kinema.io.RigidTrack`), ``sequences``
    (:class:`kinema.io.MeshSequence`) and ``frames`` (:class:`kinema.io.FrameMeshes`) under
    ``/kinema``; time code ``t · frame_rate`` holds the state at ``t`` s."""
    pxr = _pxr()
    if not (np.isfinite(frame_rate) and frame_rate > 0):
        raise ValueError("frame_rate: must be positive and finite")
    stage = pxr.Usd.Stage.CreateNew(os.fspath(path))
    pxr.UsdGeom.SetStageUpAxis(stage, pxr.UsdGeom.Tokens.y)
    pxr.UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.SetTimeCodesPerSecond(frame_rate)
    stage.SetDefaultPrim(pxr.UsdGeom.Xform.Define(stage, "/kinema").GetPrim())
    end = 0.0
    for i, (skin, motion) in enumerate(skins):
        _add_skin(pxr, stage, f"/kinema/skin{i}", skin, motion, frame_rate)
        end = max(end, (motion.frames - 1) / motion.frame_rate)
    for i, track in enumerate(rigid):
        _add_rigid(pxr, stage, f"/kinema/body{i}", track, frame_rate)
        end = max(end, float(np.max(track.times)))
    for i, seq in enumerate(sequences):
        _add_sequence(pxr, stage, f"/kinema/mesh{i}", seq, frame_rate)
        end = max(end, float(np.max(seq.times)))
    for i, each in enumerate(frames):
        _add_frames(pxr, stage, f"/kinema/frames{i}", each, frame_rate)
        end = max(end, float(np.max(each.times)))
    stage.SetStartTimeCode(0.0)
    stage.SetEndTimeCode(end * frame_rate)
    stage.GetRootLayer().Save()
