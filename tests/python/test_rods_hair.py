"""kinema.rods.Hair through Python: the scalp sampler, grooming, a turning head carrying the
roots, pickling, the Scene entry (undo of a failed frame, records), failed steps and bad
arguments."""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import pytest

import kinema
from kinema import Rotation, Scene, mocap
from kinema.geometry import Plane, Sphere
from kinema.rods import Hair, Rod, groom, sphere_cap

STIFF = {"radius": 1e-4, "youngs_modulus": 1e9, "density": 1300.0, "tolerance": 1e-8}


def hair(count: int = 20, **kwargs: object) -> Hair:
    points, normals = sphere_cap(count, radius=0.1, angle=1.0)
    return groom(points, normals, length=0.05, segments=8, **{**STIFF, **kwargs})  # type: ignore[arg-type]


def test_sphere_cap_spreads_points_on_the_cap() -> None:
    points, normals = sphere_cap(500, radius=0.2, center=(1, 2, 3), axis=(0, 0, 2), angle=0.5)
    assert points.shape == normals.shape == (500, 3)
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(points, np.array([1, 2, 3]) + 0.2 * normals, atol=1e-12)
    assert normals[:, 2].min() >= np.cos(0.5) - 1e-12
    # equal areas: the heights are uniform over the cap, so half lie above its middle height
    middle = 0.5 * (1.0 + np.cos(0.5))
    assert abs(np.mean(normals[:, 2] > middle) - 0.5) < 0.01


def test_groomed_strands_grow_along_the_normals_and_curl() -> None:
    points, normals = sphere_cap(5, radius=0.1)
    h = groom(points, normals, length=0.05, segments=10, gravity=(0, 0, 0), **STIFF)
    x = h.positions
    assert x.shape == (5, 11, 3) and len(h) == 5
    np.testing.assert_allclose(x[:, 0], points, atol=1e-15)
    np.testing.assert_allclose(x[:, -1], points + 0.05 * normals, atol=1e-12)
    c = groom(points, normals, length=0.05, segments=40, curl=0.004, **STIFF).positions
    # a helix of radius 4 mm at 45°: the tip is 0.05/√2 along the normal
    height = np.einsum("ij,ij->i", c[:, -1] - points, normals)
    np.testing.assert_allclose(height, 0.05 / np.sqrt(2), rtol=1e-12)


def test_turning_head_carries_the_roots_and_pickles_bitwise() -> None:
    h = hair()
    rest = h.positions
    turn = Rotation.from_rotvec([0.0, 0.0, 0.5])
    h.set_head(turn, (0.0, 0.01, 0.0))
    h.step(1 / 60, 6)
    x = h.positions
    np.testing.assert_allclose(
        x[:, :2],
        turn.apply(rest[:, :2].reshape(-1, 3)).reshape(-1, 2, 3) + np.array([0.0, 0.01, 0.0]),
        atol=1e-14,
    )
    q, t = h.head
    np.testing.assert_allclose(q.as_quat(), turn.as_quat())
    np.testing.assert_allclose(t, [0.0, 0.01, 0.0])
    copy = pickle.loads(pickle.dumps(h))
    for a in (h, copy):
        a.set_head(Rotation.from_rotvec([0.3, 0.0, 0.5]))
        a.step(1 / 60, 3)
    assert np.array_equal(h.positions, copy.positions)
    assert h.time == pytest.approx(9 / 60)


def test_failed_step_leaves_every_strand_as_it_was() -> None:
    h = hair(max_iterations=1)
    before = h.positions
    h.set_head(Rotation.from_rotvec([1.0, 0.0, 0.0]))
    with pytest.raises(kinema.SimulationError):
        h.step(1 / 60, 2)
    assert np.array_equal(h.positions, before)


def test_scene_steps_records_and_pickles_rods_and_hair() -> None:
    scene = Scene(dt=1 / 60, substeps=2)
    rod = scene.add(Rod.straight(11, 0.1, radius=1e-3, youngs_modulus=1e7))
    rod.clamp(0)
    h = scene.add(hair())
    scene.record("0.elastic_energy")
    scene.record("tips", lambda: h.positions[:, -1])
    scene.step(3)
    assert scene.records["tips"].shape == (3, 20, 3)
    assert scene.records["0.elastic_energy"][-1] > 0.0
    copy = pickle.loads(pickle.dumps(scene))
    scene.step(2)
    copy.step(2)
    assert np.array_equal(copy.systems[1].positions, h.positions)


