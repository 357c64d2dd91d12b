"""Scene.export and the viewer's frames of articulated characters: a limp ragdoll falling onto
a box and a tilted plane (its colliders), and a tracker following a CMU walk, recorded for a
few frames, written as glTF and USD and read back with pygltflib and pxr. Every body's node
transform is the body's frame the test saw after that frame (within 1e-6), its mesh is its
capsule (every vertex at the radius from the capsule's axis), and the colliders are drawn
where they are; the viewer (kinema.io.playback) draws the same capsules in world space."""

from __future__ import annotations

import importlib

import numpy as np
import pytest

pygltflib = pytest.importorskip("pygltflib")
pxr = pytest.importorskip("pxr")
importlib.import_module("pxr.UsdGeom")

from scipy.spatial.transform import Rotation  # noqa: E402
from test_io_gltf import read, world_matrices  # noqa: E402

from kinema import character, geometry, mocap  # noqa: E402
from kinema import rotation as krot  # noqa: E402
from kinema.scene import Scene  # noqa: E402

FRAMES = 4
BOX = geometry.Box((0.3, 0.1, 0.0), (0.2, 0.1, 0.3), krot.Rotation.from_rotvec([0.0, 0.4, 0.0]))
PLANE = geometry.Plane((0.0, 0.02, 0.0), (0.1, 1.0, 0.0))


def _frame(state):
    """The 4x4 matrix of a body frame ``(x, y, z, w, qx, qy, qz)``, computed with scipy."""
    m = np.eye(4)
    m[:3, :3] = Rotation.from_quat(state[3:], scalar_first=True).as_matrix()
    m[:3, 3] = state[:3]
    return m


def _segment_distance(v, a, b):
    """Distances of the points ``v`` (N, 3) from the segment ``a``–``b``."""
    ab = b - a
    t = np.clip((v - a) @ ab / max(ab @ ab, 1e-300), 0.0, 1.0)
    return np.linalg.norm(v - (a + t[:, None] * ab), axis=1)


@pytest.fixture(scope="module")
def recorded():
    sk = mocap.read_asf(mocap.SAMPLE_DIR / "07-walk.asf")
    walk = mocap.read_amc(mocap.SAMPLE_DIR / "07_05-walk.amc", sk)
    falling = Scene(dt=1 / 60, substeps=8)  # the ragdoll's explicit steps of 1/480 s
    ragdoll = falling.add(character.Ragdoll.from_skeleton(sk, clearance=0.2))
    ragdoll.add_collider(BOX)
    ragdoll.add_collider(PLANE)
    tracking = Scene(dt=1 / 120)  # one clip frame a step
    tracker = tracking.add(character.Tracker(sk, walk))
    seen: dict[str, list] = {"ragdoll": [], "tracker": []}
    for scene, body, key in ((falling, ragdoll, "ragdoll"), (tracking, tracker, "tracker")):
        scene.record("animation")

        def look(s, body=body, key=key):
            seen[key].append(np.c_[body.positions(), body.orientations()])

        scene.run(frames=FRAMES, progress=False, on_frame=look)
    return {"ragdoll": (falling, ragdoll), "tracker": (tracking, tracker)}, seen


@pytest.mark.parametrize("key", ["ragdoll", "tracker"])
def test_bodies_and_colliders_round_trip_through_glb(recorded, key, tmp_path):
    scenes, seen = recorded
    scene, body = scenes[key]
    path = tmp_path / "character.glb"
    scene.export(path)
    doc = pygltflib.GLTF2().load(str(path))
    capsules = body.capsules()
    assert all(c is not None for c in capsules)
    for b, (name, (a, tip, r)) in enumerate(zip(body.names, capsules, strict=True)):
        anim = next(x for x in doc.animations if x.name == f"ragdoll0_{b}_{name}")
        node = anim.channels[0].target.node
        for k in range(FRAMES):
            np.testing.assert_allclose(
                world_matrices(doc, anim, k)[node], _frame(seen[key][k][b]), atol=1e-6
            )
        mesh = doc.meshes[doc.nodes[node].mesh].primitives[0]
        v = read(doc, mesh.attributes.POSITION).astype(np.float64)
        np.testing.assert_allclose(_segment_distance(v, a, tip), r, atol=1e-6)
    colliders = [x for x in doc.animations if "collider" in x.name]
    assert len(colliders) == (2 if key == "ragdoll" else 0)
    if key == "ragdoll":
        box, plane = colliders
        node = box.channels[0].target.node
        m = world_matrices(doc, box, FRAMES - 1)[node]
        np.testing.assert_allclose(m[:3, 3], BOX.center, atol=1e-7)
        np.testing.assert_allclose(m[:3, :3], BOX.orientation.as_matrix(), atol=1e-7)
        v = read(doc, doc.meshes[doc.nodes[node].mesh].primitives[0].attributes.POSITION)
        np.testing.assert_allclose(np.abs(v), np.broadcast_to(BOX.half_extents, v.shape), 1e-7)
        node = plane.channels[0].target.node
        m = world_matrices(doc, plane, 0)[node]
        normal = np.array(PLANE.normal) / np.linalg.norm(PLANE.normal)
        np.testing.assert_allclose(m[:3, 1], normal, atol=1e-7)  # the square's +Y
        np.testing.assert_allclose(m[:3, 3], PLANE.point, atol=1e-7)


