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
Coulomb friction (sequential impulses).

``World.add_joint`` joins two bodies, or a body and the world, by a :class:`Ball`,
:class:`Hinge` (with angle limits and a velocity motor), :class:`Slider` or :class:`Fixed`
joint, enforced by one of four formulations (``method``):

- ``"penalty"``: stiff springs and dampers on the constraint (Bender et al. 2014); cheap, but
  the joint gives by about ``g/k`` and the step must stay small;
- ``"lagrange"`` (default): Lagrange multipliers from ``J M⁻¹ Jᵀ λ = …`` solved by a sparse
  Cholesky factorisation, with Baumgarte feedback and a post-stabilising projection;
- ``"impulse"``: sequential impulses on the velocities and a position pass (Catto 2005);
- ``"xpbd"``: extended position-based dynamics with substeps (Müller et al. 2020).

Contact islands that do not converge within ``World.contact_iterations`` sweeps finish with
shock propagation (Guendelman et al. 2003), so tall stacks stand at the default settings;
bodies may have linear and angular damping. See docs/rigid.md for both and for the measured
trade between the joint formulations.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from kinema import _kinema
from kinema._array import as_batch, as_vector3, real
from kinema.rotation import Rotation

__all__ = [
    "METHODS",
    "PENALTY_DAMPING",
    "PENALTY_STIFFNESS",
    "Ball",
    "Body",
    "Box",
    "Capsule",
    "Cylinder",
    "Fixed",
    "Hinge",
    "Mesh",
    "Slider",
    "Sphere",
    "World",
]

#: The joint formulations accepted by :meth:`World.add_joint`.
METHODS = ("penalty", "lagrange", "impulse", "xpbd")
#: Default penalty stiffness (1/s²) and damping (1/s) per unit mass, as in the Rust core
#: (``kinema::rigid::PENALTY_STIFFNESS``, ``PENALTY_DAMPING``).
PENALTY_STIFFNESS, PENALTY_DAMPING = 1e4, 200.0


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


@dataclass(frozen=True)
class Ball:
    """A ball joint: the point ``anchor`` (world coordinates at creation, m) of body ``a`` and of
    body ``b`` stay together; any relative rotation is free. ``b=None`` (or -1) is the world."""

    a: int
    b: int | None
    anchor: Any


@dataclass(frozen=True)
class Hinge:
    """A hinge: a ball joint at ``anchor`` that also keeps the bodies' ``axis`` (world, at
    creation) aligned, so ``b`` turns relative to ``a`` only about it.

    The hinge angle is 0 at creation and positive when ``b`` turns about ``+axis`` relative to
    ``a``. ``limits=(lo, hi)`` (rad, ``lo <= 0 <= hi``) bound it. A motor drives the angular
    velocity of ``b`` relative to ``a`` about the axis to ``motor_speed`` (rad/s) with a torque
    of at most ``max_torque`` (N m; the default, infinity, makes it a velocity constraint).
    ``b=None`` (or -1) is the world.
    """

    a: int
    b: int | None
    anchor: Any
    axis: Any
    limits: tuple[float, float] | None = None
    motor_speed: float | None = None
    max_torque: float = math.inf


@dataclass(frozen=True)
class Slider:
    """A slider (prismatic joint): no relative rotation, and ``a`` moves relative to ``b`` only
    along ``axis`` (world, at creation; it turns with ``b``). Anchored at the centre of mass of
    ``a``. ``b=None`` (or -1) is the world."""

    a: int
    b: int | None
    axis: Any


@dataclass(frozen=True)
class Fixed:
    """A fixed joint (weld): ``a`` and ``b`` keep their relative pose at creation. ``b=None`` (or
    -1) is the world."""

    a: int
    b: int | None


Joint = Ball | Hinge | Slider | Fixed


