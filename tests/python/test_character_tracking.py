"""kinema.character.Tracker (mocap tracking with a measured root assistance) and ragdolls
from BVH skeletons, from Python."""

from __future__ import annotations

import pickle
import warnings
from pathlib import Path

import numpy as np
import pytest

import kinema
from kinema import character, mocap, particles
from kinema.scene import Scene, StabilityWarning

DATA = Path(__file__).resolve().parents[1] / "data" / "mocap"
# Measured over 10 s at the defaults (tests/character_tracking.rs): root error at most
# 0.10 m, joint error 0.094 rad RMS on average; a limp ragdoll: 1.2-1.5 rad.
ROOT_BOUND, JOINT_BOUND, LIMP_BOUND = 0.15, 0.15, 0.8


def test_tracking_reports_every_frame_and_follows_the_clip(walk):
    sk, motion = walk
    t = character.Tracker(sk, motion)
    r = t.step(240)  # 2 s at 120 Hz
    assert set(r) == {"time", "root_error", "joint_error", "assist_force", "assist_torque"}
    assert all(v.shape == (240,) for v in r.values())
    assert r["time"][-1] == pytest.approx(2.0)
    assert t.frame == 240 and t.time == pytest.approx(2.0)
    assert r["root_error"].max() < ROOT_BOUND
    assert r["joint_error"].mean() < JOINT_BOUND
    assert np.all(np.isfinite(r["assist_force"])) and r["assist_force"].mean() > 0.0
    assert t.q.shape == t.reference_q.shape == (len(t.q),)
    assert t.positions().shape == (31, 3)


def test_a_limp_ragdoll_does_not_follow_the_joints(walk):
    sk, motion = walk
    r = character.Tracker(sk, motion, kp=0.0, kd=0.0, substeps=8).step(240)
    assert r["joint_error"][120:].mean() > LIMP_BOUND


def test_tracker_arguments_are_named(walk):
    sk, motion = walk
    with pytest.raises(ValueError, match="kp"):
        character.Tracker(sk, motion, kp=-1.0)
    with pytest.raises(ValueError, match="substeps"):
        character.Tracker(sk, motion, substeps=0)
    with pytest.raises(TypeError, match="motion"):
        character.Tracker(sk, "walk")
    with pytest.raises(TypeError, match="skeleton"):
        character.Tracker(motion, motion)
    with pytest.raises(ValueError, match="motion"):
        character.Tracker(sk, mocap.read_bvh(DATA / "01_01.bvh")[1])


def test_a_tracker_started_at_a_frame_is_at_that_frame_of_the_clip(walk):
    """``start_frame=k`` puts the ragdoll at the clip's frame k with its rates: as the tracker
    of the clip sliced at k (the way before), apart from the lift onto the ground (the
    slice's from its own frames, the start's from the whole clip's); tracking from there is
    checked against the slice in tests/character_tracking.rs. Bad start frames are named."""
    sk, motion = walk
    k = 40
    at = character.Tracker(sk, motion, start_frame=k)
    cut = character.Tracker(sk, motion.slice(k, motion.frames))
    assert at.frame == k and cut.frame == 0
    lift = np.zeros(len(at.q))
    lift[1] = at.q[1] - cut.q[1]
    assert abs(lift[1]) > 1e-4  # the slice is lifted by a different median
    np.testing.assert_allclose(at.q, cut.q + lift, rtol=0, atol=1e-12)
    np.testing.assert_allclose(at.reference_q, cut.reference_q + lift, rtol=0, atol=1e-12)
    first = character.Tracker(sk, motion)
    assert not np.allclose(first.q[7:], at.q[7:], atol=1e-3)  # frame 40 is another pose
    at.step(4)
    assert at.frame == k + 4 and at.time == pytest.approx(4 / 120)
    with pytest.raises(ValueError, match="start_frame"):
        character.Tracker(sk, motion, start_frame=-1)
    with pytest.raises(ValueError, match="start_frame"):
        character.Tracker(sk, motion, start_frame=first.loop_span[1])
    with pytest.raises(TypeError, match="start_frame"):
        character.Tracker(sk, motion, start_frame=1.5)