@pytest.mark.parametrize("key", ["ragdoll", "tracker"])
def test_bodies_round_trip_through_usd(recorded, key, tmp_path):
    scenes, seen = recorded
    scene, body = scenes[key]
    path = tmp_path / "character.usda"
    scene.export(path)
    stage = pxr.Usd.Stage.Open(str(path))
    for b in range(len(body.names)):
        link = pxr.UsdGeom.Xformable(stage.GetPrimAtPath(f"/kinema/body{b}"))
        for k in range(FRAMES):
            m = np.array(link.ComputeLocalToWorldTransform(k + 1.0)).T
            np.testing.assert_allclose(m, _frame(seen[key][k][b]), atol=1e-6)


@pytest.mark.parametrize("key", ["ragdoll", "tracker"])
def test_the_viewer_draws_the_capsules_where_the_bodies_are(recorded, key):
    """kinema.io.playback's frames of the scene (what the viewer draws): every vertex of
    body ``b``'s mesh at frame ``k`` is at the capsule's radius from its axis, the axis put in
    the world by the body's frame the test saw; the box collider's vertices are its corners."""
    from kinema.io.playback import scene_frames

    scenes, seen = recorded
    scene, body = scenes[key]
    times, drawn = scene_frames(scene)
    assert len(times) == FRAMES
    for b, (name, (a, tip, r)) in enumerate(zip(body.names, body.capsules(), strict=True)):
        d = drawn[f"ragdoll0_{b}_{name}"]
        assert d.kind == "mesh"
        for k in range(FRAMES):
            x, q = seen[key][k][b, :3], seen[key][k][b, 3:]
            turn = Rotation.from_quat(q, scalar_first=True)
            v = d.frames[k][0]
            np.testing.assert_allclose(
                _segment_distance(v, x + turn.apply(a), x + turn.apply(tip)), r, atol=1e-9
            )
    if key == "ragdoll":
        v = drawn["ragdoll0_collider0"].frames[-1][0]
        local = BOX.orientation.inv().apply(v - BOX.center)
        np.testing.assert_allclose(np.abs(local), np.broadcast_to(BOX.half_extents, v.shape), 1e-9)


@pytest.mark.parametrize("key", ["ragdoll", "tracker"])
def test_obj_frames_and_pictures_draw_the_capsules(recorded, key, tmp_path):
    """``Scene.export_obj`` (and ``kinema.plot``, from the same ``kinema._geometry.of_scene``)
    draw every body's capsule at the body's current frame, and a ragdoll's colliders."""
    from kinema import _geometry

    scenes, _ = recorded
    scene, body = scenes[key]
    meshes = _geometry.of_scene(scene).meshes
    x, q = body.positions(), body.orientations()
    for b, (name, (a, tip, r)) in enumerate(zip(body.names, body.capsules(), strict=True)):
        v, _ = meshes[f"ragdoll0_{b}_{name}"]
        turn = Rotation.from_quat(q[b], scalar_first=True)
        ends = x[b] + turn.apply(a), x[b] + turn.apply(tip)
        np.testing.assert_allclose(_segment_distance(v, *ends), r, atol=1e-9)
    colliders = [n for n in meshes if "collider" in n]
    assert colliders == (["ragdoll0_collider0", "ragdoll0_collider1"] if key == "ragdoll" else [])
    path = scene.export_obj(tmp_path)
    objects = [line for line in path.read_text().splitlines() if line.startswith("o ")]
    assert len(objects) == len(meshes)
