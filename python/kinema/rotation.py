"""3D rotations: a batched ``Rotation``, spherical interpolation and homogeneous transforms.

Conventions: quaternions are scalar-first ``(w, x, y, z)`` (pass ``scalar_first=False`` for
scipy's order); Euler sequences are 3-letter strings, upper case intrinsic (rotations about the
moving body axes), lower case extrinsic (about the fixed world axes), all 12 sequences of each;
angles are radians unless ``degrees=True``; vectors are rotated actively (``v' = R v``).

All numerics run in the Rust core (``kinema._kinema``), in parallel for large batches.
Sources: Shepperd 1978 (matrix to quaternion), Bernardes & Viollet 2022 (quaternion to Euler
angles), Grassia 1998 (exponential map), Shoemake 1985 (slerp).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Iterable, Sequence
from typing import Any, overload

import numpy as np

from kinema import _kinema
from kinema._array import as_batch, as_scalars

__all__ = ["GIMBAL_LOCK_TOL", "GimbalLockWarning", "Rotation", "Transform", "gimbal_lock", "slerp"]

GIMBAL_LOCK_TOL: float = _kinema.GIMBAL_LOCK_TOL
"""Radians from the singular middle angle within which Euler angles count as gimbal-locked."""


class GimbalLockWarning(UserWarning):
    """``as_euler`` met gimbal lock: the third angle was set to 0 and the first carries the rest.

    Silence it with ``warnings.simplefilter("ignore", kinema.GimbalLockWarning)``.
    """


def _check_seq(seq: object) -> str:
    if not isinstance(seq, str):
        raise ValueError(f"seq: expected a 3-letter string such as 'XYZ' or 'zxz', got {seq!r}")
    return seq


class Rotation:
    """One rotation or a stack of N rotations, stored as unit quaternions ``(N, 4)``.

    Build one with a ``from_*`` class method, :meth:`identity` or :meth:`random`. A rotation
    made from a single item (shape ``(4,)``, ``(3, 3)``, ``(3,)``...) is *single*: its
    ``as_*`` methods return single items and it has no ``len()``; a stack is indexed and
    sliced like an array. ``r1 * r2`` applies ``r2`` first, then ``r1``.
    """

    __slots__ = ("_quat", "_single")

    _quat: np.ndarray
    _single: bool

    def __init__(self, quat: Any, *, scalar_first: bool = True) -> None:
        """Same as :meth:`from_quat`."""
        other = Rotation.from_quat(quat, scalar_first=scalar_first)
        self._quat, self._single = other._quat, other._single

    @classmethod
    def _make(cls, quat: np.ndarray, single: bool) -> Rotation:
        r = object.__new__(cls)
        r._quat = quat
        r._single = single
        return r

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_quat(cls, quat: Any, *, scalar_first: bool = True) -> Rotation:
        """Rotations from quaternions ``(4,)`` or ``(N, 4)``, normalised to unit length.

        ``scalar_first=False`` reads ``(x, y, z, w)`` (scipy's order). A zero or non-finite
        quaternion raises ValueError naming its index.
        """
        q, single = as_batch(quat, "quat", (4,))
        if not scalar_first:
            q = np.ascontiguousarray(q[:, [3, 0, 1, 2]])
        return cls._make(_kinema.quat_normalize(q, False), single)

    @classmethod
    def from_matrix(cls, matrix: Any, *, orthonormalize: bool = False) -> Rotation:
        """Rotations from matrices ``(3, 3)`` or ``(N, 3, 3)`` acting on column vectors.

        A matrix further than ``ROTATION_MATRIX_TOL`` (1e-6) from orthonormal, or with a
        negative determinant, raises ValueError unless ``orthonormalize=True`` replaces it by
        the nearest rotation (polar decomposition by SVD, after an exact power-of-two scaling,
        so any finite matrix works, ``1e160 * I`` or subnormal entries included).
        """
        m, single = as_batch(matrix, "matrix", (3, 3))
        return cls._make(_kinema.matrix_to_quat(m, orthonormalize), single)

    @classmethod
    def from_rotvec(cls, rotvec: Any, *, degrees: bool = False) -> Rotation:
        """Rotations from rotation vectors ``(3,)`` or ``(N, 3)``: axis times angle."""
        v, single = as_batch(rotvec, "rotvec", (3,))
        if degrees:
            v = np.deg2rad(v)
        return cls._make(_kinema.rotvec_to_quat(v), single)

    @classmethod
    def from_axis_angle(cls, axis: Any, angle: Any, *, degrees: bool = False) -> Rotation:
        """Rotations by ``angle`` about ``axis`` (normalised here; a zero axis is an error).

        ``axis`` is ``(3,)`` or ``(N, 3)``, ``angle`` a scalar or ``(N,)``; one broadcasts
        against N.
        """
        a, single_axis = as_batch(axis, "axis", (3,))
        t, single_angle = as_scalars(angle, "angle")
        if degrees:
            t = np.deg2rad(t)
        return cls._make(_kinema.axis_angle_to_quat(a, t), single_axis and single_angle)

    @classmethod
    def from_euler(cls, seq: str, angles: Any, *, degrees: bool = False) -> Rotation:
        """Rotations from Euler angles ``(3,)`` or ``(N, 3)`` in sequence ``seq``.

        ``seq`` has 3 letters from x, y, z: upper case for intrinsic rotations (about the
        body's moving axes, "Euler angles"), lower case for extrinsic rotations (about the
        fixed world axes, "fixed angles"). ``XYZ`` with ``(a, b, c)`` equals ``zyx`` with
        ``(c, b, a)``.
        """
        a, single = as_batch(angles, "angles", (3,))
        if degrees:
            a = np.deg2rad(a)
        return cls._make(_kinema.euler_to_quat(_check_seq(seq), a), single)

    @classmethod
    def identity(cls, n: int | None = None) -> Rotation:
        """The identity: single if ``n`` is None, else a stack of ``n``."""
        q = _quats(n, np.zeros)
        q[:, 0] = 1.0
        return cls._make(q, n is None)

    @classmethod
    def random(
        cls, n: int | None = None, *, seed: int | np.random.Generator | None = None
    ) -> Rotation:
        """Rotations drawn uniformly (Haar measure): normalised Gaussian 4-vectors.

        Single if ``n`` is None, else a stack of ``n``; ``seed`` makes the draw repeatable.
        """
        rng = np.random.default_rng(seed)
        q = _quats(n, rng.standard_normal)
        return cls._make(_kinema.quat_normalize(q, False), n is None)

    @classmethod
    def concatenate(cls, rotations: Sequence[Rotation]) -> Rotation:
        """One stack holding all rotations of ``rotations`` in order."""
        if not all(isinstance(r, Rotation) for r in rotations):
            raise ValueError("rotations: every item must be a Rotation")
        quats = [r._quat for r in rotations]
        return cls._make(np.concatenate(quats) if quats else np.zeros((0, 4)), False)

    # ------------------------------------------------------------------ conversion
    def as_quat(self, *, scalar_first: bool = True, canonical: bool = False) -> np.ndarray:
        """Unit quaternions ``(4,)`` or ``(N, 4)``; ``canonical`` picks the sign with w >= 0."""
        q = _kinema.quat_normalize(self._quat, True) if canonical else self._quat.copy()
        if not scalar_first:
            q = q[:, [1, 2, 3, 0]]
        return self._out(q)

    def as_matrix(self) -> np.ndarray:
        """Rotation matrices ``(3, 3)`` or ``(N, 3, 3)``."""
        return self._out(_kinema.quat_to_matrix(self._quat))

    def as_rotvec(self, *, degrees: bool = False) -> np.ndarray:
        """Rotation vectors ``(3,)`` or ``(N, 3)`` with angle (their norm) in ``[0, pi]``."""
        v = _kinema.quat_to_rotvec(self._quat)
        return self._out(np.rad2deg(v) if degrees else v)

    def as_axis_angle(self, *, degrees: bool = False) -> tuple[np.ndarray, Any]:
        """Unit axes ``(3,)``/``(N, 3)`` and angles in ``[0, pi]``; the identity has axis +x."""
        aa = _kinema.quat_to_axis_angle(self._quat)
        angle = np.rad2deg(aa[:, 3]) if degrees else aa[:, 3]
        if self._single:
            return aa[0, :3].copy(), float(angle[0])
        return np.ascontiguousarray(aa[:, :3]), angle.copy()

    def as_euler(self, seq: str, *, degrees: bool = False) -> np.ndarray:
        """Euler angles ``(3,)`` or ``(N, 3)`` in sequence ``seq`` (see :meth:`from_euler`).

        First and third angles lie in ``(-pi, pi]``; the middle one in ``[-pi/2, pi/2]``
        (Tait–Bryan) or ``[0, pi]`` (proper Euler). At gimbal lock the third angle is set to 0,
        the first carries the combined rotation, and a :class:`GimbalLockWarning` is issued.
        No valid input gives NaN.
        """
        angles, locked = _kinema.quat_to_euler(_check_seq(seq), self._quat)
        if locked:
            warnings.warn(
                f"gimbal lock in {locked} of {len(angles)} rotations (sequence {seq!r}): third angle set to 0",
                GimbalLockWarning,
                stacklevel=2,
            )
        return self._out(np.rad2deg(angles) if degrees else angles)

    # ------------------------------------------------------------------ algebra
    def apply(self, vectors: Any, *, inverse: bool = False) -> np.ndarray:
        """Rotate ``vectors`` ``(3,)`` or ``(N, 3)``; one rotation or one vector broadcasts.

        ``inverse=True`` applies the inverse rotations.
        """
        v, single_v = as_batch(vectors, "vectors", (3,))
        out = _kinema.quat_apply(self._quat, v, inverse)
        return out[0] if self._single and single_v else out

    def __mul__(self, other: Rotation) -> Rotation:
        """Composition: ``(r1 * r2).apply(v) == r1.apply(r2.apply(v))``."""
        if not isinstance(other, Rotation):
            return NotImplemented
        q = _kinema.quat_multiply(self._quat, other._quat)
        return Rotation._make(q, self._single and other._single)

    def inv(self) -> Rotation:
        """The inverse rotations (conjugate quaternions)."""
        q = self._quat * np.array([1.0, -1.0, -1.0, -1.0])
        return Rotation._make(q, self._single)

    def magnitude(self) -> Any:
        """Rotation angles in radians, in ``[0, pi]``: a float or ``(N,)``."""
        a = _kinema.quat_angle(self._quat)[:, 0]
        return float(a[0]) if self._single else a

    def approx_equal(self, other: Rotation, atol: float = 1e-12) -> Any:
        """Whether each rotation is within ``atol`` radians of ``other`` (q and -q are equal)."""
        return (other * self.inv()).magnitude() <= atol

    # ------------------------------------------------------------------ container
    @property
    def single(self) -> bool:
        """True for a single rotation, False for a stack (even of length 1)."""
        return self._single

    def __len__(self) -> int:
        if self._single:
            raise TypeError("a single rotation has no len()")
        return len(self._quat)

    def __getitem__(self, index: Any) -> Rotation:
        if self._single:
            raise TypeError("a single rotation cannot be indexed")
        q = self._quat[index]
        return Rotation._make(np.ascontiguousarray(q.reshape(-1, 4)), q.ndim == 1)

    def __iter__(self) -> Iterable[Rotation]:
        if self._single:
            raise TypeError("a single rotation is not iterable")
        return (self[i] for i in range(len(self._quat)))

    def __repr__(self) -> str:
        if self._single:
            return f"Rotation.from_quat({self._quat[0].tolist()})"
        return f"Rotation(<{len(self._quat)} rotations>)"

    def __getstate__(self) -> tuple[np.ndarray, bool]:
        return self._quat, self._single

    def __setstate__(self, state: Any) -> None:
        """Unpickle, validating: quaternions ``(N, 4)`` of unit length (to 1e-9) and a bool
        (``(1, 4)`` when single); anything else (a damaged or foreign pickle) raises
        ValueError."""
        quat, single = _pickled(state, "quaternions", (4,))
        norms = np.linalg.norm(quat, axis=1)
        bad = np.flatnonzero(~(np.abs(norms - 1.0) <= 1e-9))
        if bad.size:
            raise ValueError(f"state: quaternion {bad[0]} is not unit (norm {norms[bad[0]]})")
        self._quat, self._single = quat, single

    def _out(self, arr: np.ndarray) -> np.ndarray:
        return arr[0] if self._single else arr


def _pickled(state: Any, what: str, item: tuple[int, ...]) -> tuple[np.ndarray, bool]:
    """The ``(array (N, *item), single)`` pickle state of a Rotation or Transform, checked for
    its types and shape (one item when single)."""
    if not (isinstance(state, tuple) and len(state) == 2 and isinstance(state[1], bool)):
        raise ValueError(f"state: expected ({what}, single), not a kinema pickle")
    array = np.ascontiguousarray(state[0], dtype=np.float64)
    if array.shape[1:] != item or array.ndim != 1 + len(item) or (state[1] and len(array) != 1):
        shape = ", ".join(["1" if state[1] else "N", *map(str, item)])
        raise ValueError(f"state: {what} must have shape ({shape}), got {array.shape}")
    return array, state[1]


def _count(n: object) -> int:
    if not isinstance(n, (int, np.integer)) or isinstance(n, bool) or n < 0:
        raise ValueError(f"n: expected a non-negative integer, got {n!r}")
    return int(n)


def _quats(n: int | None, make: Callable[[tuple[int, int]], np.ndarray]) -> np.ndarray:
    """``make((count, 4))`` for a stack of ``n`` (one when None); numpy's MemoryError, which
    names no argument, becomes one naming ``n``."""
    count = 1 if n is None else _count(n)
    try:
        return make((count, 4))
    except MemoryError:
        raise MemoryError(
            f"n: {count} rotations need {32 * count} bytes, more than is free"
        ) from None


@overload
def slerp(r0: Rotation, r1: Rotation, t: float, *, shortest: bool = True) -> Rotation: ...
@overload
def slerp(r0: Rotation, r1: Rotation, t: Any, *, shortest: bool = True) -> Rotation: ...
def slerp(r0: Rotation, r1: Rotation, t: Any, *, shortest: bool = True) -> Rotation:
    """Spherical linear interpolation ``r0 (r0⁻¹ r1)^t`` (Shoemake 1985).

    ``t`` is a scalar or ``(M,)``; values outside [0, 1] extrapolate along the same great
    circle at the same angular speed. ``r0``, ``r1`` and ``t`` broadcast (one against N).
    The shorter arc is taken unless ``shortest=False``, which follows the quaternions exactly
    as given (the long way when their dot product is negative).
    """
    if not isinstance(r0, Rotation) or not isinstance(r1, Rotation):
        raise ValueError("r0, r1: expected Rotation objects")
    tt, single_t = as_scalars(t, "t")
    q = _kinema.quat_slerp(r0._quat, r1._quat, tt, shortest)
    return Rotation._make(q, r0.single and r1.single and single_t)


def gimbal_lock(
    seq: str, angles: Any, *, atol: float = GIMBAL_LOCK_TOL, degrees: bool = False
) -> Any:
    """Whether Euler ``angles`` ``(3,)`` or ``(N, 3)`` in ``seq`` are at gimbal lock.

    True where the middle angle is within ``atol`` radians of ±90° (Tait–Bryan sequences) or
    of 0° / 180° (proper Euler sequences), where the first and third axes coincide and only
    their sum or difference is defined. Returns a bool or a bool array ``(N,)``.
    """
    a, single = as_batch(angles, "angles", (3,))
    if degrees:
        a = np.deg2rad(a)
    locked = _kinema.euler_gimbal_lock(_check_seq(seq), a, float(atol))[:, 0] != 0.0
    return bool(locked[0]) if single else locked


class Transform:
    """One homogeneous 4x4 affine transform or a stack of N, acting on column vectors.

    ``Transform(rotation, translation, scale)`` builds ``M = T R S``: scale along the body
    axes (a scalar or per-axis ``(3,)``/``(N, 3)``), then rotate, then translate. Any affine
    matrix with last row ``(0, 0, 0, 1)`` is accepted by :meth:`from_matrix`. ``t1 * t2``
    applies ``t2`` first.
    """

    __slots__ = ("_matrix", "_single")

    _matrix: np.ndarray
    _single: bool

    def __init__(
        self,
        rotation: Rotation | None = None,
        translation: Any = None,
        scale: Any = None,
    ) -> None:
        rot = Rotation.identity() if rotation is None else rotation
        if not isinstance(rot, Rotation):
            raise ValueError(f"rotation: expected a Rotation, got {type(rot).__name__}")
        t, single_t = as_batch(
            (0.0, 0.0, 0.0) if translation is None else translation, "translation", (3,)
        )
        s_arr = np.asarray(1.0 if scale is None else scale, dtype=np.float64)
        s, single_s = as_batch(
            np.broadcast_to(s_arr, (3,)) if s_arr.ndim == 0 else s_arr, "scale", (3,)
        )
        self._matrix = _kinema.transform_from_parts(rot._quat, t, s)
        self._single = rot.single and single_t and single_s

    @classmethod
    def _make(cls, matrix: np.ndarray, single: bool) -> Transform:
        t = object.__new__(cls)
        t._matrix = matrix
        t._single = single
        return t

    @classmethod
    def from_matrix(cls, matrix: Any) -> Transform:
        """Transforms from affine matrices ``(4, 4)`` or ``(N, 4, 4)`` (last row 0, 0, 0, 1)."""
        m, single = as_batch(matrix, "matrix", (4, 4))
        return cls._make(_kinema.transform_validate(m), single)

    def as_matrix(self) -> np.ndarray:
        """The matrices, ``(4, 4)`` or ``(N, 4, 4)``."""
        m = self._matrix.copy()
        return m[0] if self._single else m

    @property
    def translation(self) -> np.ndarray:
        """The translation column, ``(3,)`` or ``(N, 3)``."""
        t = np.ascontiguousarray(self._matrix[:, :3, 3])
        return t[0] if self._single else t

    def apply(self, points: Any) -> np.ndarray:
        """Transform points ``(3,)`` or ``(N, 3)``: ``M [p; 1]``."""
        return self._apply(points, "points", directions=False)

    def apply_directions(self, vectors: Any) -> np.ndarray:
        """Transform direction vectors ``(3,)`` or ``(N, 3)``: ``M [d; 0]`` (no translation).

        For surface normals under non-uniform scale use the inverse transpose instead.
        """
        return self._apply(vectors, "vectors", directions=True)

    def _apply(self, values: Any, name: str, *, directions: bool) -> np.ndarray:
        p, single_p = as_batch(values, name, (3,))
        out = _kinema.transform_apply(self._matrix, p, directions)
        return out[0] if self._single and single_p else out

    def __mul__(self, other: Transform) -> Transform:
        """Composition: ``(t1 * t2).apply(p) == t1.apply(t2.apply(p))``."""
        if not isinstance(other, Transform):
            return NotImplemented
        m = _kinema.transform_compose(self._matrix, other._matrix)
        return Transform._make(m, self._single and other._single)

    def inv(self) -> Transform:
        """The inverse transforms; a singular linear part raises ValueError."""
        return Transform._make(_kinema.transform_invert(self._matrix), self._single)

    @property
    def single(self) -> bool:
        """True for a single transform, False for a stack."""
        return self._single

    def __len__(self) -> int:
        if self._single:
            raise TypeError("a single transform has no len()")
        return len(self._matrix)

    def __getitem__(self, index: Any) -> Transform:
        if self._single:
            raise TypeError("a single transform cannot be indexed")
        m = self._matrix[index]
        return Transform._make(np.ascontiguousarray(m.reshape(-1, 4, 4)), m.ndim == 2)

    def __repr__(self) -> str:
        if self._single:
            return f"Transform.from_matrix({self._matrix[0].tolist()})"
        return f"Transform(<{len(self._matrix)} transforms>)"

    def __getstate__(self) -> tuple[np.ndarray, bool]:
        return self._matrix, self._single

    def __setstate__(self, state: Any) -> None:
        """Unpickle, validating as :meth:`from_matrix` does: affine ``(N, 4, 4)`` with last
        row ``(0, 0, 0, 1)`` and finite entries, and a bool; else ValueError."""
        matrix, single = _pickled(state, "matrices", (4, 4))
        self._matrix, self._single = _kinema.transform_validate(matrix), single
