"""Discrete elastic rods (Bergou, Wardetzky, Robinson, Audoly & Grinspun 2008; time-parallel
transport of Bergou, Audoly, Vouga, Wardetzky & Grinspun 2010): hair, ropes, cables and stems
as a polyline of vertices with one twist angle per edge, bending (with the natural curvature
of the shape given), twisting and stretching, stepped by implicit Euler (Newton on a banded
system with a line search, stable at dt = 1/60 for stiff hair) or symplectic Euler.

Build a :class:`Rod` from points (its rest shape) or with :meth:`Rod.straight`, clamp or pin
it, then ``step`` it or ``solve_static`` it. :func:`groom` grows a :class:`Hair` (many strands
of one model, stepped in parallel, roots clamped to a moving head, kept apart by a rod–rod
repulsion) from scalp points, e.g. from :func:`sphere_cap`. ``positions``, ``velocities`` and ``twists`` are
read-only numpy views of the Rust state, updated in place (no copy). See docs/rods.md.
"""

from __future__ import annotations

import operator
from typing import Any, SupportsIndex

import numpy as np

from kinema import _kinema
from kinema._array import as_orientation, as_vector3, real
from kinema.geometry import Box, Capsule, Plane, Sphere, shape_params

__all__ = ["Hair", "Rod", "groom", "sphere_cap"]


def _index(value: object, name: str) -> int:
    """An integer argument as an ``int`` (``TypeError`` naming ``name`` otherwise)."""
    if isinstance(value, bool) or not isinstance(value, SupportsIndex):
        raise TypeError(f"{name}: expected an integer, got {type(value).__name__}")
    return operator.index(value)


def _collider_params(collider: Plane | Sphere | Capsule | Box) -> tuple[str, list[float]]:
    """The shape's kind and parameters followed by its friction, for a static rod collider."""
    kind, p = shape_params(collider)
    if collider.restitution is not None:
        raise ValueError("restitution: rod contacts are inelastic; leave it None for rods")
    if isinstance(collider, Sphere) and collider.inside:
        raise ValueError("inside: rods collide with the outside of a sphere only")
    if any(v != 0.0 for v in as_vector3(collider.velocity, "velocity")):
        raise ValueError("velocity: rod colliders are static")
    return kind, [*p, 0.0 if collider.friction is None else float(collider.friction)]


