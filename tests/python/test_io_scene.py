"""Scene.export: a recorded scene (cloth, rigid bodies, an animated sphere) written as glTF and
USD, read back with pygltflib and pxr: each frame's cloth vertices and bodies' transforms are
the ones recorded (positions and rotations of the bodies within 1e-6)."""

from __future__ import annotations

import importlib

import numpy as np
import pytest

pygltflib = pytest.importorskip("pygltflib")
pxr = pytest.importorskip("pxr")
importlib.import_module("pxr.UsdSkel")

from test_io_gltf import read, world_matrices  # noqa: E402

from kinema import anim, cloth, rigid  # noqa: E402
from kinema.scene import AnimatedSphere, Scene  # noqa: E402


@pytest.fixture(scope="module")
def recorded():
    scene = Scene(dt=1 / 30)
    c = cloth.Cloth.grid(5, 5, 0.5, 0.5)
    c.set_state(c.positions + np.array([0.0, 1.0, 0.0]))
    scene.add(c)
    world = rigid.World()
    world.add_ground()
    world.add_body(
        rigid.Box([0.1, 0.2, 0.3]),
        mass=1.0,
        position=(0.5, 0.5, 0.0),
        angular_velocity=(1.0, 2.0, 3.0),  # tumbling: every frame has its own rotation
    )
    scene.add(world)
    path = anim.Track([0.0, 1.0], [[0.0, 0.4, 0.0], [0.2, 0.5, 0.1]])
    scene.add(AnimatedSphere(0.2, path))
    scene.record("animation")
    scene.record("cloth", lambda: c.positions)
    scene.record("box", lambda: np.r_[world.positions[0], world.orientations[0]])
    scene.run(frames=6, progress=False)
    return scene


def _rotation(q):
    """The rotation matrix of ``(w, x, y, z)``, by scipy."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_quat(q, scalar_first=True).as_matrix()


def test_the_glb_holds_what_the_scene_recorded(recorded, tmp_path):
    path = tmp_path / "scene.glb"
    recorded.export(path)
    doc = pygltflib.GLTF2().load(str(path))
    names = [a.name for a in doc.animations]
    assert names == ["body1_0", "sphere2", "cloth0"]
    box, cloth_anim = doc.animations[0], doc.animations[2]
    times = read(doc, box.samplers[0].input)[:, 0]
    assert np.allclose(times, np.arange(1, 7) / 30, atol=1e-6)
    prim = doc.meshes[doc.nodes[cloth_anim.channels[0].target.node].mesh].primitives[0]
    base = read(doc, prim.attributes.POSITION).astype(np.float64)
    targets = np.stack([read(doc, t["POSITION"]) for t in prim.targets]).astype(np.float64)
    w = read(doc, cloth_anim.samplers[0].output).reshape(6, 6)
    node = box.channels[0].target.node
    for k in range(6):
        got = base + np.einsum("t,tvi->vi", w[k], targets)
        assert np.abs(got - recorded.records["cloth"][k]).max() < 1e-5
        g = world_matrices(doc, box, k)[node]  # the node's transform of frame k
        assert np.abs(g[:3, 3] - recorded.records["box"][k][:3]).max() < 1e-6
        assert np.abs(g[:3, :3] - _rotation(recorded.records["box"][k][3:])).max() < 1e-6


def test_the_usd_holds_what_the_scene_recorded(recorded, tmp_path):
    path = tmp_path / "scene.usda"
    recorded.export(path)
    stage = pxr.Usd.Stage.Open(str(path))
    assert stage.GetTimeCodesPerSecond() == pytest.approx(30.0)
    points = pxr.UsdGeom.Mesh(stage.GetPrimAtPath("/kinema/mesh0")).GetPointsAttr()
    xform = pxr.UsdGeom.Xformable(
        stage.GetPrimAtPath("/kinema/body0")
    )  # the first rigid track: the box
    for k in range(6):
        code = k + 1.0
        assert np.abs(np.array(points.Get(code)) - recorded.records["cloth"][k]).max() < 1e-5
        m = np.array(xform.ComputeLocalToWorldTransform(code)).T
        assert np.abs(m[:3, 3] - recorded.records["box"][k][:3]).max() < 1e-6
        assert np.abs(m[:3, :3] - _rotation(recorded.records["box"][k][3:])).max() < 1e-6


def test_export_needs_a_recording_and_a_known_format(tmp_path):
    scene = Scene()
    with pytest.raises(ValueError, match="scene"):
        scene.export(tmp_path / "x.glb")
    with pytest.raises(ValueError, match="path"):
        scene.export(tmp_path / "x.obj")
