"""Constrained particle dynamics with Lagrange multipliers (Witkin's formulation).

``ConstrainedSystem(particle_system, ks, kd)`` holds constraints on the particles of a
:class:`kinema.particles.ParticleSystem`. Each step solves

``J W Jᵀ λ = -J̇ q̇ - J W Q - ks C - kd Ċ``

for the multipliers (sparse, by faer's Cholesky or by conjugate gradient) and adds the
constraint force ``Jᵀ λ``, which does no work; ``ks``/``kd`` feed the drift back (``0, 0``, the
default, turns feedback off). After every step, post-stabilisation (Cline & Pai 2003, on by
default, ``stabilize=False`` turns it off) projects the positions onto ``C = 0`` and the
velocities onto ``J v = 0`` with the same sparse solve, so the constraints hold to 1e-10 m at
any step. ``method`` is any ODE method of :mod:`kinema.ode`, or ``"projection"``: step and
project (Goldenthal et al. 2007), the free step moved to its closest point on ``C = 0`` by
Newton's method with the constraints' geometric stiffness; first order and dissipative, but
stable at large steps under any tension (ropes of 100,000 rods at 1/60 s). Redundant constraints get
the least-norm multipliers (relative ``1e-10`` on the diagonal); conflicting ones (no point
with ``C = 0``) make a stabilised step fail with ``kinema.SimulationError``, and without
stabilisation the multipliers satisfy them in the least-squares sense. The particle system's
colliders and emitters do not act during constrained steps.

Constraints: :class:`Distance` (rods), :class:`OnSphere` (a bead on a sphere or circle),
:class:`OnPlane`, :class:`Fixed`, :class:`OnCurve` (a bead on a wire: :class:`Line`,
:class:`Circle`, :class:`Helix` or a 3-channel :class:`kinema.anim.Track`) and :class:`Custom`
(value and gradient as Python callables, for teaching).

``formulation="penalty"`` replaces the multipliers by springs ``-stiffness C ∇C - damping Ċ ∇C``
on every constraint row (no solve; drift ∝ 1/stiffness, stable step ∝ 1/√stiffness).
:class:`ReducedBead` and :class:`ReducedPendulum` solve the same problems in reduced
coordinates (the curve parameter, the angles), where the constraints hold by construction.
See docs/constraints.md for the comparison of the three.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from kinema import _kinema
from kinema._array import as_vector3, real
from kinema.anim import Track
from kinema.particles import ParticleSystem

__all__ = [
    "Circle",
    "ConstrainedSystem",
    "Custom",
    "Distance",
    "Fixed",
    "Helix",
    "Line",
    "OnCurve",
    "OnPlane",
    "OnSphere",
    "ReducedBead",
    "ReducedPendulum",
]


@dataclass(frozen=True)
class Distance:
    """``|x_i - x_j| = length`` (m); ``length=None`` takes the current distance."""

    i: int
    j: int
    length: float | None = None


@dataclass(frozen=True)
class OnSphere:
    """``|x_i - center| = radius`` (m)."""

    i: int
    center: Any
    radius: float


@dataclass(frozen=True)
class OnPlane:
    """``normal · (x_i - point) = 0``."""

    i: int
    point: Any
    normal: Any


@dataclass(frozen=True)
class Fixed:
    """``x_i = point`` (m); ``point=None`` takes the current position."""

    i: int
    point: Any = None


@dataclass(frozen=True)
class Line:
    """The straight line ``x(u) = point + u d̂`` (m; ``u`` in metres along the unit
    direction, unbounded)."""

    point: Any
    direction: Any


@dataclass(frozen=True)
class Circle:
    """The circle ``x(u) = center + radius (cos u e₁ + sin u e₂)``, ``u`` the angle (rad)
    about ``normal`` from ``e₁``, the unit projection of +X on the plane (of +Y when ``normal``
    is along X), ``e₂ = n̂ × e₁``. With the default normal +Z, ``u`` runs from +X to +Y."""

    center: Any
    radius: float
    normal: Any = (0.0, 0.0, 1.0)


@dataclass(frozen=True)
class Helix:
    """The helix ``x(u) = center + radius (cos u e₁ + sin u e₂) + pitch u/(2π) â`` (m),
    ``u`` the angle (rad), ``e₁``, ``e₂`` as for :class:`Circle` about ``axis``; one turn rises
    ``pitch`` metres."""

    center: Any
    radius: float
    pitch: float
    axis: Any = (0.0, 1.0, 0.0)


Curve = Line | Circle | Helix | Track


def _curve_args(curve: object) -> tuple[str, list[float], Any]:
    """(kind, parameters, compiled track) of a curve for the compiled module."""
    if isinstance(curve, Line):
        return (
            "line",
            [*as_vector3(curve.point, "point"), *as_vector3(curve.direction, "direction")],
            None,
        )
    if isinstance(curve, Circle):
        return (
            "circle",
            [
                *as_vector3(curve.center, "center"),
                *as_vector3(curve.normal, "normal"),
                float(curve.radius),
            ],
            None,
        )
    if isinstance(curve, Helix):
        return (
            "helix",
            [
                *as_vector3(curve.center, "center"),
                *as_vector3(curve.axis, "axis"),
                float(curve.radius),
                float(curve.pitch),
            ],
            None,
        )
    if isinstance(curve, Track):
        return "track", [], curve._track
    raise ValueError(f"curve: expected Line, Circle, Helix or kinema.anim.Track, got {curve!r}")


@dataclass(frozen=True)
class OnCurve:
    """Particle ``i`` on a wire ``curve`` (:class:`Line`, :class:`Circle`, :class:`Helix`, or
    a 3-channel :class:`kinema.anim.Track` whose time is the parameter — use
    ``extrapolate="linear"`` or ``"cycle"`` so the wire does not stop at the last key).

    Two rows ``n_k · (x - x(u*))`` normal to the tangent, ``u*`` the closest-point parameter
    tracked from step to step (Newton); see docs/constraints.md."""

    i: int
    curve: Any


@dataclass(frozen=True)
class Custom:
    """A user constraint ``C(x) = 0`` on the particles ``indices`` (k distinct slots).

    ``value(x)`` gets their positions ``x`` ``(k, 3)`` (m) and returns ``C``: a float or ``m``
    values; ``gradient(x)`` returns ``∂C/∂x`` of shape ``(m, 3k)`` (columns ``x₀, y₀, z₀,
    x₁...``; ``(m, k, 3)`` or, for one row, ``(3k,)`` work too). ``J̇ q̇`` is taken by central
    differences of ``gradient`` along the velocity (two extra calls per evaluation, error
    ~1e-11 relative). Steps with a custom constraint hold the GIL; an exception raised by
    a callable propagates unchanged and leaves the particles at the last good step. The
    callables must not read or step the particle system themselves."""

    indices: Any
    value: Callable[[np.ndarray], Any]
    gradient: Callable[[np.ndarray], Any]


class ConstrainedSystem:
    """Constraints on ``particle_system``.

    ``formulation="multipliers"`` (default): Lagrange multipliers with feedback gains ``ks``
    (1/s²) and ``kd`` (1/s); ``solver`` is ``"cholesky"`` (sparse direct) or ``"cg"``
    (conjugate gradient); ``stabilize`` (``None``: on) ends every step with the
    position and velocity projections of Cline & Pai 2003 (up to 30 Gauss–Newton
    projections until ``max |C| ≤ 1e-10`` m, then ``J v = 0``; a step that cannot reach it
    fails and keeps the state), ``False`` leaves the drift to ``ks``, ``kd`` and the
    integrator (with ``method="projection"`` the positions always end on ``C = 0`` and
    ``False`` only skips the velocity projection). ``formulation="penalty"``: springs with ``stiffness`` (N/m, required) and
    ``damping`` (N s/m) on every constraint row instead; ``ks``, ``kd``, ``solver`` and
    ``stabilize`` do not apply and must be left at their defaults."""

    def __init__(
        self,
        particle_system: ParticleSystem,
        ks: float = 0.0,
        kd: float = 0.0,
        solver: str = "cholesky",
        *,
        formulation: str = "multipliers",
        stiffness: float | None = None,
        damping: float = 0.0,
        stabilize: bool | None = None,
    ) -> None:
        if not isinstance(particle_system, ParticleSystem):
            raise ValueError("particle_system: expected a kinema.particles.ParticleSystem")
        if stabilize is not None and not isinstance(stabilize, (bool, np.bool_)):
            raise ValueError(f"stabilize: expected True, False or None, got {stabilize!r}")
        if formulation == "penalty":
            if stiffness is None:
                raise ValueError("stiffness: required with formulation='penalty'")
            if ks != 0.0 or kd != 0.0 or solver != "cholesky":
                raise ValueError("ks: feedback gains and solver apply to formulation='multipliers'")
            if stabilize:
                raise ValueError(
                    "stabilize: post-stabilisation applies to formulation='multipliers'"
                )
        elif stiffness is not None or damping != 0.0:
            raise ValueError("stiffness: stiffness and damping apply to formulation='penalty'")
        self._particles = particle_system
        self._sys = _kinema.Constrained(
            particle_system._sys,
            real(ks, "ks"),
            real(kd, "kd"),
            solver,
            formulation,
            float(stiffness or 0.0),
            real(damping, "damping"),
            formulation != "penalty" if stabilize is None else bool(stabilize),
        )

    def add(self, constraint: Distance | OnSphere | OnPlane | Fixed | OnCurve | Custom) -> None:
        """Add a constraint (indices refer to the particle system's slots)."""
        x = self._particles.positions
        if isinstance(constraint, OnCurve):
            kind, params, track = _curve_args(constraint.curve)
            self._sys.add_on_curve(int(constraint.i), kind, params, track)
        elif isinstance(constraint, Custom):
            self._add_custom(constraint)
        elif isinstance(constraint, Distance):
            i, j = int(constraint.i), int(constraint.j)
            if constraint.length is None:
                if not (0 <= i < len(x) and 0 <= j < len(x)):
                    raise ValueError(f"i, j: particle indices must lie in [0, {len(x)})")
                length = float(np.linalg.norm(x[i] - x[j]))
            else:
                length = float(constraint.length)
            self._sys.add("distance", i, j, [length])
        elif isinstance(constraint, OnSphere):
            self._sys.add(
                "on_sphere",
                int(constraint.i),
                0,
                [*as_vector3(constraint.center, "center"), float(constraint.radius)],
            )
        elif isinstance(constraint, OnPlane):
            self._sys.add(
                "on_plane",
                int(constraint.i),
                0,
                [*as_vector3(constraint.point, "point"), *as_vector3(constraint.normal, "normal")],
            )
        elif isinstance(constraint, Fixed):
            i = int(constraint.i)
            if constraint.point is None and not 0 <= i < len(x):
                raise ValueError(f"i: particle index must lie in [0, {len(x)})")
            point = x[i] if constraint.point is None else constraint.point
            self._sys.add("fixed", i, 0, as_vector3(point, "point"))
        else:
            raise ValueError(
                "constraint: expected Distance, OnSphere, OnPlane, Fixed, OnCurve or Custom, "
                f"got {constraint!r}"
            )

    def _add_custom(self, constraint: Custom) -> None:
        idx = np.asarray(constraint.indices)
        if idx.ndim != 1 or len(idx) == 0 or not np.issubdtype(idx.dtype, np.integer):
            raise ValueError(f"indices: expected a non-empty list of integers, got {idx!r}")
        if not (callable(constraint.value) and callable(constraint.gradient)):
            raise ValueError("value: value and gradient must be callables")
        x = self._particles.positions
        if idx.min() < 0 or idx.max() >= len(x):
            raise ValueError(f"indices: particle indices must lie in [0, {len(x)})")
        rows = np.asarray(constraint.value(x[idx].copy()), dtype=np.float64).size
        if rows == 0:
            raise ValueError("value: returned no values")
        self._sys.add_custom(
            [int(i) for i in idx], constraint.value, constraint.gradient, int(rows)
        )

    def __len__(self) -> int:
        return len(self._sys)

    def step(self, dt: float, steps: int = 1, method: str = "rk4") -> None:
        """Advance ``steps`` steps of ``dt`` seconds (``method`` an ODE method or
        ``"projection"``, multipliers only); on failure ``kinema.SimulationError`` (or the
        exception a :class:`Custom` callable raised) and the last good state. The GIL is
        released unless a :class:`Custom` constraint needs Python."""
        self._sys.step(real(dt, "dt"), _steps(steps), method)

    def violation(self) -> tuple[float, float]:
        """``(max |C|, max |Ċ|)`` over all constraints (m, m/s)."""
        return self._sys.violation()

    def constraint_forces(self) -> np.ndarray:
        """Constraint forces per particle slot, ``(capacity, 3)`` (N): ``Jᵀ λ`` with
        multipliers, the spring forces with the penalty formulation."""
        return self._sys.constraint_forces()

    def curve_parameter(self, k: int) -> float | None:
        """The tracked parameter ``u`` of constraint ``k`` (in the order added) if it is an
        :class:`OnCurve`, else ``None``."""
        return self._sys.curve_parameter(int(k))

    @property
    def iterations(self) -> int:
        """Conjugate-gradient iterations of the last solve (0 with Cholesky)."""
        return self._sys.iterations()


def _steps(steps: object) -> int:
    if not isinstance(steps, (int, np.integer)) or steps < 0:
        raise ValueError(f"steps: expected a non-negative integer, got {steps!r}")
    return int(steps)


class ReducedBead:
    """A bead of ``mass`` (kg) on a wire ``curve`` (:class:`Line`, :class:`Circle`,
    :class:`Helix` or a 3-channel :class:`kinema.anim.Track`) in its one coordinate, the curve
    parameter ``u``, starting at ``u`` with rate ``u_dot`` (1/s) under ``gravity`` (m/s²).

    Lagrange's equation ``ü = (g·x' - (x'·x'') u̇²) / |x'|²`` (the second term is the
    centripetal part from the curve's second derivative), stepped by any ODE method. The bead
    is on the wire by construction (zero drift)."""

    def __init__(
        self,
        curve: Any,
        mass: float = 1.0,
        u: float = 0.0,
        u_dot: float = 0.0,
        gravity: Any = (0.0, -9.81, 0.0),
    ) -> None:
        kind, params, track = _curve_args(curve)
        self._sys = _kinema.ReducedBead(
            kind,
            params,
            track,
            real(mass, "mass"),
            as_vector3(gravity, "gravity"),
            real(u, "u"),
            real(u_dot, "u_dot"),
        )

    def step(self, dt: float, steps: int = 1, method: str = "rk4") -> None:
        """Advance ``steps`` steps of ``dt`` seconds with an ODE ``method`` (GIL released)."""
        self._sys.step(real(dt, "dt"), _steps(steps), method)

    @property
    def u(self) -> float:
        """Curve parameter."""
        return self._sys.state()[0]

    @property
    def u_dot(self) -> float:
        """Rate of the curve parameter (1/s)."""
        return self._sys.state()[1]

    @property
    def positions(self) -> np.ndarray:
        """Position ``x(u)`` as ``(1, 3)`` (m)."""
        return np.array([self._sys.position_velocity()[0]])

    @property
    def velocities(self) -> np.ndarray:
        """Velocity ``x'(u) u̇`` as ``(1, 3)`` (m/s)."""
        return np.array([self._sys.position_velocity()[1]])

    @property
    def time(self) -> float:
        """Simulated time (s)."""
        return self._sys.time

    def energy(self) -> float:
        """Kinetic plus gravitational potential energy ``½ m |v|² - m g·x`` (J)."""
        return self._sys.energy()


class ReducedPendulum:
    """A planar pendulum of one or two links in its angles: ``lengths`` (m), point ``masses``
    (kg) at the link ends, hung from ``pivot`` (m), ``angles`` (rad) from straight down,
    counter-clockwise about +Z, and ``rates`` (rad/s); gravity ``g`` (m/s²) along -Y.

    Closed-form Lagrangian equations (docs/constraints.md), stepped by any ODE method. The
    link lengths hold by construction (zero drift)."""

    def __init__(
        self,
        lengths: Any,
        masses: Any,
        angles: Any,
        rates: Any = None,
        pivot: Any = (0.0, 0.0, 0.0),
        g: float = 9.81,
    ) -> None:
        lengths_ = np.atleast_1d(np.asarray(lengths, dtype=np.float64))
        n = len(lengths_)
        try:
            masses_ = np.broadcast_to(np.asarray(masses, dtype=np.float64), (n,))
        except ValueError:
            raise ValueError(f"masses: expected a scalar or {n} values, got {masses!r}") from None
        angles_ = np.atleast_1d(np.asarray(angles, dtype=np.float64))
        rates_ = np.zeros(n) if rates is None else np.atleast_1d(np.asarray(rates, dtype=float))
        for name, arr in (("lengths", lengths_), ("angles", angles_), ("rates", rates_)):
            if arr.ndim != 1:
                raise ValueError(f"{name}: expected shape (links,), got {arr.shape}")
        self._sys = _kinema.ReducedPendulum(
            as_vector3(pivot, "pivot"),
            lengths_.tolist(),
            masses_.tolist(),
            angles_.tolist(),
            rates_.tolist(),
            real(g, "g"),
        )

    def step(self, dt: float, steps: int = 1, method: str = "rk4") -> None:
        """Advance ``steps`` steps of ``dt`` seconds with an ODE ``method`` (GIL released)."""
        self._sys.step(real(dt, "dt"), _steps(steps), method)

    @property
    def angles(self) -> np.ndarray:
        """Link angles ``(links,)`` (rad)."""
        return np.array(self._sys.state()[0])

    @property
    def rates(self) -> np.ndarray:
        """Angular rates ``(links,)`` (rad/s)."""
        return np.array(self._sys.state()[1])

    @property
    def positions(self) -> np.ndarray:
        """Positions of the link ends ``(links, 3)`` (m)."""
        return np.array([x for x, _ in self._sys.positions_velocities()])

    @property
    def velocities(self) -> np.ndarray:
        """Velocities of the link ends ``(links, 3)`` (m/s)."""
        return np.array([v for _, v in self._sys.positions_velocities()])

    @property
    def time(self) -> float:
        """Simulated time (s)."""
        return self._sys.time

    def energy(self) -> float:
        """Kinetic plus gravitational potential energy ``Σ ½ m |v|² + m g y`` (J)."""
        return self._sys.energy()
