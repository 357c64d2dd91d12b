"""Keyframing: tracks of keys for channels of any width, and subdivision curves.

``Track(times, values, interpolation=..., extrapolate=...)`` interpolates keys
``(t_i, value_i)``: scalars (``values`` of shape ``(N,)``) or vectors (``(N, D)``). Calling it
on a time or an array of times evaluates in Rust, in parallel for large arrays;
``track.derivative(n)`` gives the first or second time derivative. Schemes:

``"step"``, ``"linear"``, ``"polynomial"`` (Lagrange; warns for more than 10 keys: Runge
oscillation), ``"natural_cubic"``, ``"clamped_cubic"`` (end slopes 0 unless ``end_tangents``),
``"hermite"`` (``tangents``), ``"catmull_rom"``, ``"cardinal"`` (``tension``),
``"kochanek_bartels"`` (``tension``, ``continuity``, ``bias``), ``"bezier"`` (``handles`` of
shape ``(N-1, 2, D)``), ``"bspline"`` (uniform cubic, approximating). Extrapolation:
``"hold"``, ``"linear"``, ``"cycle"``.

``subdivide(points, scheme, iterations, closed)``: Chaikin, cubic B-spline and 4-point
subdivision.

``RotationTrack(times, rotations, interpolation="slerp" | "squad")`` interpolates
orientations on the shorter arcs and gives their angular velocity.

Not implemented yet: the C2 rotation spline, ``Clip``, easing and arc-length
reparameterisation (see docs/anim.md).
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from kinema import _kinema
from kinema.rotation import Rotation

__all__ = ["RotationTrack", "Track", "subdivide"]

INTERPOLATIONS = (
    "step",
    "linear",
    "polynomial",
    "natural_cubic",
    "clamped_cubic",
    "hermite",
    "catmull_rom",
    "cardinal",
    "kochanek_bartels",
    "bezier",
    "bspline",
)


def _float(value: Any, name: str) -> np.ndarray:
    try:
        return np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{name}: cannot convert to a float64 array ({e})") from None


class Track:
    """A keyframed channel: ``times`` ``(N,)`` strictly increasing (s), ``values`` ``(N,)`` or
    ``(N, D)``; see the module docs for ``interpolation`` and ``extrapolate``."""

    def __init__(
        self,
        times: Any,
        values: Any,
        interpolation: str = "catmull_rom",
        extrapolate: str = "hold",
        *,
        tangents: Any = None,
        end_tangents: Any = None,
        tension: float = 0.0,
        continuity: float = 0.0,
        bias: float = 0.0,
        handles: Any = None,
    ) -> None:
        t = _float(times, "times")
        if t.ndim != 1:
            raise ValueError(f"times: expected shape (N,), got {t.shape}")
        v = _float(values, "values")
        self._scalar = v.ndim == 1
        v2 = v.reshape(-1, 1) if self._scalar else v
        if v2.ndim != 2 or len(v2) != len(t):
            raise ValueError(f"values: expected shape ({len(t)},) or ({len(t)}, D), got {v.shape}")
        if interpolation not in INTERPOLATIONS:
            raise ValueError(
                f"interpolation: {interpolation!r} is not one of {', '.join(INTERPOLATIONS)}"
            )
        if interpolation == "polynomial" and len(t) > 10:
            warnings.warn(
                f"polynomial interpolation through {len(t)} keys oscillates between them (Runge's phenomenon)",
                RuntimeWarning,
                stacklevel=2,
            )
        dim = v2.shape[1]
        extra = None
        if interpolation == "hermite":
            if tangents is None:
                raise ValueError("tangents: required for hermite interpolation")
            extra = _float(tangents, "tangents").reshape(len(t), dim)
        elif interpolation == "clamped_cubic" and end_tangents is not None:
            extra = _float(end_tangents, "end_tangents").reshape(2, dim)
        elif interpolation == "bezier":
            if handles is None:
                raise ValueError("handles: required for bezier interpolation")
            extra = _float(handles, "handles").reshape(2 * (len(t) - 1), dim)
        params = [float(tension), float(continuity), float(bias)]
        self._track = _kinema.KeyTrack(
            np.ascontiguousarray(t.reshape(-1, 1)),
            np.ascontiguousarray(v2),
            interpolation,
            extrapolate,
            params,
            None if extra is None else np.ascontiguousarray(extra),
        )
        self._order = 0

    def __call__(self, t: Any) -> Any:
        """Evaluate at time ``t`` (scalar or array); shape ``t.shape`` for scalar channels,
        ``t.shape + (D,)`` for vector channels."""
        tt = _float(t, "t")
        out = self._track.eval(np.ascontiguousarray(tt.reshape(-1, 1)), self._order)
        shaped = out.reshape(*tt.shape, -1)
        if self._scalar:
            shaped = shaped[..., 0]
        return float(shaped) if tt.ndim == 0 and self._scalar else shaped

    def derivative(self, n: int = 1) -> Track:
        """The ``n``-th time derivative (n = 1 or 2) as a callable track."""
        if n not in (1, 2) or self._order + n > 2:
            raise ValueError(f"n: derivatives up to order 2 are available, got {self._order + n}")
        d = object.__new__(Track)
        d._track, d._scalar, d._order = self._track, self._scalar, self._order + n
        return d


def subdivide(
    points: Any, scheme: str = "chaikin", iterations: int = 1, closed: bool = False
) -> np.ndarray:
    """Refine the polygon ``points`` ``(N, D)`` ``iterations`` times with ``"chaikin"``
    (limit: quadratic B-spline), ``"bspline"`` (limit: cubic B-spline) or ``"four_point"``
    (interpolating); ``closed`` treats the polygon as a loop."""
    p = _float(points, "points")
    if p.ndim != 2:
        raise ValueError(f"points: expected shape (N, D), got {p.shape}")
    if not isinstance(iterations, (int, np.integer)) or iterations < 0:
        raise ValueError(f"iterations: expected a non-negative integer, got {iterations!r}")
    return _kinema.anim_subdivide(np.ascontiguousarray(p), scheme, int(iterations), bool(closed))


class RotationTrack:
    """Keyframed orientations: ``rotations`` (a stack of N :class:`kinema.Rotation`) at
    strictly increasing ``times`` ``(N,)``; ``interpolation`` is ``"slerp"`` (constant angular
    velocity per segment) or ``"squad"`` (Shoemake's spherical quadrangles, C1 for equally
    spaced keys). Keys are held outside the time range."""

    def __init__(self, times: Any, rotations: Rotation, interpolation: str = "slerp") -> None:
        t = _float(times, "times")
        if t.ndim != 1:
            raise ValueError(f"times: expected shape (N,), got {t.shape}")
        if not isinstance(rotations, Rotation) or rotations.single:
            raise ValueError("rotations: expected a stack of kinema.Rotation")
        q = rotations.as_quat()
        self._track = _kinema.KeyRotationTrack(
            np.ascontiguousarray(t.reshape(-1, 1)), q, interpolation
        )

    def __call__(self, t: Any) -> Rotation:
        """The orientation(s) at time ``t`` (a single Rotation for a scalar ``t``)."""
        tt = _float(t, "t")
        q = self._track.eval(np.ascontiguousarray(tt.reshape(-1, 1)))
        return Rotation.from_quat(q[0] if tt.ndim == 0 else q)

    def angular_velocity(self, t: Any) -> np.ndarray:
        """Angular velocity (rad/s, world frame), ``(3,)`` or ``t.shape + (3,)``."""
        tt = _float(t, "t")
        w = self._track.angular_velocity(np.ascontiguousarray(tt.reshape(-1, 1)))
        return w[0] if tt.ndim == 0 else w.reshape(*tt.shape, 3)
