"""Skinning against a numpy oracle and geometry: the bind pose gives the mesh back, LBS
equals an einsum implementation, LBS equals DQS for one bone per vertex, a walk keeps the
skin at its bones, pickling, bad arguments."""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation as R

from kinema import mocap, skin

DATA = Path(__file__).resolve().parents[1] / "data" / "mocap"


@pytest.fixture(scope="module")
def short_walk(walk):
    sk, motion = walk
    return sk, motion.slice(0, 60)


def tubes(sk, radius=0.6, rings=6, sides=8):
    """Points on a tube around every bone of ``sk`` at its rest pose (file units)."""
    pos, ori = sk.forward_kinematics(np.zeros(sk.stride))
    segments, _ = skin.bone_segments(sk, pos, ori)
    points = []
    for a, b in segments:
        axis = (b - a) / np.linalg.norm(b - a)
        u = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
        u /= np.linalg.norm(u)
        w = np.cross(axis, u)
        for t in np.linspace(0.1, 0.9, rings):
            for phi in np.linspace(0.0, 2 * np.pi, sides, endpoint=False):
                points.append(a + t * (b - a) + radius * (np.cos(phi) * u + np.sin(phi) * w))
    return np.array(points)


def skinning_matrices(sk, pose_p, pose_q, bind_p, bind_q):
    """Per joint 4x4 transforms taking the bind frame to the posed frame (numpy + scipy)."""
    parents = np.array(sk.parents)
    origin = np.where(parents < 0, 0, parents)
    origin[0] = 0

    def frames(p, q):
        m = np.zeros((len(q), 4, 4))
        m[:, :3, :3] = R.from_quat(q, scalar_first=True).as_matrix()
        m[:, :3, 3] = p[origin]
        m[:, 3, 3] = 1.0
        return m

    return frames(pose_p, pose_q) @ np.linalg.inv(frames(bind_p, bind_q))


def test_the_bind_pose_gives_the_mesh_back(short_walk):
    sk, _ = short_walk
    verts = tubes(sk)
    for method in ("dqs", "lbs"):
        s = skin.Skin(verts, sk, method=method)
        np.testing.assert_allclose(s.deform(np.zeros(sk.stride)), verts, atol=1e-12)
    bvh, bmotion = mocap.read_bvh(DATA / "01_01.bvh")
    pos, ori = bvh.forward_kinematics(np.zeros(bvh.stride))
    segments, _ = skin.bone_segments(bvh, pos, ori)
    verts = segments.mean(axis=1) + 0.5
    s = skin.Skin(verts, bvh)
    np.testing.assert_allclose(s.deform(np.zeros(bvh.stride)), verts, atol=1e-12)
    assert s.deform(bmotion.slice(0, 3)).shape == (3, len(verts), 3)


def test_linear_blend_matches_an_einsum_oracle(short_walk):
    sk, motion = short_walk
    verts = tubes(sk)
    s = skin.Skin(verts, sk, method="lbs")
    assert np.allclose(s.weights.sum(axis=1), 1.0, atol=1e-15)
    bind_p, bind_q = sk.forward_kinematics(np.zeros(sk.stride))
    pos, ori = sk.forward_kinematics(motion)
    ours = s.deform(motion)
    homogeneous = np.c_[verts, np.ones(len(verts))]
    for f in (0, 17, 59):
        m = skinning_matrices(sk, pos[f], ori[f], bind_p, bind_q)
        moved = np.einsum("bij,vj->vbi", m, homogeneous)[..., :3]
        expected = np.einsum(
            "vk,vki->vi", s.weights, moved[np.arange(len(verts))[:, None], s.bones]
        )
        np.testing.assert_allclose(ours[f], expected, atol=1e-9)


