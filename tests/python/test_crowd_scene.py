"""Crowds and flocks through the Python API's newer parts: the crowd's navigation layer
(agents leave a room by its door only with it), flock steering behaviours, and both as
Scene entries (recording, checkpoint rollback, save/load)."""

import pickle
from pathlib import Path

import numpy as np
import pytest

from kinema.crowd import Crowd
from kinema.flock import Flock
from kinema.geometry import Sphere
from kinema.scene import Scene

# A room [0, 8]^2 of wall segments with a 1 m door in its right wall.
ROOM = [
    [[0, 0], [0, 8]],
    [[0, 0], [8, 0]],
    [[0, 8], [8, 8]],
    [[8, 0], [8, 3.5]],
    [[8, 4.5], [8, 8]],
]


def room_crowd(navigation: float | None) -> Crowd:
    c = Crowd(
        "orca",
        radius=0.25,
        time_horizon=2.0,
        obstacle_time_horizon=1.0,
        neighbour_distance=3.0,
        goal_tolerance=0.5,
        navigation=navigation,
    )
    for wall in ROOM:
        c.add_obstacle(wall)
    start = np.array([[3.0 + k % 3, 3.0 + k // 3] for k in range(9)])
    c.add_agents(start, start - [8.0, 0.0])  # behind the room's left wall
    return c


def test_navigation_leads_agents_out_of_the_door_to_a_goal_behind_the_wall() -> None:
    with_nav, without = room_crowd(0.4), room_crowd(None)
    with_nav.step(0.1, 600)
    without.step(0.1, 600)
    assert with_nav.metrics()["arrived"] == 9
    assert with_nav.metrics()["obstacle_collisions"] == 0
    # The detour: out of the door, round the room: much longer than the straight 8 m.
    assert np.all(with_nav.metrics()["path_ratio"] > 2.0)
    assert without.metrics()["arrived"] == 0
    # Navigation can be switched off again: then it is the local model alone.
    c = room_crowd(0.4)
    c.set_navigation(None)
    c.step(0.1, 100)
    assert c.metrics()["arrived"] == 0


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf")])
def test_bad_navigation_clearance_is_named(bad: float) -> None:
    with pytest.raises(ValueError, match="navigation"):
        Crowd(navigation=bad)
    with pytest.raises(TypeError, match="navigation"):
        Crowd(navigation=True)  # type: ignore[arg-type]


def test_flock_arrive_and_avoid_through_python() -> None:
    f = Flock([[0.0, 0.0]], [[0.0, 0.0]], separation=0, alignment=0, cohesion=0, max_force=2.0)
    f.add_behaviour("arrive", target=[20.0, 0.0], slow_radius=10.0)
    xs = []
    for _ in range(2000):
        f.step(0.05)
        xs.append(f.positions[0, 0])
    assert max(xs) <= 20.0 and abs(xs[-1] - 20.0) < 1e-3
    y = np.linspace(-1.5, 1.5, 21)
    p = np.stack([np.zeros(21), y, 0.05 * (np.arange(21) % 3)], axis=1)
    ball = Sphere([10.0, 0.0, 0.0], 2.0)
    for avoid, inside in ((True, False), (False, True)):
        g = Flock(
            p,
            np.tile([2.0, 0.0, 0.0], (21, 1)),
            separation=0,
            alignment=0,
            cohesion=0,
            max_force=4.0,
        )
        if avoid:
            g.add_behaviour("avoid", shape=ball, horizon=2.0, clearance=0.5)
        entered = False
        for _ in range(1000):
            g.step(0.01)
            entered |= bool(np.any(np.linalg.norm(g.positions - [10, 0, 0], axis=1) < 2.0))
        assert entered == inside


def test_bad_behaviours_are_named() -> None:
    f = Flock([[0.0, 0.0]], [[1.0, 0.0]])
    with pytest.raises(ValueError, match="target"):
        f.add_behaviour("seek")
    with pytest.raises(ValueError, match="kind"):
        f.add_behaviour("dance")
    with pytest.raises(ValueError, match="slow_radius"):
        f.add_behaviour("arrive", target=[1.0, 0.0], slow_radius=-1.0)
    with pytest.raises(ValueError, match="target"):
        f.add_behaviour("seek", target=[1.0, 0.0, 0.0])  # 3-D target for a 2-D flock
    f.add_behaviour("pursue", boid=3)
    before = f.positions.copy()
    with pytest.raises(ValueError, match="target"):
        f.step(0.1)
    assert np.array_equal(f.positions, before)


def test_crowd_and_flock_as_scene_entries(tmp_path: Path) -> None:
    scene = Scene(dt=0.1)
    crowd = scene.add(room_crowd(0.4))
    flock = scene.add(
        Flock(
            np.random.default_rng(1).uniform(0, 5, (30, 2)),
            np.random.default_rng(2).uniform(-1, 1, (30, 2)),
        )
    )
    scene.record("agents", lambda: crowd.positions.copy())
    scene.record("boids", lambda: flock.positions.copy())
    scene.step(10)
    rec = scene.records
    assert rec["agents"].shape == (10, 9, 2) and rec["boids"].shape == (10, 30, 2)
    d = scene.diagnostics()
    assert d["0.agent_collisions"] == 0 and "1.polarisation" in d
    # Alone the same steps give the same bits: the scene only steps them.
    alone = room_crowd(0.4)
    alone.step(0.1, 10)
    assert np.array_equal(alone.positions, crowd.positions)
    # Checkpoint: save, step on, load, step on again: bitwise the same.
    path = tmp_path / "s.kinema"
    scene.save(path)
    scene.step(5)
    after = crowd.positions.copy(), flock.positions.copy()
    loaded = Scene.load(path)
    loaded.step(5)
    c2, f2 = loaded.systems
    assert np.array_equal(c2.positions, after[0]) and np.array_equal(f2.positions, after[1])
    assert pickle.loads(pickle.dumps(crowd)).metrics()["steps"] == crowd.metrics()["steps"]


def test_scene_rollback_restores_crowd_and_flock() -> None:
    scene = Scene(dt=0.1)
    crowd = scene.add(room_crowd(0.4))
    flock = scene.add(Flock([[0.0, 0.0], [1.0, 0.0]], [[1.0, 0.0], [1.0, 0.0]]))
    scene.step(3)
    from kinema.scene import _checkpoint

    restores = [_checkpoint(e) for e in scene._entries]
    before = crowd.positions.copy(), flock.positions.copy(), crowd.metrics()["steps"]
    crowd.step(0.1, 4)  # as a failing frame would have, before the scene rolls back
    flock.step(0.1, 4)
    assert not np.array_equal(crowd.positions, before[0])
    for r in restores:
        r()
    assert np.array_equal(crowd.positions, before[0])
    assert np.array_equal(flock.positions, before[1])
    assert crowd.metrics()["steps"] == before[2]