def _body_index(value: Any, name: str, world_ok: bool) -> int | None:
    """A body index from ``value``: a non-negative integer, or None / -1 for the world."""
    if world_ok and (value is None or (isinstance(value, (int, np.integer)) and value == -1)):
        return None
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
        what = "a body index or None (the world)" if world_ok else "a body index"
        raise ValueError(f"{name}: expected {what}, got {value!r}")
    return int(value)


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

    @property
    def friction(self) -> float:
        """Coulomb friction coefficient of the body's surface."""
        return self._world.friction(self._index)

    @property
    def linear_damping(self) -> float:
        """Linear damping rate ``c`` (1/s): ``v̇ = … − c v`` (see :meth:`World.add_body`)."""
        return self._world.damping(self._index)[0]

    @property
    def angular_damping(self) -> float:
        """Angular damping rate ``c_ω`` (1/s): ``Π̇ = … − c_ω Π`` (see :meth:`World.add_body`)."""
        return self._world.damping(self._index)[1]


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
        linear_damping: float = 0.0,
        angular_damping: float = 0.0,
    ) -> int:
        """Add a body and return its index.

        Give ``density`` (kg/m³) or ``mass`` (kg), not both; with neither the density of water
        (1000 kg/m³) is used. ``position`` places the body-frame origin (m); ``velocity`` is the
        centre of mass's (m/s); ``angular_velocity`` is in the world frame (rad/s). A ``fixed``
        body never moves. ``restitution`` (in [0, 1]) and ``friction`` (Coulomb coefficient)
        are the surface's; a contact takes the larger restitution and the geometric mean of
        the frictions of its two surfaces.

        ``linear_damping`` and ``angular_damping`` (1/s, default 0: none) slow the body as
        ``v̇ = … − c v`` and ``Π̇ = … − c_ω Π`` (angular momentum), solved exactly over each
        step (``v ← e^{−c h} v``, as Box2D's and Bullet's damping): a free body's speed falls
        as ``e^{−c t}``. Drag from air at low speed is of this form (Stokes).
        """
        for name, c in (("linear_damping", linear_damping), ("angular_damping", angular_damping)):
            if not (isinstance(c, numbers.Real) and math.isfinite(c) and c >= 0):
                raise ValueError(f"{name}: must be non-negative and finite (1/s), got {c!r}")
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
            real(restitution, "restitution"),
            real(friction, "friction"),
        )
        self._world.set_damping(
            index, real(linear_damping, "linear_damping"), real(angular_damping, "angular_damping")
        )
        self._shapes.append(shape)
        return int(index)

    def add_ground(
        self, height: float = 0.0, *, restitution: float = 0.0, friction: float = 0.5
    ) -> None:
        """Add the ground: the static plane ``y = height`` (m), solid below, with its
        ``restitution`` and Coulomb ``friction``. Bodies then collide with it (sequential
        impulses; see docs/rigid.md)."""
        self._world.add_plane(
            [0.0, 1.0, 0.0],
            real(height, "height"),
            real(restitution, "restitution"),
            real(friction, "friction"),
        )

    def add_joint(
        self,
        joint: Joint,
        method: str = "lagrange",
        *,
        stiffness: float | None = None,
        damping: float | None = None,
    ) -> int:
        """Add a :class:`Ball`, :class:`Hinge`, :class:`Slider` or :class:`Fixed` joint and
        return its index.

        ``method`` is one of :data:`METHODS` (see the module docs and docs/rigid.md). For
        ``"penalty"``, ``stiffness`` (1/s²) and ``damping`` (1/s) are per unit mass: a linear
        row's spring is ``stiffness`` times the reduced mass of the two bodies (N/m), an
        angular row's times its effective inertia, so ``√stiffness`` is the frequency at which
        the joint rings (defaults :data:`PENALTY_STIFFNESS`, :data:`PENALTY_DAMPING`: 100 rad/s,
        critically damped); other methods refuse them. Bodies joined by a joint no longer
        collide with each other. Anchors and axes are read in world coordinates at the current
        pose.
        """
        if method not in METHODS:
            raise ValueError(f"method: expected one of {', '.join(METHODS)}, got {method!r}")
        if method != "penalty" and (stiffness is not None or damping is not None):
            raise ValueError(f"stiffness: only penalty joints have one, not {method!r} joints")
        if not isinstance(joint, (Ball, Hinge, Slider, Fixed)):
            raise ValueError(f"joint: expected Ball, Hinge, Slider or Fixed, got {joint!r}")
        a = _body_index(joint.a, "a", False)
        b = _body_index(joint.b, "b", True)
        if a is None:  # not reached: the world is refused for `a`
            raise ValueError("a: expected a body index")
        anchor = [0.0, 0.0, 0.0]
        axis = [1.0, 0.0, 0.0]
        limits = motor = None
        if isinstance(joint, (Ball, Hinge)):
            anchor = as_vector3(joint.anchor, "anchor")
        if isinstance(joint, (Hinge, Slider)):
            axis = as_vector3(joint.axis, "axis")
        if isinstance(joint, Hinge):
            if joint.limits is not None:
                lo, hi = (float(x) for x in joint.limits)
                limits = (lo, hi)
            if joint.motor_speed is not None:
                motor = (float(joint.motor_speed), float(joint.max_torque))
            elif joint.max_torque != math.inf:
                raise ValueError("max_torque: a torque bound needs a motor_speed")
        kind = type(joint).__name__.lower()
        return self._world.add_joint(
            kind,
            a,
            b,
            anchor,
            axis,
            limits,
            motor,
            method,
            PENALTY_STIFFNESS if stiffness is None else real(stiffness, "stiffness"),
            PENALTY_DAMPING if damping is None else real(damping, "damping"),
        )

    @property
    def joint_violations(self) -> np.ndarray:
        """Position error per joint, ``(J, 2)``: the distance between the joint's anchors (m;
        for a slider, off its axis) and the angle of the relative rotation it forbids (rad;
        between the axes for a hinge, 0 for a ball joint)."""
        return self._world.joint_violations()

    @property
    def joint_coordinates(self) -> np.ndarray:
        """Coordinate and rate per joint, ``(J, 2)``: a hinge's angle (rad, 0 at creation) and
        the angular velocity of ``b`` relative to ``a`` about its axis (rad/s); a slider's
        displacement of ``b`` relative to ``a`` along its axis (m) and its rate (m/s); zeros for
        ball and fixed joints."""
        return self._world.joint_coordinates()

    @property
    def contact_iterations(self) -> int:
        """Sequential-impulse sweeps per step for contacts, on the velocities and then on the
        positions (default 40; more for tall stacks, fewer for speed; at most 10^6)."""
        return self._world.contact_iterations

    @contact_iterations.setter
    def contact_iterations(self, n: int) -> None:
        self._world.contact_iterations = n

    @property
    def joint_iterations(self) -> int:
        """Sequential-impulse sweeps per step (velocities, then positions) for ``"impulse"``
        joints (default 20; at most 10^6)."""
        return self._world.joint_iterations

    @joint_iterations.setter
    def joint_iterations(self, n: int) -> None:
        self._world.joint_iterations = n

    @property
    def xpbd_substeps(self) -> int:
        """Substeps per step when a joint uses ``"xpbd"`` (default 20; each substep projects
        the positions once, as Müller et al. 2020 recommend; 1 to 10^6)."""
        return self._world.xpbd_substeps

    @xpbd_substeps.setter
    def xpbd_substeps(self, n: int) -> None:
        self._world.xpbd_substeps = n

    @property
    def baumgarte(self) -> float:
        """Baumgarte factor β in [0, 1] of the ``"lagrange"`` joints (default 0.2): the
        multipliers ask for ``Ċ = −β C/h`` at the end of a step."""
        return self._world.baumgarte

    @baumgarte.setter
    def baumgarte(self, beta: float) -> None:
        self._world.baumgarte = real(beta, "beta")

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
        self._world.step(real(dt, "dt"), int(steps))

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

    def potential_energy(self) -> float:
        """Gravitational potential energy ``−Σ m g · x`` of the free bodies, zero at the origin
        (J)."""
        return self._world.potential_energy()

    def linear_momentum(self) -> np.ndarray:
        """Total linear momentum ``(3,)`` (kg m/s)."""
        return np.array(self._world.linear_momentum())

    def angular_momentum(self) -> np.ndarray:
        """Total angular momentum about the world origin ``(3,)`` (kg m²/s)."""
        return np.array(self._world.angular_momentum())
