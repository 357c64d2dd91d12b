"""``kinema run SCENE.toml``: the example scene runs and writes what it promises, a resumed run
ends where a straight one does, and mistakes in a file are reported with their place."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from kinema import ParseError, scenefile
from kinema import cloth as kinema_cloth
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


def test_scene_files_cannot_write_outside_the_output_folder(tmp_path: Path):
    for bad in ("/tmp/kinema-escape.kin", "../../escape.kin", "a/../../escape.kin", ""):
        path = tmp_path / "w.toml"
        path.write_text(f"[scene]\nframes = 1\n[output]\ncheckpoint = {bad!r}\n")
        with pytest.raises(ValueError, match=r"\[output\]: checkpoint"):
            scenefile.load(path)
        r = kinema("run", str(path), "--no-progress", "--out", "out", cwd=tmp_path)
        assert r.returncode == 2 and "checkpoint" in r.stderr, r.stderr
    assert (
        not Path("/tmp/kinema-escape.kin").exists()
        and not (tmp_path.parent / "escape.kin").exists()
    )
    # A symbolic link inside the output folder cannot lead out of it either.
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "link").symlink_to(elsewhere)
    path.write_text("[scene]\nframes = 1\n[output]\ncheckpoint = 'link/x.kin'\n")
    r = kinema("run", str(path), "--no-progress", "--out", "out", cwd=tmp_path)
    assert r.returncode == 2 and "outside the output folder" in r.stderr, r.stderr
    assert not (elsewhere / "x.kin").exists()
    # Only the command line may choose another place.
    path.write_text("[scene]\nframes = 1\n[output]\ncheckpoint = 'x.kin'\n")
    r = kinema(
        "run", str(path), "--no-progress", "--checkpoint", str(elsewhere / "y.kin"), cwd=tmp_path
    )
    assert r.returncode == 0, r.stderr
    assert Scene.load(elsewhere / "y.kin").frame == 1


SECRET = "SECRET-TOKEN-1234 not a motion file"


def test_scene_files_cannot_read_outside_their_folder_and_never_quote_inputs(tmp_path: Path):
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    private = tmp_path / "private"
    private.mkdir()
    (private / "secret.bvh").write_text(SECRET + "\n")
    (scenes / "inside.bvh").write_text(SECRET + "\n")
    cases = {
        str(private / "secret.bvh"): "must be relative",
        "../private/secret.bvh": "leads outside",
        "/etc/passwd": "must be relative",
    }
    path = scenes / "r.toml"
    for name, message in cases.items():
        path.write_text(f"[scene]\nframes = 1\n[[character]]\nbvh = {name!r}\n")
        with pytest.raises(ValueError, match=rf"character\[0\]: bvh: .*{message}") as e:
            scenefile.load(path)
        assert SECRET not in str(e.value) and "root:" not in str(e.value)
    (scenes / "link.bvh").symlink_to(private / "secret.bvh")
    path.write_text("[scene]\nframes = 1\n[[character]]\nbvh = 'link.bvh'\n")
    with pytest.raises(ValueError, match="leads outside"):
        scenefile.load(path)
    # A malformed file inside the folder is named with its line, its content is not quoted.
    path.write_text("[scene]\nframes = 1\n[[character]]\nbvh = 'inside.bvh'\n")
    with pytest.raises(ParseError, match=r"inside\.bvh:1: expected HIERARCHY") as e:
        scenefile.load(path)
    assert "SECRET" not in str(e.value)
    r = kinema("run", str(path), "--no-progress", cwd=tmp_path)
    assert r.returncode == 2 and "inside.bvh:1" in r.stderr and "SECRET" not in r.stderr
    # A folder given on the command line may be read.
    path.write_text("[scene]\nframes = 1\n[[character]]\nbvh = '../private/secret.bvh'\n")
    with pytest.raises(ParseError, match=r"secret\.bvh:1"):
        scenefile.load(path, read_dirs=[private])
    r = kinema("run", str(path), "--no-progress", "--allow-read", str(private), cwd=tmp_path)
    assert r.returncode == 2 and "secret.bvh:1" in r.stderr and "SECRET" not in r.stderr


def test_non_utf8_toml_and_obj_files_raise_parse_error_naming_the_file(tmp_path: Path):
    toml = tmp_path / "latin1.toml"
    toml.write_bytes(b"[scene]\nframes = 1\n# caf\xe9\n")
    with pytest.raises(ParseError, match=r"latin1\.toml:3: not UTF-8"):
        scenefile.load(toml)
    obj = tmp_path / "mesh.obj"
    obj.write_bytes(b"v 0 0 0\nv 1 0 0\nv 0 0 1\n# \xff\xfe\nf 1 2 3\n")
    with pytest.raises(ParseError, match=r"mesh\.obj:4: not UTF-8"):
        kinema_cloth.Cloth.from_obj(obj)
    toml.write_text("[scene]\nframes = 1\n[[cloth]]\nobj = 'mesh.obj'\n")
    with pytest.raises(ParseError, match=r"cloth\[0\]: .*mesh\.obj:4"):
        scenefile.load(toml)
    r = kinema("run", str(toml), "--no-progress", cwd=tmp_path)
    assert r.returncode == 2 and "mesh.obj:4" in r.stderr and "Traceback" not in r.stderr


def test_kinema_run_reports_a_failed_simulation_in_one_line(tmp_path: Path):
    path = tmp_path / "diverge.toml"
    path.write_text(
        "[scene]\nframes = 400\ndt = 0.1\n[[particles]]\npositions = [[0, 0, 0], [1, 0, 0]]\n"
        "items = [{ type = 'Springs', pairs = [[0, 1]], stiffness = 1e9, rest = [0.5] }]\n"
        "step = { method = 'explicit_euler' }\n"
    )
    r = kinema("run", str(path), "--no-progress", cwd=tmp_path)
    assert r.returncode == 1, (r.stdout, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert "Traceback" not in r.stderr and len(lines) == 2, r.stderr
    assert lines[0].startswith("kinema run: StabilityWarning: ")  # one line, no source line
    assert lines[1].startswith("kinema run: ") and "diverge.toml" in lines[1]
    assert "simulation failed in frame" in lines[1]
    r = kinema("run", str(path), "--no-progress", "--resume", "nowhere.kin", cwd=tmp_path)
    assert r.returncode == 2 and "nowhere.kin" in r.stderr and "Traceback" not in r.stderr
    (tmp_path / "bad.kin").write_bytes(b"not a checkpoint")
    r = kinema("run", str(path), "--no-progress", "--resume", "bad.kin", cwd=tmp_path)
    assert r.returncode == 2 and "not a kinema scene checkpoint" in r.stderr