class Rod:
    """An elastic rod at rest in the shape of ``points`` ``(N, 3)`` (m, N >= 2).

    The cross-section is an ellipse of semi-axes ``radius`` (m; one number for a round rod,
    or ``(a, b)`` with ``a`` along the material director ``m1``); ``youngs_modulus`` and
    ``shear_modulus`` in Pa (the shear modulus defaults to ``E / 3``, an incompressible
    material); ``density`` in kg/m³. The shape given is the rest shape (its curvature is the
    rod's natural curvature); ``twist`` ``(N - 1,)`` (rad) turns the material frames of the
    edges from it, or is ``None`` (untwisted). ``gravity`` in m/s²; ``integrator``
    ``"implicit"`` (implicit Euler) or ``"symplectic"`` (symplectic Euler); Newton stops when
    a step moves no vertex more than ``tolerance`` times the rod's length and no angle more
    than ``tolerance`` rad (or at the rounding level), and fails with
    :class:`kinema.SimulationError` after ``max_iterations`` (the rod unchanged).
    ``contact_stiffness`` (N/m) is the stiffness of the contact penalty against colliders (a
    resting vertex sinks by its load over it); ``friction_velocity`` (m/s) the sliding speed
    below which friction acts as a stiff spring (static friction creeps slower than it).
    ``inextensible=True`` holds every edge at its rest length (to ``tolerance``) by a fast
    projection after each step (Goldenthal et al. 2007) instead of leaving it to the stiff
    stretching alone; ``quasistatic_twist=True`` gives the twists no inertia, so each implicit
    step minimises the energy over them given the centreline (Bergou et al. 2008, sec. 6;
    implicit integrator only). ``closed=True`` makes a ring (N >= 3 points, N edges: the last point joins the first);
    its rest shape is naturally curved (an O-ring) unless :meth:`straighten` is called, and
    :meth:`twist_ring` twists it.
    """

    def __init__(
        self,
        points: Any,
        radius: Any = 1e-3,
        youngs_modulus: float = 1e6,
        shear_modulus: float | None = None,
        density: float = 1000.0,
        twist: Any = None,
        *,
        gravity: Any = (0.0, -9.81, 0.0),
        integrator: str = "implicit",
        tolerance: float = 1e-10,
        max_iterations: int = 100,
        contact_stiffness: float = 1e4,
        friction_velocity: float = 1e-3,
        inextensible: bool = False,
        quasistatic_twist: bool = False,
        closed: bool = False,
    ) -> None:
        pts = _floats(points, "points")
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise ValueError(f"points: expected shape (N, 3), got {pts.shape}")
        radii = _floats(radius, "radius")
        if radii.shape not in ((), (2,)):
            raise ValueError("radius: expected a number or two semi-axes (a, b)")
        pair = [float(radii)] * 2 if radii.shape == () else radii.tolist()
        e = real(youngs_modulus, "youngs_modulus")
        g = e / 3.0 if shear_modulus is None else real(shear_modulus, "shear_modulus")
        angles = None
        if twist is not None:
            t = _floats(twist, "twist")
            if t.ndim != 1:
                raise ValueError(f"twist: expected shape (N - 1,), got {t.shape}")
            angles = t.tolist()
        if not isinstance(integrator, str):
            raise TypeError("integrator: expected 'implicit' or 'symplectic'")
        self._r = _kinema.Rod(
            np.ascontiguousarray(pts),
            pair,
            e,
            g,
            real(density, "density"),
            angles,
            as_vector3(gravity, "gravity"),
            integrator,
            real(tolerance, "tolerance"),
            max_iterations,
            real(contact_stiffness, "contact_stiffness"),
            real(friction_velocity, "friction_velocity"),
            _flag(inextensible, "inextensible"),
            _flag(quasistatic_twist, "quasistatic_twist"),
            _flag(closed, "closed"),
        )

    @classmethod
    def straight(
        cls,
        n: int,
        length: float,
        direction: Any = (1.0, 0.0, 0.0),
        origin: Any = (0.0, 0.0, 0.0),
        **kwargs: Any,
    ) -> Rod:
        """A straight rod of ``n`` vertices (n >= 2) over ``length`` (m) from ``origin`` along
        ``direction`` (made unit); ``kwargs`` as for :class:`Rod`."""
        count = _index(n, "n")
        if count < 2:
            raise ValueError("n: a rod needs at least 2 vertices")
        size = real(length, "length")
        if not (np.isfinite(size) and size > 0.0):
            raise ValueError("length: must be finite and > 0")
        d = np.asarray(as_vector3(direction, "direction"))
        norm = float(np.linalg.norm(d))
        if not (np.isfinite(norm) and norm > 0.0):
            raise ValueError("direction: must be a finite non-zero vector")
        o = np.asarray(as_vector3(origin, "origin"))
        s = np.linspace(0.0, size, count)[:, None]
        return cls(o + s * (d / norm), **kwargs)

    def clamp(self, end: int = 0) -> None:
        """Clamp an end, ``0`` (the first vertex) or ``-1`` (the last): its first or last edge
        keeps its position and material frame."""
        e = _index(end, "end")
        if e not in (0, -1):
            raise ValueError("end: expected 0 (the first end) or -1 (the last)")
        self._r.clamp(e == -1)

    def move_clamp(
        self, end: int, rotation: Any = None, translation: Any = (0.0, 0.0, 0.0)
    ) -> None:
        """Move the clamped ``end`` (``0`` or ``-1``) by the end of the next ``step`` call
        (reached linearly over its steps) or ``solve_static``: its edge goes to its rest pose
        rotated by ``rotation`` (a single :class:`kinema.Rotation` about the origin, ``None``
        for none) and
        shifted by ``translation`` (m), its material frame turned by the same rotation (so
        turning the end by an angle about its axis twists the rod by it). One call turns the
        end by less than half a turn about its own axis."""
        e = _index(end, "end")
        if e not in (0, -1):
            raise ValueError("end: expected 0 (the first end) or -1 (the last)")
        q = as_orientation(rotation, "rotation")
        self._r.move_clamp(e == -1, q, as_vector3(translation, "translation"))

    def add_collider(self, collider: Plane | Sphere | Capsule | Box) -> None:
        """Add a static collision shape (:mod:`kinema.geometry`): the vertices keep out of
        it by the rod's radius, with Coulomb friction ``collider.friction`` (default 0;
        restitution and velocity are not used: rod contacts are inelastic, the shape static)."""
        self._r.add_collider(*_collider_params(collider))

    def straighten(self) -> None:
        """Make the rod naturally straight and untwisted: the rest curvatures and twists become
        zero, the points only its initial shape (a straight wire bent into it, as Michell's
        ring)."""
        self._r.straighten()

    def twist_ring(self, angle: float) -> None:
        """Twist a ring (``closed=True``) by ``angle`` (rad) more, spread evenly over its edges
        (the material at the seam turned by ``angle``; the link grows by ``angle / 2π``)."""
        self._r.twist_ring(real(angle, "angle"))

    def pin(self, index: int) -> None:
        """Hold vertex ``index`` (negative counts from the end) where it is."""
        k = _index(index, "index")
        self._r.pin(k + len(self) if k < 0 else k)

    def set_force(self, index: int, force: Any) -> None:
        """Apply ``force`` (N) to vertex ``index`` (negative counts from the end) during the
        later steps, until changed (gravity comes on top)."""
        k = _index(index, "index")
        self._r.set_force(k + len(self) if k < 0 else k, as_vector3(force, "force"))

    def step(self, dt: float, steps: int = 1) -> None:
        """Advance ``steps`` steps of ``dt`` seconds."""
        self._r.step(real(dt, "dt"), steps)

    def solve_static(self) -> None:
        """Move to the static equilibrium under gravity and the forces set, nearest the current
        shape (Newton with a line search on the potential energy); velocities become 0."""
        self._r.solve_static()

    def energy(self) -> float:
        """The elastic energy (J): stretching, bending and twisting."""
        return self._r.energy()

    def __len__(self) -> int:
        return len(self._r)

    @property
    def positions(self) -> np.ndarray:
        """Read-only view ``(N, 3)`` of the vertex positions (m)."""
        return self._r.positions

    @property
    def velocities(self) -> np.ndarray:
        """Read-only view ``(N, 3)`` of the vertex velocities (m/s)."""
        return self._r.velocities

    @property
    def twists(self) -> np.ndarray:
        """Read-only view ``(N - 1,)`` of the edges' twist angles (rad) from their reference
        frames."""
        return self._r.twists

    @property
    def material_frames(self) -> np.ndarray:
        """The material frames ``(N - 1, 3, 3)`` (a new array): per edge the rows tangent,
        ``m1``, ``m2`` (unit, right-handed)."""
        return self._r.material_frames()

    @property
    def masses(self) -> np.ndarray:
        """The lumped vertex masses ``(N,)`` (kg, a new array)."""
        return self._r.masses()

    @property
    def stiffness(self) -> dict[str, Any]:
        """``stretching`` ``EA`` (N), ``bending`` ``(EI1, EI2)`` (N m²), ``twisting`` ``GJ``
        (N m²)."""
        ea, ei, gj = self._r.stiffness()
        return {"stretching": ea, "bending": tuple(ei), "twisting": gj}

    @property
    def time(self) -> float:
        """Simulated time (s)."""
        return self._r.time

    @property
    def stats(self) -> dict[str, int]:
        """What the last ``step`` or ``solve_static`` did: ``steps``, ``iterations`` (Newton,
        summed), ``halvings`` (of the line searches, summed)."""
        return self._r.stats()


