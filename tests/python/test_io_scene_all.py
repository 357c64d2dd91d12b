"""Scene.export of every system: particles (born and dying), a fluid and its surface, a rod,
hair, a crowd, a flock, a motion-captured character and a biped, recorded for a few frames,
written as glTF and USD and read back with pygltflib and pxr. Each frame's points, polylines,
meshes and rigid frames (the biped's links, as node transforms within 1e-6), evaluated in the test from the file (morph targets, the STEP visibility of
per-frame nodes, USD time samples), are the ones the test saw after that frame."""

from __future__ import annotations

import importlib
from pathlib import Path

import numpy as np
import pytest

pygltflib = pytest.importorskip("pygltflib")
pxr = pytest.importorskip("pxr")
importlib.import_module("pxr.UsdGeom")

from scipy.spatial.transform import Rotation  # noqa: E402
from test_io_gltf import read, world_matrices  # noqa: E402

import kinema  # noqa: E402
from kinema import character, mocap, particles  # noqa: E402
from kinema.crowd import Crowd  # noqa: E402
from kinema.flock import Flock  # noqa: E402
from kinema.fluid import Fluid  # noqa: E402
from kinema.rods import Rod, groom, sphere_cap  # noqa: E402
from kinema.scene import Character, Scene  # noqa: E402

DATA = Path(kinema.__file__).parent / "data"
FRAMES = 5


@pytest.fixture(scope="module")
def recorded():
    scene = Scene(dt=1 / 100, substeps=100)  # the biped needs steps of 0.1 ms
    ps = particles.ParticleSystem(np.zeros((0, 3)), capacity=200)
    ps.add(particles.Emitter(rate=300, velocity=[0, 2, 0], lifespan=0.1, seed=3))
    ps.add(particles.Gravity())
    scene.add(ps)
    fl = Fluid(spacing=0.05)
    fl.add_boundary_box([0, 0, 0], [0.4, 0.4, 0.2])
    fl.add_block([0, 0, 0], [0.15, 0.2, 0.15])
    scene.add(fl)
    rod = scene.add(Rod.straight(6, 0.5, origin=(1.0, 1.0, 0.0)))
    points, normals = sphere_cap(4, radius=0.1, angle=1.0)
    hair = scene.add(groom(points, normals, length=0.05, segments=4))
    crowd = Crowd("orca", radius=0.25)
    crowd.add_agents([[0.0, 0.0], [2.0, 0.0]], [[2.0, 1.0], [0.0, 1.0]])
    scene.add(crowd)
    flock = scene.add(Flock([[0.0, 0.0], [1.0, 0.0]], [[1.0, 0.0], [1.0, 0.5]]))
    biped = scene.add(character.Biped())
    skel = mocap.read_asf(DATA / "07-walk.asf")
    walker = Character(skel, mocap.read_amc(DATA / "07_05-walk.amc", skel), radius=0.05)
    scene.add(walker)
    scene.record("animation")
    seen: dict[str, list] = {k: [] for k in ("ps", "fl", "surf", "rod", "hair", "crowd")}
    seen.update({k: [] for k in ("flock", "biped", "joints")})

    def look(s: Scene) -> None:
        seen["ps"].append(ps.positions[ps.alive].copy())
        seen["fl"].append(np.array(fl.positions))
        seen["surf"].append(fl.surface_mesh())
        seen["rod"].append(np.array(rod.positions))
        seen["hair"].append(np.array(hair.positions).reshape(-1, 3))
        seen["crowd"].append(np.c_[crowd.positions[:, 0], np.zeros(2), crowd.positions[:, 1]])
        seen["flock"].append(np.c_[flock.positions, np.zeros(2)])
        seen["biped"].append(np.c_[biped.positions(), biped.orientations()])
        seen["joints"].append(walker.joints(s.time))

    scene.run(frames=FRAMES, progress=False, on_frame=look)
    sizes = {len(p) for p in seen["ps"]}
    assert len(sizes) > 1, "the particles' count should change while recording"
    return scene, seen, walker


def _frame(state):
    """The 4x4 matrix of a body frame ``(x, y, z, w, qx, qy, qz)`` (kinema's quaternion order),
    computed with scipy."""
    m = np.eye(4)
    m[:3, :3] = Rotation.from_quat(state[3:], scalar_first=True).as_matrix()
    m[:3, 3] = state[:3]
    return m


