"""kinema.sweep: designs, and sweeps run serially and on a real 2-worker Dask LocalCluster
(scheduler and workers as processes) giving the same bits, resuming without recomputing,
recording failed tasks."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

import kinema
from kinema import sweep as ks
from kinema.particles import Gravity, ParticleSystem, Springs


@pytest.fixture(scope="module")
def client():
    from dask.distributed import Client, LocalCluster

    cluster = LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
    )
    with Client(cluster) as c:
        yield c
    cluster.close()


# A hanging chain of 8 particles (the first pinned) on springs of `stiffness` (N/m), stepped
# 400 times by symplectic Euler. Its stability limit is dt < 2 / sqrt(4 k / m), about
# 0.032 s at k = 1000 N/m and 0.058 s at 300 N/m: dt = 0.05 diverges at 1000 N/m (the state
# grows ~8x a step until it is not finite: kinema.SimulationError).
def build(stiffness: float, dt: float, log: str = "") -> dict:
    n = 8
    x = np.zeros((n, 3))
    x[:, 0] = np.arange(n) * 0.1
    masses = np.full(n, 1.0)
    masses[0] = np.inf
    ps = ParticleSystem(x, masses=masses)
    ps.add(Springs(np.array([[i, i + 1] for i in range(n - 1)]), stiffness, damping=0.1))
    ps.add(Gravity())
    return {"ps": ps, "dt": dt, "log": log, "params": (stiffness, dt)}


def run(system: dict) -> dict:
    if system["log"]:
        with open(system["log"], "a") as f:  # one line per call, from any process
            f.write(f"{system['params']}\n")
    ps, dt = system["ps"], system["dt"]
    ps.step(dt, steps=400)
    return {
        "tip_y": ps.positions[-1, 1],
        "energy": ps.kinetic_energy() + ps.potential_energy(),
        "positions": ps.positions.copy(),
        "threads": kinema.num_threads(),
        "pid": os.getpid(),
    }


def calls(log: Path) -> list[str]:
    return log.read_text().splitlines() if log.exists() else []


def same_numbers(a, b) -> None:
    """Bitwise equal parameters and outputs (not timings or process ids)."""
    assert list(a.columns) == list(b.columns)
    assert list(a["status"]) == list(b["status"])
    for name in ["stiffness", "dt", "tip_y", "energy"]:
        assert np.array_equal(a[name].to_numpy(), b[name].to_numpy(), equal_nan=True), name
    for pa, pb in zip(a["positions"], b["positions"], strict=True):
        assert (pa is None and pb is None) or (pa.shape == (8, 3) and np.array_equal(pa, pb))


# ---------------------------------------------------------------- designs


def test_grid_is_every_combination_first_axis_slowest():
    g = ks.grid(dt=[0.01, 0.02], k=np.array([1, 10, 100]), method=["rk4"])
    assert len(g) == 6
    assert g[0] == {"dt": 0.01, "k": 1, "method": "rk4"}
    assert g[1] == {"dt": 0.01, "k": 10, "method": "rk4"}
    assert g[3] == {"dt": 0.02, "k": 1, "method": "rk4"}
    assert all(type(p["k"]) is int for p in g)  # numpy scalars unwrapped


@pytest.mark.parametrize(
    ("axes", "name"),
    [
        ({}, "grid"),
        ({"dt": []}, "dt"),
        ({"dt": "0.1"}, "dt"),
        ({"dt": 0.1}, "dt"),
        ({"dt": [0.1, [0.2]]}, "dt"),
        ({"dt": [0.1, None]}, "dt"),
    ],
)
def test_grid_rejects_bad_axes(axes, name):
    with pytest.raises(ValueError, match=f"^{name}:"):
        ks.grid(**axes)


def test_latin_hypercube_puts_one_point_in_every_stratum():
    n = 50
    design = ks.latin_hypercube(n, seed=7, k=(10.0, 1000.0), dt=(1e-3, 2e-3))
    assert len(design) == n
    for name, (low, high) in [("k", (10.0, 1000.0)), ("dt", (1e-3, 2e-3))]:
        u = (np.array([p[name] for p in design]) - low) / (high - low)
        assert np.all((u >= 0) & (u < 1))
        assert sorted(np.floor(u * n).astype(int)) == list(range(n))
    assert design == ks.latin_hypercube(n, seed=7, k=(10.0, 1000.0), dt=(1e-3, 2e-3))
    other = ks.latin_hypercube(n, seed=8, k=(10.0, 1000.0), dt=(1e-3, 2e-3))
    assert design != other
    # The pairing of strata is random: the two coordinates are not correlated (|r| of
    # independent permutations of 50 is below 0.45 with probability > 0.999).
    r = np.corrcoef([p["k"] for p in design], [p["dt"] for p in design])[0, 1]
    assert abs(r) < 0.45


@pytest.mark.parametrize(
    ("call", "name"),
    [
        (lambda: ks.latin_hypercube(0, seed=0, k=(0, 1)), "n"),
        (lambda: ks.latin_hypercube(2.5, seed=0, k=(0, 1)), "n"),
        (lambda: ks.latin_hypercube(True, seed=0, k=(0, 1)), "n"),
        (lambda: ks.latin_hypercube(4, seed=-1, k=(0, 1)), "seed"),
        (lambda: ks.latin_hypercube(4, seed="1", k=(0, 1)), "seed"),
        (lambda: ks.latin_hypercube(4, seed=0), "ranges"),
        (lambda: ks.latin_hypercube(4, seed=0, k=(1, 1)), "k"),
        (lambda: ks.latin_hypercube(4, seed=0, k=(0, np.inf)), "k"),
        (lambda: ks.latin_hypercube(4, seed=0, k=(0, np.nan)), "k"),
        (lambda: ks.latin_hypercube(4, seed=0, k=(0, 1, 2)), "k"),
        (lambda: ks.latin_hypercube(4, seed=0, k="ab"), "k"),
    ],
)
def test_latin_hypercube_rejects_bad_arguments(call, name):
    with pytest.raises(ValueError, match=f"^{name}:"):
        call()


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"params": {"stiffness": 1.0, "dt": 0.01}}, "params"),
        ({"params": []}, "params"),
        ({"params": "stiffness"}, "params"),
        ({"params": [{"stiffness": 1.0, "dt": 0.01}, {"stiffness": 2.0}]}, r"params\[1\]"),
        ({"params": [{"stiffness": 1.0, "dt": 0.01}] * 2}, "params"),
        ({"params": [{"stiffness": 1.0, "dt": 0.01}, 3]}, r"params\[1\]"),
        ({"params": [{"stiffness": 1.0, "dt": [0.01]}]}, r"params\[0\]\['dt'\]"),
        ({"params": [{"stiffness": 1.0, "status": 0.01}]}, r"params\[0\]"),
        ({"retries": -1}, "retries"),
        ({"retries": 1.5}, "retries"),
        ({"client": "threads"}, "client"),
        ({"progress": "yes"}, "progress"),
        ({"build": 3}, "build"),
        ({"run": None}, "run"),
    ],
)
def test_sweep_rejects_bad_arguments(kwargs, name, tmp_path):
    args = {"build": build, "params": ks.grid(stiffness=[1.0], dt=[0.01]), "run": run}
    args.update({"client": "serial", **kwargs})
    with pytest.raises(ValueError, match=f"^{name}:"):
        ks.sweep(args.pop("build"), args.pop("params"), args.pop("run"), **args)


def test_checkpoint_dir_must_be_a_directory(tmp_path):
    (tmp_path / "file").write_text("x")
    with pytest.raises(ValueError, match=r"^checkpoint_dir:"):
        ks.sweep(
            build,
            ks.grid(stiffness=[1.0], dt=[0.01]),
            run,
            client="serial",
            checkpoint_dir=tmp_path / "file",
            progress=False,
        )


# ---------------------------------------------------------------- sweeps

DESIGN = ks.grid(stiffness=[100.0, 300.0, 1000.0], dt=[0.002, 0.005, 0.01, 0.05])


def test_serial_and_two_worker_cluster_give_the_same_bits(client):
    serial = ks.sweep(build, DESIGN, run, client="serial", progress=False)
    assert list(serial["status"]) == [
        "failed" if p["dt"] == 0.05 and p["stiffness"] >= 1000 else "ok" for p in DESIGN
    ]
    cluster = ks.sweep(build, DESIGN, run, client=client, progress=False)
    same_numbers(serial, cluster)
    ok = cluster["status"] == "ok"
    # The workers ran the tasks, with kinema's pool at one thread each.
    assert set(cluster["pid"][ok]) <= {w["pid"] for w in _workers(client)}
    assert set(cluster["threads"][ok]) == {1}
    # The table holds what `run` returned for each parameter set, where it belongs.
    direct = run(build(**DESIGN[4]))
    assert cluster["tip_y"][4] == direct["tip_y"] and cluster["energy"][4] == direct["energy"]
    assert np.array_equal(cluster["positions"][4], direct["positions"])
    assert np.all(cluster["tip_y"][ok] < 0)  # the chains fell


def _workers(client) -> list[dict]:
    return list(client.run(lambda: {"pid": os.getpid()}).values())


def test_a_diverging_task_is_recorded_with_its_parameters_and_error(client):
    design = ks.grid(stiffness=[1000.0], dt=[0.01, 0.05, 0.005])
    table = ks.sweep(build, design, run, client=client, progress=False)
    assert list(table["status"]) == ["ok", "failed", "ok"]
    bad = table.iloc[1]
    assert (bad["stiffness"], bad["dt"]) == (1000.0, 0.05)
    assert bad["error"].startswith("SimulationError:")
    assert np.isnan(bad["tip_y"]) and bad["positions"] is None
    assert table["error"][0] is None and table["error"][2] is None
    # Recorded by the worker that ran it (with its time), not by a retry of a lost batch; and
    # the same in a plain loop.
    assert bad["seconds"] > 0
    serial = ks.sweep(build, design, run, client="serial", progress=False)
    assert list(serial["status"]) == ["ok", "failed", "ok"]
    assert serial["error"][1] == bad["error"]


def test_an_interrupted_sweep_resumes_on_the_cluster_without_recomputing(client, tmp_path):
    log = tmp_path / "calls.txt"
    design = ks.grid(
        stiffness=[100.0, 300.0, 1000.0], dt=[0.002, 0.005, 0.01, 0.05], log=[str(log)]
    )
    stop_at = 5

    def interrupted_run(system: dict) -> dict:
        if len(calls(log)) == stop_at:
            raise KeyboardInterrupt  # Ctrl-C during the sixth task
        return run(system)

    results = tmp_path / "results"
    with pytest.raises(KeyboardInterrupt):
        ks.sweep(
            build, design, interrupted_run, client="serial", checkpoint_dir=results, progress=False
        )
    assert len(calls(log)) == stop_at
    assert len(list(results.glob("part-*.parquet"))) == stop_at  # one file per finished task
    assert not list(results.glob(".*"))  # no temporary files left

    resumed = ks.sweep(build, design, run, client=client, checkpoint_dir=results, progress=False)
    assert sorted(calls(log)) == sorted(f"{(p['stiffness'], p['dt'])}" for p in design)
    # A third run finds everything on disk and calls nothing.
    again = ks.sweep(build, design, run, client=client, checkpoint_dir=results, progress=False)
    assert len(calls(log)) == len(design)
    reference = ks.sweep(build, design, run, client="serial", progress=False)
    same_numbers(reference, resumed)
    same_numbers(reference, again)
    assert np.array_equal(again["pid"], resumed["pid"], equal_nan=True)  # read, not rerun


def test_array_and_integer_outputs_come_back_from_parquet_unchanged(tmp_path):
    def many(system: dict) -> dict:
        return {
            "grid": np.arange(12.0).reshape(2, 3, 2) * system["dt"],
            "flags": np.array([True, False]),
            "count": np.int32(7),
            "tiny": 5e-324,
        }

    design = ks.grid(stiffness=[1.0], dt=[0.1, 0.3])
    first = ks.sweep(build, design, many, client="serial", checkpoint_dir=tmp_path, progress=False)

    def never(system: dict) -> dict:
        raise AssertionError("a finished task was run again")

    back = ks.sweep(build, design, never, client="serial", checkpoint_dir=tmp_path, progress=False)
    for a, b in zip(first["grid"], back["grid"], strict=True):
        assert b.shape == (2, 3, 2) and b.dtype == np.float64 and np.array_equal(a, b)
    assert back["flags"][0].dtype == np.bool_ and list(back["flags"][1]) == [True, False]
    assert list(back["count"]) == [7, 7] and list(back["tiny"]) == [5e-324, 5e-324]
    # Only the design's tasks are returned, in its order, even with other results on disk.
    one = ks.sweep(
        build, design[1:], never, client="serial", checkpoint_dir=tmp_path, progress=False
    )
    assert list(one["dt"]) == [0.3]


def test_python_scalars_give_the_columns_their_numpy_forms_give():
    def python(system: dict) -> dict:
        return {"flag": True, "count": -(2**63), "value": 0.1}

    def numpy(system: dict) -> dict:
        return {"flag": np.bool_(True), "count": np.int64(-(2**63)), "value": np.float64(0.1)}

    design = ks.grid(stiffness=[1.0], dt=[0.1])
    a = ks.sweep(build, design, python, client="serial", progress=False)
    b = ks.sweep(build, design, numpy, client="serial", progress=False)
    for name in ("flag", "count", "value"):
        assert a[name].dtype == b[name].dtype and a[name][0] == b[name][0]
        assert type(a[name].tolist()[0]) is type(b[name].tolist()[0])
    big = ks.sweep(build, design, lambda s: {"count": 2**64}, client="serial", progress=False)
    assert big["error"][0].startswith("TypeError: run: result 'count' must be numbers")


def test_a_bad_return_value_fails_its_task_with_a_clear_error():
    def bad(system: dict) -> dict:
        return {"text": "not a number"}  # type: ignore[dict-item]

    table = ks.sweep(
        build, ks.grid(stiffness=[1.0], dt=[0.1]), bad, client="serial", progress=False
    )
    assert table["status"][0] == "failed"
    assert table["error"][0].startswith("TypeError: run: result 'text' must be numbers")


def _worker_settings() -> tuple:
    import dask

    return (
        dask.config.get("distributed.worker.profile.enabled"),
        dask.config.get("distributed.admin.tick.interval"),
        os.environ.get("KINEMA_NUM_THREADS"),
    )


def test_local_client_starts_quiet_single_threaded_workers_and_stops_them():
    import dask

    with pytest.raises(ValueError, match="n_workers"):
        ks.local_client(0)
    with ks.local_client(1) as c:
        settings = c.run(_worker_settings)
        cluster = c.cluster
    assert list(settings.values()) == [(False, "500ms", "1")]
    assert dask.config.get("distributed.worker.profile.enabled")  # this process's unchanged
    assert cluster.status.name == "closed"


def test_no_client_starts_a_local_cluster_of_single_threaded_processes():
    table = ks.sweep(build, ks.grid(stiffness=[100.0], dt=[0.01, 0.005]), run, progress=False)
    assert list(table["status"]) == ["ok", "ok"]
    assert set(table["threads"]) == {1}
    assert os.getpid() not in set(table["pid"])
