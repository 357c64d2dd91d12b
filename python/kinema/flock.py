"""Flocks of boids: Reynolds' (1987, "Flocks, herds, and schools") separation, alignment
and cohesion, with a neighbour radius and a field of view, as steering forces bounded by a
maximum force and speed (Reynolds 1999, "Steering behaviors for autonomous characters"), in
2-D or 3-D, computed in Rust on a uniform grid, in parallel and bitwise the same on any
number of threads; Reynolds' (1999) steering behaviours (seek, flee, arrive, pursue, evade,
wander, obstacle avoidance) add as weighted forces (:meth:`Flock.add_behaviour`). See
docs/crowd.md.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from kinema import _kinema
from kinema._array import real
from kinema.geometry import shape_params

__all__ = ["Flock"]


def _rows(value: object, name: str, dim: int | None) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: cannot convert to a float64 array") from None
    if arr.ndim != 2 or arr.shape[1] not in (2, 3) or (dim is not None and arr.shape[1] != dim):
        want = f"(N, {dim})" if dim is not None else "(N, 2) or (N, 3)"
        raise ValueError(f"{name}: expected shape {want}, got {arr.shape}")
    out = np.zeros((arr.shape[0], 3))
    out[:, : arr.shape[1]] = arr
    return out


class Flock:
    """Boids at ``positions`` ``(N, 2)`` or ``(N, 3)`` (m) flying at ``velocities`` (m/s,
    the same shape; a 2-D flock stays in its plane).

    Each boid sees the others closer than ``neighbour_radius`` (m) within its
    ``field_of_view`` (full angle in rad about its velocity, up to ``2 pi``) and steers by
    ``separation`` (away from those closer than ``separation_distance`` m, weighted by the
    inverse distance), ``alignment`` (towards their mean velocity) and ``cohesion`` (towards
    their centre): each rule asks for its direction at ``max_speed`` (m/s), its steering is
    that minus the velocity, and the weighted sum is at most ``max_force`` (m/s²).
    """

    def __init__(
        self,
        positions: Any,
        velocities: Any,
        *,
        separation: float = 1.5,
        alignment: float = 1.0,
        cohesion: float = 1.0,
        neighbour_radius: float = 2.0,
        separation_distance: float = 1.0,
        field_of_view: float = 1.5 * np.pi,
        max_speed: float = 2.0,
        max_force: float = 1.0,
    ) -> None:
        p = _rows(positions, "positions", None)
        self._dim = np.asarray(positions).shape[1]
        v = _rows(velocities, "velocities", self._dim)
        if v.shape[0] != p.shape[0]:
            raise ValueError("velocities: expected one velocity per position")
        self._f = _kinema.Flock(
            p,
            v,
            real(separation, "separation"),
            real(alignment, "alignment"),
            real(cohesion, "cohesion"),
            real(neighbour_radius, "neighbour_radius"),
            real(separation_distance, "separation_distance"),
            real(field_of_view, "field_of_view"),
            real(max_speed, "max_speed"),
            real(max_force, "max_force"),
        )

    def step(self, dt: float, steps: int = 1) -> None:
        """Advance ``steps`` steps of ``dt`` seconds."""
        self._f.step(real(dt, "dt"), steps)

    def __len__(self) -> int:
        return len(self._f)

    @property
    def dimension(self) -> int:
        """2 or 3, as the positions given."""
        return self._dim

    @property
    def positions(self) -> np.ndarray:
        """Read-only view ``(N, dimension)`` of the positions (m), updated in place."""
        return self._f.positions[:, : self._dim]

    @property
    def velocities(self) -> np.ndarray:
        """Read-only view ``(N, dimension)`` of the velocities (m/s), updated in place."""
        return self._f.velocities[:, : self._dim]

    @property
    def time(self) -> float:
        """Simulated time (s)."""
        return self._f.time

    def polarisation(self) -> float:
        """The polarisation order parameter ``|sum v_i / |v_i|| / N`` (Vicsek et al. 1995):
        1 when all fly one way, about ``1 / sqrt(N)`` for random headings."""
        return self._f.polarisation()

    def cohesion(self, radius: float | None = None) -> float:
        """The fraction of the boids in the largest cluster, boids linked when closer than
        ``radius`` (m; default the neighbour radius) and clusters the connected sets of links
        (Grégoire & Chaté 2004): 1 for one flock, about ``1 / N`` for scattered boids."""
        return self._f.cohesion(None if radius is None else real(radius, "radius"))

    def add_behaviour(
        self,
        kind: str,
        *,
        target: Any = None,
        boid: int = 0,
        slow_radius: float = 1.0,
        distance: float = 2.0,
        radius: float = 1.0,
        seed: int = 0,
        shape: Any = None,
        path: Any = None,
        horizon: float = 1.0,
        clearance: float = 0.0,
        weight: float = 1.0,
        boids: tuple[int, int] | None = None,
    ) -> None:
        """Add a steering behaviour of Reynolds (1999), weighted by ``weight`` and acting on
        the boids ``boids = (first, end)`` (all if ``None``), on top of the flocking rules:

        - ``"seek"`` / ``"flee"``: towards / away from ``target`` (m) at the maximum speed;
        - ``"arrive"``: towards ``target``, slowing linearly within ``slow_radius`` (m) to
          stop on it;
        - ``"pursue"`` / ``"evade"``: seek / flee where boid ``boid`` will be, predicted
          straight on for its distance over the maximum speed;
        - ``"wander"``: seek a point ``radius`` (m) from the point ``distance`` (m) ahead, in a
          direction drawn each step from ``seed`` (deterministic; in-plane for a 2-D flock);
        - ``"avoid"``: steer sideways from ``shape`` (a :mod:`kinema.geometry` shape) when the
          straight path within ``horizon`` (s) comes closer than ``clearance`` (m), straight
          out when already closer;
        - ``"follow"``: follow the polyline ``path`` ``(M, 2)`` / ``(M, 3)`` (m, as the
          flock's positions), ``radius`` (m) its half-width: the position predicted
          ``horizon`` (s) ahead is projected onto the path; within ``radius`` and moving
          forwards, no correction, else seek the path's point ``radius`` farther along.

        Each gives a desired velocity; its steering is that minus the velocity, at most
        ``max_force``; the weighted sum with the flocking rules is at most ``max_force``."""
        if not isinstance(kind, str):
            raise TypeError("kind: expected a behaviour name")
        values: list[float] = []
        shape_kind = ""
        if kind in ("seek", "flee", "arrive"):
            if target is None:
                raise ValueError(f"target: {kind} needs a target")
            values = _rows([target], "target", self._dim)[0].tolist()
            if kind == "arrive":
                values.append(real(slow_radius, "slow_radius"))
        elif kind == "wander":
            values = [real(distance, "distance"), real(radius, "radius")]
        elif kind == "avoid":
            if shape is None:
                raise ValueError("shape: avoid needs a shape")
            shape_kind, params = shape_params(shape)
            values = [*params, real(horizon, "horizon"), real(clearance, "clearance")]
        elif kind == "follow":
            if path is None:
                raise ValueError("path: follow needs a path")
            points = _rows(path, "path", self._dim).ravel().tolist()
            values = [*points, real(radius, "radius"), real(horizon, "horizon")]
        first, end = (0, len(self)) if boids is None else boids
        self._f.add_steering(
            kind,
            real(weight, "weight"),
            first,
            end,
            values,
            boid,
            seed,
            self._dim == 2,
            shape_kind,
        )
