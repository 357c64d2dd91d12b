"""Keyframing: tracks of keys for channels of any width, and subdivision curves.

``Track(times, values, interpolation=..., extrapolate=...)`` interpolates keys
``(t_i, value_i)``: scalars (``values`` of shape ``(N,)``) or vectors (``(N, D)``). Calling it
on a time or an array of times evaluates in Rust, in parallel for large arrays;
``track.derivative(n)`` gives the first or second time derivative. Schemes:

``"step"``, ``"linear"``, ``"polynomial"`` (Lagrange; warns for more than 10 keys: Runge
oscillation), ``"natural_cubic"``, ``"clamped_cubic"`` (end slopes 0 unless ``end_tangents``),
``"hermite"`` (``tangents``), ``"catmull_rom"``, ``"cardinal"`` (``tension``),
``"kochanek_bartels"`` (``tension``, ``continuity``, ``bias``), ``"bezier"`` (``handles`` of
shape ``(N-1, 2, D)``), ``"bspline"`` (uniform cubic, approximating). Per-key modes:
``interpolation`` may be a list with one scheme per key (the last key's entry is unused) or
per segment; each segment then follows the scheme of the key it leaves (C0 where the scheme
changes). Extrapolation: ``"hold"``, ``"linear"``, ``"cycle"``.

``subdivide(points, scheme, iterations, closed)``: Chaikin, cubic B-spline and 4-point
subdivision.

``RotationTrack(times, rotations, interpolation="slerp" | "squad" | "spline")`` interpolates
orientations (on the shorter arcs unless ``shortest`` says otherwise per segment) and gives
their angular velocity and acceleration; ``"spline"`` is C2 (continuous angular
acceleration), as scipy's ``RotationSpline``.

``reparameterize_by_arc_length(track)`` gives the curve at constant speed, ``ease`` the timing
curves, ``Clip`` samples named channels together at a frame rate.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from kinema import _kinema
from kinema._array import real
from kinema.rotation import Rotation

__all__ = [
    "ArcLengthCurve",
    "Clip",
    "RotationTrack",
    "Track",
    "ease",
    "reparameterize_by_arc_length",
    "subdivide",
]

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


def _number(value: Any, name: str) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a number") from None


class Track:
    """A keyframed channel: ``times`` ``(N,)`` strictly increasing (s), ``values`` ``(N,)`` or
    ``(N, D)``; see the module docs for ``interpolation`` and ``extrapolate``."""

    def __init__(
        self,
        times: Any,
        values: Any,
        interpolation: str | list[str] = "catmull_rom",
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
        schemes = [interpolation] if isinstance(interpolation, str) else list(interpolation)
        if not isinstance(interpolation, str) and len(schemes) not in (len(t) - 1, len(t)):
            raise ValueError(
                f"interpolation: expected one scheme or one per key ({len(t)}) or per segment "
                f"({len(t) - 1}), got {len(schemes)}"
            )
        schemes = schemes[: max(len(t) - 1, 1)]
        for name in schemes:
            if name not in INTERPOLATIONS:
                raise ValueError(
                    f"interpolation: {name!r} is not one of {', '.join(INTERPOLATIONS)}"
                )
        if "polynomial" in schemes and len(t) > 10:
            warnings.warn(
                f"polynomial interpolation through {len(t)} keys oscillates between them (Runge's phenomenon)",
                RuntimeWarning,
                stacklevel=2,
            )
        dim = v2.shape[1]
        extra = None
        with_data = sorted({"hermite", "clamped_cubic", "bezier"} & set(schemes))
        if len(with_data) > 1:
            raise ValueError(
                f"interpolation: {' and '.join(with_data)} each take their own data "
                "(tangents, end_tangents, handles) and cannot be mixed in one track"
            )
        if "hermite" in schemes:
            if tangents is None:
                raise ValueError("tangents: required for hermite interpolation")
            extra = _float(tangents, "tangents").reshape(len(t), dim)
        elif "clamped_cubic" in schemes and end_tangents is not None:
            extra = _float(end_tangents, "end_tangents").reshape(2, dim)
        elif "bezier" in schemes:
            if handles is None:
                raise ValueError("handles: required for bezier interpolation")
            extra = _float(handles, "handles").reshape(2 * (len(t) - 1), dim)
        params = [real(tension, "tension"), real(continuity, "continuity"), real(bias, "bias")]
        self._track = _kinema.KeyTrack(
            np.ascontiguousarray(t.reshape(-1, 1)),
            np.ascontiguousarray(v2),
            schemes,
            extrapolate,
            params,
            None if extra is None else np.ascontiguousarray(extra),
        )
        self._order = 0
        self._times = t.copy()

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
        d._track, d._scalar, d._order, d._times = (
            self._track,
            self._scalar,
            self._order + n,
            self._times,
        )
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
    return _kinema.anim_subdivide(np.ascontiguousarray(p), scheme, iterations, bool(closed))


class RotationTrack:
    """Keyframed orientations: ``rotations`` (a stack of N :class:`kinema.Rotation`) at
    strictly increasing ``times`` ``(N,)``. ``interpolation`` is ``"slerp"`` (constant angular
    velocity per segment; Shoemake 1985), ``"squad"`` (Shoemake's spherical quadrangles, C1 for
    equally spaced keys) or ``"spline"`` (C2: angular velocity and acceleration continuous at
    the keys; Sander 2015, the method of scipy's ``RotationSpline``, with the end rates set to
    the mean rates of the end segments). Segment ``k`` turns the shorter way unless
    ``shortest`` (a bool, or one per segment) is false there. Keys are held outside the time
    range."""

    def __init__(
        self,
        times: Any,
        rotations: Rotation,
        interpolation: str = "slerp",
        *,
        shortest: Any = True,
    ) -> None:
        t = _float(times, "times")
        if t.ndim != 1:
            raise ValueError(f"times: expected shape (N,), got {t.shape}")
        if not isinstance(rotations, Rotation) or rotations.single:
            raise ValueError("rotations: expected a stack of kinema.Rotation")
        try:
            flags = np.broadcast_to(np.asarray(shortest), (max(len(t) - 1, 0),))
        except ValueError:
            flags = np.asarray(shortest, dtype=object)
        if flags.dtype != np.bool_:
            raise ValueError(f"shortest: expected a bool or one bool per segment, got {shortest!r}")
        self._track = _kinema.KeyRotationTrack(
            np.ascontiguousarray(t.reshape(-1, 1)),
            rotations.as_quat(),
            interpolation,
            [bool(f) for f in flags],
        )
        self._times = t.copy()

    @property
    def times(self) -> np.ndarray:
        """The key times ``(N,)`` (a copy)."""
        return self._times.copy()

    def __call__(self, t: Any) -> Rotation:
        """The orientation(s) at time ``t`` (a single Rotation for a scalar ``t``)."""
        tt = _float(t, "t")
        q = self._track.eval(np.ascontiguousarray(tt.reshape(-1, 1)))
        return Rotation.from_quat(q[0] if tt.ndim == 0 else q)

    def _rates(self, t: Any, order: int, frame: str) -> np.ndarray:
        if frame not in ("world", "body"):
            raise ValueError("frame: expected 'world' or 'body'")
        tt = _float(t, "t")
        w = self._track.rates(np.ascontiguousarray(tt.reshape(-1, 1)), order)
        if frame == "body":
            # ω_body = Rᵀ ω_world, and its derivative Rᵀ α_world (the term Rᵀ (ω × ω) is 0).
            w = self(tt.reshape(-1)).apply(w, inverse=True)
        return w[0] if tt.ndim == 0 else w.reshape(*tt.shape, 3)

    def angular_velocity(self, t: Any, *, frame: str = "world") -> np.ndarray:
        """Angular velocity (rad/s), ``(3,)`` or ``t.shape + (3,)``, in the world frame or,
        with ``frame="body"``, in the rotating body's frame (as scipy's ``RotationSpline``)."""
        return self._rates(t, 1, frame)

    def angular_acceleration(self, t: Any, *, frame: str = "world") -> np.ndarray:
        """Angular acceleration (rad/s²), ``(3,)`` or ``t.shape + (3,)``, in the world frame or,
        with ``frame="body"``, in the body frame (``Rᵀ α``)."""
        return self._rates(t, 2, frame)


class ArcLengthCurve:
    """A track reparameterised by arc length: ``curve(s)`` is the point at distance ``s`` along
    the track (0 ≤ s ≤ ``length``), so sampling ``s`` uniformly moves at constant speed.

    Built by :func:`reparameterize_by_arc_length`; ``time_at(s)`` gives the track time. The
    table and Newton's method are in Rust (``kinema::anim::ArcLengthCurve``).
    """

    def __init__(self, track: Track, table: Any) -> None:
        self._track, self._table = track, table
        self.length = float(table.length)

    def time_at(self, s: Any) -> np.ndarray:
        """Track times at arc lengths ``s`` (clamped to [0, length]), by Newton's method
        (safeguarded by bisection) on ``S(t) = s``, to 1e-12 of the length; a NaN ``s`` is a
        ``ValueError``."""
        ss = _float(s, "s")
        t = self._table.time_at(np.ascontiguousarray(ss.reshape(-1, 1)))
        return t.reshape(ss.shape)

    def __call__(self, s: Any) -> Any:
        return self._track(self.time_at(s))


def reparameterize_by_arc_length(track: Track, tol: float = 1e-10) -> ArcLengthCurve:
    """Tabulate the arc length of ``track`` (over its key range) with 8-point Gauss–Legendre on
    subintervals, halving them until the total changes by at most ``tol`` times the length,
    and return the curve parameterised by arc length (Parent, *Computer Animation*, §3.2).
    A ``tol`` not met with 4096 subintervals per key interval is a ``ValueError`` naming
    ``tol`` (never a silently less accurate table)."""
    if not isinstance(track, Track) or track._order != 0:
        raise ValueError("track: expected a kinema.anim.Track (not a derivative)")
    return ArcLengthCurve(track, _kinema.ArcLengthTable(track._track, _number(tol, "tol")))


EASINGS = ("linear", "ease_in", "ease_out", "ease_in_out", "smoothstep")


def ease(u: Any, kind: str = "ease_in_out") -> Any:
    """Timing curve on ``u`` in [0, 1] (clamped), with ``ease(0) = 0`` and ``ease(1) = 1``:
    ``"linear"``; ``"ease_in"`` (``u²``, starts at rest); ``"ease_out"`` (``1 - (1-u)²``, ends at
    rest); ``"ease_in_out"`` (sinusoidal, ``(1 - cos πu)/2``, rests at both ends, Parent §3.2.2);
    ``"smoothstep"`` (``3u² - 2u³``). Combine with :func:`reparameterize_by_arc_length` to move
    along a path with a speed profile: ``curve(ease(u) * curve.length)``. Computed in Rust
    (``kinema::anim::Easing``); NaN is a ``ValueError``."""
    x = _float(u, "u")
    y = _kinema.anim_ease(np.ascontiguousarray(x.reshape(-1, 1)), kind)
    return float(y[0, 0]) if x.ndim == 0 else y.reshape(x.shape)


class Clip:
    """Named channels animated together: ``Clip({"position": track, "opacity": track, ...})``.

    ``duration`` spans the earliest to the latest key of all channels; ``sample(fps)`` evaluates
    every channel on one frame grid ``start + k / fps`` and returns ``(times, {name: array})``
    (in Rust: ``kinema::anim::Clip``).
    """

    def __init__(self, channels: dict[str, Track | RotationTrack]) -> None:
        if not channels or not all(
            isinstance(c, (Track, RotationTrack)) for c in channels.values()
        ):
            raise ValueError("channels: expected a non-empty dict of Track or RotationTrack")
        if any(isinstance(c, Track) and c._order != 0 for c in channels.values()):
            raise ValueError("channels: expected tracks, not derivatives of tracks")
        self.channels = dict(channels)
        self._clip = _kinema.AnimClip(
            list(self.channels), [c._track for c in self.channels.values()]
        )
        self.start = float(self._clip.start)
        self.end = float(self._clip.end)

    @property
    def duration(self) -> float:
        """Seconds from the first key to the last."""
        return self.end - self.start

    def sample(self, fps: float) -> tuple[np.ndarray, dict[str, Any]]:
        """Frame times at ``fps`` frames per second (covering start to end) and each channel's
        values there (rotation channels as ``kinema.Rotation`` stacks)."""
        t, samples = self._clip.sample(_number(fps, "fps"))
        out: dict[str, Any] = {}
        for (name, channel), values in zip(self.channels.items(), samples, strict=True):
            if isinstance(channel, RotationTrack):
                out[name] = Rotation.from_quat(values)
            else:
                out[name] = values[:, 0] if channel._scalar else values
        return t, out
