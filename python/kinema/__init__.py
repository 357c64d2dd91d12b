"""kinema: physically based animation with a fast Rust core.

One submodule per subject, each loaded on first use (``import kinema; kinema.cloth`` works,
PEP 562): :mod:`kinema.rotation` (rotations, Euler angles, slerp), :mod:`kinema.transform` (4x4
transforms), :mod:`kinema.ode` (integrators and stability), :mod:`kinema.geometry` (collision
shapes), :mod:`kinema.particles` (forces, colliders,
emitters), :mod:`kinema.constraints` (rods, beads and user constraints), :mod:`kinema.rigid`
(rigid bodies, contacts, joints), :mod:`kinema.cloth` (implicit cloth), :mod:`kinema.fluid`
(SPH fluids), :mod:`kinema.crowd` (crowds: ORCA and social forces), :mod:`kinema.flock`
(boids), :mod:`kinema.rods` (discrete elastic rods), :mod:`kinema.character` (articulated
characters, ragdolls), :mod:`kinema.anim`
(keyframe tracks and easing), :mod:`kinema.mocap` (ASF/AMC and BVH motion capture, motion
editing), :mod:`kinema.ik` (inverse kinematics), :mod:`kinema.skin` (skinning, a body mesh for any skeleton),
:mod:`kinema.walkcycle` (crowd agents posed by a walk clip), :mod:`kinema.io` (export to glTF and
USD), :mod:`kinema.view` (a viewer in the browser), :mod:`kinema.scene` (scenes coupling them,
checkpoints), :mod:`kinema.scenefile` (scenes from TOML), :mod:`kinema.sweep` (parameter sweeps on
Dask), :mod:`kinema.plot` (pictures and animations), :mod:`kinema.demos` and the ``kinema`` command line (:mod:`kinema.cli`).

The most used names are re-exported here: :class:`Rotation`, :class:`Transform`,
:func:`slerp`, :class:`Scene`, the exceptions :class:`KinemaError` (the root
of kinema's own), :class:`ParseError`, :class:`SimulationError` and :class:`CheckpointError`, and the thread pool's :func:`num_threads` / :func:`set_num_threads`.
SI units, +Y up, quaternions ``(w, x, y, z)``; see README.md and ARCHITECTURE.md.
"""

import importlib as _importlib
import os as _os
import warnings as _warnings
from typing import Any as _Any

from kinema._kinema import (
    KinemaError,
    ParseError,
    SimulationError,
    __version__,
    num_threads,
    set_num_threads,
)
from kinema.rotation import GimbalLockWarning, Rotation, slerp
from kinema.scene import CheckpointError, Scene
from kinema.transform import Transform


def _threads_from_environment() -> None:
    """Apply ``KINEMA_NUM_THREADS`` (an integer from 1 to 1024); any other value is ignored
    with a ``RuntimeWarning`` naming the variable, and the default pool (one thread per
    core) is kept, so a bad environment never stops ``import kinema``."""
    value = _os.environ.get("KINEMA_NUM_THREADS", "")
    if not value:
        return
    try:
        set_num_threads(int(value))
    except ValueError as e:
        _warnings.warn(
            f"KINEMA_NUM_THREADS={value!r} ignored ({e}); using {num_threads()} threads",
            RuntimeWarning,
            stacklevel=3,
        )


_threads_from_environment()

__all__ = [
    "CheckpointError",
    "GimbalLockWarning",
    "KinemaError",
    "ParseError",
    "Rotation",
    "Scene",
    "SimulationError",
    "Transform",
    "__version__",
    "num_threads",
    "set_num_threads",
    "slerp",
]

_SUBMODULES = frozenset(
    {
        "anim",
        "character",
        "cli",
        "cloth",
        "constraints",
        "crowd",
        "demos",
        "flock",
        "fluid",
        "geometry",
        "ik",
        "io",
        "mocap",
        "ode",
        "particles",
        "plot",
        "rigid",
        "rods",
        "rotation",
        "scene",
        "scenefile",
        "skin",
        "sweep",
        "transform",
        "view",
        "walkcycle",
    }
)


def __getattr__(name: str) -> _Any:
    """Import submodule ``name`` on first access (PEP 562), as scipy does."""
    if name in _SUBMODULES:
        return _importlib.import_module(f"kinema.{name}")
    raise AttributeError(f"module 'kinema' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | _SUBMODULES)
