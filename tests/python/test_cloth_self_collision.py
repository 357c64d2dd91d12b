"""Cloth self-collision from Python: the keywords, their defaults, the stats, pickles, and
clear errors (the scenes' numbers are checked in tests/cloth_self_collision.rs)."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

import kinema
from kinema.cloth import Cloth, Plane


def folded(self_collision: bool) -> Cloth:
    """A 12 x 12 sheet of 0.5 m folded over itself in a U, its upper half falling on the
    lower one (2 cm apart at the start)."""
    cloth = Cloth.grid(12, 12, 0.5, 0.5, self_collision=self_collision)
    x = cloth.positions.copy()
    upper = x[:, 0] > 0.0
    x[upper, 0] = -x[upper, 0] + 0.01
    x[upper, 1] = 0.02
    cloth.set_state(x)
    cloth.add_collider(Plane(normal=(0, 1, 0), point=(0, -0.01, 0)))
    return cloth


def test_defaults_thickness_and_stats() -> None:
    plain = Cloth.grid(11, 11, 1.0, 1.0)
    assert not plain.self_collision and plain.thickness == 1e-3
    on = Cloth.grid(11, 11, 1.0, 1.0, self_collision=True)
    # A tenth of the mean edge length: edges of 0.1 and diagonals of 0.1·√2.
    mean = (2 * 0.1 + 0.1 * np.sqrt(2)) / 3
    assert on.self_collision and on.thickness == pytest.approx(0.1 * mean, rel=1e-12)
    assert Cloth.grid(11, 11, self_collision=True, thickness=0.004).thickness == 0.004
    on.step(0.01)
    stats = on.stats
    for key in ("proximities", "ccd_iterations", "impact_zones", "self_collision_seconds"):
        assert key in stats
    assert stats["proximities"] == 0 and stats["impact_zones"] == 0


def layer_gap(cloth: Cloth) -> float:
    """Mean height of the folded-over columns (7..11, away from the fold) above the columns
    under them (0..4), in thicknesses."""
    column = np.arange(len(cloth)) % 12
    y = cloth.positions[:, 1]
    return float((y[column >= 7].mean() - y[column <= 4].mean()) / cloth.thickness)


def test_folded_sheet_keeps_its_layers_apart() -> None:
    cloth = folded(True)
    cloth.step(0.01, 30)
    # The upper layer came down on the lower one and rests on it, apart.
    assert cloth.stats["proximities"] > 0
    assert layer_gap(cloth) >= 0.25


def test_pickle_keeps_the_settings_and_the_trajectory() -> None:
    cloth = folded(True)
    cloth.step(0.01, 5)
    copy = pickle.loads(pickle.dumps(cloth))
    assert copy.self_collision and copy.thickness == cloth.thickness
    cloth.step(0.01, 5)
    copy.step(0.01, 5)
    np.testing.assert_array_equal(copy.positions, cloth.positions)


def test_bad_arguments_name_themselves() -> None:
    with pytest.raises(ValueError, match="self_friction"):
        Cloth.grid(4, 4, self_collision=True, self_friction=-1.0)
    with pytest.raises(ValueError, match="self_iterations"):
        Cloth.grid(4, 4, self_collision=True, self_iterations=-1)
    with pytest.raises(ValueError, match="thickness"):
        Cloth.grid(4, 4, self_collision=True, thickness=float("nan"))
    cloth = Cloth.grid(4, 4, self_collision=True)
    before = cloth.positions.copy()
    with pytest.raises(ValueError, match="integrator"):
        cloth.step(1e-4, integrator="rk4")
    np.testing.assert_array_equal(cloth.positions, before)
    assert issubclass(kinema.KinemaError, Exception)
