"""Homogeneous 4x4 affine transforms ``M = T R S`` (see :class:`Transform`), built on
:class:`kinema.Rotation`; the numerics run in the Rust core (``kinema._kinema``)."""

from __future__ import annotations

from typing import Any

import numpy as np

from kinema import _kinema
from kinema._array import as_batch
from kinema.rotation import Rotation

__all__ = ["Transform"]


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
        self._matrix = _kinema.transform_from_parts(rot.as_quat().reshape(-1, 4), t, s)
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


def _pickled(state: Any, what: str, item: tuple[int, ...]) -> tuple[np.ndarray, bool]:
    """The ``(array (N, *item), single)`` pickle state of a Transform, checked for its types
    and shape (one item when single)."""
    if not (isinstance(state, tuple) and len(state) == 2 and isinstance(state[1], bool)):
        raise ValueError(f"state: expected ({what}, single), not a kinema pickle")
    array = np.ascontiguousarray(state[0], dtype=np.float64)
    if array.shape[1:] != item or array.ndim != 1 + len(item) or (state[1] and len(array) != 1):
        shape = ", ".join(["1" if state[1] else "N", *map(str, item)])
        raise ValueError(f"state: {what} must have shape ({shape}), got {array.shape}")
    return array, state[1]
