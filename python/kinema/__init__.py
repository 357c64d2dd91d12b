"""kinema: physically based animation with a fast Rust core.

Subjects live in submodules (``kinema.rotation`` so far); the most used names are
re-exported here. See README.md and ARCHITECTURE.md.
"""

import os as _os
import warnings as _warnings

from kinema._kinema import ParseError, SimulationError, __version__, num_threads, set_num_threads
from kinema.rotation import GimbalLockWarning, Rotation, Transform, slerp
from kinema.scene import Scene


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
    "GimbalLockWarning",
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
