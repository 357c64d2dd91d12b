"""Scenes described in a small TOML file, for ``kinema run SCENE.toml``.

A file has a ``[scene]`` table (``dt``, ``substeps``, and ``frames`` or ``duration``), an
optional ``[output]`` table, and any number of systems. Items inside a system are tables with a
``type`` naming a class of the system's module and its constructor arguments, so every force,
collider and shape of the Python API is available under its own name::

    [scene]
    dt = 0.0333          # frame interval (s)
    substeps = 2
    duration = 2.0       # or: frames = 60

    [output]             # all optional; relative paths inside the output folder
    gif = "scene.gif"    # or .mp4
    png = "scene.png"    # the last frame
    obj = "obj"          # an OBJ sequence in this folder
    checkpoint = "scene.kin"
    record = ["0.kinetic_energy"]   # keys of Scene.diagnostics(), saved to records.npz

    [[cloth]]
    grid = { nx = 20, ny = 20, width = 1.0, height = 1.0, stretch = 2000.0 }
    offset = [0.0, 1.0, 0.0]
    pin = [0, 19]
    colliders = [{ type = "Plane" }]
    step = { integrator = "implicit_euler", tol = 1e-3 }

    [[particles]]
    capacity = 1000
    items = [{ type = "Gravity" }, { type = "Plane", restitution = 0.3 },
             { type = "Emitter", rate = 300.0, velocity = [0.0, 3.0, 0.0], lifespan = 1.0 }]
    step = { method = "symplectic_euler" }

    [[rigid]]
    ground = { friction = 0.6 }
    bodies = [{ shape = { type = "Box", half_extents = [0.1, 0.1, 0.1] }, mass = 1.0,
                position = [0.0, 0.1, 0.0] }]

    [[animated_sphere]]
    radius = 0.3
    times = [0.0, 1.0]
    centers = [[0.0, 0.3, 0.0], [0.5, 0.3, 0.0]]
    interpolation = "linear"

    [[character]]          # asf + amc, or bvh; paths relative to the TOML file's folder
    asf = "07-walk.asf"
    amc = "07_05-walk.amc"
    radius = 0.06

Cloth also takes ``obj = "mesh.obj"`` (with the material keys) instead of ``grid``. Rigid
bodies take every keyword of :meth:`kinema.rigid.World.add_body`; an ``orientation`` (of a
body or a box collider) is a scalar-first quaternion. Mistakes are reported with their place,
e.g. ``particles[0].items[1]``.

A scene file cannot reach outside the folders it is given (it may come from someone else):

- **Inputs** (``asf``, ``amc``, ``bvh``, ``obj``) are relative paths, resolved from the scene
  file's folder, that must end inside it (symbolic links followed), inside kinema's bundled
  data folder (``kinema/data``) or inside a folder given to :func:`load` as ``read_dirs``
  (``kinema run --allow-read DIR``). Errors about an unreadable or malformed input name the
  file, the line and the field, never its content.
- **Outputs** (``gif``, ``png``, ``obj``, ``checkpoint``) are relative paths without ``..``,
  written inside the output folder (:meth:`Output.path`); only the command line may write
  elsewhere (``kinema run --checkpoint PATH``).
"""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path, PurePath
from typing import Any

import numpy as np

from kinema import anim, cloth, mocap, particles, rigid
from kinema._array import real
from kinema._kinema import ParseError
from kinema.rotation import Rotation
from kinema.scene import AnimatedSphere, Character, Scene

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = ["Output", "load"]


