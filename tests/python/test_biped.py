"""kinema.character.Biped: the planar SIMBICON walker from Python (walking forward,
counting steps, pushes, the scene entry and its undo, pickling, errors naming the argument)."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

import kinema
from kinema import character
from kinema.scene import Scene

DT = 1e-4


def test_the_biped_walks_forward_and_counts_its_steps():
    b = character.Biped()
    assert b.feet_in_contact == (True, True)
    start = b.com[0]
    b.step(DT, 20_000)  # 2 s
    assert b.time == pytest.approx(2.0)
    x = b.com[0]
    b.step(DT, 20_000)
    speed = (b.com[0] - x) / 2.0
    assert 0.45 < speed < 0.75, speed
    assert b.com[0] > start
    assert 8 <= b.steps <= 14
    assert 0.9 < b.q[1] < 1.0  # hips up
    assert abs(b.q[2] + 0.15) < 0.1  # the torso near its lean


def test_gait_keywords_round_trip_and_change_the_walk():
    b = character.Biped(torso=(0.0, 0.0), kp=250.0)
    g = b.gait
    assert g["torso"] == (0.0, 0.0) and g["kp"] == 250.0
    assert g["swing_hip"] == (0.5, -0.1) and g["cd"] == (0.0, 2.2)
    b.step(DT, 30_000)
    assert b.com[0] < 0.5  # upright, this model does not walk forward (docs/character.md)


def test_a_push_from_behind_speeds_it_up_and_it_recovers():
    b = character.Biped()
    b.step(DT, 20_000)
    b.push(250.0, 0.2)
    x = b.com[0]
    b.step(DT, 2_000)
    assert (b.com[0] - x) / 0.2 > 0.6  # faster during the push
    b.step(DT, 28_000)
    assert 0.9 < b.q[1] < 1.0 and abs(b.q[2]) < 0.5


def test_pickle_resumes_bit_for_bit():
    b = character.Biped()
    b.step(DT, 3_000)
    c = pickle.loads(pickle.dumps(b))
    b.step(DT, 3_000)
    c.step(DT, 3_000)
    assert np.array_equal(b.q, c.q) and np.array_equal(b.qd, c.qd)
    assert b.steps == c.steps and b.state == c.state


def test_scene_steps_the_biped_and_undoes_a_failed_frame():
    scene = Scene(dt=1 / 100, substeps=100)
    b = scene.add(character.Biped())
    scene.run(0.3)
    assert b.time == pytest.approx(0.3)
    q, state = b.q.copy(), b.state
    core = b._w
    core._mark()
    b.step(DT, 1_000)
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
        b.step(1.0, 10)  # explicit PD at dt = 1 s diverges
    assert np.array_equal(b.q, q)
