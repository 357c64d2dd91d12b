"""Every script in examples/ runs to completion (quick mode) and the CLI demos work."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import pytest

from kinema.demos import DEMOS

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = sorted((ROOT / "examples").glob("*.py"))


def _run(args: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, KINEMA_QUICK="1", MPLBACKEND="Agg")
    return subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, timeout=300)


def test_there_are_examples():
    assert EXAMPLES


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.name for p in EXAMPLES])
def test_example_runs(path: Path, tmp_path: Path):
    result = _run([sys.executable, str(path)], cwd=tmp_path)
    assert result.returncode == 0, result.stdout + result.stderr


@pytest.mark.parametrize("name", sorted(DEMOS))
def test_demo_writes_pictures_and_prints_numbers(name: str, tmp_path: Path):
    result = _run(
        [sys.executable, "-m", "kinema", "demo", name, "--quick", "--out", "out"], tmp_path
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert f"== demo {name}" in result.stdout
    pictures = list((tmp_path / "out").glob("*.png")) + list((tmp_path / "out").glob("*.gif"))
    assert pictures and all(p.stat().st_size > 1000 for p in pictures)
    if name == "skin" and importlib.util.find_spec("pygltflib") is not None:
        # The skinned walk is also written as glTF, and an independent reader opens it.
        import pygltflib

        gltf = pygltflib.GLTF2().load(str(tmp_path / "out" / "skin.glb"))
        assert gltf.skins and gltf.animations and gltf.meshes


def test_cli_info_and_bad_demo(tmp_path: Path):
    result = _run([sys.executable, "-m", "kinema", "info"], tmp_path)
    assert result.returncode == 0 and "kinema" in result.stdout
    result = _run([sys.executable, "-m", "kinema", "demo", "no-such-demo"], tmp_path)
    assert result.returncode == 2 and "invalid choice" in result.stderr
