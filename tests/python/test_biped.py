"""kinema.character.Biped: the planar SIMBICON walker from Python (walking forward,
counting steps, pushes, the scene entry and its undo, pickling, errors naming the argument)."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

import kinema
from kinema import character
from kinema.scene import Scene

DT = 1e-3


def test_the_biped_walks_forward_and_counts_its_steps():
    b = character.Biped()
    assert b.feet_in_contact == (True, True)
    start = b.com[0]
    b.step(DT, 2_000)  # 2 s
    assert b.time == pytest.approx(2.0)
    x = b.com[0]
    b.step(DT, 2_000)
    speed = (b.com[0] - x) / 2.0
    assert 1.0 < speed < 1.3, speed  # the paper's walk: 1.14 m/s (docs/character.md)
    assert b.com[0] > start
    assert 9 <= b.steps <= 14
    assert 0.85 < b.q[1] < 1.0  # hips up
    assert abs(b.q[2]) < 0.2  # the torso upright


def test_gait_keywords_round_trip_and_change_the_walk():
    b = character.Biped(swing_hip=(0.5, -0.1), swing_ankle=(0.6, 0.15), stance_ankle=(0, 0))
    g = b.gait
    assert g["torso"] == (0.0, 0.0) and g["kp"] == 300.0 and g["torso_kp"] == 300.0
    assert g["swing_hip"] == (0.5, -0.1) and g["cd"] == (0.0, 2.2)
    assert g["stance_ankle"] == (0.0, 0.0) and g["swing_knee"] == (-1.1, -0.05)
    b.step(DT, 6_000)
    assert b.com[0] < 0.3  # these misremembered targets walk backwards (docs/character.md)


def test_a_push_from_behind_speeds_it_up_and_it_recovers():
    b = character.Biped()
    b.step(DT, 2_000)
    b.push(350.0, 0.2)
    x = b.com[0]
    b.step(DT, 200)
    assert (b.com[0] - x) / 0.2 > 1.2  # faster during the push
    b.step(DT, 2_800)
    assert 0.85 < b.q[1] < 1.0 and abs(b.q[2]) < 0.5


def test_the_biped_climbs_a_five_degree_slope():
    b = character.Biped(slope=np.radians(5.0))
    b.step(2e-3, 2_000)  # 4 s
    x = b.com[0]
    b.step(2e-3, 1_000)
    assert 0.2 < (b.com[0] - x) / 2.0 < 0.5  # 0.30 m/s up the slope
    assert 0.85 < b.q[1] < 1.0


def test_pickle_resumes_bit_for_bit():
    b = character.Biped()
    b.step(DT, 300)
    c = pickle.loads(pickle.dumps(b))
    b.step(DT, 300)
    c.step(DT, 300)
    assert np.array_equal(b.q, c.q) and np.array_equal(b.qd, c.qd)
    assert b.steps == c.steps and b.state == c.state


def test_scene_steps_the_biped_and_undoes_a_failed_frame():
    scene = Scene(dt=1 / 100, substeps=10)
    b = scene.add(character.Biped())
    scene.run(0.3)
    assert b.time == pytest.approx(0.3)
    q, state = b.q.copy(), b.state
    core = b._w
    core._mark()
    b.step(DT, 100)
    core._rollback()
    assert np.array_equal(b.q, q) and b.state == state


def test_bad_arguments_name_the_argument_without_quoting_it():
    with pytest.raises(ValueError, match=r"^kp") as e:
        character.Biped(kp=-1.0)
    with pytest.raises(ValueError, match="swing_hip"):
        character.Biped(swing_hip=(0.5, float("nan")))
    with pytest.raises(ValueError, match="duration"):
        character.Biped(duration=0.0)
    with pytest.raises(TypeError, match="wobble"):
        character.Biped(wobble=(1, 2))
    with pytest.raises(ValueError, match=r"^slope"):
        character.Biped(slope=2.0)
    b = character.Biped()
    with pytest.raises(ValueError, match=r"^dt"):
        b.step(-1.0)
    with pytest.raises(ValueError, match=r"^body"):
        b.push(10.0, 0.1, body="tail-secret")
    assert "tail-secret" not in str(e.value)
    with pytest.raises(ValueError, match="duration"):
        b.push(10.0, -0.1)
    q = b.q.copy()
    with pytest.raises(kinema.SimulationError):
        b.step(1.0, 10)  # dt = 1 s diverges
    assert np.array_equal(b.q, q)
