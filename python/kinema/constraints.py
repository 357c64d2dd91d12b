"""Constrained particle dynamics with Lagrange multipliers (Witkin's formulation).

``ConstrainedSystem(particle_system, ks, kd)`` holds constraints on the particles of a
:class:`kinema.particles.ParticleSystem`. Each step solves

``J W Jᵀ λ = -J̇ q̇ - J W Q - ks C - kd Ċ``

for the multipliers (sparse, by faer's Cholesky or by conjugate gradient) and adds the
constraint force ``Jᵀ λ``, which does no work; ``ks``/``kd`` feed the drift back (``0, 0`` turns
feedback off). ``method`` is any ODE method of :mod:`kinema.ode`, or ``"projection"``: velocity-
level impulses with position post-stabilisation (Cline & Pai 2003), first order but stable at
large steps (ropes at 1/60 s). Redundant or conflicting constraints get a regularised
least-norm answer (relative ``1e-10`` on the diagonal). The particle system's colliders and
emitters do not act during constrained steps.

Constraints: :class:`Distance` (rods), :class:`OnSphere` (a bead on a sphere or circle),
:class:`OnPlane`, :class:`Fixed`. Not implemented yet: ``OnCurve``, ``Custom`` (Python
callables), the penalty formulation and reduced coordinates (see docs/constraints.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from kinema import _kinema
from kinema._array import as_vector3
from kinema.particles import ParticleSystem

__all__ = ["ConstrainedSystem", "Distance", "Fixed", "OnPlane", "OnSphere"]


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


class ConstrainedSystem:
    """Constraints on ``particle_system`` with feedback gains ``ks`` (1/s²) and ``kd`` (1/s);
    ``solver`` is ``"cholesky"`` (sparse direct) or ``"cg"`` (conjugate gradient)."""

    def __init__(
        self,
        particle_system: ParticleSystem,
        ks: float = 0.0,
        kd: float = 0.0,
        solver: str = "cholesky",
    ) -> None:
        if not isinstance(particle_system, ParticleSystem):
            raise ValueError("particle_system: expected a kinema.particles.ParticleSystem")
        self._particles = particle_system
        self._sys = _kinema.Constrained(particle_system._sys, float(ks), float(kd), solver)

    def add(self, constraint: Distance | OnSphere | OnPlane | Fixed) -> None:
        """Add a constraint (indices refer to the particle system's slots)."""
        x = self._particles.positions
        if isinstance(constraint, Distance):
            i, j = int(constraint.i), int(constraint.j)
            if constraint.length is None:
                if not (0 <= i < len(x) and 0 <= j < len(x)):
                    raise ValueError(f"i: particle indices must lie in [0, {len(x)})")
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
                f"constraint: expected Distance, OnSphere, OnPlane or Fixed, got {constraint!r}"
            )

    def __len__(self) -> int:
        return len(self._sys)

    def step(self, dt: float, steps: int = 1, method: str = "rk4") -> None:
        """Advance ``steps`` steps of ``dt`` seconds (``method`` an ODE method or
        ``"projection"``); on failure ``kinema.SimulationError`` and the last good state."""
        if not isinstance(steps, (int, np.integer)) or steps < 0:
            raise ValueError(f"steps: expected a non-negative integer, got {steps!r}")
        self._sys.step(float(dt), int(steps), method)

    def violation(self) -> tuple[float, float]:
        """``(max |C|, max |Ċ|)`` over all constraints (m, m/s)."""
        return self._sys.violation()

    def constraint_forces(self) -> np.ndarray:
        """Constraint forces ``Jᵀ λ`` per particle slot, ``(capacity, 3)`` (N)."""
        return self._sys.constraint_forces()

    @property
    def iterations(self) -> int:
        """Conjugate-gradient iterations of the last solve (0 with Cholesky)."""
        return self._sys.iterations()
