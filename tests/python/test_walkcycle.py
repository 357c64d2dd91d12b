"""Crowd agents drawn by the CMU 07_05 walk (docs/crowd.md): the cycle found in the clip, and
foot skate measured on the posed agents — the stance foot stays nearly still when the clip is
played by travelled distance, at the clip's speed or slower, and slides at the walking speed
when it is played by time at twice the speed."""

from __future__ import annotations

import numpy as np
import pytest

from kinema import mocap
from kinema.crowd import Crowd
from kinema.walkcycle import WalkCycle

DATA = mocap.SAMPLE_DIR


@pytest.fixture(scope="module")
def clip() -> tuple:
    sk = mocap.read_asf(DATA / "07-walk.asf")
    return sk, mocap.read_amc(DATA / "07_05-walk.amc", sk)


@pytest.fixture(scope="module")
def cycle(clip: tuple) -> WalkCycle:
    return WalkCycle(*clip)


def stance_speeds(cycle: WalkCycle, speed: float, by_distance: bool = True) -> list[float]:
    """Median horizontal speed (m/s) of each foot while it is within 2 cm of its lowest, for
    one agent walking 4 s straight at `speed` (m/s), posed at 120 Hz."""
    t = np.arange(0.0, 4.0, 1.0 / 120.0)
    heading = np.array([0.6, 0.8])
    positions = np.array([3.0, -2.0]) + np.outer(speed * t, heading)
    played = speed * t if by_distance else cycle.speed * t
    frames = np.stack([cycle.pose(positions[k], heading, played[k])[0] for k in range(len(t))])
    out = []
    for name in ("lfoot", "rfoot"):
        foot = frames[:, cycle.joint_names.index(name)]
        stance = foot[1:, 1] < foot[:, 1].min() + 0.02
        v = np.linalg.norm(np.diff(foot[:, [0, 2]], axis=0), axis=1) * 120.0
        out.append(float(np.median(v[stance])))
    return out


def test_cycle_is_one_gait_cycle_of_the_clip(cycle: WalkCycle, clip: tuple) -> None:
    motion = clip[1]
    # The clip walks 4.16 m in 517 frames (0.965 m/s); a slow walk's gait cycle is 1-1.6 s.
    assert 1.0 < cycle.period < 1.6
    assert abs(cycle.speed - 0.965) < 0.03
    assert abs(cycle.stride - cycle.speed * cycle.period) < 1e-12
    assert cycle.mismatch < 0.03  # m: the cycle's ends nearly coincide
    assert cycle.first + cycle.frames < motion.frames
    # Poses over one stride repeat: distance 0 and one stride give the same pose.
    a = cycle.pose([0.0, 0.0], [1.0, 0.0], [0.0])
    b = cycle.pose([0.0, 0.0], [1.0, 0.0], [cycle.stride])
    np.testing.assert_allclose(a, b, atol=1e-9)


def test_feet_stay_planted_when_played_by_distance(cycle: WalkCycle) -> None:
    for speed in (cycle.speed, 0.5 * cycle.speed):
        for v in stance_speeds(cycle, speed):
            assert v < 0.15 * cycle.speed, (speed, v)
    # Played by time at twice the speed, the stance foot slides at about the walking speed.
    for v in stance_speeds(cycle, 2.0 * cycle.speed, by_distance=False):
        assert v > 0.8 * cycle.speed, v


def test_pose_turns_and_places_the_clip(cycle: WalkCycle) -> None:
    # One pose facing +x at the origin, and the same turned by 90° to +z and moved.
    a = cycle.pose([0.0, 0.0], [2.0, 0.0], [0.3])[0]
    b = cycle.pose([5.0, 7.0], [0.0, 3.0], [0.3])[0]
    np.testing.assert_allclose(b[:, 1], a[:, 1], atol=1e-12)
    np.testing.assert_allclose(b[:, 0] - 5.0, -a[:, 2], atol=1e-12)
    np.testing.assert_allclose(b[:, 2] - 7.0, a[:, 0], atol=1e-12)
    # Standing on the ground: the lowest joint is within a few cm of y = 0 (CMU's floor).
    assert abs(a[:, 1].min()) < 0.08


def test_a_crowd_is_posed_per_agent(cycle: WalkCycle) -> None:
    crowd = Crowd("orca", radius=0.3, preferred_speed=cycle.speed)
    start = np.array([[-5.0, 0.0], [5.0, 0.2], [0.0, -5.0]])
    crowd.add_agents(start, -start)
    crowd.step(0.1, steps=30)
    m = crowd.metrics()
    poses = cycle.pose(crowd.positions, crowd.velocities, m["path_lengths"])
    assert poses.shape == (3, len(cycle.joint_names), 3)
    root = cycle.joint_names.index("root")
    np.testing.assert_allclose(
        poses[:, root, [0, 2]], crowd.positions, atol=0.1
    )  # the root sways a few cm about the agent's position


def test_bad_arguments_are_named(cycle: WalkCycle, clip: tuple) -> None:
    with pytest.raises(ValueError, match="headings"):
        cycle.pose([[0.0, 0.0]], [[1.0, 0.0], [0.0, 1.0]], [0.0])
    with pytest.raises(ValueError, match="distances"):
        cycle.pose([[0.0, 0.0]], [[1.0, 0.0]], [0.0, 1.0])
    with pytest.raises(ValueError, match="distances"):
        cycle.pose([[0.0, 0.0]], [[1.0, 0.0]], [np.nan])
    with pytest.raises(ValueError, match="positions"):
        cycle.pose([[np.inf, 0.0]], [[1.0, 0.0]], [0.0])
    with pytest.raises(ValueError, match="min_period"):
        WalkCycle(*clip, min_period=5.0, max_period=9.0)
