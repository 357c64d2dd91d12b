"""kinema.character.Biped(dims=3): the 3-D SIMBICON walker from Python (walking forward,
a push from the side, the scene entry and its undo, pickling, errors naming the argument)."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from kinema import character, mocap
from kinema.scene import Scene

DT = 1e-3


def test_the_3d_biped_walks_forward_and_keeps_its_line():
    b = character.Biped(dims=3)
    assert b.dims == 3 and b.q.shape == (25,) and b.qd.shape == (20,)
    assert len(b.names) == 9 and b.positions().shape == (9, 3)
    assert b.feet_in_contact == (True, True)
    b.step(DT, 2_000)
    x = b.com[0]
    b.step(DT, 2_000)
    speed = (b.com[0] - x) / 2.0
    assert 1.0 < speed < 1.35, speed  # 1.17 m/s over 20 s (docs/character.md)
    assert abs(b.com[2]) < 0.5  # sideways drift
    assert 9 <= b.steps <= 16
    assert 0.85 < b.q[1] < 1.05


def test_a_push_from_the_side_moves_it_sideways_and_it_recovers():
    b = character.Biped(dims=3)
    b.step(DT, 4_000)
    z = b.com[2]
    b.push((0.0, 0.0, 100.0), 0.2)
    b.step(DT, 200)
    assert b.com[2] > z + 0.01  # pushed to +z
    b.step(DT, 2_800)
    assert 0.85 < b.q[1] < 1.05  # still walking


def test_coronal_keywords_round_trip_and_are_refused_in_2d():
    b = character.Biped(dims=3, coronal_cv=0.5, coronal_swing_hip=0.02)
    g = b.gait
    assert g["coronal_cv"] == 0.5 and g["coronal_swing_hip"] == 0.02 and g["coronal_cd"] == 0.0
    assert g["torso_kp"] == 1000.0 and g["torso_kd"] == 100.0  # the 3-D defaults
    assert character.Biped().gait["torso_kp"] == 300.0
    with pytest.raises(TypeError, match="coronal_cv"):
        character.Biped(coronal_cv=0.5)
    with pytest.raises(ValueError, match="dims"):
        character.Biped(dims=4)
    with pytest.raises(ValueError, match="coronal_cd"):
        character.Biped(dims=3, coronal_cd=float("nan"))


def test_a_failed_step_and_a_scene_frame_leave_it_as_it_was():
    b = character.Biped(dims=3)
    b.step(DT, 500)
    q, phase = b.q.copy(), b._w.phase()
    with pytest.raises(ValueError, match="dt"):
        b.step(float("nan"))
    np.testing.assert_array_equal(b.q, q)
    assert b._w.phase() == phase
    scene = Scene(dt=4e-3, substeps=4)
    scene.add(b)
    scene.step(10)
    assert b.time == pytest.approx(0.5 + 0.04)
    q, state = b.q.copy(), b.state
    b._w._mark()
    b.step(DT, 100)
    b._w._rollback()
    assert np.array_equal(b.q, q) and b.state == state


def test_pickle_restores_the_walk_bitwise():
    b = character.Biped(dims=3)
    b.step(DT, 700)
    c = pickle.loads(pickle.dumps(b))
    b.step(DT, 300)
    c.step(DT, 300)
    np.testing.assert_array_equal(b.q, c.q)
    assert b.steps == c.steps and b.dims == c.dims == 3
    with pytest.raises(ValueError, match="data"):
        type(b._w)._from_snapshot(b"kinema:Walker3d:garbage")
    planar = character.Biped()._w.__reduce__()[1][0]
    with pytest.raises(ValueError, match="data"):
        type(b._w)._from_snapshot(planar)


def test_a_scene_of_walkers_and_a_ragdoll_resumes_from_its_checkpoint_bitwise(tmp_path):
    # Scene.save / Scene.load store the walkers (planar and 3-D) and a ragdoll through their
    # Rust snapshots: the loaded scene goes on bit for bit as the one saved.
    sk = mocap.read_asf(mocap.SAMPLE_DIR / "07-walk.asf")
    scene = Scene(dt=4e-3, substeps=4)
    scene.add(character.Biped(dims=3))
    scene.add(character.Biped())
    scene.add(character.Ragdoll.from_skeleton(sk, clearance=0.3))
    scene.step(25)
    scene.save(tmp_path / "walkers.kin")
    back = Scene.load(tmp_path / "walkers.kin")
    assert [type(s) for s in back.systems] == [type(s) for s in scene.systems]
    scene.step(25)
    back.step(25)
    for a, b in zip(scene.systems, back.systems, strict=True):
        assert a.q.tobytes() == b.q.tobytes() and a.qd.tobytes() == b.qd.tobytes()
    assert back.systems[0].dims == 3 and back.systems[0].steps == scene.systems[0].steps