def test_a_bvh_ragdoll_has_a_body_per_joint_and_falls_limp():
    sk, _ = mocap.read_bvh(DATA / "01_01.bvh")
    with pytest.raises(ValueError, match="scale"):
        character.Ragdoll.from_skeleton(sk)
    r = character.Ragdoll.from_skeleton(sk, scale=0.0254 / 0.45, clearance=0.3)
    assert len(r) == len(sk.joint_names) and r.names == list(sk.joint_names)
    assert r.nv == 6 + 3 * (len(r) - 1)  # every CMU BVH joint has three rotation channels
    e0 = sum(r.energy())
    r.step(1 / 960, 960)  # unlimited joints: 1/480 s diverged after 0.8 s (docs, Known limits)
    assert np.all(np.isfinite(r.q)) and sum(r.energy()) < e0
    assert r.com[1] < 0.3


def test_a_tracker_is_a_scene_entry_whose_failed_frame_is_undone(walk):
    # In a scene it tracks one clip frame per step (dt / substeps a whole number of frames,
    # else refused naming dt), bit for bit as alone; a frame that fails in another system
    # (a spring pair diverging, stepped after it) puts it back: state, frame and reference.
    sk, motion = walk
    alone = character.Tracker(sk, motion)
    alone.step(6)
    scene = Scene(dt=1 / 60, substeps=2)
    t = scene.add(character.Tracker(sk, motion))
    assert t.frame_rate == 120.0
    scene.step(3)
    assert t.frame == 6 and t.q.tobytes() == alone.q.tobytes()
    with pytest.raises(ValueError, match="dt"):
        Scene(dt=1 / 100).add(character.Tracker(sk, motion))
    with pytest.raises(ValueError, match="options"):
        Scene(dt=1 / 120).add(character.Tracker(sk, motion), method="rk4")

    pair = particles.ParticleSystem([[0.0, 3.0, 0.0], [1.0, 3.0, 0.0]])
    pair.add(particles.Springs([[0, 1]], stiffness=1e12, rest=[0.5]))
    scene.add(pair, method="explicit_euler")
    for _ in range(100):
        before = (t.q.tobytes(), t.reference_q.tobytes(), t.frame, t.time)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", StabilityWarning)
                scene.step()
        except kinema.SimulationError:
            break
    else:
        pytest.fail("the spring pair never diverged")
    assert (t.q.tobytes(), t.reference_q.tobytes(), t.frame, t.time) == before
    assert before[2] > 6


def test_a_scene_with_a_tracker_resumes_from_its_checkpoint_bitwise(walk, tmp_path):
    # Scene.save stores the tracker through its Rust snapshot (skeleton, clip, options,
    # ragdoll, frame); the loaded scene tracks on bit for bit, and pickling does the same.
    sk, motion = walk
    scene = Scene(dt=1 / 60, substeps=2)
    scene.add(character.Tracker(sk, motion, kp=200.0))
    scene.step(10)
    scene.save(tmp_path / "tracker.kin")
    back = Scene.load(tmp_path / "tracker.kin")
    copy = pickle.loads(pickle.dumps(scene.systems[0]))
    a, b = scene.systems[0], back.systems[0]
    assert b.frame == a.frame == copy.frame == 20
    scene.step(10)
    back.step(10)
    copy.step(20)
    assert a.q.tobytes() == b.q.tobytes() == copy.q.tobytes()
    assert a.reference_q.tobytes() == b.reference_q.tobytes()
    with pytest.raises(ValueError, match="data"):
        type(a._t)._from_snapshot(a._t.__reduce__()[1][0][:-9])


def test_a_bvh_clip_is_tracked_with_the_assistance_reported():
    """The BVH conversion of CMU 01_01 (jumps; its first frame, a T-pose the conversion adds,
    dropped) tracked 2 s by the ragdoll of its hierarchy: every frame reported, the root
    within 0.3 m of the clip's and the joints within 0.15 rad RMS on average (measured over
    5 s in tests/character_tracking_bvh.rs: 0.25 m at most, 0.085 rad), the assistance finite
    and carrying part of the weight; ``scale`` is required for a BVH skeleton."""
    sk, motion = mocap.read_bvh(DATA / "01_01.bvh")
    clip = motion.slice(1, motion.frames)
    with pytest.raises(ValueError, match="scale"):
        character.Tracker(sk, clip)
    t = character.Tracker(sk, clip, scale=0.0254 / 0.45)
    assert t.names == list(sk.joint_names)
    r = t.step(240)
    assert r["time"][-1] == pytest.approx(240 / t.frame_rate)
    assert r["root_error"].max() < 0.3 and r["joint_error"].mean() < 0.15
    force = r["assist_force"]
    assert np.all(np.isfinite(force)) and np.all(np.isfinite(r["assist_torque"]))
    assert 0.0 < force.mean() < 3.0 * t.mass * 9.81