def _morphed(doc, name):
    """The frames of the morph-target node ``name``: base + weights · targets at every key,
    the primitive's mode and indices."""
    anim = next(a for a in doc.animations if a.name == name)
    node = doc.nodes[anim.channels[0].target.node]
    prim = doc.meshes[node.mesh].primitives[0]
    base = read(doc, prim.attributes.POSITION).astype(np.float64)
    targets = np.stack([read(doc, t["POSITION"]) for t in prim.targets]).astype(np.float64)
    w = read(doc, anim.samplers[0].output).reshape(len(targets), -1)
    frames = base + np.einsum("kt,tvi->kvi", w, targets)
    indices = None if prim.indices is None else read(doc, prim.indices).ravel()
    return frames, prim.mode, indices


def _shown(doc, name, time):
    """The child of the frame node ``name`` whose STEP ``scale`` key at ``time`` is 1 (exactly
    one must be), as ``(positions, indices)``; positions empty for a node without a mesh."""
    anim = next(a for a in doc.animations if a.name == name)
    visible = []
    for c in anim.channels:
        keys = read(doc, anim.samplers[c.sampler].input)[:, 0]
        values = read(doc, anim.samplers[c.sampler].output)
        at = max(int(np.searchsorted(keys, time + 1e-7, side="right")) - 1, 0)  # STEP
        if values[at, 0] == 1.0:
            visible.append(c.target.node)
        else:
            assert np.all(values[at] == 0.0)
    assert len(visible) == 1, f"{name}: {len(visible)} frames shown at {time}"
    node = doc.nodes[visible[0]]
    if node.mesh is None:
        return np.zeros((0, 3)), None
    prim = doc.meshes[node.mesh].primitives[0]
    indices = None if prim.indices is None else read(doc, prim.indices).ravel()
    return read(doc, prim.attributes.POSITION).astype(np.float64), indices


def test_every_system_round_trips_through_glb(recorded, tmp_path):
    scene, seen, walker = recorded
    path = tmp_path / "all.glb"
    scene.export(path)
    doc = pygltflib.GLTF2().load(str(path))
    times = scene.records["animation"][:, 0]
    for name, key in (("rods2", "rod"), ("rods3", "hair"), ("agents4", "crowd")):
        frames, mode, indices = _morphed(doc, name)
        np.testing.assert_allclose(frames, np.array(seen[key]), atol=1e-5)
        assert mode == (pygltflib.LINES if key != "crowd" else pygltflib.POINTS)
    _, _, indices = _morphed(doc, "rods3")  # four strands of five vertices, end to end
    pairs = indices.reshape(-1, 2)
    assert len(pairs) == 16 and np.all(pairs[:, 1] == pairs[:, 0] + 1)
    assert not np.any(pairs[:, 1] % 5 == 0)
    frames, _, _ = _morphed(doc, "agents5")
    np.testing.assert_allclose(frames, np.array(seen["flock"]), atol=1e-5)
    for b, name in enumerate(character.Biped().names):  # each link a node moved rigidly
        anim = next(a for a in doc.animations if a.name == f"biped6_{name}")
        node = anim.channels[0].target.node
        for k in range(FRAMES):
            np.testing.assert_allclose(
                world_matrices(doc, anim, k)[node], _frame(seen["biped"][k][b]), atol=1e-6
            )
        box = doc.meshes[doc.nodes[node].mesh].primitives[0]
        v = read(doc, box.attributes.POSITION).astype(np.float64)
        centre, half = character.Biped().link_boxes()[b]
        np.testing.assert_allclose(v.min(axis=0), centre - half, atol=1e-7)
        np.testing.assert_allclose(v.max(axis=0), centre + half, atol=1e-7)
    frames, _, indices = _morphed(doc, "character7")
    bones = walker._bones.reshape(-1)
    np.testing.assert_allclose(frames, np.array(seen["joints"])[:, bones], atol=1e-5)
    for k, t in enumerate(times):
        points, indices = _shown(doc, "particles0", t)
        assert indices is None and len(points) == len(seen["ps"][k])
        np.testing.assert_allclose(points, seen["ps"][k], atol=1e-5)
        points, _ = _shown(doc, "fluid1", t)
        np.testing.assert_allclose(points, seen["fl"][k], atol=1e-5)
        v, tri = _shown(doc, "fluid1_surface", t)
        np.testing.assert_allclose(v, seen["surf"][k][0], atol=1e-5)
        assert np.array_equal(tri, np.asarray(seen["surf"][k][1]).ravel())
    for a in doc.accessors:  # the validator's bounds rule, on every accessor
        data = read(doc, doc.accessors.index(a))
        assert a.count >= 1
        if a.min is not None:
            np.testing.assert_array_equal(data.min(axis=0), np.array(a.min, data.dtype))
            np.testing.assert_array_equal(data.max(axis=0), np.array(a.max, data.dtype))


