"""Argument checking shared by every Python-facing function.

Array-likes are converted once to C-contiguous float64; shapes are checked with messages
that name the argument and the shape received (see CONVENTIONS: "Arrays and the Python
boundary").
"""

from __future__ import annotations

import numbers

import numpy as np


def real(value: object, name: str) -> float:
    """``value`` (a Python or numpy real number, or a 0-d array of one) as a ``float``;
    anything else raises ``TypeError`` naming ``name`` (never quoting the value)."""
    if type(value) is float:
        return value  # the usual case, without the ABC check (1.7 µs -> 0.1 µs a call)
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value.item()
    if not isinstance(value, numbers.Real):
        raise TypeError(f"{name}: expected a real number, got {type(value).__name__}")
    return float(value)


def as_batch(value: object, name: str, row_shape: tuple[int, ...]) -> tuple[np.ndarray, bool]:
    """Convert ``value`` to a C-contiguous float64 batch of shape ``(N, *row_shape)``.

    A single item of shape ``row_shape`` is accepted too and becomes a batch of one.
    Returns the batch and whether the input was a single item.

    Raises ValueError naming ``name`` for values that cannot be converted to float64 or that
    have another shape. Finiteness is checked by the Rust kernels, which name the item.
    """
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{name}: cannot convert to a float64 array ({e})") from None
    if arr.shape == row_shape:
        return np.ascontiguousarray(arr.reshape((1, *row_shape))), True
    if arr.ndim == len(row_shape) + 1 and arr.shape[1:] == row_shape:
        return np.ascontiguousarray(arr), False
    expected = ", ".join(str(d) for d in row_shape)
    raise ValueError(f"{name}: expected shape ({expected}) or (N, {expected}), got {arr.shape}")


def as_stack(
    value: object, name: str, row_shape: tuple[int, ...]
) -> tuple[np.ndarray, tuple[int, ...]]:
    """Convert ``value`` of shape ``(*lead, *row_shape)`` (any number of leading axes) to a
    C-contiguous float64 batch ``(prod(lead), *row_shape)``; returns it and ``lead``.

    Raises ValueError naming ``name`` for values that cannot be converted to float64 or whose
    trailing axes are not ``row_shape``.
    """
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{name}: cannot convert to a float64 array ({e})") from None
    k = len(row_shape)
    if arr.ndim < k or arr.shape[arr.ndim - k :] != row_shape:
        expected = ", ".join(str(d) for d in row_shape)
        raise ValueError(f"{name}: expected shape (..., {expected}), got {arr.shape}")
    lead = arr.shape[: arr.ndim - k]
    return np.ascontiguousarray(arr.reshape((-1, *row_shape))), lead


def as_scalars(value: object, name: str) -> tuple[np.ndarray, bool]:
    """Convert a scalar or 1-D array-like to a float64 column ``(N, 1)``; see :func:`as_batch`."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{name}: cannot convert to a float64 array ({e})") from None
    if arr.ndim == 0:
        return arr.reshape(1, 1), True
    if arr.ndim == 1:
        return np.ascontiguousarray(arr.reshape(-1, 1)), False
    raise ValueError(f"{name}: expected a scalar or shape (N,), got {arr.shape}")


def as_vector3(value: object, name: str) -> list[float]:
    """One 3-vector as a list of floats, or ValueError naming ``name`` (any other shape)."""
    arr, single = as_batch(value, name, (3,))
    if not single:
        raise ValueError(f"{name}: expected one 3-vector, got shape {arr.shape}")
    return arr[0].tolist()


def as_orientation(value: object, name: str) -> list[float]:
    """A single ``kinema.Rotation`` (or ``None``, the identity) as ``[w, x, y, z]``."""
    from kinema.rotation import Rotation

    if value is None:
        return [1.0, 0.0, 0.0, 0.0]
    if not isinstance(value, Rotation) or not value.single:
        raise ValueError(f"{name}: expected a single kinema.Rotation, got {type(value).__name__}")
    return [float(c) for c in value.as_quat()]