def test_scene_rolls_back_the_hair_when_the_rod_fails() -> None:
    scene = Scene(dt=1 / 60, substeps=2)
    h = scene.add(hair())
    rod = scene.add(Rod.straight(11, 0.1, radius=1e-3, youngs_modulus=1e7, max_iterations=1))
    rod.clamp(0)
    before = h.positions
    with pytest.raises(kinema.SimulationError):
        scene.step()
    assert np.array_equal(h.positions, before)
    assert scene.frame == 0


@pytest.mark.parametrize(
    ("call", "name"),
    [
        (lambda: sphere_cap(0), "count"),
        (lambda: sphere_cap(3, radius=-1.0), "radius"),
        (lambda: sphere_cap(3, angle=4.0), "angle"),
        (lambda: sphere_cap(3, axis=(0, 0, 0)), "axis"),
        (lambda: groom(np.zeros((2, 3)), np.ones((3, 3))), "normals"),
        (lambda: groom(np.zeros((2, 3)), np.zeros((2, 3))), "normals"),
        (lambda: groom(np.zeros((2, 2)), np.ones((2, 3))), "points"),
        (lambda: groom(np.zeros((2, 3)), np.ones((2, 3)), length=-1.0), "length"),
        (lambda: groom(np.zeros((2, 3)), np.ones((2, 3)), segments=0), "segments"),
        (lambda: groom(np.zeros((2, 3)), np.ones((2, 3)), curl=-1.0), "curl"),
        (
            lambda: groom(np.zeros((2, 3)), np.ones((2, 3)), repulsion_stiffness=-1.0),
            "repulsion_stiffness",
        ),
        (
            lambda: groom(np.zeros((2, 3)), np.ones((2, 3)), strand_friction=-0.5),
            "strand_friction",
        ),
        (lambda: hair().set_head_collider(Plane()), "ball"),
        (lambda: hair().set_head_collider(Sphere((0, 0, 0), -1.0)), "radius"),
        (lambda: hair().set_head_collider(Sphere((0, 0, 0), 0.1, friction=0.5)), "friction"),
        (lambda: hair().set_head("secret-text"), "rotation"),
        (lambda: hair().step(float("nan")), "dt"),
    ],
)
def test_bad_hair_arguments_name_the_argument(call: object, name: str) -> None:
    with pytest.raises((ValueError, TypeError)) as info:
        call()  # type: ignore[operator]
    assert name in str(info.value)
    assert "secret-text" not in str(info.value)


def test_head_collider_keeps_hanging_strands_out_of_the_moving_head() -> None:
    """Soft strands hanging over a 10 cm head turned and nodded for 0.5 s: with the head as a
    collider no centreline gets inside it (by more than 0.1 mm); without, they fall into it."""
    deepest = []
    for collider in (True, False):
        points, normals = sphere_cap(30, radius=0.1, angle=1.0)
        h = groom(points, normals, length=0.15, segments=12, tolerance=1e-8, max_iterations=300)
        if collider:
            h.set_head_collider(Sphere((0, 0, 0), 0.1))
        worst = -np.inf
        for k in range(1, 31):
            t = k / 60
            h.set_head(Rotation.from_rotvec([0.3 * np.sin(4.8 * t), 0.7 * np.sin(np.pi * t), 0]))
            h.step(1 / 60)
            worst = max(worst, float((0.1 - np.linalg.norm(h.positions[:, 2:], axis=2)).max()))
        deepest.append(worst)
    assert deepest[0] < 1e-4, deepest
    assert deepest[1] > 5e-3, deepest