def test_every_system_round_trips_through_usd(recorded, tmp_path):
    scene, seen, walker = recorded
    path = tmp_path / "all.usda"
    scene.export(path)
    stage = pxr.Usd.Stage.Open(str(path))
    geom = pxr.UsdGeom
    ps = geom.Points(stage.GetPrimAtPath("/kinema/frames0"))
    fl = geom.Points(stage.GetPrimAtPath("/kinema/frames1"))
    surface = geom.Mesh(stage.GetPrimAtPath("/kinema/frames2"))
    rod = geom.BasisCurves(stage.GetPrimAtPath("/kinema/mesh0"))
    hair = geom.BasisCurves(stage.GetPrimAtPath("/kinema/mesh1"))
    crowd = geom.Points(stage.GetPrimAtPath("/kinema/mesh2"))
    bones = geom.BasisCurves(stage.GetPrimAtPath("/kinema/mesh4"))
    links = [geom.Xformable(stage.GetPrimAtPath(f"/kinema/body{b}")) for b in range(7)]
    assert list(hair.GetCurveVertexCountsAttr().Get()) == [5] * 4
    assert hair.GetTypeAttr().Get() == geom.Tokens.linear
    assert list(bones.GetCurveVertexCountsAttr().Get()) == [2] * len(walker._bones)
    for k in range(FRAMES):
        code = k + 1.0  # time codes are frames: the state after frame k

        def at(prim, code=code):
            return np.array(prim.GetPointsAttr().Get(code), dtype=np.float64).reshape(-1, 3)

        np.testing.assert_allclose(at(ps), seen["ps"][k].reshape(-1, 3), atol=1e-5)
        np.testing.assert_allclose(at(fl), seen["fl"][k], atol=1e-5)
        np.testing.assert_allclose(at(surface), seen["surf"][k][0], atol=1e-5)
        tri = np.array(surface.GetFaceVertexIndicesAttr().Get(code))
        assert np.array_equal(tri, np.asarray(seen["surf"][k][1]).ravel())
        np.testing.assert_allclose(at(rod), seen["rod"][k], atol=1e-5)
        np.testing.assert_allclose(at(hair), seen["hair"][k], atol=1e-5)
        np.testing.assert_allclose(at(crowd), seen["crowd"][k], atol=1e-5)
        joints = np.array(seen["joints"][k])[walker._bones.reshape(-1)]
        np.testing.assert_allclose(at(bones), joints, atol=1e-5)
        for b, link in enumerate(links):
            m = np.array(link.ComputeLocalToWorldTransform(code)).T
            np.testing.assert_allclose(m, _frame(seen["biped"][k][b]), atol=1e-6)


def test_the_glb_plays_back_every_system_frame_by_frame(recorded, tmp_path):
    """kinema.io.playback evaluates the file as a glTF viewer would (what ``kinema view
    out.glb`` draws): every frame of every system is the recorded one, the per-frame nodes of
    the particles hidden except at their own frame."""
    from kinema.io.playback import glb_frames

    scene, seen, _ = recorded
    path = tmp_path / "all.glb"
    scene.export(path)
    times, drawn = glb_frames(path)
    np.testing.assert_allclose(times, scene.records["animation"][:, 0], atol=1e-6)
    assert drawn["rods3"].kind == "lines" and drawn["agents4"].kind == "points"
    for k in range(FRAMES):
        for name, key in (("rods2", "rod"), ("rods3", "hair"), ("agents5", "flock")):
            np.testing.assert_allclose(drawn[name].frames[k][0], seen[key][k], atol=1e-5)
        shown = [n for n, d in drawn.items() if n.startswith("particles0_") and d.frames[k]]
        assert shown == ([f"particles0_{k}"] if len(seen["ps"][k]) else [])
        if shown:
            np.testing.assert_allclose(drawn[shown[0]].frames[k][0], seen["ps"][k], atol=1e-5)
        v, tri = drawn[f"fluid1_surface_{k}"].frames[k]
        np.testing.assert_allclose(v, seen["surf"][k][0], atol=1e-5)
        assert np.array_equal(tri, seen["surf"][k][1])