class Hair:
    """Strands on a head, made by :func:`groom`: one rod model (the template strand) placed on
    every scalp point, stepped together in parallel (implicit Euler; bitwise the same on any
    number of threads), their root edges clamped to the head's pose (:meth:`set_head`), kept
    apart by a penalty on the distance between the centrelines of different strands."""

    def __init__(self, core: Any) -> None:
        self._h = core

    def set_head(self, rotation: Any = None, translation: Any = (0.0, 0.0, 0.0)) -> None:
        """Move the head to ``rotation`` (a single :class:`kinema.Rotation` about the origin,
        ``None`` for none) then ``translation`` (m) by the end of the next :meth:`step` call
        (slerp and linearly over its steps); the roots follow it exactly."""
        q = as_orientation(rotation, "rotation")
        self._h.set_head(q, as_vector3(translation, "translation"))

    @property
    def head(self) -> tuple[Any, np.ndarray]:
        """The head's pose after the last step: a :class:`kinema.Rotation` and a translation
        (m)."""
        from kinema.rotation import Rotation

        q, t = self._h.head()
        return Rotation.from_quat(q), np.array(t)

    def add_collider(self, collider: Plane | Sphere | Capsule | Box) -> None:
        """Add a static collision shape for every strand (as :meth:`Rod.add_collider`)."""
        self._h.add_collider(*_collider_params(collider))

    def set_head_collider(self, ball: Sphere) -> None:
        """Make the head a moving collider: ``ball`` (a :class:`kinema.geometry.Sphere`, m, where
        it is with the head at rest) moves with the head, and the strands' vertices keep out of
        it by their radius (the penalty of ``contact_stiffness``; frictionless), the ball at the
        head's pose at the end of each step. Replaces the head ball set before."""
        if not isinstance(ball, Sphere):
            raise TypeError(f"ball: expected a kinema.geometry.Sphere, got {type(ball).__name__}")
        _, p = _collider_params(ball)
        if p[-1] != 0.0:
            raise ValueError("friction: the head collider is frictionless; leave it None")
        self._h.set_head_collider(p[:3], p[3])

    def step(self, dt: float, steps: int = 1) -> None:
        """Advance ``steps`` steps of ``dt`` seconds; on a :class:`kinema.SimulationError` every
        strand and the head are as they were."""
        self._h.step(real(dt, "dt"), steps)

    def __len__(self) -> int:
        return len(self._h)

    @property
    def positions(self) -> np.ndarray:
        """The vertex positions ``(S, N, 3)`` of the ``S`` strands (m, a new array)."""
        return self._h.positions().reshape(len(self), -1, 3)

    @property
    def time(self) -> float:
        """Simulated time (s)."""
        return self._h.time

    @property
    def stats(self) -> dict[str, int]:
        """What the last ``step`` did: ``steps``, ``iterations`` and ``halvings`` summed over
        the strands."""
        return self._h.stats()

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        return (Hair, (self._h,))