@dataclass
class Output:
    """What ``kinema run`` writes, from the ``[output]`` table."""

    frames: int
    gif: str | None = None
    png: str | None = None
    obj: str | None = None
    checkpoint: str | None = None
    record: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        for name in ("gif", "png", "obj", "checkpoint"):
            value = getattr(self, name)
            if value is None:
                continue
            if not isinstance(value, str) or not value:
                raise ValueError(f"{name}: expected a file name, got {value!r}")
            parts = PurePath(value).parts
            if PurePath(value).is_absolute() or Path(value).anchor or ".." in parts:
                raise ValueError(
                    f"{name}: {value!r} must be a relative path inside the output folder "
                    "(no absolute path, no '..'); choose the folder with --out"
                )
        if not isinstance(self.record, list) or not all(isinstance(r, str) for r in self.record):
            raise ValueError("record: expected a list of diagnostics names")

    def path(self, out_dir: str | os.PathLike[str], name: str) -> Path:
        """Where output ``name`` (a value of this table) is written: inside ``out_dir``, after
        following symbolic links; ``ValueError`` if a link leads outside."""
        root = Path(out_dir).resolve()
        target = (root / name).resolve()
        if not target.is_relative_to(root):
            raise ValueError(f"{name!r}: leads outside the output folder {root}")
        return target


def load(
    path: str | os.PathLike[str], *, read_dirs: Sequence[str | os.PathLike[str]] = ()
) -> tuple[Scene, Output]:
    """Read a scene file; return the scene and what to write. Input files it names must lie
    in its folder, in kinema's data folder or in one of ``read_dirs`` (see the module
    docstring). Raises ``ValueError`` (``kinema.ParseError`` for text that is not UTF-8 or
    TOML) naming the place of any mistake."""
    path = Path(path)
    data = path.read_bytes()
    try:
        doc = tomllib.loads(data.decode("utf-8"))
    except UnicodeDecodeError as e:
        line = data[: e.start].count(b"\n") + 1
        raise ParseError(f"{path}:{line}: not UTF-8 text") from None
    except tomllib.TOMLDecodeError as e:
        raise ParseError(f"{path}: not valid TOML: {e}") from None
    known = {"scene", "output", "cloth", "particles", "rigid", "animated_sphere", "character"}
    unknown = set(doc) - known
    if unknown:
        raise ValueError(f"{path}: unknown tables {sorted(unknown)}; expected {sorted(known)}")
    head = dict(doc.get("scene", {}))
    try:
        dt = float(head.pop("dt", 1.0 / 60.0))
        substeps = int(head.pop("substeps", 1))
        frames = head.pop("frames", None)
        duration = head.pop("duration", None)
        if head:
            raise ValueError(f"unknown keys {sorted(head)}")
        if (frames is None) == (duration is None):
            raise ValueError("give frames or duration")
        scene = Scene(dt=dt, substeps=substeps)
    except (ValueError, TypeError) as e:
        raise ValueError(f"{path}: [scene]: {e}") from None
    n = int(frames) if frames is not None else round(real(duration, "duration") / dt)
    roots = [path.parent, Path(__file__).parent / "data", *map(Path, read_dirs)]

    def inside(name: Any, key: str) -> Path:
        return _input(name, key, path.parent, roots)

    builders = {
        "cloth": lambda t: _cloth(t, inside),
        "particles": _particles,
        "rigid": _rigid,
        "animated_sphere": _animated,
        "character": lambda t: _character(t, inside),
    }
    for kind, build in builders.items():
        for i, table in enumerate(doc.get(kind, [])):
            try:
                item, options = build(dict(table))
                scene.add(item, **options)
            except ParseError as e:
                raise ParseError(f"{path}: {kind}[{i}]: {e}") from None
            except (ValueError, TypeError, KeyError, OSError) as e:
                raise ValueError(f"{path}: {kind}[{i}]: {_plain(e)}") from None
    out = dict(doc.get("output", {}))
    try:
        output = Output(frames=n, **out)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{path}: [output]: {e}") from None
    for name in output.record:
        scene.record(name)
    return scene, output


def _input(name: Any, key: str, base: Path, roots: list[Path]) -> Path:
    """The input file ``name`` (field ``key``), resolved from ``base``; ``ValueError`` unless
    it is a relative path that ends inside one of ``roots`` (symbolic links followed)."""
    if not isinstance(name, str) or not name:
        raise ValueError(f"{key}: expected a relative file path, got {name!r}")
    if PurePath(name).is_absolute() or Path(name).anchor:
        raise ValueError(f"{key}: {name!r} must be relative to the scene file's folder")
    target = (base / name).resolve()
    if not any(target.is_relative_to(r.resolve()) for r in roots):
        raise ValueError(
            f"{key}: {name!r} leads outside the scene file's folder (allow another folder "
            "with --allow-read)"
        )
    return target


