"""Homogeneous 4x4 transforms ``M = T R S`` (see :class:`Transform`) with the operations of
scipy's ``RigidTransform``, built on :class:`kinema.Rotation`; the numerics run in the Rust
core (``kinema._kinema``, ``src/rotation/transform.rs`` and ``src/rotation/screw.rs``)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from kinema import _kinema
from kinema._array import as_stack
from kinema._stack import Stack
from kinema.rotation import Rotation, _broadcast, _float, _lead

__all__ = ["Transform"]


class Transform(Stack):
    """One homogeneous 4x4 transform or a stack of any shape, acting on column vectors.

    ``Transform(rotation, translation, scale)`` builds ``M = T R S``: scale along the body
    axes (a scalar or per-axis ``(..., 3)``), then rotate, then translate; the shapes of the
    three broadcast. Without a scale the transform is rigid, and every operation of scipy's
    ``RigidTransform`` is here: components, exponential coordinates, dual quaternions,
    powers, means. Any affine matrix with last row ``(0, 0, 0, 1)`` is accepted by
    :meth:`from_matrix`; the rigid-only operations refuse a linear part that is not a
    rotation. ``t1 * t2`` applies ``t2`` first. Lengths are in the caller's units, angles in
    radians, quaternions scalar-first unless ``scalar_first=False``.
    """

    __slots__ = ("_matrix", "_shape")
    _NOUN = "transform"
    _ITEM = (4, 4)

    _matrix: np.ndarray
    _shape: tuple[int, ...]

    def __init__(
        self,
        rotation: Rotation | None = None,
        translation: Any = None,
        scale: Any = None,
    ) -> None:
        self._matrix, self._shape = _parts(rotation, translation, scale)

    @classmethod
    def _make(cls, matrix: np.ndarray, shape: tuple[int, ...]) -> Transform:
        t = object.__new__(cls)
        t._matrix = matrix
        t._shape = tuple(shape)
        return t

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_matrix(cls, matrix: Any) -> Transform:
        """Transforms from affine matrices ``(..., 4, 4)`` (finite, last row 0, 0, 0, 1)."""
        m, shape = as_stack(matrix, "matrix", (4, 4))
        return cls._make(_kinema.transform_validate(m), shape)

    @classmethod
    def from_rotation(cls, rotation: Rotation) -> Transform:
        """Pure rotations: ``Transform(rotation)``."""
        return cls._make(*_parts(rotation, None, None))

    @classmethod
    def from_translation(cls, translation: Any) -> Transform:
        """Pure translations ``(..., 3)``: ``Transform(translation=translation)``."""
        return cls._make(*_parts(None, translation, None))

    @classmethod
    def from_components(cls, translation: Any, rotation: Rotation) -> Transform:
        """Rotate, then translate (scipy's argument order): ``Transform(rotation, translation)``."""
        return cls._make(*_parts(rotation, translation, None))

    @classmethod
    def from_exp_coords(cls, exp_coords: Any) -> Transform:
        """Rigid transforms from exponential coordinates ``(..., 6)`` of SE(3): the rotation
        vector (rad) then the twist's translational part (Lynch & Park 2017, eq. 3.88)."""
        x, shape = as_stack(exp_coords, "exp_coords", (6,))
        return cls._make(_kinema.transform_from_exp_coords(x), shape)

    @classmethod
    def from_dual_quat(cls, dual_quat: Any, *, scalar_first: bool = True) -> Transform:
        """Rigid transforms from dual quaternions ``(..., 8)``: real part then dual part, each
        scalar-first (``scalar_first=False``: scalar-last). Normalised: both halves divided by
        the real part's norm, the dual part made orthogonal to the real part (Kavan et al.
        2007); a zero real part raises ValueError."""
        d, shape = as_stack(dual_quat, "dual_quat", (8,))
        if not scalar_first:
            d = np.ascontiguousarray(d[:, [3, 0, 1, 2, 7, 4, 5, 6]])
        return cls._make(_kinema.transform_from_dual_quat(d), shape)

    @classmethod
    def identity(
        cls, n: int | None = None, *, shape: int | tuple[int, ...] | None = None
    ) -> Transform:
        """The identity: single if ``n`` and ``shape`` are None, else a stack of ``n`` or of
        ``shape`` (give one of them)."""
        lead = _lead(n, shape)
        return cls._make(np.tile(np.eye(4), (math.prod(lead), 1, 1)), lead)

    @classmethod
    def concatenate(cls, transforms: Transform | Sequence[Transform]) -> Transform:
        """One stack holding all of ``transforms`` in order, joined along the first axis (a
        single transform counts as a stack of one); one Transform gives a copy."""
        if isinstance(transforms, Transform):
            return cls._make(transforms._matrix.copy(), transforms._shape)
        if not all(isinstance(t, Transform) for t in transforms):
            raise TypeError("transforms: every item must be a Transform")
        if not transforms:
            return cls._make(np.zeros((0, 4, 4)), (0,))
        try:
            m = np.concatenate(
                [
                    t._matrix.reshape((*t._shape, 4, 4) if t._shape else (1, 4, 4))
                    for t in transforms
                ]
            )
        except ValueError:
            raise ValueError("transforms: stacks must agree in every axis but the first") from None
        return cls._make(np.ascontiguousarray(m.reshape(-1, 4, 4)), m.shape[:-2])

    # ------------------------------------------------------------------ conversion
    def as_matrix(self) -> np.ndarray:
        """The matrices ``(*shape, 4, 4)``."""
        return self._out(self._matrix.copy())

    def as_components(self) -> tuple[np.ndarray, Rotation]:
        """``(translation, rotation)`` with ``self == from_components(translation, rotation)``;
        rigid transforms only (else ValueError)."""
        return self.translation, self.rotation

    def as_exp_coords(self) -> np.ndarray:
        """Exponential coordinates ``(*shape, 6)``, rotation angle in ``[0, pi]``, the inverse
        of :meth:`from_exp_coords` (Barfoot 2017, eq. 7.95); rigid transforms only."""
        return self._out(_kinema.transform_to_exp_coords(self._matrix))

    def as_dual_quat(self, *, scalar_first: bool = True) -> np.ndarray:
        """Unit dual quaternions ``(*shape, 8)``, real part ``w >= 0``; rigid transforms only."""
        d = _kinema.transform_to_dual_quat(self._matrix)
        return self._out(d if scalar_first else d[:, [1, 2, 3, 0, 5, 6, 7, 4]])

    @property
    def rotation(self) -> Rotation:
        """The rotations, of ``shape``; rigid transforms only (else ValueError)."""
        return Rotation.from_matrix(self._out(self._matrix[:, :3, :3]))

    @property
    def translation(self) -> np.ndarray:
        """The translation columns ``(*shape, 3)``."""
        return self._out(np.ascontiguousarray(self._matrix[:, :3, 3]))

    # ------------------------------------------------------------------ operations
    def apply(self, vector: Any, inverse: bool = False) -> np.ndarray:
        """Transform points ``(..., 3)``, ``M [p; 1]`` (``inverse``: by the inverses); the
        transforms' shape and the points' leading shape broadcast (numpy rules)."""
        m = self.inv()._matrix if inverse else self._matrix
        return self._apply(m, vector, "vector", directions=False)

    def apply_directions(self, vectors: Any) -> np.ndarray:
        """Transform direction vectors ``(..., 3)``, ``M [d; 0]`` (no translation), shapes
        broadcast as :meth:`apply`. For surface normals under non-uniform scale use the inverse
        transpose instead."""
        return self._apply(self._matrix, vectors, "vectors", directions=True)

    def _apply(self, matrix: np.ndarray, values: Any, name: str, *, directions: bool) -> np.ndarray:
        p, p_shape = as_stack(values, name, (3,))
        m, p, shape = _broadcast(matrix, self._shape, p, p_shape, name)
        return _kinema.transform_apply(m, p, directions).reshape((*shape, 3))

    def __mul__(self, other: Transform) -> Transform:
        """Composition: ``(t1 * t2).apply(p) == t1.apply(t2.apply(p))``; shapes broadcast."""
        if not isinstance(other, Transform):
            return NotImplemented
        a, b, shape = _broadcast(self._matrix, self._shape, other._matrix, other._shape, "other")
        return self._make(_kinema.transform_compose(a, b), shape)

    def __pow__(self, n: float, modulus: None = None) -> Transform:
        """The transform ``n`` times: the same screw axis, ``n`` times the exponential
        coordinates (``0`` the identity, ``-1`` the inverse, ``0.5`` half the screw motion)."""
        if modulus is not None:
            raise NotImplementedError("modulus not supported")
        if np.size(n) != 1:
            raise ValueError("n: Array exponent must be a scalar (one element)")
        p = _float(np.reshape(n, ()), "n")
        if p == 0:
            return self.identity(shape=self._shape) if self._shape else self.identity()
        if p == 1:
            return self._make(self._matrix.copy(), self._shape)
        if p == -1:
            return self.inv()
        x = p * _kinema.transform_to_exp_coords(self._matrix)
        return self._make(_kinema.transform_from_exp_coords(x), self._shape)

    def inv(self) -> Transform:
        """The inverse transforms; a singular linear part raises ValueError."""
        return self._make(_kinema.transform_invert(self._matrix), self._shape)

    def mean(self, weights: Any = None, axis: int | tuple[int, ...] | None = None) -> Transform:
        """The weighted mean of rigid transforms: the rotations' chordal mean
        (:meth:`Rotation.mean`, Markley et al. 2007) and the weighted mean translation, over
        ``axis`` (all axes by default); ``weights`` non-negative, of ``shape``."""
        if weights is not None:
            w = np.asarray(weights, dtype=np.float64)
            if w.shape != self._shape:
                raise ValueError(f"weights: expected shape {self._shape}, got {w.shape}")
            if np.any(w < 0):
                raise ValueError("weights: must be non-negative")
        rot = self.rotation.mean(weights, axis=axis)
        shape = self._shape or (1,)
        nd = len(shape)
        over = (
            tuple(range(nd)) if axis is None else tuple({int(a) % nd for a in np.atleast_1d(axis)})
        )
        w = np.ones(shape) if weights is None else np.broadcast_to(weights, shape)
        t = self._matrix[:, :3, 3].reshape((*shape, 3))
        total = np.sum(w, axis=over)[..., None]
        mean_t = np.sum(t * w[..., None], axis=over) / total
        return self._make(*_parts(rot, mean_t, None))

    # ------------------------------------------------------------------ container
    def __repr__(self) -> str:
        if self.single:
            return f"Transform.from_matrix({self._matrix[0].tolist()})"
        return f"Transform(<shape {self._shape}>)"

    def __getstate__(self) -> tuple[np.ndarray, tuple[int, ...]]:
        return self._matrix, self._shape

    def __setstate__(self, state: Any) -> None:
        """Unpickle, validating as :meth:`from_matrix` does: affine ``(prod(shape), 4, 4)``
        with last row ``(0, 0, 0, 1)`` and finite entries, and the shape, a tuple of
        non-negative ints; else ValueError."""
        matrix, shape = self._state(state, "matrices")
        self._matrix, self._shape = _kinema.transform_validate(matrix), shape

    def _data(self) -> np.ndarray:
        return self._matrix


def _parts(rotation: Any, translation: Any, scale: Any) -> tuple[np.ndarray, tuple[int, ...]]:
    """The matrices ``(N, 4, 4)`` and shape of ``M = T R S``, the three shapes broadcast."""
    rot = Rotation.identity() if rotation is None else rotation
    if not isinstance(rot, Rotation):
        raise ValueError(f"rotation: expected a Rotation, got {type(rot).__name__}")
    t, t_shape = as_stack(
        (0.0, 0.0, 0.0) if translation is None else translation, "translation", (3,)
    )
    s_arr = np.asarray(1.0 if scale is None else scale)
    s, s_shape = as_stack(
        np.repeat(s_arr[..., None], 3, -1) if s_arr.ndim == 0 else s_arr, "scale", (3,)
    )
    try:
        shape = np.broadcast_shapes(rot.shape, t_shape, s_shape)
    except ValueError:
        raise ValueError(
            "translation, scale: shapes do not broadcast against the rotation"
        ) from None

    def full(rows: np.ndarray, lead: tuple[int, ...]) -> np.ndarray:
        """One row stays one (the kernel broadcasts it); else the rows of ``shape``."""
        if len(rows) == 1 or lead == shape:
            return rows
        wide = np.broadcast_to(rows.reshape((*lead, -1)), (*shape, rows.shape[-1]))
        return np.ascontiguousarray(wide.reshape((-1, rows.shape[-1])))

    q, t, s = full(rot._quat, rot.shape), full(t, t_shape), full(s, s_shape)
    return _kinema.transform_from_parts(q, t, s), shape
