"""The container part that :class:`kinema.Rotation` and :class:`kinema.Transform` share: a
stack of items of shape ``_ITEM`` with any leading ``shape`` (``()`` for a single item), kept
as rows ``(prod(shape), *_ITEM)``; ``len``, indexing, assignment and iteration act on the
first axis, as on a numpy array."""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

if TYPE_CHECKING:
    from typing_extensions import Self


class Stack:
    """Base of the stacked value classes; a subclass gives ``_NOUN`` (``"rotation"``),
    ``_ITEM`` (``(4,)``), ``_data()`` (its rows) and ``_make(rows, shape)``."""

    __slots__ = ()

    _NOUN: ClassVar[str]
    _ITEM: ClassVar[tuple[int, ...]]
    _shape: tuple[int, ...]

    if TYPE_CHECKING:

        def _data(self) -> np.ndarray: ...

        @classmethod
        def _make(cls, rows: np.ndarray, shape: tuple[int, ...]) -> Self: ...

    @property
    def single(self) -> bool:
        """True for a single item (``shape == ()``), False for a stack (even of length 1)."""
        return self._shape == ()

    @property
    def shape(self) -> tuple[int, ...]:
        """The stack's shape, ``()`` for a single item."""
        return self._shape

    def __len__(self) -> int:
        if self.single:
            raise TypeError(f"a single {self._NOUN} has no len()")
        return self._shape[0]

    def __bool__(self) -> bool:
        """Always true, even for an empty stack (as scipy): a stack is a value, not a
        container whose emptiness tests false."""
        return True

    def __getitem__(self, index: Any) -> Self:
        if self.single:
            raise TypeError(f"a single {self._NOUN} cannot be indexed")
        k = len(self._ITEM)
        items = self._data().reshape((*self._shape, *self._ITEM))[index]
        if items.ndim < k or items.shape[items.ndim - k :] != self._ITEM:
            raise IndexError(f"index: too many indices for the {self._NOUN} stack")
        return self._make(np.array(items.reshape(-1, *self._ITEM)), items.shape[:-k])

    def __setitem__(self, index: Any, value: Self) -> None:
        """Replace the items at ``index`` (first axes, as numpy) by ``value`` (broadcast)."""
        if self.single:
            raise TypeError(f"a single {self._NOUN} does not support item assignment")
        if not (isinstance(value, Stack) and value._NOUN == self._NOUN):
            raise TypeError(f"value: expected a {self._NOUN.capitalize()}")
        self._data().reshape((*self._shape, *self._ITEM))[index] = value._out(value._data())

    def __iter__(self) -> Iterator[Self]:
        if self.single:
            raise TypeError(f"a single {self._NOUN} is not iterable")
        return (self[i] for i in range(self._shape[0]))

    def _out(self, arr: np.ndarray) -> np.ndarray:
        """Kernel rows ``(N, *item)`` as ``(*shape, *item)``."""
        return arr.reshape((*self._shape, *arr.shape[1:]))

    @classmethod
    def _state(cls, state: Any, rows: str) -> tuple[np.ndarray, tuple[int, ...]]:
        """The rows (as float64) and shape of a pickled ``(rows, shape)`` after checking their
        form: ``shape`` a tuple of non-negative ints and the rows ``(prod(shape), *_ITEM)``;
        else ValueError naming ``rows`` (e.g. ``"quaternions"``). Values are the caller's to
        check."""
        if not (
            isinstance(state, tuple)
            and len(state) == 2
            and isinstance(state[1], tuple)
            and all(isinstance(d, int) and not isinstance(d, bool) and d >= 0 for d in state[1])
        ):
            raise ValueError(f"state: expected ({rows}, shape), not a kinema pickle")
        data = np.ascontiguousarray(state[0], dtype=np.float64)
        if data.shape != (math.prod(state[1]), *cls._ITEM):
            item = ", ".join(map(str, cls._ITEM))
            raise ValueError(
                f"state: {rows} must have shape (prod(shape), {item}), got {data.shape}"
            )
        return data, state[1]
