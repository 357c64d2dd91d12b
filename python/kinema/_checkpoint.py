"""The checkpoint format of :meth:`kinema.Scene.save`: data only, validated before use.

A checkpoint names no code. It is the header (``_HEADER``: magic, format version, payload
length, SHA-256 of the payload), then the payload: the length of a UTF-8 JSON manifest (8 bytes,
little-endian), the manifest, and the binary blobs it refers to, back to back. The blobs are
the Rust snapshots of the compiled systems (``kinema::snapshot``, which validate every index,
length and value when read) and the bytes of numpy arrays (dtype and shape in the manifest).

The manifest's ``"root"`` is a value: JSON ``null``, booleans, integers, strings and finite
floats (written with ``repr``, so they read back bit for bit) stand for themselves; every other
value is a one-key tag:

- ``{"$float": "inf" | "-inf" | "nan"}``, ``{"$tuple": [...]}``, ``{"$dict": {str: value}}``;
- ``{"$array": [blob, dtype, shape]}`` with ``dtype`` one of :data:`_DTYPES`;
- ``{"$rotation": value}``: a :class:`kinema.Rotation` from its ``(..., 4)`` quaternions;
- ``{"$native": [name, id, blob, [args]]}``: a compiled object, ``name`` one of
  :data:`_NATIVES`, rebuilt by its ``_from_snapshot(blob, *args)``;
- ``{"$object": [name, id, {attribute: value}]}``: a kinema Python object, ``name`` one of
  the classes of :data:`_SCHEMAS`, whose attributes must be exactly those listed there, each
  of the type listed;
- ``{"$ref": id}``: the object or compiled object of that ``id`` again (shared references,
  e.g. a constrained system and its particle system).

Reading goes through these tags only, so a file can build nothing but kinema's own data;
every class, attribute, type, blob index, dtype and shape is checked before it is used, and
every failure is a :class:`CheckpointError`.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import struct
from dataclasses import dataclass
from typing import Any

import numpy as np

from kinema import _kinema, anim, character, cloth, crowd, flock, fluid, particles, rigid, rods
from kinema.constraints import ConstrainedSystem
from kinema.rotation import Rotation
from kinema.scene import (
    FORMAT_VERSION,
    RECEIVERS,
    AnimatedSphere,
    Character,
    CheckpointError,
    Scene,
    _Entry,
)

_MAGIC = b"KINEMA-SCENE\r\n\x1a\n"  # 16 bytes; the line ends catch text-mode mangling
_HEADER = struct.Struct("<16sIQ32s")  # magic, version, payload length, SHA-256 of payload
_LENGTH = struct.Struct("<Q")  # manifest length, at the start of the payload

_DTYPES = ("<f8", "<i8", "|b1")
"""Array element types a checkpoint may hold: float64, int64, bool."""

_NATIVES: dict[str, Any] = {
    c.__name__: c
    for c in (
        _kinema.Particles,
        _kinema.Constrained,
        _kinema.ClothCore,
        _kinema.RigidWorld,
        _kinema.Fluid,
        _kinema.Crowd,
        _kinema.Flock,
        _kinema.KeyTrack,
        _kinema.AsfSkeleton,
        _kinema.AmcMotion,
        _kinema.BvhSkeleton,
        _kinema.Walker,
        _kinema.Walker3d,
        _kinema.ArticulatedBody,
        _kinema.Tracker,
        _kinema.Rod,
        _kinema.Hair,
    )
}
"""The compiled classes a checkpoint may hold (each pickles through its Rust snapshot)."""

_Number = (int, float)
_Array = np.ndarray


@dataclass(frozen=True)
class _Schema:
    """A Python class a checkpoint may hold: its attributes and the types they may have."""

    cls: type
    attributes: dict[str, type | tuple[type, ...]]


_SCHEMAS: dict[str, _Schema] = {
    s.cls.__name__: s
    for s in (
        _Schema(
            Scene,
            {
                "_dt": float,
                "_substeps": int,
                "_h": float,
                "_entries": list,
                "_kinematic": list,
                "_steps": int,
                "_recorders": dict,
                "_records": dict,
                "_previous": (list, type(None)),
                "interrupted": bool,
            },
        ),
        _Schema(_Entry, {"colliders": list, "obj": object, "options": dict, "receives": bool}),
        _Schema(AnimatedSphere, {"radius": _Number, "center": anim.Track, "friction": _Number}),
        _Schema(
            Character,
            {
                "skeleton": (_kinema.AsfSkeleton, _kinema.BvhSkeleton),
                "motion": _kinema.AmcMotion,
                "radius": _Number,
                "scale": _Number,
                "offset": object,
                "loop": bool,
                "friction": _Number,
                "_joints": _Array,
                "_bones": _Array,
                "_chains": _Array,
            },
        ),
        _Schema(
            particles.ParticleSystem,
            {"_sys": _kinema.Particles, "_fields": list, "_colliders": int, "_stiffest": float},
        ),
        _Schema(
            ConstrainedSystem,
            {"_particles": particles.ParticleSystem, "_sys": _kinema.Constrained},
        ),
        _Schema(cloth.Cloth, {"_core": _kinema.ClothCore, "model": str}),
        _Schema(rigid.World, {"_world": _kinema.RigidWorld, "_shapes": list}),
        _Schema(fluid.Fluid, {"_f": _kinema.Fluid}),
        _Schema(crowd.Crowd, {"_c": _kinema.Crowd}),
        _Schema(flock.Flock, {"_f": _kinema.Flock, "_dim": int}),
        _Schema(character.Biped, {"_w": (_kinema.Walker, _kinema.Walker3d)}),
        _Schema(character.ArticulatedBody, {"_b": _kinema.ArticulatedBody}),
        _Schema(character.Ragdoll, {"_b": _kinema.ArticulatedBody}),
        _Schema(character.Tracker, {"_t": _kinema.Tracker}),
        _Schema(rods.Rod, {"_r": _kinema.Rod}),
        _Schema(rods.Hair, {"_h": _kinema.Hair}),
        _Schema(rigid.Sphere, {"radius": _Number}),
        _Schema(rigid.Box, {"half_extents": object}),
        _Schema(rigid.Capsule, {"radius": _Number, "height": _Number}),
        _Schema(rigid.Cylinder, {"radius": _Number, "height": _Number}),
        _Schema(rigid.Mesh, {"vertices": object, "triangles": object}),
        _Schema(
            anim.Track,
            {"_scalar": bool, "_track": _kinema.KeyTrack, "_order": int, "_times": _Array},
        ),
    )
}
"""The Python classes a checkpoint may hold, by name."""


# ---------------------------------------------------------------------------------- writing
def dumps(scene: Scene) -> bytes:
    """The checkpoint of ``scene`` (header and payload); :class:`CheckpointError` naming the
    object if something in it cannot be stored as data."""
    writer = _Writer()
    root = writer.value(scene, "scene")
    manifest = json.dumps(
        {"blobs": [len(b) for b in writer.blobs], "root": root},
        allow_nan=False,
        separators=(",", ":"),
    ).encode()
    payload = b"".join([_LENGTH.pack(len(manifest)), manifest, *writer.blobs])
    digest = hashlib.sha256(payload).digest()
    return _HEADER.pack(_MAGIC, FORMAT_VERSION, len(payload), digest) + payload


class _Writer:
    def __init__(self) -> None:
        self.blobs: list[bytes] = []
        self.ids: dict[int, int] = {}
        self.alive: list[Any] = []  # keeps every id()'d object alive while writing

    def blob(self, data: bytes) -> int:
        self.blobs.append(data)
        return len(self.blobs) - 1

    def value(self, v: Any, where: str) -> Any:
        if v is None or isinstance(v, (bool, str)):
            return v
        if isinstance(v, np.bool_):
            return bool(v)
        if isinstance(v, (int, np.integer)):
            return int(v)
        if isinstance(v, (float, np.floating)):
            f = float(v)
            return f if math.isfinite(f) else {"$float": repr(f)}
        if isinstance(v, list):
            return [self.value(x, f"{where}[{i}]") for i, x in enumerate(v)]
        if isinstance(v, tuple):
            return {"$tuple": [self.value(x, f"{where}[{i}]") for i, x in enumerate(v)]}
        if isinstance(v, dict):
            if not all(isinstance(k, str) for k in v):
                raise CheckpointError(f"{where}: a dict with keys other than strings")
            return {"$dict": {k: self.value(x, f"{where}[{k!r}]") for k, x in v.items()}}
        if isinstance(v, np.ndarray):
            a = v if v.flags.c_contiguous else v.copy(order="C")  # keeps 0-d arrays 0-d
            dtype = a.dtype.newbyteorder("<") if a.dtype.byteorder == ">" else a.dtype
            if dtype.str not in _DTYPES:
                raise CheckpointError(f"{where}: an array of {a.dtype} (not one of {_DTYPES})")
            a = a.astype(dtype.str, copy=False)
            return {"$array": [self.blob(a.tobytes()), dtype.str, list(a.shape)]}
        if isinstance(v, Rotation):
            return {"$rotation": self.value(v.as_quat(), where)}
        if id(v) in self.ids:
            return {"$ref": self.ids[id(v)]}
        name = type(v).__name__
        if _NATIVES.get(name) is type(v):
            return self.native(v, name, where)
        schema = _SCHEMAS.get(name)
        if schema is None or schema.cls is not type(v):
            what = "a Python function" if callable(v) else f"a {type(v).__module__}.{name}"
            raise CheckpointError(
                f"{where}: {what} cannot be stored in a checkpoint (only kinema's own data "
                "can); see docs/scene.md, Checkpoints"
            )
        return self.object(v, name, schema, where)

    def remember(self, v: Any) -> int:
        self.ids[id(v)] = len(self.ids)
        self.alive.append(v)
        return self.ids[id(v)]

    def native(self, v: Any, name: str, where: str) -> Any:
        try:
            _, (data, *args) = v.__reduce__()
        except ValueError as e:
            raise CheckpointError(f"{where}: cannot be stored: {e}") from e
        encoded = [self.value(a, f"{where}.<argument {i}>") for i, a in enumerate(args)]
        return {"$native": [name, self.remember(v), self.blob(bytes(data)), encoded]}

    def object(self, v: Any, name: str, schema: _Schema, where: str) -> Any:
        ident = self.remember(v)
        attributes = _attributes(v)
        if set(attributes) != set(schema.attributes):
            raise CheckpointError(
                f"{where}: a {name} with attributes {sorted(attributes)}, but the checkpoint "
                f"format lists {sorted(schema.attributes)} (update kinema._checkpoint._SCHEMAS)"
            )
        if isinstance(v, Scene):
            # The data of every recorder is kept; recorders given as functions are not (they
            # are registered again after loading, see docs/scene.md).
            attributes["_recorders"] = {k: None for k, fn in v._recorders.items() if fn is None}
        if isinstance(v, particles.ParticleSystem) and v._fields:
            raise CheckpointError(
                f"{where}: a particles.Field force is a Python function and cannot be stored "
                "in a checkpoint"
            )
        if isinstance(v, AnimatedSphere) and not isinstance(v.center, anim.Track):
            raise CheckpointError(
                f"{where}: an AnimatedSphere whose center is a Python function cannot be stored "
                "in a checkpoint; give it a kinema.anim.Track, or add it again after loading"
            )
        state = {k: self.value(x, _place(v, k, where)) for k, x in attributes.items()}
        return {"$object": [name, ident, state]}


def _place(owner: Any, attribute: str, where: str) -> str:
    """How an error names ``owner.attribute``: a scene's systems as in ``Scene.systems``."""
    if isinstance(owner, Scene) and attribute == "_entries":
        return f"{where}.systems"
    if isinstance(owner, Scene) and attribute == "_kinematic":
        return f"{where}.systems[{len(owner._entries)}:]"
    if isinstance(owner, _Entry) and attribute == "obj":
        return where
    return f"{where}.{attribute}"


