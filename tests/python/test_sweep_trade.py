"""kinema.sweep.trade (error against a reference and cost, per method and time step; the
work–precision diagram) and kinema.sweep.to_xarray (the parameters as coordinates)."""

from __future__ import annotations

import numpy as np
import pytest

from kinema import sweep as ks
from kinema.particles import ParticleSystem, Springs

T = 1.0  # s simulated by every run


# A free chain of 3 unit masses on undamped springs of 40 N/m (fastest mode ~11 rad/s), the
# ends moving apart at first: smooth, so each method shows its order.
def build(method: str, dt: float) -> tuple[ParticleSystem, str, float]:
    x = np.array([[0.0, 0, 0], [0.5, 0, 0], [1.0, 0, 0]])
    v = np.array([[-0.3, 0.1, 0], [0.0, 0, 0], [0.3, 0, 0.2]])
    chain = ParticleSystem(x, velocities=v, masses=np.ones(3))
    chain.add(Springs([[0, 1], [1, 2]], 40.0, rest=[0.4, 0.4]))
    return chain, method, dt


def run(system: tuple[ParticleSystem, str, float]) -> dict:
    chain, method, dt = system
    steps = round(T / dt)
    chain.step(dt, steps=steps, method=method)
    return {"x": chain.positions.copy(), "v": chain.velocities.copy(), "steps": steps}


DTS = [0.02, 0.01, 0.005, 0.0025]
ORDERS = {"symplectic_euler": 1, "velocity_verlet": 2, "rk4": 4}


def test_trade_shows_each_method_converging_at_its_order(tmp_path):
    picture = tmp_path / "wp.png"
    table = ks.trade(
        build,
        run,
        reference={"method": "rk4", "dt": 1e-4},
        dts=DTS,
        methods=list(ORDERS),
        cost="steps",
        plot=picture,
    )
    assert list(table["status"]) == ["ok"] * 12
    assert list(table["method"]) == [m for m in ORDERS for _ in DTS]
    for method, order in ORDERS.items():
        rows = table[table["method"] == method]
        slope = np.polyfit(np.log(rows["dt"]), np.log(rows["deviation"]), 1)[0]
        assert abs(slope - order) < 0.2 * order, (method, slope)
        assert list(rows["cost"]) == [round(T / h) for h in DTS]  # the deterministic cost
    # The errors are errors: halving dt four times with rk4 leaves far less than euler's.
    assert table["deviation"].max() < 0.5
    last = table[table["dt"] == DTS[-1]].set_index("method")["deviation"]
    assert last["rk4"] < 1e-3 * last["velocity_verlet"] < 1e-3 * last["symplectic_euler"]
    assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and picture.stat().st_size > 5000


def build_stiff(method: str, dt: float) -> tuple[ParticleSystem, str, float]:
    chain, _, _ = build(method, dt)
    chain.add(Springs([[0, 1], [1, 2]], 4000.0, rest=[0.4, 0.4]))  # fastest mode ~110 rad/s
    return chain, method, dt


def run_long(system: tuple[ParticleSystem, str, float]) -> dict:
    chain, method, dt = system
    steps = round(30.0 / dt)
    chain.step(dt, steps=steps, method=method)
    return {"x": chain.positions.copy(), "steps": steps}


