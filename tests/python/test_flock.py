"""kinema.flock: boids through the Python API — alignment raises the polarisation, 2-D and
3-D shapes, bad arguments named, pickling, determinism across thread counts."""

import pickle

import numpy as np
import pytest

import kinema
from kinema.flock import Flock


def square(n: int, side: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    a = rng.uniform(0.0, 2 * np.pi, n)
    return rng.uniform(0.0, side, (n, 2)), np.stack([np.cos(a), np.sin(a)], axis=1)


def test_alignment_orders_a_2d_flock_and_it_stays_planar() -> None:
    p, v = square(100, 10.0, 1)
    kw = dict(separation=2.0, neighbour_radius=5.0, separation_distance=1.5)
    f = Flock(p, v, **kw)
    assert f.dimension == 2 and f.positions.shape == (100, 2)
    assert not f.positions.flags.writeable
    start = f.polarisation()
    f.step(0.1, 400)
    assert start < 0.25 and f.polarisation() > 0.9, (start, f.polarisation())
    assert np.all(f._f.positions[:, 2] == 0.0)
    free = Flock(p, v, alignment=0.0, **kw)
    free.step(0.1, 400)
    assert free.polarisation() < 0.4


def test_3d_positions_give_a_3d_flock() -> None:
    rng = np.random.default_rng(2)
    f = Flock(rng.uniform(0, 5, (50, 3)), rng.normal(size=(50, 3)))
    f.step(0.05, 10)
    assert f.dimension == 3 and f.velocities.shape == (50, 3)
    assert np.all(np.linalg.norm(f.velocities, axis=1) <= 2.0 + 1e-12)


@pytest.mark.parametrize(
    "kwargs,arg",
    [
        ({"max_speed": 0.0}, "max_speed"),
        ({"max_force": -1.0}, "max_force"),
        ({"field_of_view": 7.0}, "field_of_view"),
        ({"separation_distance": 5.0}, "separation_distance"),
        ({"alignment": float("nan")}, "alignment"),
    ],
)
def test_bad_settings_name_the_argument(kwargs: dict, arg: str) -> None:
    p, v = square(5, 3.0, 0)
    with pytest.raises(ValueError, match=arg):
        Flock(p, v, **kwargs)


def test_bad_arrays_and_steps_name_the_argument_and_change_nothing() -> None:
    p, v = square(5, 3.0, 0)
    with pytest.raises(ValueError, match="positions"):
        Flock(np.zeros((5, 4)), v)
    with pytest.raises(ValueError, match="velocities"):
        Flock(p, np.zeros((4, 2)))
    with pytest.raises(ValueError, match="velocities"):
        Flock(p, np.zeros((5, 3)))
    bad = p.copy()
    bad[2, 1] = np.nan
    with pytest.raises(ValueError, match="positions"):
        Flock(bad, v)
    f = Flock(p, v)
    before = f.positions.copy()
    with pytest.raises(ValueError, match="dt"):
        f.step(-1.0)
    with pytest.raises(TypeError, match="dt"):
        f.step("0.1")  # type: ignore[arg-type]
    assert np.array_equal(f.positions, before)


def test_pickle_round_trip_continues_bitwise() -> None:
    p, v = square(200, 12.0, 3)
    f = Flock(p, v)
    f.step(0.1, 5)
    g = pickle.loads(pickle.dumps(f))
    f.step(0.1, 5)
    g.step(0.1, 5)
    assert np.array_equal(f.positions, g.positions) and g.dimension == 2


def test_same_bits_on_one_and_two_threads() -> None:
    p, v = square(3000, 60.0, 4)
    out = []
    old = kinema.num_threads()
    try:
        for threads in (1, 2):
            kinema.set_num_threads(threads)
            f = Flock(p, v)
            f.step(0.1, 10)
            out.append(f.positions.copy())
    finally:
        kinema.set_num_threads(old)
    assert np.array_equal(out[0], out[1])
