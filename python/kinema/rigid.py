"""Rigid bodies: shapes with exact mass properties, and worlds of free bodies.

A :class:`World` holds bodies made from :class:`Sphere`, :class:`Box`, :class:`Capsule`,
:class:`Cylinder` or closed triangle :class:`Mesh` shapes (mass properties from the closed forms
and, for meshes, the polyhedral integrals of Blow & Binstock 2004), and steps the Newton–Euler
equations under gravity and applied forces. Capsules and cylinders have their axis along the
body's +Y. Rotations are integrated by one of:

- ``"splitting"`` (default): McLachlan's 1993 Lie–Poisson splitting into exact rotations about
  the principal axes; second order, symplectic, conserves world angular momentum to rounding,
  reproduces the intermediate-axis (Dzhanibekov) flip;
- ``"implicit_gyroscopic"``: Catto's 2015 implicit gyroscopic step; first order, stable,
  slightly dissipative;
- ``"symplectic_euler"``: explicit gyroscopic term, as in most game engines; first order;
- ``"explicit_euler"``: forward Euler, for comparison (energy grows).

``World.add_ground`` adds a ground plane; bodies collide with it and with each other
(spheres, boxes and capsules; cylinders and meshes with the ground only) with restitution and
Coulomb friction (sequential impulses). Not implemented yet: joints and their four
formulations, stable stacks taller than five boxes; see docs/rigid.md.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from kinema import _kinema
from kinema._array import as_batch, as_vector3
from kinema.rotation import Rotation

__all__ = ["Body", "Box", "Capsule", "Cylinder", "Mesh", "Sphere", "World"]


@dataclass(frozen=True)
class Sphere:
    """A ball of ``radius`` (m) centred at the body origin."""

    radius: float


@dataclass(frozen=True)
class Box:
    """A box centred at the body origin with ``half_extents`` (m) along x, y, z."""

    half_extents: Sequence[float]


@dataclass(frozen=True)
class Capsule:
    """A cylinder of length ``height`` (m) along +Y with hemispherical caps of ``radius``."""

    radius: float
    height: float


@dataclass(frozen=True)
class Cylinder:
    """A solid cylinder of ``radius`` and total ``height`` (m) along +Y, centred."""

    radius: float
    height: float


@dataclass(frozen=True)
class Mesh:
    """A closed triangle mesh with outward (counter-clockwise) faces.

    ``vertices`` is ``(V, 3)`` in metres, ``triangles`` ``(T, 3)`` vertex indices. Open,
    inconsistently oriented, inverted or flat meshes are refused by :meth:`World.add_body`.
    """

    vertices: Any
    triangles: Any


Shape = Sphere | Box | Capsule | Cylinder | Mesh


class Body:
    """Read-only view of one body of a :class:`World` (its index and mass properties)."""

    __slots__ = ("_index", "_world")

    def __init__(self, world: _kinema.RigidWorld, index: int) -> None:
        self._world, self._index = world, index

    @property
    def index(self) -> int:
        """Index of the body in its world."""
        return self._index

    @property
    def mass(self) -> float:
        """Mass (kg)."""
        return self._world.mass(self._index)

    @property
    def inertia(self) -> np.ndarray:
        """Inertia tensor about the centre of mass in body-frame axes, ``(3, 3)`` (kg m²)."""
        return np.array(self._world.inertia(self._index)).reshape(3, 3)

    @property
    def center_of_mass(self) -> np.ndarray:
        """Centre of mass in the body frame, ``(3,)`` (m)."""
        return np.array(self._world.center_of_mass(self._index))


class World:
    """Rigid bodies in a uniform gravity field, stepped with one clock, colliding with the
    ground when one is added.

    ``gravity`` is in m/s² (default ``(0, -9.81, 0)``, +Y up); ``integrator`` names the rotation
    integrator (see the module docs); ``collisions=False`` turns off contacts between bodies
    (a world of free bodies then steps with the exact free update and pays no broad phase).
    State arrays (``positions`` ...) are fresh copies.
    """

    def __init__(
        self,
        gravity: Any = (0.0, -9.81, 0.0),
        integrator: str = "splitting",
        *,
        collisions: bool = True,
    ) -> None:
        self._world = _kinema.RigidWorld(
            as_vector3(gravity, "gravity"), integrator, bool(collisions)
        )
        self._shapes: list[Shape] = []

    def add_body(
        self,
        shape: Shape,
        *,
        density: float | None = None,
        mass: float | None = None,
        position: Any = (0.0, 0.0, 0.0),
        orientation: Rotation | None = None,
        velocity: Any = (0.0, 0.0, 0.0),
        angular_velocity: Any = (0.0, 0.0, 0.0),
        fixed: bool = False,
        restitution: float = 0.0,
        friction: float = 0.5,
    ) -> int:
        """Add a body and return its index.

        Give ``density`` (kg/m³) or ``mass`` (kg), not both; with neither the density of water
        (1000 kg/m³) is used. ``position`` places the body-frame origin (m); ``velocity`` is the
        centre of mass's (m/s); ``angular_velocity`` is in the world frame (rad/s). A ``fixed``
        body never moves. ``restitution`` (in [0, 1]) and ``friction`` (Coulomb coefficient)
        are the surface's; a contact takes the larger restitution and the geometric mean of
        the frictions of its two surfaces.
        """
        verts = tris = None
        if isinstance(shape, Sphere):
            kind, dims = "sphere", [float(shape.radius)]
        elif isinstance(shape, Box):
            kind, dims = "box", as_vector3(shape.half_extents, "half_extents")
        elif isinstance(shape, Capsule):
            kind, dims = "capsule", [float(shape.radius), float(shape.height)]
        elif isinstance(shape, Cylinder):
            kind, dims = "cylinder", [float(shape.radius), float(shape.height)]
        elif isinstance(shape, Mesh):
            kind, dims = "mesh", []
            verts, _ = as_batch(shape.vertices, "vertices", (3,))
            tris, _ = as_batch(shape.triangles, "triangles", (3,))
        else:
            raise ValueError(
                f"shape: expected Sphere, Box, Capsule, Cylinder or Mesh, got {shape!r}"
            )
        rot = Rotation.identity() if orientation is None else orientation
        if not isinstance(rot, Rotation) or not rot.single:
            raise ValueError("orientation: expected a single kinema.Rotation")
        index = self._world.add_body(
            kind,
            dims,
            verts,
            tris,
            density,
            mass,
            as_vector3(position, "position"),
            rot.as_quat().tolist(),
            as_vector3(velocity, "velocity"),
            as_vector3(angular_velocity, "angular_velocity"),
            bool(fixed),
            float(restitution),
            float(friction),
        )
        self._shapes.append(shape)
        return int(index)

    def add_ground(
        self, height: float = 0.0, *, restitution: float = 0.0, friction: float = 0.5
    ) -> None:
        """Add the ground: the static plane ``y = height`` (m), solid below, with its
        ``restitution`` and Coulomb ``friction``. Bodies then collide with it (sequential
        impulses; see docs/rigid.md)."""
        self._world.add_plane([0.0, 1.0, 0.0], float(height), float(restitution), float(friction))

    @property
    def shapes(self) -> list[Shape]:
        """The shape of each body, in the order added."""
        return list(self._shapes)

    @property
    def bodies(self) -> list[Body]:
        """The bodies, in the order they were added."""
        return [Body(self._world, i) for i in range(len(self._world))]

    def __len__(self) -> int:
        return len(self._world)

    def step(self, dt: float, steps: int = 1) -> None:
        """Advance ``steps`` steps of ``dt`` seconds.

        Raises ``kinema.SimulationError`` (state left at the last good step) on divergence.
        """
        if not isinstance(steps, (int, np.integer)) or steps < 0:
            raise ValueError(f"steps: expected a non-negative integer, got {steps!r}")
        self._world.step(float(dt), int(steps))

    def apply_force(self, body: int, force: Any, point: Any = None) -> None:
        """Apply ``force`` (N, world frame) at world ``point`` (m; default the centre of mass)
        of ``body`` during the next step."""
        if point is None:
            com = self.bodies[body].center_of_mass
            point = Rotation.from_quat(self.orientations[body]).apply(com) + self.positions[body]
        self._world.apply_force(int(body), as_vector3(force, "force"), as_vector3(point, "point"))

    @property
    def positions(self) -> np.ndarray:
        """World positions of the body-frame origins, ``(N, 3)`` (m)."""
        return self._world.positions()

    @property
    def orientations(self) -> np.ndarray:
        """Orientations as scalar-first unit quaternions, ``(N, 4)`` (body → world)."""
        return self._world.orientations()

    @property
    def velocities(self) -> np.ndarray:
        """Centre-of-mass velocities, ``(N, 3)`` (m/s)."""
        return self._world.velocities()

    @property
    def angular_velocities(self) -> np.ndarray:
        """Angular velocities in the world frame, ``(N, 3)`` (rad/s)."""
        return self._world.angular_velocities()

    def kinetic_energy(self) -> float:
        """Total kinetic energy, translational plus rotational (J)."""
        return self._world.kinetic_energy()

    def linear_momentum(self) -> np.ndarray:
        """Total linear momentum ``(3,)`` (kg m/s)."""
        return np.array(self._world.linear_momentum())

    def angular_momentum(self) -> np.ndarray:
        """Total angular momentum about the world origin ``(3,)`` (kg m²/s)."""
        return np.array(self._world.angular_momentum())