def test_trade_by_wall_time_and_diverged_runs():
    # At dt = 0.05 s both methods are far beyond their limits (2/omega ~ 0.018 s for symplectic
    # Euler, 2.8/omega for RK4) and the state overflows within the 600 steps.
    table = ks.trade(
        build_stiff,
        run_long,
        reference={"method": "rk4", "dt": 1e-3},
        dts=[0.05, 0.005],
        methods=["rk4", "symplectic_euler"],
        repeat=2,
    )
    assert table["cost"].equals(table["seconds"]) and (table["cost"] > 0).all()
    assert list(table["status"]) == ["failed", "ok", "failed", "ok"]
    bad = table[table["status"] == "failed"]
    assert np.isnan(bad["deviation"]).all() and bad["error"].str.startswith("SimulationError").all()
    assert (table[table["status"] == "ok"]["deviation"] > 0).all()


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"reference": 1.0}, "reference"),
        ({"reference": {"method": "rk4", "dt": [1e-3]}}, r"reference\['dt'\]"),
        ({"reference": {}}, "reference"),
        ({"reference": {"method": "no-such", "dt": 1e-3}}, "reference"),
        ({"dts": []}, "dts"),
        ({"dts": "0.1"}, "dts"),
        ({"dts": [0.1, -0.1]}, "dts"),
        ({"dts": [0.1, float("nan")]}, "dts"),
        ({"methods": "rk4"}, "methods"),
        ({"methods": []}, "methods"),
        ({"methods": [4]}, "methods"),
        ({"cost": "flops"}, "cost"),
        ({"cost": ""}, "cost"),
        ({"repeat": 0}, "repeat"),
    ],
)
def test_trade_rejects_bad_arguments(kwargs, name):
    args = {"reference": {"method": "rk4", "dt": 1e-2}, "dts": [0.1], "methods": ["rk4"]}
    args.update(kwargs)
    with pytest.raises(ValueError, match=f"^{name}:"):
        ks.trade(build, run, **args)


# ---------------------------------------------------------------- to_xarray


def test_a_grid_becomes_a_dataset_over_its_parameters():
    # RK4's limit on the stiff chain is ~0.025 s, symplectic Euler's ~0.018 s.
    design = ks.grid(method=["rk4", "symplectic_euler"], dt=[0.05, 0.005, 0.02])
    table = ks.sweep(build_stiff, design, run_long, client="serial", progress=False)
    assert list(table["status"]) == ["failed", "ok", "ok", "failed", "ok", "failed"]
    ds = ks.to_xarray(table)
    assert ds["x"].dims == ("method", "dt", "x_dim0", "x_dim1")
    assert ds["x"].shape == (2, 3, 3, 3)
    assert list(ds["method"].values) == ["rk4", "symplectic_euler"]
    assert list(ds["dt"].values) == [0.05, 0.005, 0.02]  # the design's order, not sorted
    for i, p in enumerate(design):
        cell = ds.sel({"method": p["method"], "dt": p["dt"]})  # not sel(method=): a keyword of sel
        assert cell["status"].item() == table["status"][i]
        if table["status"][i] == "ok":
            assert np.array_equal(cell["x"].values, table["x"][i])
            assert cell["steps"].item() == table["steps"][i]
        else:  # NaN where a diverged run's numbers would be
            assert np.isnan(cell["x"].values).all() and np.isnan(cell["steps"].item())
    assert int((ds["status"] == "failed").sum()) == 3


def test_a_latin_hypercube_becomes_a_dataset_over_tasks():
    design = ks.latin_hypercube(5, seed=3, dt=(0.001, 0.01), tag=(0.0, 1.0))
    table = ks.sweep(lambda dt, tag: build("rk4", dt), design, run, client="serial", progress=False)
    ds = ks.to_xarray(table)
    assert ds["x"].dims == ("task", "x_dim0", "x_dim1")
    assert ds["dt"].dims == ds["tag"].dims == ("task",)  # 5 points, not a 5 x 5 grid
    assert np.array_equal(ds["dt"].values, [p["dt"] for p in design])
    assert np.array_equal(ds["v"].values[3], table["v"][3])
    # The same table along an explicit dimension (every dt is distinct: a grid of one axis).
    along = ks.to_xarray(table, dims=["dt"])
    assert along["x"].dims == ("dt", "x_dim0", "x_dim1") and along["tag"].dims == ("dt",)


def test_to_xarray_rejects_what_is_not_a_sweep_table():
    table = ks.sweep(build, ks.grid(method=["rk4"], dt=[0.1]), run, client="serial", progress=False)
    with pytest.raises(ValueError, match=r"^table:"):
        ks.to_xarray({"dt": [0.1]})
    with pytest.raises(ValueError, match=r"^dims:"):
        ks.to_xarray(table, dims=["stiffness"])
    with pytest.raises(ValueError, match=r"^dims:"):
        ks.to_xarray(table, dims=[])
