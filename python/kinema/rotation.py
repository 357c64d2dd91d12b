"""3D rotations: ``Rotation`` (one or a stack of any shape) and spherical interpolation.

Conventions: quaternions are scalar-first ``(w, x, y, z)`` (pass ``scalar_first=False`` for
scipy's order); Euler sequences are 3-letter strings, upper case intrinsic (rotations about the
moving body axes), lower case extrinsic (about the fixed world axes), all 12 sequences of each;
angles are radians unless ``degrees=True``; vectors are rotated actively (``v' = R v``).

All numerics run in the Rust core (``kinema._kinema``), in parallel for large batches.
Sources: Shepperd 1978 (matrix to quaternion), Bernardes & Viollet 2022 (quaternion to Euler
angles), Grassia 1998 (exponential map), Shoemake 1985 (slerp).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, overload

import numpy as np

from kinema import _kinema
from kinema._array import as_batch, as_scalars, as_stack, real
from kinema._stack import Stack

if TYPE_CHECKING:
    from typing_extensions import Self

__all__ = ["GIMBAL_LOCK_TOL", "GimbalLockWarning", "Rotation", "gimbal_lock", "slerp"]

GIMBAL_LOCK_TOL: float = _kinema.GIMBAL_LOCK_TOL
"""Radians from the singular middle angle within which Euler angles count as gimbal-locked."""


class GimbalLockWarning(UserWarning):
    """``as_euler`` met gimbal lock: the third angle was set to 0 and the first carries the rest.

    Silence it with ``warnings.simplefilter("ignore", kinema.GimbalLockWarning)``.
    """


def _check_seq(seq: object, lengths: tuple[int, ...] = (3,)) -> str:
    """``seq`` if it is a string of one of ``lengths``; the letters are checked in Rust."""
    if not isinstance(seq, str) or len(seq) not in lengths:
        n = " or ".join(map(str, lengths))
        raise ValueError(f"seq: expected a string of {n} axes such as 'XYZ' or 'zxz'")
    return seq


class Rotation(Stack):
    """One rotation or a stack of rotations of any shape, stored as unit quaternions.

    Build one with a ``from_*`` class method, :meth:`identity` or :meth:`random`. A rotation
    made from a single item (shape ``(4,)``, ``(3, 3)``, ``(3,)``...) is *single*
    (``shape == ()``): its ``as_*`` methods return single items and it has no ``len()``. A
    stack made from ``(*shape, 4)`` quaternions has that ``shape``; ``len``, indexing,
    assignment and iteration act on its first axis, as on a numpy array. ``r1 * r2`` applies
    ``r2`` first, then ``r1``; stacks broadcast as numpy arrays do.
    """

    __slots__ = ("_quat", "_shape")
    _NOUN = "rotation"
    _ITEM = (4,)

    _quat: np.ndarray
    _shape: tuple[int, ...]

    def __init__(self, quat: Any, *, scalar_first: bool = True) -> None:
        """Same as :meth:`from_quat`."""
        other = Rotation.from_quat(quat, scalar_first=scalar_first)
        self._quat, self._shape = other._quat, other._shape

    @classmethod
    def _make(cls, quat: np.ndarray, shape: tuple[int, ...]) -> Self:
        """A rotation of leading ``shape`` from unit quaternions ``(prod(shape), 4)``."""
        r = object.__new__(cls)
        r._quat = quat
        r._shape = tuple(shape)
        return r

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_quat(cls, quat: Any, *, scalar_first: bool = True) -> Self:
        """Rotations from quaternions ``(..., 4)``, normalised to unit length.

        ``scalar_first=False`` reads ``(x, y, z, w)`` (scipy's order). A zero or non-finite
        quaternion raises ValueError naming its index (in the flattened stack).
        """
        q, shape = as_stack(quat, "quat", (4,))
        if not scalar_first:
            q = np.ascontiguousarray(q[:, [3, 0, 1, 2]])
        return cls._make(_kinema.quat_normalize(q, False), shape)

    @classmethod
    def from_matrix(cls, matrix: Any, *, orthonormalize: bool = False) -> Self:
        """Rotations from matrices ``(..., 3, 3)`` acting on column vectors.

        A matrix further than ``ROTATION_MATRIX_TOL`` (1e-6) from orthonormal, or with a
        negative determinant, raises ValueError unless ``orthonormalize=True`` replaces it by
        the nearest rotation (polar decomposition by SVD, after an exact power-of-two scaling,
        so any finite matrix works, ``1e160 * I`` or subnormal entries included).
        """
        m, shape = as_stack(matrix, "matrix", (3, 3))
        return cls._make(_kinema.matrix_to_quat(m, orthonormalize), shape)

    @classmethod
    def from_rotvec(cls, rotvec: Any, *, degrees: bool = False) -> Self:
        """Rotations from rotation vectors ``(..., 3)``: axis times angle."""
        v, shape = as_stack(rotvec, "rotvec", (3,))
        if degrees:
            v = np.deg2rad(v)
        return cls._make(_kinema.rotvec_to_quat(v), shape)

    @classmethod
    def from_axis_angle(cls, axis: Any, angle: Any, *, degrees: bool = False) -> Self:
        """Rotations by ``angle`` about ``axis`` (normalised here; a zero axis is an error).

        ``axis`` is ``(3,)`` or ``(N, 3)``, ``angle`` a scalar or ``(N,)``; one broadcasts
        against N.
        """
        a, single_axis = as_batch(axis, "axis", (3,))
        t, single_angle = as_scalars(angle, "angle")
        if degrees:
            t = np.deg2rad(t)
        q = _kinema.axis_angle_to_quat(a, t)
        return cls._make(q, () if single_axis and single_angle else (len(q),))

    @classmethod
    def from_euler(cls, seq: str, angles: Any, *, degrees: bool = False) -> Self:
        """Rotations from Euler angles in sequence ``seq`` of 1, 2 or 3 axes.

        ``seq`` has letters from x, y, z, consecutive ones different: upper case for
        intrinsic rotations (about the body's moving axes, "Euler angles"), lower case for
        extrinsic rotations (about the fixed world axes, "fixed angles"). ``angles`` is
        ``(..., len(seq))`` (a scalar counts as ``(1,)``). ``XYZ`` with
        ``(a, b, c)`` equals ``zyx`` with ``(c, b, a)``. Sequences of one or two axes are the
        three-axis sequence completed by a zero angle (which is exactly the identity).
        """
        seq = _check_seq(seq, (1, 2, 3))
        a = angles if np.ndim(angles) else [angles]
        flat, shape = as_stack(a, "angles", (len(seq),))
        if degrees:
            flat = np.deg2rad(flat)
        if len(seq) < 3:
            other = next(c for c in "xyz" if c != seq[-1].lower())
            other = other.upper() if seq.isupper() else other
            seq = (seq + other + seq[0])[:3] if len(seq) == 1 else seq + seq[0]
            flat = np.ascontiguousarray(np.pad(flat, ((0, 0), (0, 3 - flat.shape[1]))))
        return cls._make(_kinema.euler_to_quat(seq, flat), shape)

    @classmethod
    def from_davenport(cls, axes: Any, order: str, angles: Any, *, degrees: bool = False) -> Self:
        """Rotations by Davenport angles: turns by ``angles`` ``(..., n)`` about ``n`` (1 to 3)
        ``axes`` ``(..., n, 3)`` (one set for all, ``(n, 3)`` or a single axis ``(3,)``, or a
        set per rotation; leading shapes broadcast with the angles'), any non-zero vectors,
        normalised here, consecutive ones orthogonal to 1e-7; ``order`` ``"extrinsic"``/``"e"``
        (fixed axes, the first turn first) or ``"intrinsic"``/``"i"`` (axes moving with the
        body). Euler angles are the case of coordinate axes (Davenport 1973; Shuster & Markley
        2003)."""
        intrinsic = _order(order)
        ax, ax_shape = _davenport_axes(axes, None)
        n = ax.shape[1]
        flat, shape = as_stack(angles if np.ndim(angles) else [angles], "angles", (n,))
        if degrees:
            flat = np.deg2rad(flat)
        ax, flat, shape = _broadcast(ax, ax_shape, flat, shape, "angles")
        q = _kinema.rotvec_to_quat(np.zeros((max(len(ax), len(flat)), 3)))
        for k in range(n):
            turn = _kinema.axis_angle_to_quat(
                np.ascontiguousarray(ax[:, k]), np.ascontiguousarray(flat[:, k : k + 1])
            )
            q = _kinema.quat_multiply(q, turn) if intrinsic else _kinema.quat_multiply(turn, q)
        return cls._make(q, shape)

    @classmethod
    def from_mrp(cls, mrp: Any) -> Self:
        """Rotations from modified Rodrigues parameters ``(..., 3)``: axis times
        ``tan(angle / 4)`` (Schaub & Junkins 2003, sec. 3.8)."""
        p, shape = as_stack(mrp, "mrp", (3,))
        return cls._make(_kinema.mrp_to_quat(p), shape)

    @classmethod
    def create_group(cls, group: str, axis: str = "Z") -> Self:
        """The elements of a finite rotation group as a stack: ``"I"`` (icosahedral, 60),
        ``"O"`` (octahedral, 24), ``"T"`` (tetrahedral, 12), ``"Cn"`` (cyclic, ``n``
        rotations about ``axis``) or ``"Dn"`` (dihedral, ``2n``: ``Cn`` and ``n`` half turns
        about axes normal to ``axis``); ``axis`` is ``"X"``, ``"Y"`` or ``"Z"``."""
        if not isinstance(group, str):
            raise ValueError("group: must be a string such as 'O' or 'D6'")
        if not isinstance(axis, str):
            raise ValueError("axis: expected one of 'X', 'Y', 'Z'")
        q = _kinema.rotation_group(group, axis)
        return cls._make(q, (len(q),))

    @classmethod
    def align_vectors(
        cls, a: Any, b: Any, weights: Any = None, return_sensitivity: bool = False
    ) -> tuple[Any, ...]:
        """The rotation ``C`` minimising ``Σ wᵢ |aᵢ - C bᵢ|²`` over vectors ``a``, ``b``
        ``(3,)`` or ``(N, 3)`` (Wahba's problem by the SVD, Markley 1988), with its ``rssd``
        ``sqrt(Σ wᵢ |aᵢ - C bᵢ|²)``, and with ``return_sensitivity`` the 3x3 sensitivity
        matrix (covariance of the rotation-vector error per unit vector noise, times the mean
        weight; Markley 1988 eq. 38).

        ``weights`` ``(N,)`` are non-negative; one may be ``inf``: that primary pair is
        aligned exactly, and the others only turn ``C`` about it (no sensitivity then). A
        single pair is always primary (the shortest arc). Warns when ``C`` is not unique (all
        vectors on one line).
        """
        av, single_a = as_batch(a, "a", (3,))
        bv, _ = as_batch(b, "b", (3,))
        if av.shape != bv.shape:
            raise ValueError(
                f"b: expected the shape of a, {av.shape[1:] if single_a else av.shape}"
            )
        n = len(av)
        w = np.ones(n)
        if weights is not None:
            given = np.asarray(weights, dtype=np.float64)
            if given.shape != (n,):
                raise ValueError(f"weights: expected shape ({n},), got {given.shape}")
            if np.isnan(given).any() or (given < 0).any():
                raise ValueError("weights: must not be negative or NaN")
            if n > 1:  # a single pair is primary whatever its weight
                w = given
        if return_sensitivity and (n == 1 or np.isinf(w).any()):
            raise ValueError(
                "return_sensitivity: no sensitivity with an infinite weight or one vector pair"
            )
        row = _kinema.align_vectors(av, bv, np.ascontiguousarray(w.reshape(-1, 1)))[0]
        if row[14]:
            warnings.warn(
                "Optimal rotation is not uniquely or poorly defined for the given sets of vectors.",
                UserWarning,
                stacklevel=2,
            )
        rot = cls._make(np.ascontiguousarray(row[None, :4]), ())
        if return_sensitivity:
            return rot, float(row[4]), row[5:14].reshape(3, 3).copy()
        return rot, float(row[4])

    @classmethod
    def identity(cls, n: int | None = None, *, shape: int | tuple[int, ...] | None = None) -> Self:
        """The identity: single if ``n`` and ``shape`` are None, else a stack of ``n`` or of
        ``shape`` (give one of them)."""
        lead = _lead(n, shape)
        q = _quats(lead, np.zeros)
        q[:, 0] = 1.0
        return cls._make(q, lead)

    @classmethod
    def random(
        cls,
        n: int | None = None,
        *,
        rng: int | np.random.Generator | None = None,
        shape: int | tuple[int, ...] | None = None,
    ) -> Self:
        """Rotations drawn uniformly (Haar measure): normalised Gaussian 4-vectors.

        Single if ``n`` and ``shape`` are None, else a stack of ``n`` or of ``shape``; ``rng``
        (a seed or a ``numpy.random.Generator``) makes the draw repeatable.
        """
        lead = _lead(n, shape)
        q = _quats(lead, np.random.default_rng(rng).standard_normal)
        return cls._make(_kinema.quat_normalize(q, False), lead)

    @classmethod
    def concatenate(cls, rotations: Sequence[Rotation]) -> Self:
        """One stack holding all rotations of ``rotations`` in order, joined along the first
        axis (a single rotation counts as a stack of one)."""
        if not all(isinstance(r, Rotation) for r in rotations):
            raise ValueError("rotations: every item must be a Rotation")
        if not rotations:
            return cls._make(np.zeros((0, 4)), (0,))
        try:
            q = np.concatenate(
                [r._quat.reshape((*r._shape, 4) if r._shape else (1, 4)) for r in rotations]
            )
        except ValueError:
            raise ValueError("rotations: stacks must agree in every axis but the first") from None
        return cls._make(np.ascontiguousarray(q.reshape(-1, 4)), q.shape[:-1])

    # ------------------------------------------------------------------ conversion
    def as_quat(self, *, scalar_first: bool = True, canonical: bool = False) -> np.ndarray:
        """Unit quaternions ``(*shape, 4)``; ``canonical`` picks the sign with w >= 0."""
        q = _kinema.quat_normalize(self._quat, True) if canonical else self._quat.copy()
        if not scalar_first:
            q = q[:, [1, 2, 3, 0]]
        return self._out(q)

    def as_matrix(self) -> np.ndarray:
        """Rotation matrices ``(*shape, 3, 3)``."""
        return self._out(_kinema.quat_to_matrix(self._quat))

    def as_rotvec(self, *, degrees: bool = False) -> np.ndarray:
        """Rotation vectors ``(*shape, 3)`` with angle (their norm) in ``[0, pi]``."""
        v = _kinema.quat_to_rotvec(self._quat)
        return self._out(np.rad2deg(v) if degrees else v)

    def as_axis_angle(self, *, degrees: bool = False) -> tuple[np.ndarray, Any]:
        """Unit axes ``(*shape, 3)`` and angles ``shape`` in ``[0, pi]``; the identity has
        axis +x (a float angle for a single rotation)."""
        aa = _kinema.quat_to_axis_angle(self._quat)
        angle = np.rad2deg(aa[:, 3]) if degrees else aa[:, 3]
        if self.single:
            return aa[0, :3].copy(), float(angle[0])
        return self._out(np.ascontiguousarray(aa[:, :3])), angle.reshape(self._shape)

    def as_euler(self, seq: str, *, degrees: bool = False) -> np.ndarray:
        """Euler angles ``(*shape, 3)`` in sequence ``seq`` of 3 axes (see :meth:`from_euler`).

        First and third angles lie in ``(-pi, pi]``; the middle one in ``[-pi/2, pi/2]``
        (Tait–Bryan) or ``[0, pi]`` (proper Euler). At gimbal lock the third angle is set to 0,
        the first carries the combined rotation, and a :class:`GimbalLockWarning` is issued.
        No valid input gives NaN.
        """
        angles, locked = _kinema.quat_to_euler(_check_seq(seq), self._quat)
        if locked:
            warnings.warn(
                f"Gimbal lock in {locked} of {len(angles)} rotations (sequence {seq!r}): third angle set to 0",
                GimbalLockWarning,
                stacklevel=2,
            )
        return self._out(np.rad2deg(angles) if degrees else angles)

    def as_davenport(self, axes: Any, order: str, *, degrees: bool = False) -> np.ndarray:
        """Davenport angles ``(*shape, 3)`` about 3 ``axes`` ``(..., 3, 3)`` (normalised;
        consecutive ones orthogonal to 1e-7; one set for all or a set per rotation, leading
        shapes broadcast), ``order`` as in :meth:`from_davenport`.

        With ``n3 = R_n2(λ) n1`` the middle angle lies in ``[λ, λ + π]`` for ``λ <= 0`` and in
        ``[λ - π, λ]`` otherwise (``λ`` of ``n1``, ``n3`` swapped for intrinsic order), which
        for coordinate axes are the ranges of :meth:`as_euler`, whose angles these then are;
        first and third in ``(-pi, pi]``. Bernardes & Viollet 2022, sec. 3. At gimbal lock the
        third angle is set to 0 and a :class:`GimbalLockWarning` is issued.
        """
        intrinsic = _order(order)
        ax, ax_shape = _davenport_axes(axes, 3)
        ax, q, shape = _broadcast(ax.reshape(-1, 9), ax_shape, self._quat, self._shape, "axes")
        angles, locked = _kinema.quat_to_davenport(ax, intrinsic, q)
        if locked:
            warnings.warn(
                f"Gimbal lock in {locked} of {len(angles)} rotations: third angle set to 0",
                GimbalLockWarning,
                stacklevel=2,
            )
        angles = np.rad2deg(angles) if degrees else angles
        return angles.reshape((*shape, 3))

    def as_mrp(self) -> np.ndarray:
        """Modified Rodrigues parameters ``(*shape, 3)`` of norm at most 1 (the angle taken
        in ``[0, pi]``)."""
        return self._out(_kinema.quat_to_mrp(self._quat))

    # ------------------------------------------------------------------ algebra
    def apply(self, vectors: Any, *, inverse: bool = False) -> np.ndarray:
        """Rotate ``vectors`` ``(..., 3)``: the rotations' shape and the vectors' leading
        shape broadcast (numpy rules); the result is ``(*broadcast, 3)``.

        ``inverse=True`` applies the inverse rotations.
        """
        v, vshape = as_stack(vectors, "vectors", (3,))
        q, v, shape = _broadcast(self._quat, self._shape, v, vshape, "vectors")
        return _kinema.quat_apply(q, v, inverse).reshape((*shape, 3))

    def __mul__(self, other: Rotation) -> Self:
        """Composition: ``(r1 * r2).apply(v) == r1.apply(r2.apply(v))``; shapes broadcast."""
        if not isinstance(other, Rotation):
            return NotImplemented
        a, b, shape = _broadcast(self._quat, self._shape, other._quat, other._shape, "other")
        return self._make(_kinema.quat_multiply(a, b), shape)

    def __pow__(self, n: float, modulus: None = None) -> Self:
        """The rotation ``n`` times: the same axis, ``n`` times the angle in ``[0, pi]``
        (``r ** 0.5`` is the half-way rotation; ``-1`` the inverse, ``0`` the identity)."""
        if modulus is not None:
            raise NotImplementedError("modulus not supported")
        if np.size(n) != 1:
            raise ValueError("n: Array exponent must be a scalar (one element)")
        p = _float(np.reshape(n, ()), "n")
        if p == 1:
            return self._make(self._quat.copy(), self._shape)
        if p == -1:
            return self.inv()
        return self._make(
            _kinema.rotvec_to_quat(p * _kinema.quat_to_rotvec(self._quat)), self._shape
        )

    def inv(self) -> Self:
        """The inverse rotations (conjugate quaternions)."""
        return self._make(self._quat * np.array([1.0, -1.0, -1.0, -1.0]), self._shape)

    def magnitude(self) -> Any:
        """Rotation angles in radians, in ``[0, pi]``: a float or an array of ``shape``."""
        a = _kinema.quat_angle(self._quat)[:, 0]
        return float(a[0]) if self.single else a.reshape(self._shape)

    def approx_equal(
        self, other: Rotation, atol: float | None = None, *, degrees: bool = False
    ) -> Any:
        """Whether each rotation is less than ``atol`` from ``other`` (the angle of
        ``other * self.inv()``; q and -q are equal), as scipy's ``approx_equal``.

        ``atol`` is in radians, or degrees when ``degrees``; None means 1e-8 radians (and
        warns when ``degrees`` is set, which then has nothing to apply to).
        """
        if atol is None:
            if degrees:
                warnings.warn(
                    "atol: not given, so degrees has no effect; using 1e-8 rad", stacklevel=2
                )
            tol = 1e-8
        else:
            tol = np.deg2rad(_float(atol, "atol")) if degrees else _float(atol, "atol")
        return (other * self.inv()).magnitude() < tol

    def mean(self, weights: Any = None, *, axis: int | tuple[int, ...] | None = None) -> Self:
        """The weighted mean rotation (Markley et al. 2007, eq. 13): the rotation minimising
        the weighted sum of squared chordal (Frobenius) distances of the matrices.

        ``weights`` (non-negative, broadcast to ``shape``; all equal when None) weigh the
        rotations; ``axis`` (an int or a tuple) names the axes averaged over, all of them by
        default (the result is then single), as numpy's reductions.
        """
        shape = self._shape or (1,)
        if math.prod(shape) == 0:
            raise ValueError("self: the mean of an empty stack is undefined")
        nd = len(shape)
        axes: Any = tuple(range(nd)) if axis is None else axis
        axes = (axes,) if np.ndim(axes) == 0 else axes
        if not isinstance(axes, tuple) or not all(
            isinstance(a, (int, np.integer)) and not isinstance(a, bool) and -nd <= a < nd
            for a in axes
        ):
            raise ValueError(f"axis: expected None, or ints in [-{nd}, {nd})")
        over = sorted({int(a) % nd for a in axes})
        keep = [a for a in range(nd) if a not in over]
        order = [*keep, *over]
        size = math.prod(shape[a] for a in over)
        q = self._quat.reshape((*shape, 4)).transpose((*order, nd))
        w = np.ones(shape) if weights is None else np.asarray(weights, dtype=np.float64)
        try:
            w = np.broadcast_to(w, shape)
        except ValueError:
            raise ValueError(f"weights: shape {w.shape} does not broadcast to {shape}") from None
        m = _kinema.quat_mean(
            np.ascontiguousarray(q.reshape(-1, 4)),
            np.ascontiguousarray(w.transpose(order).reshape(-1, 1)),
            size,
        )
        return self._make(m, tuple(shape[a] for a in keep) if self._shape else ())

    def reduce(
        self,
        left: Rotation | None = None,
        right: Rotation | None = None,
        return_indices: bool = False,
    ) -> Any:
        """The rotations ``l * p * r`` of smallest angle, ``l`` from ``left`` and ``r`` from
        ``right`` (None: the identity alone), e.g. an orientation reduced by the symmetry
        groups of two crystals (:meth:`create_group`). With ``return_indices`` also the indices
        of the chosen ``l`` and ``r`` (None for an absent side), arrays of ``shape``."""
        none = np.zeros((0, 4))
        for name, g in (("left", left), ("right", right)):
            if g is not None and not isinstance(g, Rotation):
                raise ValueError(f"{name}: expected a Rotation or None")
        out = _kinema.quat_reduce(
            self._quat,
            none if left is None else left._quat,
            none if right is None else right._quat,
        )
        rot = self._make(np.ascontiguousarray(out[:, :4]), self._shape)
        if not return_indices:
            return rot
        li, ri = (self._out(out[:, k].astype(np.intp)) for k in (4, 5))
        return rot, None if left is None else li, None if right is None else ri

    # ------------------------------------------------------------------ container
    def __repr__(self) -> str:
        if self.single:
            return f"Rotation.from_quat({self._quat[0].tolist()})"
        return f"Rotation(<shape {self._shape}>)"

    def __getstate__(self) -> tuple[np.ndarray, tuple[int, ...]]:
        return self._quat, self._shape

    def __setstate__(self, state: Any) -> None:
        """Unpickle, validating: quaternions ``(prod(shape), 4)`` of unit length (to 1e-9)
        and the shape, a tuple of non-negative ints; anything else (a damaged or foreign
        pickle) raises ValueError."""
        quat, shape = self._state(state, "quaternions")
        norms = np.linalg.norm(quat, axis=1)
        bad = np.flatnonzero(~(np.abs(norms - 1.0) <= 1e-9))
        if bad.size:
            raise ValueError(f"state: quaternion {bad[0]} is not unit (norm {norms[bad[0]]})")
        self._quat, self._shape = quat, shape

    def _data(self) -> np.ndarray:
        return self._quat


def _float(value: Any, name: str) -> float:
    """A finite real number, or ValueError naming ``name``."""
    try:
        f = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a real number") from None
    if not math.isfinite(f):
        raise ValueError(f"{name}: must be finite")
    return f


def _broadcast(
    a: np.ndarray, a_shape: tuple[int, ...], b: np.ndarray, b_shape: tuple[int, ...], name: str
) -> tuple[np.ndarray, np.ndarray, tuple[int, ...]]:
    """Rows of ``a`` and ``b`` (leading shapes ``a_shape``, ``b_shape``) broadcast for a
    kernel that pairs rows one to one or one against N; numpy's rules, copying only when
    neither side is one row and the shapes differ."""
    try:
        shape = np.broadcast_shapes(a_shape, b_shape)
    except ValueError:
        raise ValueError(f"{name}: shape {b_shape} does not broadcast against {a_shape}") from None
    if len(a) == 1 or len(b) == 1 or a_shape == b_shape:
        return a, b, shape

    def full(rows: np.ndarray, lead: tuple[int, ...]) -> np.ndarray:
        item = rows.shape[1:]
        return np.ascontiguousarray(
            np.broadcast_to(rows.reshape((*lead, *item)), (*shape, *item)).reshape((-1, *item))
        )

    return full(a, a_shape), full(b, b_shape), shape


def _order(order: object) -> bool:
    """Whether a Davenport ``order`` is intrinsic."""
    if order not in ("e", "extrinsic", "i", "intrinsic"):
        raise ValueError("order: expected 'e'/'extrinsic' or 'i'/'intrinsic'")
    return str(order)[0] == "i"


def _davenport_axes(axes: Any, count: int | None) -> tuple[np.ndarray, tuple[int, ...]]:
    """Davenport axes ``(..., n, 3)`` (or one axis ``(3,)``) as unit rows ``(M, n, 3)`` and
    their leading shape; ``n`` must be ``count`` if given, else 1 to 3."""
    try:
        a = np.asarray(axes, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"axes: cannot convert to a float64 array ({e})") from None
    if a.ndim == 1:
        a = a[None]
    n = a.shape[-2] if a.ndim >= 2 else 0
    if a.shape[-1:] != (3,) or not 1 <= n <= 3 or (count is not None and n != count):
        want = f"{count}, 3)" if count else "n, 3) with n from 1 to 3"
        raise ValueError(f"axes: expected shape (..., {want}, got {a.shape}")
    norms = np.linalg.norm(a, axis=-1, keepdims=True)
    if not (norms > 0).all() or not np.isfinite(norms).all():
        raise ValueError("axes: must be finite and non-zero")
    a = a / norms
    if (np.abs(np.sum(a[..., 1:, :] * a[..., :-1, :], axis=-1)) > 1e-7).any():
        raise ValueError("axes: consecutive axes must be orthogonal")
    return np.ascontiguousarray(a.reshape(-1, n, 3)), a.shape[:-2]


def _lead(n: object, shape: object) -> tuple[int, ...]:
    """The stack shape of ``identity``/``random``: ``()`` (single), ``(n,)`` or ``shape``."""
    if n is not None and shape is not None:
        raise ValueError("n, shape: give at most one of them")
    if shape is None:
        return () if n is None else (_count(n, "n"),)
    dims = (shape,) if isinstance(shape, (int, np.integer)) else shape
    if not isinstance(dims, tuple):
        raise ValueError("shape: expected an int or a tuple of ints")
    return tuple(_count(d, "shape") for d in dims)


def _count(n: object, name: str) -> int:
    if not isinstance(n, (int, np.integer)) or isinstance(n, bool) or n < 0:
        raise ValueError(f"{name}: expected a non-negative integer")
    return int(n)


def _quats(shape: tuple[int, ...], make: Callable[[tuple[int, int]], np.ndarray]) -> np.ndarray:
    """``make((count, 4))`` for a stack of ``shape``; numpy's MemoryError, which names no
    argument, becomes one naming ``n``."""
    count = math.prod(shape)
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
    return Rotation._make(q, () if r0.single and r1.single and single_t else (len(q),))


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
    locked = _kinema.euler_gimbal_lock(_check_seq(seq), a, real(atol, "atol"))[:, 0] != 0.0
    return bool(locked[0]) if single else locked
