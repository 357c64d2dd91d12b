"""Cloth against moving triangle meshes from Python: the API, bad input named, a failed step
and pickles (the guarantees are checked step by step, exactly, in tests/cloth_mesh_collider.rs)."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

import kinema
from kinema.cloth import Cloth

FACES = np.array(
    [
        [0, 2, 1],
        [1, 2, 3],
        [4, 5, 6],
        [5, 7, 6],
        [0, 1, 4],
        [1, 5, 4],
        [2, 6, 3],
        [3, 6, 7],
        [0, 4, 2],
        [2, 4, 6],
        [1, 3, 5],
        [3, 7, 5],
    ]
)


def box(centre: list[float], half: float) -> np.ndarray:
    """The 8 corners of the axis-aligned cube of ``centre`` and half extent ``half`` (m), in
    the order of ``FACES``."""
    k = np.arange(8)
    signs = np.stack([np.where(k & b, 1.0, -1.0) for b in (1, 2, 4)], axis=1)
    return np.asarray(centre) + half * signs


def test_a_sheet_falls_onto_a_mesh_box_and_stays_outside() -> None:
    cloth = Cloth.grid(12, 12, 0.6, 0.6)
    cloth.set_state(cloth.positions + np.array([0.0, 0.35, 0.0]))
    assert cloth.add_mesh_collider(box([0, 0.15, 0], 0.15), FACES) == 0
    assert cloth.mesh_colliders == 1
    for _ in range(40):
        cloth.step(1 / 60)
        inside = np.all(np.abs(cloth.positions - [0, 0.15, 0]) < 0.15, axis=1)
        assert not inside.any()
    centre = cloth.positions[np.argmin(np.linalg.norm(cloth.positions[:, [0, 2]], axis=1))]
    assert 0.3 < centre[1] < 0.3 + 10 * cloth.thickness
    assert cloth.stats["proximities"] > 0


def test_bad_input_names_the_argument() -> None:
    cloth = Cloth.grid(4, 4)
    corners = box([0, -1, 0], 0.1)
    cases = [
        (dict(vertices=corners[:, :2], triangles=FACES), "vertices"),
        (dict(vertices=corners, triangles=FACES[:, :2]), "triangles"),
        (dict(vertices=corners, triangles=FACES.astype(float)), "triangles"),
        (dict(vertices=corners, triangles=FACES + 1), "triangles"),
        (dict(vertices=corners, triangles=-FACES), "triangles"),
        (dict(vertices=corners, triangles=FACES[:0]), "triangles"),
        (dict(vertices=np.where(corners > 0, np.nan, corners), triangles=FACES), "vertices"),
        (dict(vertices=corners, triangles=FACES, velocities=corners[:7]), "velocities"),
        (dict(vertices=corners, triangles=FACES, velocities=corners * np.inf), "velocities"),
        (dict(vertices=corners, triangles=FACES, friction=-0.1), "friction"),
        (dict(vertices=corners, triangles=FACES, friction=float("nan")), "friction"),
    ]
    for kwargs, name in cases:
        with pytest.raises(ValueError, match=name):
            cloth.add_mesh_collider(**kwargs)
    assert cloth.mesh_colliders == 0
    i = cloth.add_mesh_collider(corners, FACES)
    with pytest.raises(ValueError, match="index"):
        cloth.set_mesh_collider(i + 1, corners)
    with pytest.raises(ValueError, match="vertices"):
        cloth.set_mesh_collider(i, corners[:5])
    with pytest.raises(ValueError, match="velocities"):
        cloth.set_mesh_collider(i, corners, np.full((8, 3), np.nan))
    with pytest.raises(ValueError, match="integrator"):
        cloth.step(1e-3, integrator="rk4")


def test_a_failed_step_leaves_the_cloth_and_meshes_as_they_were_and_pickles_keep_them() -> None:
    cloth = Cloth.grid(8, 8, 0.5, 0.5)
    cloth.set_state(cloth.positions + np.array([0.0, 0.32, 0.0]))
    cloth.add_mesh_collider(box([0, 0.15, 0], 0.15), FACES, np.tile([0.0, 0.3, 0.0], (8, 1)))
    cloth.step(1 / 60, steps=3)
    x, v, t = cloth.positions.copy(), cloth.velocities.copy(), cloth.time
    with pytest.raises(kinema.KinemaError):
        cloth.step(1e5)
    assert np.array_equal(cloth.positions, x) and np.array_equal(cloth.velocities, v)
    assert cloth.time == t
    copy = pickle.loads(pickle.dumps(cloth))
    assert copy.mesh_colliders == 1
    cloth.step(1 / 60, steps=2)
    copy.step(1 / 60, steps=2)
    assert np.array_equal(copy.positions, cloth.positions)
