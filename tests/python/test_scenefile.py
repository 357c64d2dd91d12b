"""``kinema run SCENE.toml``: the example scene runs and writes what it promises, a resumed run
ends where a straight one does, and mistakes in a file are reported with their place."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from kinema import scenefile
from kinema.scene import Scene

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "scene.toml"


def kinema(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, MPLBACKEND="Agg")
    return subprocess.run(
        [sys.executable, "-m", "kinema", *args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_example_scene_runs_and_writes_its_outputs(tmp_path: Path):
    r = kinema("run", str(EXAMPLE), "--frames", "4", "--no-progress", "--out", "out", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "ran to frame 4" in r.stdout and "0.kinetic_energy" in r.stdout
    out = tmp_path / "out"
    for name in ["scene.gif", "scene.png", "scene.kin", "records.npz"]:
        assert (out / name).stat().st_size > 100, name
    with np.load(out / "records.npz") as rec:
        assert rec["0.kinetic_energy"].shape == (4,)
    assert Scene.load(out / "scene.kin").frame == 4


def test_resumed_run_ends_where_a_straight_run_does(tmp_path: Path):
    assert (
        kinema(
            "run", str(EXAMPLE), "--frames", "6", "--no-progress", "--out", "a", cwd=tmp_path
        ).returncode
        == 0
    )
    assert (
        kinema(
            "run", str(EXAMPLE), "--frames", "3", "--no-progress", "--out", "b", cwd=tmp_path
        ).returncode
        == 0
    )
    r = kinema(
        "run",
        str(EXAMPLE),
        "--resume",
        "b/scene.kin",
        "--frames",
        "3",
        "--no-progress",
        "--out",
        "b",
        cwd=tmp_path,
    )
    assert r.returncode == 0, r.stderr
    a, b = Scene.load(tmp_path / "a" / "scene.kin"), Scene.load(tmp_path / "b" / "scene.kin")
    assert a.frame == b.frame == 6
    for x, y in zip(a.systems[:3], b.systems[:3], strict=True):
        assert np.array_equal(x.positions, y.positions)


def test_scene_file_builds_every_kind(tmp_path: Path):
    scene, output = scenefile.load(EXAMPLE)
    kinds = [type(s).__name__ for s in scene.systems]
    assert kinds == ["Cloth", "ParticleSystem", "World", "AnimatedSphere", "Character"]
    assert output.frames == 60 and scene.substeps == 2
    assert len(scene.systems[2].shapes) == 4


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("[scene]\ndt = 0.01\n", "give frames or duration"),
        ("[scene]\nframes = 1\n[[clothes]]\n", "unknown tables"),
        (
            "[scene]\nframes = 1\n[[particles]]\nitems = [{ type = 'Gravit' }]\n",
            r"particles\[0\]: items\[0\].type",
        ),
        (
            "[scene]\nframes = 1\n[[particles]]\nitems = [{ type = 'Gravity', strength = 1 }]\n",
            r"items\[0\]: .*strength",
        ),
        (
            "[scene]\nframes = 1\n[[rigid]]\nbodies = [{ shape = { type = 'Box', half_extents = [1, 1, 1] }, mass = -1 }]\n",
            r"rigid\[0\]",
        ),
        ("[scene]\nframes = 1\n[[cloth]]\noffset = [0, 1, 0]\n", "grid"),
        ("[scene]\nframes = 1\n[output]\nmovie = 'a.mp4'\n", r"\[output\]"),
        ("[scene\n", "not valid TOML"),
    ],
)
def test_mistakes_are_reported_with_their_place(tmp_path: Path, text: str, message: str):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        scenefile.load(path)
    r = kinema("run", str(path), "--no-progress", cwd=tmp_path)
    assert r.returncode == 2 and "bad.toml" in r.stderr


def test_cli_demo_default_bench_and_info(tmp_path: Path):
    r = kinema("info", cwd=tmp_path)
    assert r.returncode == 0 and "build: profile" in r.stdout
    r = kinema("bench", "no_such_bench", cwd=tmp_path)
    assert r.returncode == 2 and "unknown benchmarks" in r.stderr
    r = kinema("demo", "--quick", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "== demo showcase" in r.stdout and (tmp_path / "kinema-out" / "showcase.gif").exists()


def test_box_collider_with_orientation_in_a_file(tmp_path: Path):
    path = tmp_path / "box.toml"
    path.write_text(
        "[scene]\nframes = 2\n[[cloth]]\ngrid = { nx = 4, ny = 4 }\n"
        "colliders = [{ type = 'Box', center = [0, -1, 0], half_extents = [1, 0.5, 1], "
        "orientation = [0.9950041652780258, 0, 0.09983341664682815, 0] }]\n"
    )
    scene, _ = scenefile.load(path)
    scene.run(frames=2, progress=False)
    assert np.isfinite(scene.systems[0].positions).all()
