"""kinema.fluid: the Python API of the SPH fluid (the physics is tested in tests/fluid.rs)."""

import pickle

import numpy as np
import pytest

import kinema
from kinema.fluid import Fluid


def small(**kw):
    f = Fluid(spacing=0.02, **kw)
    f.add_boundary_box([0, 0, 0], [0.3, 0.3, 0.1])
    n = f.add_block([0, 0, 0], [0.1, 0.2, 0.1])
    assert n == 5 * 10 * 5 == len(f)
    return f


def test_block_falls_spreads_and_stays_in_the_tank():
    f = small()
    x = f.positions
    assert x.shape == (250, 3) and not x.flags.writeable
    x0 = x.copy()
    f.step(1 / 60, steps=20)
    # The view is updated in place.
    assert not np.array_equal(x, x0)
    assert np.all(x >= 0) and np.all(x <= [0.3, 0.3, 0.1])
    assert x[:, 0].max() > 0.15
    s = f.stats
    assert s["substeps"] >= 1 and s["density_error"] <= 0.05
    rho = f.densities
    assert rho.shape == (250,) and np.all(np.isfinite(rho))
    assert 900 < np.median(rho) < 1100
    assert f.pressures.shape == (250,)
    assert f.time == pytest.approx(20 / 60)
    assert f.particle_mass == pytest.approx(1000 * 0.02**3, rel=0.02)
    assert f.boundary_particles.shape[1] == 3


def test_views_survive_their_parent_and_freeze_blocks():
    f = small()
    v = f.velocities
    with pytest.raises(ValueError, match="lower"):
        f.add_block([0.2, 0, 0], [0.3, 0.1, 0.1])
    f.step(1 / 60)
    del f
    assert np.all(np.isfinite(v))


def test_wcsph_runs():
    f = small(solver="wcsph")
    f.step(1 / 60, 5)
    assert np.all(np.isfinite(f.positions))
    assert f.stats["density_iterations"] == 0


def test_pickle_round_trip_continues_bit_for_bit():
    f = small()
    f.step(1 / 60, 2)
    g = pickle.loads(pickle.dumps(f))
    f.step(1 / 60, 2)
    g.step(1 / 60, 2)
    assert np.array_equal(f.positions, g.positions)
    assert np.array_equal(f.velocities, g.velocities)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"spacing": 0.0}, "spacing"),
        ({"spacing": -1.0}, "spacing"),
        ({"spacing": float("nan")}, "spacing"),
        ({"spacing": 0.1, "rest_density": 0.0}, "rest_density"),
        ({"spacing": 0.1, "viscosity": 2.0}, "viscosity"),
        ({"spacing": 0.1, "solver": "sph?"}, "solver"),
        ({"spacing": 0.1, "kernel": "gauss"}, "kernel"),
        ({"spacing": 0.1, "max_iterations": 0}, "max_iterations"),
        ({"spacing": 0.1, "gravity": [0, float("nan"), 0]}, "gravity"),
        ({"spacing": 0.1, "surface_tension": -1.0}, "surface_tension"),
    ],
)
def test_bad_settings_name_the_argument(kwargs, name):
    with pytest.raises(ValueError, match=name) as e:
        Fluid(**kwargs)
    assert "sph?" not in str(e.value) and "gauss" not in str(e.value)


def test_bad_blocks_and_steps_leave_the_fluid_unchanged():
    f = small()
    with pytest.raises(ValueError, match="lower"):
        f.add_block([0.25, 0.25, 0], [0.5, 0.5, 0.1])  # outside the tank
    with pytest.raises(ValueError, match="lower"):
        f.add_block([0, 0, 0], [0.1, 0.1, 0.1])  # on top of the fluid
    with pytest.raises(ValueError, match="upper"):
        f.add_block([0.2, 0, 0], [0.21, 0.1, 0.1])  # thinner than the spacing
    with pytest.raises(ValueError, match="lower"):
        f.add_block([np.nan, 0, 0], [0.3, 0.1, 0.1])
    assert len(f) == 250
    with pytest.raises(ValueError, match="dt"):
        f.step(float("nan"))
    with pytest.raises(ValueError, match="steps"):
        f.step(0.01, -1)
    strict = small(max_substeps=2)
    before = strict.positions.copy()
    with pytest.raises(kinema.SimulationError):
        strict.step(1.0)
    assert np.array_equal(strict.positions, before)
    assert strict.time == 0.0


def test_empty_fluid_and_floor_without_fluid():
    f = Fluid(spacing=0.05)
    f.add_boundary_plane([0, 0, 0], [0, 2, 0], 0.5)
    f.step(0.1, 2)
    assert len(f) == 0 and f.positions.shape == (0, 3) and f.densities.shape == (0,)
    assert f.time == pytest.approx(0.2)
    with pytest.raises(ValueError, match="normal"):
        f.add_boundary_plane([0, 0, 0], [0, 0, 0], 0.5)


def test_fluid_on_a_floor_plane_stays_above_it():
    f = Fluid(spacing=0.02)
    f.add_boundary_plane([0, 0, 0], [0, 1, 0], 0.3)
    f.add_block([-0.05, 0.0, -0.05], [0.05, 0.1, 0.05])
    f.step(1 / 60, 15)
    assert f.positions[:, 1].min() > 0.0