def groom(
    points: Any,
    normals: Any,
    length: float = 0.1,
    segments: int = 16,
    curl: float = 0.0,
    *,
    radius: float = 5e-5,
    youngs_modulus: float = 1e9,
    shear_modulus: float | None = None,
    density: float = 1300.0,
    gravity: Any = (0.0, -9.81, 0.0),
    tolerance: float = 1e-10,
    max_iterations: int = 100,
    contact_stiffness: float = 1e4,
    friction_velocity: float = 1e-3,
    inextensible: bool = False,
    quasistatic_twist: bool = False,
    repulsion_stiffness: float = 0.0,
    thickness: float | None = None,
    strand_friction: float = 0.0,
) -> Hair:
    """Grow a :class:`Hair`: one strand from each scalp point ``points`` ``(S, 3)`` (m, the
    head at rest) along ``normals`` ``(S, 3)`` (made unit): ``segments`` edges over the arc
    length ``length`` (m), straight when ``curl`` is 0, else a helix of radius ``curl`` (m)
    about the normal at a 45° pitch (natural curvature ``1 / (2 curl)``). The template is
    turned from ``+z`` onto each normal by the shortest arc. The material is that of
    :class:`Rod` (defaults: human hair, ``E = 1 GPa``, ``r = 50 µm``, ``ρ = 1300 kg/m³``).
    ``repulsion_stiffness`` (N/m, 0 for none) penalises centrelines of different strands
    closer than ``thickness`` (m, default twice the radius), with Coulomb friction
    ``strand_friction`` between them (lagged, on the relative tangential motion of the closest
    points). ``inextensible`` and ``quasistatic_twist`` are those of :class:`Rod`."""
    pts, nrm = _floats(points, "points"), _floats(normals, "normals")
    for a, name in ((pts, "points"), (nrm, "normals")):
        if a.ndim != 2 or a.shape[1] != 3:
            raise ValueError(f"{name}: expected shape (S, 3), got {a.shape}")
    r = real(radius, "radius")
    e = real(youngs_modulus, "youngs_modulus")
    g = e / 3.0 if shear_modulus is None else real(shear_modulus, "shear_modulus")
    return Hair(
        _kinema.Hair(
            np.ascontiguousarray(pts),
            np.ascontiguousarray(nrm),
            real(length, "length"),
            _index(segments, "segments"),
            real(curl, "curl"),
            [r, r],
            e,
            g,
            real(density, "density"),
            as_vector3(gravity, "gravity"),
            real(tolerance, "tolerance"),
            max_iterations,
            real(contact_stiffness, "contact_stiffness"),
            real(friction_velocity, "friction_velocity"),
            _flag(inextensible, "inextensible"),
            _flag(quasistatic_twist, "quasistatic_twist"),
            real(repulsion_stiffness, "repulsion_stiffness"),
            2.0 * r if thickness is None else real(thickness, "thickness"),
            real(strand_friction, "strand_friction"),
        )
    )


