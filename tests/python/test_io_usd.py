"""USD export read back with pxr: the skeleton, its frames, and the points pxr's UsdSkel
skins (dual quaternion and linear) against kinema's; time-sampled points of a mesh sequence;
a rigid track's transform."""

from __future__ import annotations

import importlib

import numpy as np
import pytest

pxr = pytest.importorskip("pxr")
importlib.import_module("pxr.UsdSkel")

from scipy.spatial.transform import Rotation as R  # noqa: E402

from kinema import io, skin  # noqa: E402


@pytest.fixture(scope="module")
def short_walk(walk):
    sk, motion = walk
    return sk, motion.slice(0, 30)


@pytest.mark.parametrize("method", ["dqs", "lbs"])
def test_a_skinned_walk_round_trips(short_walk, tmp_path, method):
    sk, motion = short_walk
    body = skin.body_mesh(sk, 1.0, cell=0.4, method=method)
    path = tmp_path / "walk.usdc"
    io.write_usd(path, skins=[(body, motion)], frame_rate=120.0)
    stage = pxr.Usd.Stage.Open(str(path))
    assert stage.GetTimeCodesPerSecond() == 120.0
    assert stage.GetEndTimeCode() == motion.frames - 1
    skel = pxr.UsdSkel.Skeleton(stage.GetPrimAtPath("/kinema/skin0/skeleton"))
    paths = list(skel.GetJointsAttr().Get())
    names = list(sk.joint_names)
    parents = [names.index(p.split("/")[-2]) if "/" in p else -1 for p in paths]
    assert [p.split("/")[-1] for p in paths] == names
    assert parents == list(sk.parents)
    cache = pxr.UsdSkel.Cache()
    root = pxr.UsdSkel.Root(stage.GetPrimAtPath("/kinema/skin0"))
    cache.Populate(root, pxr.Usd.TraverseInstanceProxies())
    query = cache.GetSkelQuery(skel)
    (binding,) = cache.ComputeSkelBindings(root, pxr.Usd.TraverseInstanceProxies())
    (skinning,) = binding.GetSkinningTargets()
    points = pxr.UsdGeom.Mesh(stage.GetPrimAtPath("/kinema/skin0/body")).GetPointsAttr()
    expected = body.deform(motion) * sk.metres_per_unit
    for k in (0, 11, motion.frames - 1):
        xforms = query.ComputeSkinningTransforms(k)
        p = points.Get(k)
        assert skinning.ComputeSkinnedPoints(xforms, p, k)
        got = np.array(p, dtype=np.float64)
        assert np.abs(got - expected[k]).max() < 1e-5


def test_sequences_and_rigid_tracks_round_trip(tmp_path):
    times = np.arange(4) / 30.0
    frames = np.random.default_rng(3).normal(size=(4, 5, 3))
    rot = R.from_rotvec(np.outer(times, [1.0, -2.0, 0.5]))
    x = np.c_[times, -times, times**2]
    path = tmp_path / "scene.usda"
    io.write_usd(
        path,
        sequences=[io.MeshSequence([[0, 1, 2], [2, 3, 4]], times, frames)],
        rigid=[io.RigidTrack(np.eye(3), [[0, 1, 2]], times, x, rot.as_quat(scalar_first=True))],
        frame_rate=30.0,
    )
    stage = pxr.Usd.Stage.Open(str(path))
    points = pxr.UsdGeom.Mesh(stage.GetPrimAtPath("/kinema/mesh0")).GetPointsAttr()
    assert list(points.GetTimeSamples()) == [0.0, 1.0, 2.0, 3.0]
    xform = pxr.UsdGeom.Xformable(stage.GetPrimAtPath("/kinema/body0"))
    for k in range(4):
        assert np.abs(np.array(points.Get(k)) - frames[k]).max() < 1e-6
        m = np.array(xform.ComputeLocalToWorldTransform(k)).T  # USD: row vectors
        assert np.allclose(m[:3, 3], x[k], atol=1e-6)
        assert np.allclose(m[:3, :3], rot[k].as_matrix(), atol=1e-6)


def test_bad_input_names_the_argument(tmp_path):
    with pytest.raises(ValueError, match="frame_rate"):
        io.write_usd(tmp_path / "x.usda", frame_rate=0.0)
