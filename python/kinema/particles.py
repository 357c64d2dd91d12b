"""Particle systems: forces, colliders and emitters on a fixed-capacity struct of arrays.

Build a :class:`ParticleSystem`, ``add`` what the scene needs (nothing else is computed) and
``step`` it with any fixed-step method of :mod:`kinema.ode` (default ``symplectic_euler``).
``positions`` and ``velocities`` are read-only numpy views of the Rust state, updated in place
by every step (no copy); write through :meth:`ParticleSystem.set_state`.

Forces: :class:`Gravity`, :class:`Drag` (linear and quadratic ``½ρC_dA|u|u``, with wind),
:class:`Damping`, :class:`Springs` (Hooke + dampers), :class:`Attractor` (softened inverse
square; negative strength repels), :class:`Vortex`, :class:`Turbulence` (curl noise, Bridson
et al. 2007), :class:`NeighborRepulsion` (spatial hash grid, never all pairs),
:class:`NBodyGravity` (all pairs). Colliders: :class:`Plane`, :class:`Box`, :class:`Capsule`, :class:`Sphere` (inside or
outside) with restitution and Coulomb friction, resting contact without jitter: the shapes
of :mod:`kinema.geometry`, re-exported here.
:class:`Emitter` recycles dead slots. :class:`Field` adds any Python callable on the batch of
particles, evaluated once per step (held constant within the step).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from kinema import _kinema
from kinema._array import as_batch, as_scalars, as_vector3, real
from kinema.geometry import Box, Capsule, Plane, Shape, Sphere, shape_params

__all__ = [
    "Attractor",
    "Box",
    "Capsule",
    "Damping",
    "Drag",
    "Emitter",
    "Field",
    "Gravity",
    "NBodyGravity",
    "NeighborRepulsion",
    "ParticleSystem",
    "Plane",
    "Sphere",
    "Springs",
    "Turbulence",
    "Vortex",
]


@dataclass(frozen=True)
class Gravity:
    """Uniform gravity ``f = m g`` (m/s²); default ``(0, -9.81, 0)``."""

    g: Any = (0.0, -9.81, 0.0)


@dataclass(frozen=True)
class Drag:
    """Air drag ``f = -linear u - quadratic |u| u`` with ``u = v - wind``.

    ``quadratic = ½ ρ C_d A`` (kg/m), ``linear`` in kg/s, ``wind`` in m/s.
    """

    quadratic: float = 0.0
    linear: float = 0.0
    wind: Any = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Damping:
    """Velocity damping ``f = -rate m v`` (rate in 1/s)."""

    rate: float


@dataclass(frozen=True)
class Springs:
    """Damped springs between particle ``pairs`` ``(M, 2)``.

    ``f_i = -[k (|d| - L) + c (v_i - v_j)·d̂] d̂``; ``rest`` lengths ``(M,)`` default to the
    current distances.
    """

    pairs: Any
    stiffness: float
    damping: float = 0.0
    rest: Any = None


@dataclass(frozen=True)
class Attractor:
    """``f = strength m (c - x) / (|c - x|² + softening²)^{3/2}``; negative strength repels."""

    center: Any
    strength: float
    softening: float = 0.1


@dataclass(frozen=True)
class Vortex:
    """Swirl about ``axis`` through ``center``: ``f = strength m (â × r⊥) / (|r⊥| + core)``."""

    center: Any
    strength: float
    axis: Any = (0.0, 1.0, 0.0)
    core: float = 0.1


@dataclass(frozen=True)
class Turbulence:
    """Divergence-free curl-noise force ``strength m curl ψ(x / scale)``."""

    strength: float
    scale: float = 1.0
    seed: int = 0


@dataclass(frozen=True)
class NeighborRepulsion:
    """Soft repulsion ``k (r - d) d̂`` between particles closer than ``radius`` (hash grid)."""

    radius: float
    stiffness: float


@dataclass(frozen=True)
class NBodyGravity:
    """Newtonian gravity between every pair of free particles, softened (O(N²))."""

    constant: float = 6.674e-11
    softening: float = 0.0


@dataclass(frozen=True)
class Field:
    """A force field given as a Python callable ``force(t, positions, velocities) -> (N, 3)``
    on all slots at once (N; dead slots may get anything, they do not move). Evaluated once per
    step and held constant within the step, so a stiff field needs small steps."""

    force: Any


@dataclass(frozen=True)
class Emitter:
    """Emits ``rate`` particles/s from a ball of ``position_spread`` around ``position`` with
    velocities ``velocity`` ± a ball of ``velocity_spread``; they live ``lifespan`` seconds
    (forever when infinite).

    Each particle also gets the rendering properties of Reeves 1983 ("Particle systems"): a
    ``color`` (linear RGB or RGBA in [0, 1], alpha 1 when omitted) with each of R, G, B drawn
    uniformly within ± ``color_spread`` (clamped to [0, 1]; alpha kept), and a ``size``
    (diameter, m) drawn uniformly within ± ``size_spread`` (``0 <= size_spread < size``).
    The spreads draw from the emitter's ``seed`` after the position and velocity, and only when
    not zero. Read them as :attr:`ParticleSystem.colors` and :attr:`ParticleSystem.sizes`."""

    rate: float
    position: Any = (0.0, 0.0, 0.0)
    velocity: Any = (0.0, 0.0, 0.0)
    position_spread: float = 0.0
    velocity_spread: float = 0.0
    lifespan: float = math.inf
    mass: float = 1.0
    seed: int = 0
    color: Any = (1.0, 1.0, 1.0, 1.0)
    color_spread: float = 0.0
    size: float = 0.01
    size_spread: float = 0.0


def _rgba(color: Any, name: str) -> list[float]:
    """One colour as four floats: RGB gets alpha 1."""
    try:
        c = np.asarray(color, dtype=np.float64).ravel()
    except (TypeError, ValueError) as e:
        raise ValueError(f"{name}: cannot convert to float64 numbers ({e})") from None
    if c.shape not in ((3,), (4,)):
        raise ValueError(f"{name}: expected RGB or RGBA (3 or 4 numbers), got shape {c.shape}")
    return [*c.tolist(), 1.0] if len(c) == 3 else c.tolist()


def _collider(c: Shape) -> tuple[str, list[float]]:
    """The compiled collider's kind and parameters: the shape's, then restitution, friction,
    velocity and inside."""
    kind, p = shape_params(c)
    return kind, [
        *p,
        0.5 if c.restitution is None else float(c.restitution),
        0.0 if c.friction is None else float(c.friction),
        *as_vector3(c.velocity, "velocity"),
        float(isinstance(c, Sphere) and bool(c.inside)),
    ]


class ParticleSystem:
    """Particles with positions ``(N, 3)`` (m), velocities ``(N, 3)`` (m/s, default 0) and
    masses (kg; a scalar or ``(N,)``; ``inf`` pins a particle), with room for ``capacity``
    particles in all (default N; emitters fill dead slots).

    ``colors`` (one RGB(A) colour or ``(N, 3)`` / ``(N, 4)``, linear, in [0, 1]) and ``sizes``
    (diameters in m: a scalar or ``(N,)``) give the N particles their rendering properties;
    by default opaque white and 1 cm, as for the empty slots. Emitted particles take theirs
    from their :class:`Emitter`."""

    def __init__(
        self,
        positions: Any,
        velocities: Any = None,
        masses: Any = 1.0,
        capacity: int | None = None,
        colors: Any = None,
        sizes: Any = None,
    ) -> None:
        x, _ = as_batch(positions, "positions", (3,))
        v, _ = as_batch(np.zeros_like(x) if velocities is None else velocities, "velocities", (3,))
        m, single = as_scalars(masses, "masses")
        if single:
            m = np.full((len(x), 1), m[0, 0])
        cap = len(x) if capacity is None else capacity
        self._sys = _kinema.Particles(x, v, m, cap)
        if colors is not None or sizes is not None:
            c = np.ones((cap, 4))
            s = np.full((cap, 1), 0.01)
            if colors is not None:
                rows = np.asarray(colors, dtype=np.float64)
                rows = rows.reshape(1, -1) if rows.ndim == 1 else rows
                if rows.ndim != 2 or rows.shape[1] not in (3, 4) or len(rows) not in (1, len(x)):
                    raise ValueError(
                        f"colors: expected one RGB(A) colour or ({len(x)}, 3|4), "
                        f"got shape {np.shape(colors)}"
                    )
                c[: len(x), : rows.shape[1]] = rows
            if sizes is not None:
                sz, _ = as_scalars(sizes, "sizes")
                if len(sz) not in (1, len(x)):
                    raise ValueError(f"sizes: expected a scalar or ({len(x)},), got {len(sz)}")
                s[: len(x)] = sz
            self._sys.set_appearance(c, s)
        self._fields: list[Field] = []
        self._colliders = 0
        self._stiffest = 0.0  # largest k (1/m_i + 1/m_j) of any spring, 1/s²

    def add(self, item: Any) -> None:
        """Add a force, a collider or an emitter (colliders are numbered in the order added,
        for :meth:`set_collider`)."""
        s = self._sys
        if isinstance(item, Gravity):
            s.add_force("gravity", as_vector3(item.g, "g"))
        elif isinstance(item, Drag):
            s.add_force(
                "drag", [float(item.linear), float(item.quadratic), *as_vector3(item.wind, "wind")]
            )
        elif isinstance(item, Damping):
            s.add_force("damping", [float(item.rate)])
        elif isinstance(item, Springs):
            pairs, _ = as_batch(item.pairs, "pairs", (2,))
            if item.rest is None:
                x = np.asarray(self.positions)
                idx = pairs.astype(np.int64)
                if (idx < 0).any() or (idx >= len(x)).any():
                    raise ValueError(f"pairs: indices must lie in [0, {len(x)})")
                rest = np.linalg.norm(x[idx[:, 0]] - x[idx[:, 1]], axis=1)
            else:
                rest = np.asarray(item.rest, dtype=np.float64).ravel()
            inv_m = 1.0 / self.masses
            idx = pairs.astype(np.int64)
            if len(idx) and (idx >= 0).all() and (idx < len(inv_m)).all():
                reduced = inv_m[idx[:, 0]] + inv_m[idx[:, 1]]
                self._stiffest = max(self._stiffest, float(item.stiffness) * float(reduced.max()))
            s.add_force(
                "springs",
                [float(item.stiffness), float(item.damping)],
                pairs,
                np.ascontiguousarray(rest.reshape(-1, 1)),
            )
        elif isinstance(item, Attractor):
            s.add_force(
                "attractor",
                [*as_vector3(item.center, "center"), float(item.strength), float(item.softening)],
            )
        elif isinstance(item, Vortex):
            s.add_force(
                "vortex",
                [
                    *as_vector3(item.center, "center"),
                    *as_vector3(item.axis, "axis"),
                    float(item.strength),
                    float(item.core),
                ],
            )
        elif isinstance(item, Turbulence):
            s.add_force("turbulence", [float(item.strength), float(item.scale)], seed=item.seed)
        elif isinstance(item, NeighborRepulsion):
            s.add_force("neighbor_repulsion", [float(item.radius), float(item.stiffness)])
        elif isinstance(item, NBodyGravity):
            s.add_force("nbody_gravity", [float(item.constant), float(item.softening)])
        elif isinstance(item, Field):
            if not callable(item.force):
                raise ValueError("force: expected a callable force(t, positions, velocities)")
            self._fields.append(item)
        elif isinstance(item, (Plane, Sphere, Capsule, Box)):
            s.add_collider(*_collider(item))
            self._colliders += 1
        elif isinstance(item, Emitter):
            s.add_emitter(
                [
                    float(item.rate),
                    *as_vector3(item.position, "position"),
                    float(item.position_spread),
                    *as_vector3(item.velocity, "velocity"),
                    float(item.velocity_spread),
                    float(item.lifespan),
                    float(item.mass),
                    *_rgba(item.color, "color"),
                    float(item.color_spread),
                    float(item.size),
                    float(item.size_spread),
                ],
                item.seed,
            )
        else:
            raise ValueError(
                f"item: expected a force, collider or emitter of kinema.particles, got {item!r}"
            )

    def set_collider(self, index: int, collider: Plane | Sphere | Capsule | Box) -> None:
        """Replace collider ``index`` (move it between steps)."""
        self._sys.set_collider(index, *_collider(collider))

    @property
    def stiffest_spring(self) -> float:
        """``max k (1/m_i + 1/m_j)`` (1/s²) over the springs added, the square of the fastest
        spring's angular frequency (0 without springs); ``kinema.Scene`` checks explicit steps
        against it."""
        return self._stiffest

    def step(
        self,
        dt: float,
        steps: int = 1,
        method: str = "symplectic_euler",
        sparse_jacobian: bool = True,
    ) -> None:
        """Advance ``steps`` steps of ``dt`` seconds; on divergence raise
        ``kinema.SimulationError`` (step and particle named) and keep the last good state.

        The implicit methods (``implicit_euler``, ``trapezoidal``, ``bdf2``) solve each step by
        Newton iterations with the analytic sparse Jacobian of the forces and a sparse LU, whose
        cost grows about linearly with the particles; ``sparse_jacobian=False`` uses a dense
        Jacobian by finite differences and a dense LU instead (cost ``O(capacity³)``, for
        comparison). ``NBodyGravity`` couples every pair, so with it the solve is dense."""
        # `type(...) is` first: the usual arguments skip the slower isinstance checks, which
        # cost more than a step of a small system.
        if not (type(steps) is int or isinstance(steps, (int, np.integer))) or steps < 0:
            raise ValueError(f"steps: expected a non-negative integer, got {steps!r}")
        if not (type(sparse_jacobian) is bool or isinstance(sparse_jacobian, np.bool_)):
            raise ValueError(f"sparse_jacobian: expected a bool, got {sparse_jacobian!r}")
        if not self._fields:
            self._sys.step(real(dt, "dt"), int(steps), method, bool(sparse_jacobian))
            return
        sparse = bool(sparse_jacobian)
        for _ in range(int(steps)):
            x, v = self.positions, self.velocities
            total = np.zeros_like(x)
            for source in self._fields:
                f = np.asarray(source.force(self.time, x, v), dtype=np.float64)
                if f.shape != x.shape:
                    raise ValueError(
                        f"force: the field returned shape {f.shape}, expected {x.shape}"
                    )
                total += f
            self._sys.set_external_forces(np.ascontiguousarray(total))
            self._sys.step(real(dt, "dt"), 1, method, sparse)

    @property
    def positions(self) -> np.ndarray:
        """Read-only view ``(capacity, 3)`` of the positions (m)."""
        return self._sys.positions

    @property
    def velocities(self) -> np.ndarray:
        """Read-only view ``(capacity, 3)`` of the velocities (m/s)."""
        return self._sys.velocities

    @property
    def alive(self) -> np.ndarray:
        """Which slots hold live particles, bool ``(capacity,)``."""
        return self._sys.alive()[:, 0] != 0.0

    @property
    def ages(self) -> np.ndarray:
        """Age of each slot (s), ``(capacity,)``."""
        return self._sys.ages()[:, 0]

    @property
    def masses(self) -> np.ndarray:
        """Mass of each slot (kg, inf when pinned), ``(capacity,)``."""
        return self._sys.masses()[:, 0]

    @property
    def colors(self) -> np.ndarray:
        """Read-only view ``(capacity, 4)`` of the colours (linear RGBA in [0, 1]), set by the
        constructor or by the emitter of each particle; slots are never reordered, so a
        particle keeps its row while others die."""
        return self._sys.colors

    @property
    def sizes(self) -> np.ndarray:
        """Read-only view ``(capacity,)`` of the sizes (diameters, m)."""
        return self._sys.sizes

    @property
    def time(self) -> float:
        """Simulated time (s)."""
        return self._sys.time

    @property
    def stats(self) -> dict[str, int]:
        """Counters of the last ``step`` call: emitted, dropped, expired, contacts, and
        factorizations (numeric LU factorisations of the implicit methods' Newton matrix: kept
        while it is bitwise unchanged, so a linear chain at a constant ``dt`` makes one)."""
        return self._sys.stats()

    def set_state(self, positions: Any, velocities: Any) -> None:
        """Overwrite all positions and velocities ``(capacity, 3)``."""
        x, _ = as_batch(positions, "positions", (3,))
        v, _ = as_batch(velocities, "velocities", (3,))
        self._sys.set_state(x, v)

    def kinetic_energy(self) -> float:
        """Kinetic energy of the live, unpinned particles (J)."""
        return self._sys.kinetic_energy()

    def potential_energy(self) -> float:
        """Potential energy of gravity, springs, attractors and n-body gravity (J)."""
        return self._sys.potential_energy()