def _plain(e: BaseException) -> str:
    """An error's message; for a file that cannot be opened, its reason and name only."""
    if isinstance(e, OSError) and e.strerror:
        return f"{e.strerror}: {e.filename}"
    return str(e)


def _make(module: Any, spec: Any, where: str) -> Any:
    """``module.<type>(**rest)`` for a table ``{type = "...", ...}``."""
    if not isinstance(spec, dict) or "type" not in spec:
        raise ValueError(f"{where}: expected a table with a 'type'")
    spec = dict(spec)
    name = spec.pop("type")
    cls = getattr(module, str(name), None)
    if not isinstance(cls, type) or name.startswith("_"):
        raise ValueError(f"{where}.type: {name!r} is not a class of {module.__name__}")
    if "orientation" in spec:  # a scalar-first quaternion in a file
        spec["orientation"] = Rotation.from_quat(spec["orientation"])
    try:
        return cls(**spec)
    except TypeError as e:
        raise ValueError(f"{where}: {e}") from None


def _cloth(t: dict[str, Any], inside: Any) -> tuple[Any, dict[str, Any]]:
    step = t.pop("step", {})
    offset = np.asarray(t.pop("offset", (0.0, 0.0, 0.0)), dtype=np.float64)
    pins = t.pop("pin", [])
    colliders = t.pop("colliders", [])
    if "grid" in t:
        c = cloth.Cloth.grid(**t.pop("grid"))
    elif "obj" in t:
        c = cloth.Cloth.from_obj(inside(t.pop("obj"), "obj"), **t.pop("material", {}))
    else:
        raise ValueError("give grid = {...} or obj = 'file.obj'")
    if t:
        raise ValueError(f"unknown keys {sorted(t)}")
    c.set_state(c.positions + offset)
    if pins:
        c.pin(pins)
    for k, spec in enumerate(colliders):
        c.add_collider(_make(cloth, spec, f"colliders[{k}]"))
    return c, step


def _particles(t: dict[str, Any]) -> tuple[Any, dict[str, Any]]:
    step = t.pop("step", {})
    items = t.pop("items", [])
    positions = np.asarray(t.pop("positions", np.zeros((0, 3))), dtype=np.float64).reshape(-1, 3)
    p = particles.ParticleSystem(positions, **t)
    for k, spec in enumerate(items):
        p.add(_make(particles, spec, f"items[{k}]"))
    return p, step


def _rigid(t: dict[str, Any]) -> tuple[Any, dict[str, Any]]:
    step = t.pop("step", {})
    ground = t.pop("ground", None)
    bodies = t.pop("bodies", [])
    w = rigid.World(**t)
    if ground is not None:
        w.add_ground(**ground)
    for k, body in enumerate(bodies):
        body = dict(body)
        shape = _make(rigid, body.pop("shape", None), f"bodies[{k}].shape")
        if "orientation" in body:
            body["orientation"] = Rotation.from_quat(body["orientation"])
        try:
            w.add_body(shape, **body)
        except TypeError as e:
            raise ValueError(f"bodies[{k}]: {e}") from None
    return w, step


def _animated(t: dict[str, Any]) -> tuple[Any, dict[str, Any]]:
    track = anim.Track(t.pop("times"), t.pop("centers"), t.pop("interpolation", "catmull_rom"))
    return AnimatedSphere(center=track, **t), {}


def _character(t: dict[str, Any], inside: Any) -> tuple[Any, dict[str, Any]]:
    if "bvh" in t:
        skeleton, motion = mocap.read_bvh(inside(t.pop("bvh"), "bvh"))
    else:
        skeleton = mocap.read_asf(inside(t.pop("asf"), "asf"))
        motion = mocap.read_amc(
            inside(t.pop("amc"), "amc"),
            skeleton,
            **({"frame_rate": t.pop("frame_rate")} if "frame_rate" in t else {}),
        )
    return Character(skeleton, motion, **t), {}