def test_strand_friction_is_pickled_and_zero_friction_changes_nothing() -> None:
    """Strand friction survives pickling (bitwise resume); ``strand_friction=0`` is the
    frictionless repulsion bitwise."""
    kw = {"count": 40, "repulsion_stiffness": 10.0, "thickness": 0.03, "max_iterations": 300}
    a, b, c = hair(**kw), hair(**kw, strand_friction=0.0), hair(**kw, strand_friction=0.8)
    for h in (a, b, c):
        h.set_head(Rotation.from_rotvec([0.0, 0.4, 0.0]))
        h.step(1 / 60, 5)
    assert np.array_equal(a.positions, b.positions)
    assert not np.array_equal(a.positions, c.positions)
    d = pickle.loads(pickle.dumps(c))
    for h in (c, d):
        h.step(1 / 60, 3)
    assert np.array_equal(c.positions, d.positions)


def test_hair_demo_moves_the_head_by_the_cmu_walk(tmp_path: Path) -> None:
    # `kinema demo hair` (quick): the head is posed by the CMU walk's head joint, the roots
    # sit on that pose, the head turns, nods and travels, and the hair stays out of it.
    from kinema.demos import hair as demo

    out = demo.run(tmp_path, quick=True)
    assert out["roots off the CMU head pose (m)"] < 1e-12  # type: ignore[operator]
    assert out["head turn range (deg)"] > 3.0  # type: ignore[operator]
    assert out["head nod range (deg)"] > 1.0  # type: ignore[operator]
    assert out["head travel (cm)"] > 1.0  # type: ignore[operator]
    assert out["vertices inside the head"] == 0
    assert out["largest stretch (%)"] < 0.01  # type: ignore[operator]
    assert (tmp_path / "hair.gif").stat().st_size > 1000
    # The poses are the head joint's: at the capture's first frame the identity, and the
    # rotation at 1 s is the joint's orientation then relative to frame 0.
    skeleton = mocap.read_asf(mocap.SAMPLE_DIR / "07-walk.asf")
    motion = mocap.read_amc(mocap.SAMPLE_DIR / "07_05-walk.amc", skeleton)
    _, orientations = skeleton.forward_kinematics(motion)
    joint = skeleton.joint_names.index("head")
    rotations, translations = demo.head_motion(np.array([0.0, 1.0]))
    np.testing.assert_allclose(translations[0], 0.0, atol=1e-15)
    relative = (
        Rotation.from_quat(orientations[120, joint])
        * Rotation.from_quat(orientations[0, joint]).inv()
    )
    assert relative.approx_equal(rotations[1], atol=1e-12)
    assert relative.magnitude() > 0.02


def test_groom_passes_the_inextensible_and_quasistatic_twist_settings() -> None:
    # The stiff strands stretch by 5e-7 under their weight and the turning head; inextensible
    # ones hold their groomed edge lengths to the tolerance (1e-8), with the quasi-static
    # twist too.
    strains = []
    for inextensible in (False, True):
        h = hair(8, inextensible=inextensible, quasistatic_twist=True)
        rest = np.linalg.norm(np.diff(h.positions, axis=1), axis=2)
        h.set_head(Rotation.from_rotvec([0.0, 0.3, 0.0]))
        h.step(1 / 60, 10)
        edges = np.linalg.norm(np.diff(h.positions, axis=1), axis=2)
        strains.append(float(np.max(np.abs(edges / rest - 1.0))))
    assert strains[0] > 1e-7 and strains[1] < 1e-8, strains


def test_a_scene_of_rods_and_hair_resumes_from_its_checkpoint_bitwise(tmp_path: Path) -> None:
    scene = Scene(dt=1 / 60, substeps=2)
    rod = scene.add(Rod.straight(11, 0.1, radius=1e-3, youngs_modulus=1e7))
    rod.clamp(0)
    h = scene.add(hair())
    h.set_head(Rotation.from_rotvec([0.0, 0.0, 0.3]))
    scene.step(3)
    scene.save(tmp_path / "hair.kin")
    back = Scene.load(tmp_path / "hair.kin")
    scene.step(3)
    back.step(3)
    for a, b in zip(scene.systems, back.systems, strict=True):
        assert type(a) is type(b)
        assert a.positions.tobytes() == b.positions.tobytes()
    assert h.head[1].tobytes() == back.systems[1].head[1].tobytes()
