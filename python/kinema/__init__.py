"""kinema: physically based animation with a fast Rust core.

Subjects live in submodules (``kinema.rotation`` so far); the most used names are
re-exported here. See README.md and ARCHITECTURE.md.
"""

import os as _os

from kinema._kinema import ParseError, SimulationError, __version__, num_threads, set_num_threads
from kinema.rotation import GimbalLockWarning, Rotation, Transform, slerp
from kinema.scene import Scene

if _os.environ.get("KINEMA_NUM_THREADS"):
    try:
        set_num_threads(int(_os.environ["KINEMA_NUM_THREADS"]))
    except ValueError as _e:
        raise ValueError(f"KINEMA_NUM_THREADS: {_e}") from None

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