def _attributes(v: Any) -> dict[str, Any]:
    if hasattr(v, "__dict__"):
        return dict(vars(v))
    return {k: getattr(v, k) for k in type(v).__slots__}


# ---------------------------------------------------------------------------------- reading
def loads(data: bytes, where: str) -> Scene:
    """The scene in checkpoint bytes ``data`` (read from ``where``, named in errors); raise
    :class:`CheckpointError` for anything that is not a valid checkpoint of this version."""
    if len(data) < _HEADER.size or not data.startswith(_MAGIC):
        raise CheckpointError(f"{where}: not a kinema scene checkpoint")
    _, version, length, digest = _HEADER.unpack_from(data)
    if version != FORMAT_VERSION:
        old = " (version 1 files are Python pickles, which can run code: they are not read)"
        raise CheckpointError(
            f"{where}: checkpoint format version {version}; this kinema reads version "
            f"{FORMAT_VERSION}{old if version == 1 else ''}"
        )
    payload = data[_HEADER.size :]
    if len(payload) != length:
        raise CheckpointError(
            f"{where}: truncated or extended: {len(payload)} bytes of payload, header says {length}"
        )
    if hashlib.sha256(payload).digest() != digest:
        raise CheckpointError(f"{where}: damaged: the checksum does not match")
    try:
        scene = _Reader(payload).scene()
        _check_scene(scene)
    except _Invalid as e:
        raise CheckpointError(f"{where}: invalid checkpoint: {e}") from None
    except RecursionError:
        raise CheckpointError(f"{where}: invalid checkpoint: nested too deeply") from None
    return scene


