"""Flocks of boids: Reynolds' (1987, "Flocks, herds, and schools") separation, alignment
and cohesion, with a neighbour radius and a field of view, as steering forces bounded by a
maximum force and speed (Reynolds 1999, "Steering behaviors for autonomous characters"), in
2-D or 3-D, computed in Rust on a uniform grid, in parallel and bitwise the same on any
number of threads. See docs/crowd.md.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from kinema import _kinema
from kinema._array import real

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