def test_one_bone_per_vertex_is_rigid_with_both_methods(short_walk):
    sk, motion = short_walk
    verts = tubes(sk)
    near = skin.Skin(verts, sk, influences=1)
    weights = (near.bones, np.ones_like(near.weights))
    lbs = skin.Skin(verts, sk, weights, method="lbs").deform(motion)
    dqs = skin.Skin(verts, sk, weights, method="dqs").deform(motion)
    np.testing.assert_allclose(lbs, dqs, atol=1e-9)
    # Rigid: distances between vertices of one bone are kept.
    same = np.flatnonzero(near.bones[:, 0] == near.bones[0, 0])
    d0 = np.linalg.norm(verts[same][:, None] - verts[same][None], axis=-1)
    d = np.linalg.norm(dqs[30, same][:, None] - dqs[30, same][None], axis=-1)
    np.testing.assert_allclose(d, d0, atol=1e-9)


def test_a_walk_keeps_the_skin_near_its_bones(short_walk):
    sk, motion = short_walk
    verts = tubes(sk, radius=0.6)
    pos, ori = sk.forward_kinematics(motion)
    # Bind distance 0.6 (file units, ~3.4 cm). One bone per vertex: rigid, exactly kept.
    # Four bones: blending where bones meet moves a vertex by at most 0.25 (~1.4 cm) more;
    # a wrong skinning transform moves vertices by whole bone lengths.
    for influences, bound in ((1, 0.6 + 1e-9), (4, 0.6 + 0.25)):
        out = skin.Skin(verts, sk, influences=influences).deform(motion)
        for f in (0, 20, 40, 59):
            segments, _ = skin.bone_segments(sk, pos[f], ori[f])
            a, ab = segments[:, 0], segments[:, 1] - segments[:, 0]
            along = np.einsum("vsi,si->vs", out[f][:, None] - a[None], ab)
            t = np.clip(along / np.einsum("si,si->s", ab, ab), 0.0, 1.0)
            closest = a[None] + t[..., None] * ab[None]
            distance = np.linalg.norm(out[f][:, None] - closest, axis=-1).min(axis=1)
            assert distance.max() < bound, f"{influences} bones, frame {f}: {distance.max()}"


def test_pickling_keeps_the_skin(short_walk):
    sk, motion = short_walk
    s = skin.Skin(tubes(sk), sk)
    back = pickle.loads(pickle.dumps(s._skin))
    pos, ori = sk.forward_kinematics(motion)
    args = (pos.reshape(-1, 3), ori.reshape(-1, 4), "dqs")
    np.testing.assert_array_equal(back.deform(*args), s._skin.deform(*args))


def test_bad_arguments_name_the_argument(short_walk):
    sk, _ = short_walk
    verts = tubes(sk)
    with pytest.raises(ValueError, match="method"):
        skin.Skin(verts, sk, method="slerp")
    with pytest.raises(TypeError, match="skeleton"):
        skin.Skin(verts, "skeleton")
    with pytest.raises(ValueError, match="vertices"):
        skin.Skin(np.full((3, 3), np.nan), sk)
    with pytest.raises(ValueError, match="weights"):
        skin.Skin(verts, sk, (np.zeros((len(verts), 2), int), np.ones((len(verts), 3))))
    with pytest.raises(ValueError, match="weights"):
        skin.Skin(verts, sk, (np.full((len(verts), 1), 99), np.ones((len(verts), 1))))
    with pytest.raises(ValueError, match="weights"):
        skin.Skin(verts, sk, (np.zeros((len(verts), 1), int), np.zeros((len(verts), 1))))
    with pytest.raises(ValueError, match="weights"):
        skin.Skin(verts, sk, "heat")  # heat weights need the triangles
    with pytest.raises(ValueError, match="weights"):
        skin.Skin(verts, sk, "nearest")
    with pytest.raises(ValueError, match="influences"):
        skin.Skin(verts, sk, influences=0)
    with pytest.raises(ValueError, match="falloff"):
        skin.Skin(verts, sk, falloff=-1.0)
    with pytest.raises(ValueError, match="triangles"):
        skin.Skin(verts, sk, triangles=[[0, 1, len(verts)]])
    with pytest.raises(ValueError, match="motion"):
        skin.Skin(verts, sk).deform(np.zeros(3))