class _Invalid(Exception):
    """A checkpoint's content is not valid (the message says where and why)."""


def _need(ok: bool, message: str) -> None:
    if not ok:
        raise _Invalid(message)


class _Reader:
    def __init__(self, payload: bytes) -> None:
        _need(len(payload) >= _LENGTH.size, "no manifest")
        (n,) = _LENGTH.unpack_from(payload)
        _need(n <= len(payload) - _LENGTH.size, f"manifest length {n} beyond the payload")
        try:
            manifest = json.loads(payload[_LENGTH.size : _LENGTH.size + n].decode("utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as e:
            raise _Invalid(f"manifest: not JSON: {e}") from None
        _need(isinstance(manifest, dict) and set(manifest) == {"blobs", "root"}, "manifest keys")
        sizes = manifest["blobs"]
        _need(
            isinstance(sizes, list) and all(_is_int(s) and s >= 0 for s in sizes),
            "manifest: blobs must be a list of sizes",
        )
        _need(
            sum(sizes) == len(payload) - _LENGTH.size - n,
            "manifest: the blob sizes do not add up to the rest of the payload",
        )
        offsets = list(itertools.accumulate(sizes, initial=_LENGTH.size + n))
        view = memoryview(payload)
        self.blobs = [bytes(view[a:b]) for a, b in itertools.pairwise(offsets)]
        self.used = [False] * len(sizes)
        self.objects: dict[int, Any] = {}
        self.root = manifest["root"]

    def scene(self) -> Scene:
        scene = self.value(self.root, "root")
        _need(isinstance(scene, Scene), f"root: a {type(scene).__name__}, not a Scene")
        _need(all(self.used), "blobs not referred to")
        return scene

    def blob(self, index: Any, where: str) -> bytes:
        _need(_is_int(index) and 0 <= index < len(self.blobs), f"{where}: blob index {index!r}")
        _need(not self.used[index], f"{where}: blob {index} used twice")
        self.used[index] = True
        return self.blobs[index]

    def value(self, v: Any, where: str) -> Any:
        if v is None or isinstance(v, (bool, int, float, str)):
            return v
        if isinstance(v, list):
            return [self.value(x, f"{where}[{i}]") for i, x in enumerate(v)]
        _need(isinstance(v, dict) and len(v) == 1, f"{where}: not a value")
        ((tag, body),) = v.items()
        if tag == "$float":
            _need(body in ("inf", "-inf", "nan"), f"{where}: $float {body!r}")
            return float(body)
        if tag == "$tuple":
            _need(isinstance(body, list), f"{where}: $tuple of a {type(body).__name__}")
            return tuple(self.value(x, f"{where}[{i}]") for i, x in enumerate(body))
        if tag == "$dict":
            _need(isinstance(body, dict), f"{where}: $dict of a {type(body).__name__}")
            return {k: self.value(x, f"{where}[{k!r}]") for k, x in body.items()}
        if tag == "$array":
            return self.array(body, where)
        if tag == "$rotation":
            q = self.value(body, where)
            _need(isinstance(q, np.ndarray), f"{where}: $rotation of a {type(q).__name__}")
            try:
                return Rotation.from_quat(q)
            except ValueError as e:
                raise _Invalid(f"{where}: {e}") from None
        if tag == "$ref":
            _need(_is_int(body) and body in self.objects, f"{where}: $ref to unknown {body!r}")
            return self.objects[body]
        if tag == "$native":
            return self.native(body, where)
        if tag == "$object":
            return self.object(body, where)
        raise _Invalid(f"{where}: unknown tag {tag!r}")

    def array(self, body: Any, where: str) -> np.ndarray:
        _need(isinstance(body, list) and len(body) == 3, f"{where}: $array needs 3 fields")
        index, dtype, shape = body
        _need(dtype in _DTYPES, f"{where}: dtype {dtype!r} is not one of {_DTYPES}")
        _need(
            isinstance(shape, list) and all(_is_int(n) and n >= 0 for n in shape),
            f"{where}: shape {shape!r}",
        )
        data = self.blob(index, where)
        itemsize = np.dtype(dtype).itemsize
        _need(
            math.prod(shape) * itemsize == len(data),
            f"{where}: shape {shape} of {dtype} does not match {len(data)} bytes",
        )
        a = np.frombuffer(data, dtype=dtype).reshape(shape).copy()
        if dtype == "|b1":
            _need(set(data) <= {0, 1}, f"{where}: booleans other than 0 and 1")
        return a

    def identity(self, ident: Any, where: str) -> int:
        _need(_is_int(ident) and ident not in self.objects, f"{where}: id {ident!r} reused")
        return int(ident)

    def native(self, body: Any, where: str) -> Any:
        _need(isinstance(body, list) and len(body) == 4, f"{where}: $native needs 4 fields")
        name, ident, index, args = body
        _need(isinstance(name, str) and name in _NATIVES, f"{where}: unknown class {name!r}")
        ident = self.identity(ident, where)
        _need(isinstance(args, list), f"{where}: arguments")
        data = self.blob(index, where)
        values = [self.value(a, f"{where}.<argument {i}>") for i, a in enumerate(args)]
        expected = _NATIVE_ARGUMENTS.get(name, ())
        _need(
            len(values) == len(expected)
            and all(isinstance(a, t) for a, t in zip(values, expected, strict=True)),
            f"{where}: wrong arguments for {name}",
        )
        try:
            obj = _NATIVES[name]._from_snapshot(data, *values)
        except ValueError as e:
            raise _Invalid(f"{where}: {e}") from None
        self.objects[ident] = obj
        return obj

    def object(self, body: Any, where: str) -> Any:
        _need(isinstance(body, list) and len(body) == 3, f"{where}: $object needs 3 fields")
        name, ident, state = body
        _need(isinstance(name, str) and name in _SCHEMAS, f"{where}: unknown class {name!r}")
        schema = _SCHEMAS[name]
        ident = self.identity(ident, where)
        _need(
            isinstance(state, dict) and set(state) == set(schema.attributes),
            f"{where}: {name} has attributes {sorted(schema.attributes)}",
        )
        obj: Any = object.__new__(schema.cls)
        self.objects[ident] = obj
        for key, kind in schema.attributes.items():
            value = self.value(state[key], f"{where}.{key}")
            _need(
                isinstance(value, kind) and not (kind is int and isinstance(value, bool)),
                f"{where}.{key}: a {type(value).__name__}",
            )
            object.__setattr__(obj, key, value)
        return obj


_NATIVE_ARGUMENTS: dict[str, tuple[type | tuple[type, ...], ...]] = {
    "Constrained": (_kinema.Particles,),
    "AmcMotion": ((_kinema.AsfSkeleton, _kinema.BvhSkeleton),),
}
"""The arguments besides the snapshot of the compiled classes that take some."""


def _is_int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


# ------------------------------------------------------------------------------ validation
def _check_scene(scene: Scene) -> None:
    """Every number, index and cross-reference of a scene read from a checkpoint."""
    _need(math.isfinite(scene._dt) and scene._dt > 0, f"dt {scene._dt}")
    _need(scene._substeps >= 1, f"substeps {scene._substeps}")
    _need(scene._h == scene._dt / scene._substeps, "step size is not dt / substeps")
    _need(scene._steps >= 0, f"steps {scene._steps}")
    objects = [e.obj for e in scene._entries] + list(scene._kinematic)
    objects += [e.obj._particles for e in scene._entries if isinstance(e.obj, ConstrainedSystem)]
    _need(len({id(o) for o in objects}) == len(objects), "a system added twice")
    for i, e in enumerate(scene._entries):
        _check_entry(e, f"systems[{i}]", scene._h)
    for k in scene._kinematic:
        _need(isinstance(k, (AnimatedSphere, Character)), f"kinematic object {type(k).__name__}")
        _check_kinematic(k)
    _need(
        all(v is None for v in scene._recorders.values())
        and set(scene._recorders) <= set(scene._records),
        "recorders",
    )
    for name, rows in scene._records.items():
        _need(
            isinstance(name, str)
            and isinstance(rows, list)
            and all(isinstance(r, np.ndarray) and r.dtype == np.float64 for r in rows),
            f"records[{name!r}]",
        )
    if scene._previous is not None:
        for s in scene._previous:
            _check_shape(s)


def _check_entry(e: Any, where: str, h: float) -> None:
    _need(isinstance(e, _Entry), f"{where}: a {type(e).__name__}")
    obj = e.obj
    kinds = (
        particles.ParticleSystem,
        ConstrainedSystem,
        cloth.Cloth,
        rigid.World,
        fluid.Fluid,
        crowd.Crowd,
        flock.Flock,
        character.Biped,
        character.ArticulatedBody,
        character.Tracker,
        rods.Rod,
        rods.Hair,
    )
    _need(isinstance(obj, kinds), f"{where}: a {type(obj).__name__}")
    _need(
        e.receives == isinstance(obj, RECEIVERS),
        f"{where}: receives",
    )
    _need(
        all(isinstance(k, str) and isinstance(v, (str, int, float)) for k, v in e.options.items()),
        f"{where}: options must be names with numbers, booleans or strings",
    )
    count = obj._colliders if isinstance(obj, particles.ParticleSystem) else None
    _need(
        all(_is_int(c) and c >= 0 and (count is None or c < count) for c in e.colliders)
        and len(set(e.colliders)) == len(e.colliders),
        f"{where}: collider indices {e.colliders}",
    )
    if isinstance(obj, particles.ParticleSystem):
        _need(not obj._fields and obj._colliders >= 0, f"{where}: fields or colliders")
        _need(math.isfinite(obj._stiffest) and obj._stiffest >= 0, f"{where}: stiffest spring")
    elif isinstance(obj, ConstrainedSystem):
        _need(obj._sys is not None, f"{where}: constraints")
    elif isinstance(obj, cloth.Cloth):
        _need(obj.model in cloth.MODELS, f"{where}: model {obj.model!r}")
    elif isinstance(obj, rigid.World):
        _need(all(type(s).__name__ in _SCHEMAS for s in obj._shapes), f"{where}: shapes")
        _need(len(obj._shapes) == len(obj.positions), f"{where}: one shape per body")
    elif isinstance(obj, character.Tracker):
        frames = h * obj.frame_rate
        whole = round(frames) >= 1 and abs(frames - round(frames)) <= 1e-9 * frames
        _need(not e.options and whole, f"{where}: a Tracker steps whole frames, no options")


def _check_kinematic(k: AnimatedSphere | Character) -> None:
    where = type(k).__name__
    _need(math.isfinite(k.radius) and k.radius > 0, f"{where}: radius {k.radius}")
    _need(math.isfinite(k.friction) and k.friction >= 0, f"{where}: friction {k.friction}")
    if isinstance(k, AnimatedSphere):
        _check_track(k.center)
        return
    j, b = k._joints, k._bones
    _need(
        j.ndim == 3 and j.shape[0] >= 1 and j.shape[2] == 3 and bool(np.isfinite(j).all()),
        f"{where}: joints",
    )
    _need(
        b.dtype == np.int64
        and b.ndim == 2
        and b.shape[1] == 2
        and bool(((b >= 0) & (b < j.shape[1])).all()),
        f"{where}: bones",
    )
    c = k._chains
    _need(
        c.dtype == np.float64
        and c.shape == (j.shape[1], j.shape[1])
        and bool(((c == 0.0) | (c == 1.0)).all()),
        f"{where}: chains",
    )
    _need(math.isfinite(float(k.motion.frame_rate)) and k.motion.frame_rate > 0, f"{where}: rate")


def _check_track(t: anim.Track) -> None:
    _need(t._order in (0, 1, 2), f"Track: derivative order {t._order}")
    _need(t._times.ndim == 1 and t._times.dtype == np.float64, "Track: times")


def _check_shape(s: Any) -> None:
    """A collider pose of ``Scene._previous``: a kind, then finite numbers, arrays of them or
    rotations."""
    _need(isinstance(s, tuple) and len(s) >= 4 and s[0] in ("sphere", "capsule", "box"), "shape")
    for part in s[1:]:
        if isinstance(part, Rotation):
            continue
        if isinstance(part, (list, tuple)):
            part = np.asarray(part) if all(isinstance(x, (int, float)) for x in part) else None
        ok = isinstance(part, (int, float)) or (
            isinstance(part, np.ndarray) and part.dtype == np.float64
        )
        _need(ok and bool(np.isfinite(part).all()), "collider pose")