def test_pbf_keeps_the_fluid_in_the_tank_at_its_tolerance():
    f = small(solver="pbf")
    f.step(1 / 60, 20)
    x = f.positions
    assert np.all(x >= 0) and np.all(x <= [0.3, 0.3, 0.1])
    assert x[:, 0].max() > 0.15
    s = f.stats
    assert s["density_iterations"] >= 1 and s["divergence_iterations"] == 0
    assert s["max_density_error"] < 5.0
    with pytest.raises(ValueError, match="tensile"):
        Fluid(spacing=0.02, solver="pbf", tensile=2.0)


def test_emitter_and_kill_box_change_the_count_and_give_copies():
    f = Fluid(spacing=0.02, gravity=[0, 0, 0])
    f.add_emitter([0, 0, 0], [2, 0, 0], speed=1.0, radius=0.04)
    f.kill_box([-0.1, -0.1, -0.1], [0.3, 0.1, 0.1])
    f.step(1 / 60, 30)
    n = len(f)
    f.step(1 / 60, 30)
    assert abs(len(f) - n) <= 13 and n > 100
    x = f.positions
    assert x.shape == (len(f), 3) and np.all(x[:, 0] <= 0.3)
    # A copy: the count changes, so no view is handed out, and emitters may still be added.
    f.step(1 / 60)
    assert not np.shares_memory(x, f.positions)
    f.add_emitter([0, 0.05, 0], [1, 0, 0], speed=1.0, radius=0.02)
    v = small().velocities
    assert v.shape == (250, 3)


@pytest.mark.parametrize(
    ("args", "name"),
    [
        (([0, 0, 0], [0, 0, 0], 1.0, 0.04), "direction"),
        (([0, 0, 0], [1, 0, 0], 0.0, 0.04), "speed"),
        (([0, 0, 0], [1, 0, 0], 1.0, 0.001), "radius"),
        (([np.nan, 0, 0], [1, 0, 0], 1.0, 0.04), "position"),
    ],
)
def test_bad_emitters_name_the_argument(args, name):
    f = Fluid(spacing=0.02)
    with pytest.raises(ValueError, match=name):
        f.add_emitter(*args)


def test_emitters_and_kill_box_refused_once_viewed():
    f = small()
    f.positions  # noqa: B018 - takes a view
    with pytest.raises(ValueError, match="position"):
        f.add_emitter([0.2, 0.2, 0.05], [1, 0, 0], 1.0, 0.02)
    with pytest.raises(ValueError, match="lower"):
        f.kill_box([0, 0, 0], [1, 1, 1])
    with pytest.raises(ValueError, match="upper"):
        Fluid(spacing=0.02).kill_box([1, 1, 1], [0, 0, 0])


def test_scene_steps_saves_and_rolls_back_a_fluid(tmp_path):
    scene = kinema.Scene(dt=1 / 60)
    f = scene.add(small())
    scene.step(3)
    path = tmp_path / "fluid.kinema"
    scene.save(path)
    again = kinema.Scene.load(path)
    scene.step(2)
    again.step(2)
    g = again.systems[0]
    assert np.array_equal(f.positions, g.positions)
    # A failing frame puts every system back (the fluid too, in place).
    strict = Fluid(spacing=0.02, max_substeps=1)
    strict.add_boundary_box([0, 0, 0], [0.3, 0.3, 0.1])
    strict.add_block([0, 0, 0], [0.1, 0.2, 0.1])
    two = kinema.Scene(dt=1.0)
    a = two.add(small())
    two.add(strict)
    before = a.positions.copy()
    with pytest.raises(kinema.SimulationError):
        two.step()
    assert np.array_equal(a.positions, before) and a.time == 0.0


def test_surface_mesh_is_closed_and_encloses_the_block():
    f = small()
    v, t = f.surface_mesh()
    assert v.shape[1] == 3 and t.shape[1] == 3 and t.dtype == np.uint32
    # Closed and oriented: every directed edge once, its reverse once; Euler characteristic 2.
    edges = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    keys = edges[:, 0].astype(np.int64) * len(v) + edges[:, 1]
    back = edges[:, 1].astype(np.int64) * len(v) + edges[:, 0]
    assert len(np.unique(keys)) == len(keys) and np.array_equal(np.sort(keys), np.sort(back))
    assert len(v) - len(keys) // 2 + len(t) == 2
    a, b, c = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
    volume = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0
    # A thin block (5 x 10 x 5 spacings): its rounded edges take 7.1 % (measured).
    assert volume == pytest.approx(len(f) * 0.02**3, rel=0.09)
    assert Fluid(spacing=0.02).surface_mesh()[0].shape == (0, 3)
    with pytest.raises(ValueError, match="resolution"):
        f.surface_mesh(0.0)


def test_scene_obj_frame_holds_the_fluid_surface(tmp_path):
    scene = kinema.Scene(dt=1 / 60)
    f = scene.add(small())
    path = scene.export_obj(tmp_path)
    text = path.read_text()
    assert "o fluid0" in text
    assert text.count("\nf ") == len(f.surface_mesh()[1])
