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


def _bench_crowd():  # type: ignore[no-untyped-def]
    """bench/bench_crowd.py, whose numpy/cKDTree boids are the benchmark's peer."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "bench" / "bench_crowd.py"
    spec = importlib.util.spec_from_file_location("bench_crowd", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_boids_match_an_independent_numpy_ckdtree_implementation() -> None:
    """The benchmark's reference (numpy, scipy's cKDTree, the same rules written again)
    agrees with kinema to rounding over 10 steps of 400 boids at the defaults."""
    bench = _bench_crowd()
    p, v = bench.boid_field(400)
    f = Flock(p, v)
    f.step(0.05, 10)
    rp, rv = bench.boids_reference(p, v, 0.05, 10)
    assert np.abs(f.positions - p).max() > 0.1  # they moved
    np.testing.assert_allclose(f.positions, rp, atol=1e-12)
    np.testing.assert_allclose(f.velocities, rv, atol=1e-12)


def test_a_million_boids_step() -> None:
    """The extreme of issue #25: 10⁶ boids (2-D, 0.5 per m²) take a step, finite, within the
    speed limit, each moving at most max_speed · dt."""
    rng = np.random.default_rng(5)
    n = 1_000_000
    side = (n / 0.5) ** 0.5
    p = rng.uniform(0, side, (n, 2))
    f = Flock(p, rng.uniform(-1, 1, (n, 2)))
    f.step(0.05, 2)
    assert np.isfinite(f.positions).all() and np.isfinite(f.velocities).all()
    assert np.linalg.norm(f.velocities, axis=1).max() <= 2.0 + 1e-12
    assert np.linalg.norm(f.positions - p, axis=1).max() <= 2 * 2.0 * 0.05 + 1e-9


def test_follow_keeps_boids_on_a_path() -> None:
    """Path following (Reynolds 1999) from Python: boids 5 m off a straight path join it and
    fly along it; a path of one point is refused, naming the argument."""
    p = np.array([[0.0, 5.0], [3.0, -5.0], [6.0, 4.0]])
    v = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0]])
    quiet = dict(separation=0.0, alignment=0.0, cohesion=0.0, max_force=2.0)
    f = Flock(p, v, **quiet)
    f.add_behaviour("follow", path=[[0.0, 0.0], [200.0, 0.0]], radius=0.5, horizon=1.0)
    f.step(0.05, 400)
    assert np.abs(f.positions[:, 1]).max() < 0.5 + 2.0, f.positions
    assert (f.positions[:, 0] > 20.0).all(), f.positions
    with pytest.raises(ValueError, match="path"):
        f.add_behaviour("follow", path=[[0.0, 0.0]])
    with pytest.raises(ValueError, match="path"):
        f.add_behaviour("follow", path=[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])


def test_cohesion_is_the_largest_clusters_fraction() -> None:
    """Two chains of boids 1 m apart, 7 and 3 boids, 20 m between them: at the neighbour
    radius 1.5 m the largest cluster holds 0.7 of the flock; at 0.9 m every boid is alone."""
    x = np.r_[np.arange(7.0), 30.0 + np.arange(3.0)]
    f = Flock(np.c_[x, np.zeros(10)], np.ones((10, 2)), neighbour_radius=1.5)
    assert f.cohesion() == 0.7
    assert f.cohesion(0.9) == 0.1
    with pytest.raises(ValueError, match="radius"):
        f.cohesion(-1.0)
