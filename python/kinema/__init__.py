"""kinema: physically based animation with a fast Rust core.

Subjects live in submodules (``kinema.rotation`` so far); the most used names are
re-exported here. See README.md and ARCHITECTURE.md.
"""

from kinema._kinema import ParseError, SimulationError, __version__
from kinema.rotation import GimbalLockWarning, Rotation, Transform, slerp

__all__ = [
    "GimbalLockWarning",
    "ParseError",
    "Rotation",
    "SimulationError",
    "Transform",
    "__version__",
    "slerp",
]