def sphere_cap(
    count: int,
    radius: float = 0.1,
    center: Any = (0.0, 0.0, 0.0),
    axis: Any = (0.0, 1.0, 0.0),
    angle: float = np.pi / 2,
) -> tuple[np.ndarray, np.ndarray]:
    """``count`` points ``(count, 3)`` spread evenly (a Fibonacci spiral, equal areas) over the
    cap of the sphere of ``radius`` (m) about ``center`` within ``angle`` (rad, up to π) of
    ``axis``, and their outward unit normals: a scalp for :func:`groom`."""
    n = _index(count, "count")
    if n < 1:
        raise ValueError("count: expected at least 1 point")
    r, a = real(radius, "radius"), real(angle, "angle")
    if not (np.isfinite(r) and r > 0.0):
        raise ValueError("radius: must be finite and > 0")
    if not (np.isfinite(a) and 0.0 < a <= np.pi):
        raise ValueError("angle: must be in (0, pi]")
    z = np.asarray(as_vector3(axis, "axis"))
    norm = float(np.linalg.norm(z))
    if not (np.isfinite(norm) and norm > 0.0):
        raise ValueError("axis: must be a finite non-zero vector")
    z = z / norm
    x = np.cross(z, [1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    k = np.arange(n) + 0.5
    h = 1.0 - (1.0 - np.cos(a)) * k / n  # equal areas: uniform in the height
    rho = np.sqrt(np.clip(1.0 - h * h, 0.0, None))
    phi = np.pi * (3.0 - np.sqrt(5.0)) * k
    normals = rho[:, None] * (np.cos(phi)[:, None] * x + np.sin(phi)[:, None] * y) + h[:, None] * z
    return np.asarray(as_vector3(center, "center")) + r * normals, normals


def _flag(value: object, name: str) -> bool:
    """A boolean argument (``TypeError`` naming ``name`` otherwise)."""
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name}: expected True or False, got {type(value).__name__}")
    return bool(value)


def _floats(value: object, name: str) -> np.ndarray:
    """``value`` as a float64 array, or ``ValueError`` naming ``name`` (never quoting it)."""
    try:
        return np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected numbers, got {type(value).__name__}") from None
