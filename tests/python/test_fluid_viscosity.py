"""kinema.fluid's implicit viscosity (Weiler et al. 2018) from Python: the option, its
stats, bad input and a failed step (the physics is tested in tests/fluid_viscosity.rs)."""

import pickle

import numpy as np
import pytest

import kinema
from kinema.fluid import Fluid


def honey(**kw):
    f = Fluid(spacing=0.02, viscosity=0.05, viscosity_model="implicit", **kw)
    f.add_boundary_box([0, 0, 0], [0.4, 0.3, 0.1])
    f.add_block([0, 0, 0], [0.1, 0.2, 0.1])
    return f


def test_honey_spreads_slower_than_water():
    water = Fluid(spacing=0.02)
    water.add_boundary_box([0, 0, 0], [0.4, 0.3, 0.1])
    water.add_block([0, 0, 0], [0.1, 0.2, 0.1])
    f = honey()
    f.step(1 / 60, steps=15)
    water.step(1 / 60, steps=15)
    s = f.stats
    assert s["viscosity_iterations"] > 0 and 0 <= s["viscosity_error"] <= 0.01
    assert water.stats["viscosity_iterations"] == 0
    assert np.all(np.isfinite(f.positions))
    assert f.positions[:, 0].max() < water.positions[:, 0].max()


def test_implicit_default_is_water():
    a = Fluid(spacing=0.02, viscosity_model="implicit")
    b = Fluid(spacing=0.02, viscosity=1e-6, viscosity_model="implicit")
    for f in (a, b):
        f.add_boundary_box([0, 0, 0], [0.2, 0.2, 0.1])
        f.add_block([0, 0, 0], [0.1, 0.1, 0.1])
        f.step(1 / 60, steps=2)
    assert np.array_equal(a.positions, b.positions)


@pytest.mark.parametrize("bad", [-1e-3, float("nan"), float("inf")])
def test_bad_viscosity_names_the_argument(bad):
    with pytest.raises(ValueError, match="viscosity"):
        Fluid(spacing=0.02, viscosity=bad, viscosity_model="implicit")


def test_bad_model_names_the_argument():
    with pytest.raises(ValueError, match="viscosity_model"):
        Fluid(spacing=0.02, viscosity_model="explicit")
    with pytest.raises(TypeError, match="viscosity_model"):
        Fluid(spacing=0.02, viscosity_model=1)  # type: ignore[arg-type]
    # XSPH's coefficient stays a fraction.
    with pytest.raises(ValueError, match="viscosity"):
        Fluid(spacing=0.02, viscosity=2.0)


def test_failed_step_leaves_the_fluid_and_warm_start_unchanged():
    f = honey(max_substeps=4)
    f.step(1 / 60)
    before = pickle.dumps(f)
    x, v = f.positions.copy(), f.velocities.copy()
    with pytest.raises(kinema.SimulationError):
        f.step(0.1)
    assert np.array_equal(f.positions, x) and np.array_equal(f.velocities, v)
    assert pickle.dumps(f) == before
    # A pickled honey fluid continues bit for bit.
    g = pickle.loads(before)
    f.step(1 / 60)
    g.step(1 / 60)
    assert np.array_equal(f.positions, g.positions)


@pytest.mark.parametrize("solver", ["pbf", "wcsph"])
def test_every_solver_takes_the_implicit_viscosity(solver):
    f = honey(solver=solver)
    f.step(1 / 60, steps=3)
    s = f.stats
    assert s["viscosity_iterations"] > 0 and s["viscosity_error"] <= 0.01
    assert np.all(np.isfinite(f.positions)) and np.all(f.positions >= 0)
