"""Collision shapes, one class per shape, shared by every system (particles, cloth, scenes).

A shape is placed in the world (metres) and carries what a contact with it does, kept apart
from its geometry: ``restitution`` (in [0, 1]) and Coulomb ``friction`` (>= 0), each ``None``
for the default of the system it is added to (particles: restitution 0.5, friction 0; cloth:
friction 0.5, and cloth contacts are inelastic, so a cloth takes no restitution), and the
``velocity`` (m/s) the shape moves at (particles: restitution and friction act on the velocity
relative to it; cloth: the shape is moved by ``velocity · dt`` each step). The same classes are
importable as ``kinema.particles.Plane``, ``kinema.cloth.Sphere`` and so on.

Distances and normals are computed in Rust (``kinema::geometry``): signed distance negative
inside the solid, outward unit normal of the nearest surface point.
"""

from __future__ import annotations

from dataclasses import KW_ONLY, dataclass
from typing import Any

from kinema._array import as_orientation, as_vector3

__all__ = ["Box", "Capsule", "Plane", "Shape", "Sphere"]


@dataclass(frozen=True)
class Plane:
    """The plane through ``point`` with ``normal``: the side ``normal`` points to is free, the
    other solid."""

    point: Any = (0.0, 0.0, 0.0)
    normal: Any = (0.0, 1.0, 0.0)
    _: KW_ONLY
    restitution: float | None = None
    friction: float | None = None
    velocity: Any = (0.0, 0.0, 0.0)

    def _params(self) -> tuple[str, list[float]]:
        return "plane", as_vector3(self.point, "point") + as_vector3(self.normal, "normal")


@dataclass(frozen=True)
class Sphere:
    """A solid ball of ``radius`` (m) at ``center``; with ``inside=True`` (particles only) the
    particles are kept inside it instead."""

    center: Any
    radius: float
    _: KW_ONLY
    inside: bool = False
    restitution: float | None = None
    friction: float | None = None
    velocity: Any = (0.0, 0.0, 0.0)

    def _params(self) -> tuple[str, list[float]]:
        return "sphere", [*as_vector3(self.center, "center"), float(self.radius)]


@dataclass(frozen=True)
class Capsule:
    """A solid capsule: the points within ``radius`` (m) of the segment ``a``–``b``."""

    a: Any
    b: Any
    radius: float
    _: KW_ONLY
    restitution: float | None = None
    friction: float | None = None
    velocity: Any = (0.0, 0.0, 0.0)

    def _params(self) -> tuple[str, list[float]]:
        return "capsule", as_vector3(self.a, "a") + as_vector3(self.b, "b") + [float(self.radius)]


@dataclass(frozen=True)
class Box:
    """A solid box of ``half_extents`` (m) centred at ``center``, turned by ``orientation`` (a
    :class:`kinema.Rotation`, default none)."""

    center: Any
    half_extents: Any
    orientation: Any = None
    _: KW_ONLY
    restitution: float | None = None
    friction: float | None = None
    velocity: Any = (0.0, 0.0, 0.0)

    def _params(self) -> tuple[str, list[float]]:
        return "box", [
            *as_vector3(self.center, "center"),
            *as_orientation(self.orientation, "orientation"),
            *as_vector3(self.half_extents, "half_extents"),
        ]


Shape = Plane | Sphere | Capsule | Box
"""Any collision shape."""


def shape_params(c: Any) -> tuple[str, list[float]]:
    """The kind and the shape's parameters of ``c``, as the compiled ``add_collider`` takes
    them; a ``TypeError`` for anything but a shape of this module."""
    if not isinstance(c, (Plane, Sphere, Capsule, Box)):
        raise TypeError(f"collider must be a Plane, Sphere, Capsule or Box, got {type(c).__name__}")
    return c._params()
