"""glTF export read back with pygltflib (parsing) and trimesh (loading), the skin, animation
and morph targets evaluated here with numpy: frame k's vertices agree with kinema's within
1e-5 m; the joint hierarchy; accessor bounds; normalised weights."""

from __future__ import annotations

import copy

import numpy as np
import pytest

pygltflib = pytest.importorskip("pygltflib")
trimesh = pytest.importorskip("trimesh")

from scipy.spatial.transform import Rotation as R  # noqa: E402

from kinema import io, skin  # noqa: E402

DTYPES = {5126: np.float32, 5123: np.uint16, 5125: np.uint32, 5121: np.uint8}
WIDTH = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}


def read(doc, index):
    """Accessor ``index`` of ``doc`` as a numpy array ``(count, width)``."""
    a = doc.accessors[index]
    view = doc.bufferViews[a.bufferView]
    blob = doc.binary_blob()
    start = (view.byteOffset or 0) + (a.byteOffset or 0)
    n = a.count * WIDTH[a.type]
    return np.frombuffer(blob, DTYPES[a.componentType], n, start).reshape(a.count, WIDTH[a.type])


def trs(t, q):
    m = np.eye(4)
    m[:3, :3] = R.from_quat(q).as_matrix()  # glTF (x, y, z, w)
    m[:3, 3] = t
    return m


def sample(doc, animation, node, path, k):
    """The value of ``node``'s ``path`` channel at key ``k`` (None without one)."""
    for c in animation.channels:
        if c.target.node == node and c.target.path == path:
            return read(doc, animation.samplers[c.sampler].output)[k].astype(np.float64)
    return None


@pytest.fixture(scope="module")
def skinned_walk(walk):
    sk, motion = walk
    return sk, motion.slice(0, 40), skin.body_mesh(sk, 1.0, cell=0.4)


def world_matrices(doc, animation, k):
    """Every node's world matrix at key ``k`` of ``animation``."""
    parent = {c: i for i, n in enumerate(doc.nodes) for c in n.children}
    out = {}

    def world(i):
        if i not in out:
            n = doc.nodes[i]
            t = sample(doc, animation, i, "translation", k)
            q = sample(doc, animation, i, "rotation", k)
            local = trs(
                n.translation if t is None else t, (n.rotation or [0, 0, 0, 1]) if q is None else q
            )
            out[i] = local if i not in parent else world(parent[i]) @ local
        return out[i]

    for i in range(len(doc.nodes)):
        world(i)
    return out


def test_a_skinned_walk_round_trips(skinned_walk, tmp_path):
    sk, motion, body = skinned_walk
    path = tmp_path / "walk.glb"
    io.write_glb(path, skins=[(body, motion)])
    doc = pygltflib.GLTF2().load(str(path))
    (gskin,) = doc.skins
    # The joint hierarchy: names and parents of the skeleton.
    names = [doc.nodes[j].name for j in gskin.joints]
    assert names == list(sk.joint_names)
    parent = {c: i for i, n in enumerate(doc.nodes) for c in n.children}
    parents = [gskin.joints.index(parent[j]) if j in parent else -1 for j in gskin.joints]
    assert parents == list(sk.parents)
    # Frame k from the file: world joint matrices times inverse bind, blended linearly.
    mesh_node = next(n for n in doc.nodes if n.skin == 0)
    prim = doc.meshes[mesh_node.mesh].primitives[0]
    rest = read(doc, prim.attributes.POSITION).astype(np.float64)
    joints = read(doc, prim.attributes.JOINTS_0).astype(np.int64)
    weights = read(doc, prim.attributes.WEIGHTS_0).astype(np.float64)
    ibm = read(doc, gskin.inverseBindMatrices).reshape(-1, 4, 4).transpose(0, 2, 1)
    (animation,) = doc.animations
    times = read(doc, animation.samplers[0].input)[:, 0]
    assert np.allclose(times, np.arange(motion.frames) / motion.frame_rate)
    lbs = copy.copy(body)  # glTF skinning is linear blend skinning
    lbs.method = "lbs"
    expected = lbs.deform(motion) * sk.metres_per_unit
    for k in (0, 17, motion.frames - 1):
        g = world_matrices(doc, animation, k)
        m = np.stack([g[j] for j in gskin.joints]) @ ibm
        homogeneous = np.c_[rest, np.ones(len(rest))]
        per_bone = np.einsum(
            "vij,vj->vi", m[joints].reshape(-1, 4, 4), np.repeat(homogeneous, 4, axis=0)
        )
        got = np.einsum("vc,vci->vi", weights, per_bone.reshape(len(rest), 4, 4))[:, :3]
        assert np.abs(got - expected[k]).max() < 1e-5
    # Validator rules: bounds of every accessor, weights summing to 1, unit rotations.
    for i, a in enumerate(doc.accessors):
        data = read(doc, i)
        assert a.min == pytest.approx(data.min(axis=0).tolist(), abs=0)
        assert a.max == pytest.approx(data.max(axis=0).tolist(), abs=0)
    assert np.abs(weights.astype(np.float32).sum(axis=1, dtype=np.float32) - 1).max() <= 2e-7 * 4
    # An independent loader sees the bind-pose mesh.
    scene = trimesh.load(path, process=False)
    (loaded,) = scene.geometry.values()
    assert np.allclose(np.asarray(loaded.vertices), rest, atol=1e-6)


def test_rigid_tracks_and_mesh_sequences_round_trip(tmp_path):
    times = np.arange(5) / 10.0
    rot = R.from_rotvec(np.outer(times, [0.0, 2.0, 1.0]))
    x = np.c_[times, times**2, -times]
    body = io.RigidTrack(np.eye(3), [[0, 1, 2]], times, x, rot.as_quat(scalar_first=True))
    frames = np.random.default_rng(1).normal(size=(5, 4, 3))
    cloth = io.MeshSequence([[0, 1, 2], [0, 2, 3]], times, frames)
    path = tmp_path / "scene.glb"
    io.write_glb(path, rigid=[body], sequences=[cloth])
    doc = pygltflib.GLTF2().load(str(path))
    rigid, seq = doc.animations
    node = rigid.channels[0].target.node
    for k in range(5):
        g = world_matrices(doc, rigid, k)[node]
        assert np.allclose(g[:3, 3], x[k], atol=1e-6)
        assert np.allclose(g[:3, :3], rot[k].as_matrix(), atol=1e-6)
    prim = doc.meshes[doc.nodes[seq.channels[0].target.node].mesh].primitives[0]
    base = read(doc, prim.attributes.POSITION).astype(np.float64)
    targets = np.stack([read(doc, t["POSITION"]) for t in prim.targets]).astype(np.float64)
    w = read(doc, seq.samplers[0].output).reshape(5, 5)
    for k in range(5):
        assert np.abs(base + np.einsum("t,tvi->vi", w[k], targets) - frames[k]).max() < 1e-5


def test_bad_input_names_the_argument(tmp_path):
    with pytest.raises(ValueError, match="times"):
        io.write_glb(
            tmp_path / "x.glb",
            sequences=[io.MeshSequence([[0, 1, 2]], [0.0, 0.0], np.zeros((2, 3, 3)))],
        )
    with pytest.raises(ValueError, match="frames"):
        io.write_glb(
            tmp_path / "x.glb", sequences=[io.MeshSequence([[0, 1, 2]], [0.0], np.zeros(3))]
        )
