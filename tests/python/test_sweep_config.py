"""``kinema sweep CONFIG.toml``: the config's functions come from the user's code directory,
the design from the file; results as the Python API gives them; bad configs exit 2 with a
message that names the key and never quotes the file's text."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from kinema import cli
from kinema import sweep as ks

TASKS = """
import numpy as np
from kinema.particles import Gravity, ParticleSystem, Springs


def build(stiffness, dt):
    x = np.zeros((5, 3))
    x[:, 0] = np.arange(5) * 0.1
    chain = ParticleSystem(x, masses=np.r_[np.inf, np.ones(4)])
    chain.add(Springs([[i, i + 1] for i in range(4)], stiffness, damping=0.1))
    chain.add(Gravity())
    return chain, dt


def run(system):
    chain, dt = system
    chain.step(dt, steps=200)
    return {"tip_y": chain.positions[-1, 1]}
"""


def _project(tmp_path: Path, module: str, body: str) -> Path:
    code = tmp_path / "code"
    code.mkdir()
    (code / f"{module}.py").write_text(TASKS)
    config = tmp_path / "sweep.toml"
    config.write_text(body)
    return config


def test_cli_runs_a_grid_serially_and_prints_the_table(tmp_path, capsys):
    config = _project(
        tmp_path,
        "cfg_tasks_a",
        """
[sweep]
build = "cfg_tasks_a:build"
run = "cfg_tasks_a:run"
client = "serial"
checkpoint_dir = "out"

[grid]
stiffness = [100.0, 1000.0]
dt = [0.005, 0.05]
""",
    )
    status = cli.main(["sweep", str(config), "--code", str(tmp_path / "code"), "--no-progress"])
    printed = capsys.readouterr().out
    assert status == 1  # dt = 0.05 diverges at 1000 N/m: one task failed
    assert "4 tasks: 3 ok, 1 failed" in printed and "SimulationError" in printed
    assert list((tmp_path / "out").glob("part-*.parquet"))
    # The same numbers as the Python API gives.
    sys.path.insert(0, str(tmp_path / "code"))
    import cfg_tasks_a

    table = ks.sweep(
        cfg_tasks_a.build,
        ks.grid(stiffness=[100.0, 1000.0], dt=[0.005, 0.05]),
        cfg_tasks_a.run,
        client="serial",
        checkpoint_dir=tmp_path / "out",  # read back from what the CLI wrote
        progress=False,
    )
    direct = cfg_tasks_a.run(cfg_tasks_a.build(100.0, 0.005))["tip_y"]
    assert table["tip_y"][0] == direct and list(table["status"]) == ["ok", "ok", "ok", "failed"]


def test_cli_runs_a_latin_hypercube_on_a_local_cluster(tmp_path):
    config = _project(
        tmp_path,
        "cfg_tasks_b",
        """
[sweep]
build = "cfg_tasks_b:build"
run = "cfg_tasks_b:run"
checkpoint_dir = "out"

[latin_hypercube]
n = 4
seed = 2
stiffness = [100.0, 200.0]
dt = [0.001, 0.002]
""",
    )
    # The default code directory is the config's folder: move the module there.
    (tmp_path / "code" / "cfg_tasks_b.py").rename(tmp_path / "cfg_tasks_b.py")
    env = dict(os.environ, MPLBACKEND="Agg")
    result = subprocess.run(
        [sys.executable, "-m", "kinema", "sweep", str(config), "--no-progress"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr
    assert "4 tasks: 4 ok, 0 failed" in result.stdout
    design = ks.latin_hypercube(4, seed=2, stiffness=(100.0, 200.0), dt=(0.001, 0.002))

    def never(system):
        raise AssertionError("the CLI's results were not stored")

    sys.path.insert(0, str(tmp_path))
    import cfg_tasks_b

    table = ks.sweep(
        cfg_tasks_b.build,
        design,
        never,
        client="serial",
        checkpoint_dir=tmp_path / "out",
        progress=False,
    )
    for i, p in enumerate(design):
        assert table["tip_y"][i] == cfg_tasks_b.run(cfg_tasks_b.build(**p))["tip_y"]


SECRET = "zq_secret_text"  # must never appear in an error message


@pytest.mark.parametrize(
    ("body", "key"),
    [
        (
            f'[sweep]\nbuild = "os:system"\nrun = "tasks:run"\n[grid]\nk = [1]\n# {SECRET}',
            "sweep.build",
        ),
        (f'[sweep]\nbuild = "{SECRET}:build"\nrun = "tasks:run"\n[grid]\nk = [1]', "sweep.build"),
        (f'[sweep]\nbuild = "tasks:{SECRET}"\nrun = "tasks:run"\n[grid]\nk = [1]', "sweep.build"),
        ('[sweep]\nbuild = "tasks.build()"\nrun = "tasks:run"\n[grid]\nk = [1]', "sweep.build"),
        ('[sweep]\nbuild = "../tasks:build"\nrun = "tasks:run"\n[grid]\nk = [1]', "sweep.build"),
        (
            f'[sweep]\nbuild = "tasks:build"\nrun = "tasks:run"\n{SECRET} = 1\n[grid]\nk = [1]',
            "sweep",
        ),
        (
            f'[sweep]\nbuild = "tasks:build"\nrun = "tasks:run"\nclient = "{SECRET}"\n[grid]\nk = [1]',
            "sweep.client",
        ),
        (
            '[sweep]\nbuild = "tasks:build"\nrun = "tasks:run"\n[grid]\nk = [1]\n[[params]]\nk = 2',
            "design",
        ),
        ('[sweep]\nbuild = "tasks:build"\nrun = "tasks:run"\n', "design"),
        ('[sweep]\nbuild = "tasks:build"\nrun = "tasks:run"\n[grid]\nk = []', "k"),
        (
            '[sweep]\nbuild = "tasks:build"\nrun = "tasks:run"\n[latin_hypercube]\nn = 0\nseed = 1\nk = [1, 2]',
            "n",
        ),
        (
            '[sweep]\nbuild = "tasks:build"\nrun = "tasks:run"\n[[params]]\nk = 1\n[[params]]\nk = 1',
            "params",
        ),
        (
            '[sweep]\nbuild = "tasks:build"\nrun = "tasks:run"\nretries = -1\n[grid]\nk = [1]',
            "sweep.retries",
        ),
        (f'[sweep\nbuild = "{SECRET}"', "sweep.toml"),
        (
            f'[sweep]\nbuild = "tasks:build"\nrun = "tasks:run"\n[{SECRET}]\n[grid]\nk = [1]',
            "sweep.toml",
        ),
    ],
)
def test_a_bad_config_exits_2_naming_the_key(tmp_path, capsys, body, key):
    (tmp_path / "tasks.py").write_text(TASKS)
    config = tmp_path / "sweep.toml"
    config.write_text(body)
    assert cli.main(["sweep", str(config), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"kinema sweep: {key}:"), err
    assert SECRET not in err
