"""The procedural body of a CMU skeleton: closed and manifold, the capsules' volume (Monte
Carlo), a walk that keeps every vertex near its bone, and heat weights that stretch the
surface less than proximity weights."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from kinema import mocap, skin

DATA = Path(__file__).resolve().parents[1] / "data" / "mocap"
RADIUS = 1.0  # file units (5.6 cm)


@pytest.fixture(scope="module")
def body():
    sk = mocap.read_asf(DATA / "07-walk.asf")
    return sk, skin.body_mesh(sk, RADIUS, blend=0.0, cell=0.3)


def volume(v, t):
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def segment_distance(points, a, b):
    """Distance of every point ``(N, 3)`` to every segment ``(S,)`` ``a``–``b``: ``(N, S)``."""
    d = b - a
    l2 = np.maximum(np.einsum("sj,sj->s", d, d), 1e-300)
    t = np.clip(np.einsum("nsj,sj->ns", points[:, None] - a, d) / l2, 0.0, 1.0)
    return np.linalg.norm(points[:, None] - (a + t[..., None] * d), axis=2)


def test_the_body_is_closed_manifold_and_faces_out(body):
    _, s = body
    t = s.triangles
    undirected = Counter(
        tuple(sorted(e))
        for tri in t
        for e in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0]))
    )
    directed = Counter(
        (a, b) for tri in t for a, b in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0]))
    )
    assert set(undirected.values()) == {2}
    assert set(directed.values()) == {1}
    assert volume(s.vertices, t) > 0
    assert np.allclose(s.weights.sum(axis=1), 1.0)


def test_the_volume_is_the_union_of_the_capsules(body):
    """Monte Carlo over each capsule's bounding box: ``|union| = Σ_i |box_i| E[1_i(x) / m(x)]``
    with ``m(x)`` the number of capsules holding ``x`` (each point of the union counted once)."""
    sk, s = body
    segments, _ = skin.bone_segments(sk, *sk.forward_kinematics(np.zeros(sk.stride)))
    a, b = segments[:, 0], segments[:, 1]
    rng = np.random.default_rng(7)
    union = 0.0
    for i in range(len(segments)):
        lo = np.minimum(a[i], b[i]) - RADIUS
        hi = np.maximum(a[i], b[i]) + RADIUS
        x = lo + (hi - lo) * rng.random((4000, 3))
        inside = segment_distance(x, a, b) < RADIUS
        share = np.where(inside[:, i], 1.0 / np.maximum(inside.sum(axis=1), 1), 0.0)
        union += np.prod(hi - lo) * share.mean()
    assert volume(s.vertices, s.triangles) == pytest.approx(union, rel=0.03)


def bone_distance(sk, points, main, positions, orientations):
    """Each point's distance to the segments of its bone ``main`` at one pose."""
    seg, own = skin.bone_segments(sk, positions, orientations)
    own = np.array(own)
    out = np.full(len(points), np.inf)
    for b in np.unique(main):
        mine = main == b
        d = segment_distance(points[mine], seg[own == b, 0], seg[own == b, 1])
        out[mine] = d.min(axis=1)
    return out


def test_a_walk_keeps_every_vertex_near_its_bone(body):
    """Every vertex stays within its bind-time distance of its most weighted bone, plus half
    the radius, over the whole CMU walk (DQS, four influences)."""
    sk, s = body
    motion = mocap.read_amc(DATA / "07_05-walk.amc", sk)
    frames = s.deform(motion)
    positions, orientations = sk.forward_kinematics(motion)
    main = s.bones[np.arange(len(s.vertices)), np.argmax(s.weights, axis=1)]
    rest = bone_distance(sk, s.vertices, main, *sk.forward_kinematics(np.zeros(sk.stride)))
    worst = max(
        float((bone_distance(sk, frames[f], main, positions[f], orientations[f]) - rest).max())
        for f in range(0, motion.frames, 7)
    )
    assert np.isfinite(rest).all()
    assert worst < 0.5 * RADIUS, worst


def largest_edge_stretch(body, motion):
    """The largest length of any edge of the skinned surface over every third frame of
    ``motion``, relative to its length in the bind pose."""
    t = body.triangles
    edges = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    rest = np.linalg.norm(body.vertices[edges[:, 0]] - body.vertices[edges[:, 1]], axis=1)
    worst = 0.0
    for i in range(0, motion.frames, 3):
        v = body.deform(motion.pose(i))
        length = np.linalg.norm(v[edges[:, 0]] - v[edges[:, 1]], axis=1)
        worst = max(worst, float((length / rest).max()))
    return worst


def test_heat_weights_stretch_the_walking_body_less_than_proximity():
    """Over the CMU walk (DQS, four influences) no edge of the heat-weighted body stretches to
    more than twice its length (measured 1.80; 7.25 when the four largest weights are cut off
    without subtracting the fifth), where proximity weights stretch one to 3.39."""
    sk = mocap.read_asf(DATA / "07-walk.asf")
    motion = mocap.read_amc(DATA / "07_05-walk.amc", sk)
    heat = largest_edge_stretch(skin.body_mesh(sk, RADIUS, cell=0.4), motion)
    near = largest_edge_stretch(skin.body_mesh(sk, RADIUS, cell=0.4, weights="proximity"), motion)
    assert heat < 2.0, heat
    assert heat < 0.6 * near, (heat, near)


def test_bad_arguments_name_themselves():
    sk = mocap.read_asf(DATA / "07-walk.asf")
    for kwargs, name in (
        ({"radius": -1.0}, "radius"),
        ({"radius": [1.0, 2.0]}, "radius"),
        ({"radius": 1.0, "blend": float("nan")}, "blend"),
        ({"radius": 1.0, "cell": 0.0}, "cell"),
        ({"radius": 1.0, "cell": 1e-4}, "cell"),
    ):
        with pytest.raises(ValueError, match=name):
            skin.body_mesh(sk, **kwargs)
