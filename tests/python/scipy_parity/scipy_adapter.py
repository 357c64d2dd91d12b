"""Run scipy's own tests of ``scipy.spatial.transform`` against kinema.

scipy's installed test files are imported at test time (nothing of them is copied into this
repository) and their module globals ``Rotation``, ``Slerp``, ``RotationSpline`` and
``RigidTransform`` are replaced by the classes below. These only translate conventions:
scipy's scalar-last quaternion order is the default here, scipy's keyword names (``num``,
``order``) map onto kinema's, the interpolators are kinema's ``RotationTrack``, and error
messages are checked by their exception type only (kinema's messages follow its own wording
convention: the argument's name first, never the input; see ``_Wording``). No numerics live
here.

The expected failures are listed, with their reasons, in one place: the table "scipy parity"
of ``docs/rotations.md``, read by ``conftest.py``.
"""

from __future__ import annotations

import importlib.util
import pathlib
import warnings
from types import ModuleType
from typing import Any

import pytest

import kinema
from kinema.anim import RotationTrack


class Rotation(kinema.Rotation):
    """kinema's Rotation with scipy's default quaternion order ``(x, y, z, w)``."""

    __slots__ = ()

    def __init__(
        self, quat: Any, normalize: bool = True, copy: bool = True, *, scalar_first: bool = False
    ) -> None:
        super().__init__(quat, scalar_first=scalar_first)

    @classmethod
    def from_quat(cls, quat: Any, *, scalar_first: bool = False) -> Rotation:  # type: ignore[override]
        return super().from_quat(quat, scalar_first=scalar_first)  # type: ignore[return-value]

    def as_quat(self, canonical: bool = False, *, scalar_first: bool = False) -> Any:  # type: ignore[override]
        return super().as_quat(canonical=canonical, scalar_first=scalar_first)

    @classmethod
    def identity(cls, num: int | None = None, *, shape: Any = None) -> Rotation:  # type: ignore[override]
        return super().identity(num, shape=shape)  # type: ignore[return-value]

    @classmethod
    def random(  # type: ignore[override]
        cls, num: int | None = None, rng: Any = None, *, shape: Any = None, random_state: Any = None
    ) -> Rotation:
        # random_state is scipy's older name of rng.
        return super().random(num, rng=rng if random_state is None else random_state, shape=shape)  # type: ignore[return-value]

    def as_euler(self, seq: str, degrees: bool = False, *, suppress_warnings: bool = False) -> Any:  # type: ignore[override]
        # kinema silences its GimbalLockWarning through the warnings filter.
        with warnings.catch_warnings():
            if suppress_warnings:
                warnings.simplefilter("ignore", kinema.GimbalLockWarning)
            return super().as_euler(seq, degrees=degrees)

    def as_davenport(  # type: ignore[override]
        self, axes: Any, order: str, degrees: bool = False, *, suppress_warnings: bool = False
    ) -> Any:
        with warnings.catch_warnings():
            if suppress_warnings:
                warnings.simplefilter("ignore", kinema.GimbalLockWarning)
            return super().as_davenport(axes, order, degrees=degrees)


def _plain(r: Any) -> Any:
    """The adapter's rotations as kinema's own class (scalar-first default), for kinema code
    that reads ``as_quat()``; anything else unchanged, for kinema to refuse."""
    if isinstance(r, kinema.Rotation):
        return kinema.Rotation.from_quat(r.as_quat(scalar_first=True))
    return r


def _wrap(r: kinema.Rotation) -> Rotation:
    """A kinema rotation as the adapter's class (same quaternions)."""
    return Rotation.from_quat(r.as_quat(), scalar_first=True)


class Slerp:
    """scipy's ``Slerp(times, rotations)``: kinema's ``RotationTrack`` with ``"slerp"``."""

    def __init__(self, times: Any, rotations: kinema.Rotation) -> None:
        self._track = RotationTrack(times, _plain(rotations), "slerp")

    def __call__(self, times: Any) -> Rotation:
        return _wrap(self._track(times))

    def __getattr__(self, name: str) -> Any:
        return getattr(self._track, name)


class RotationSpline:
    """scipy's ``RotationSpline(times, rotations)``: kinema's ``RotationTrack`` with
    ``"spline"``; ``order`` 1 and 2 are its angular velocity and acceleration."""

    def __init__(self, times: Any, rotations: kinema.Rotation) -> None:
        self._track = RotationTrack(times, _plain(rotations), "spline")

    def __call__(self, times: Any, order: int = 0) -> Any:
        if order == 1:
            return self._track.angular_velocity(times, frame="body")
        if order == 2:
            return self._track.angular_acceleration(times, frame="body")
        if order != 0:
            raise ValueError("order must be 0, 1 or 2")
        return _wrap(self._track(times))

    def __getattr__(self, name: str) -> Any:
        return getattr(self._track, name)


class RigidTransform(kinema.Transform):
    """kinema's Transform with scipy's constructor ``RigidTransform(matrix)``, scalar-last
    dual quaternions and rotations in scipy's quaternion order."""

    __slots__ = ()

    def __init__(self, matrix: Any, normalize: bool = True, copy: bool = True) -> None:
        t = kinema.Transform.from_matrix(matrix)
        self._matrix, self._shape = t._matrix, t.shape

    @classmethod
    def identity(cls, num: int | None = None, *, shape: Any = None) -> RigidTransform:  # type: ignore[override]
        return super().identity(num, shape=shape)  # type: ignore[return-value]

    @classmethod
    def from_dual_quat(cls, dual_quat: Any, *, scalar_first: bool = False) -> RigidTransform:  # type: ignore[override]
        return super().from_dual_quat(dual_quat, scalar_first=scalar_first)  # type: ignore[return-value]

    def as_dual_quat(self, *, scalar_first: bool = False) -> Any:  # type: ignore[override]
        return super().as_dual_quat(scalar_first=scalar_first)

    @property
    def rotation(self) -> Rotation:  # type: ignore[override]
        return _wrap(super().rotation)

    def as_components(self) -> tuple[Any, Rotation]:  # type: ignore[override]
        return self.translation, self.rotation


class _Wording:
    """scipy's test modules see this in place of ``pytest``: ``raises`` and ``warns`` check the
    exception or warning type, not scipy's wording (``match=``), which is a convention of
    scipy's; everything else is pytest's own."""

    @staticmethod
    def raises(expected: Any, *args: Any, match: Any = None, **kwargs: Any) -> Any:
        return pytest.raises(expected, *args, **kwargs)

    @staticmethod
    def warns(expected: Any, *args: Any, match: Any = None, **kwargs: Any) -> Any:
        return pytest.warns(expected, *args, **kwargs)

    def __getattr__(self, name: str) -> Any:
        return getattr(pytest, name)


ADAPTED = {
    "Rotation": Rotation,
    "Slerp": Slerp,
    "RotationSpline": RotationSpline,
    "RigidTransform": RigidTransform,
}


def load(filename: str) -> dict[str, Any]:
    """The test functions, classes and fixtures of scipy's installed
    ``scipy/spatial/transform/tests/<filename>``, with the adapted classes swapped in.

    Skips the calling module when scipy or its test files are not installed.
    """
    transform = pytest.importorskip("scipy.spatial.transform")
    path = pathlib.Path(transform.__file__).parent / "tests" / filename
    if not path.is_file():
        pytest.skip(f"scipy's {filename} is not installed", allow_module_level=True)
    spec = importlib.util.spec_from_file_location(f"scipy_parity_{path.stem}", path)
    assert spec is not None and spec.loader is not None
    module: ModuleType = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    for name, cls in ADAPTED.items():
        if hasattr(module, name):
            setattr(module, name, cls)
    if hasattr(module, "pytest"):
        module.pytest = _Wording()
    return {
        k: v
        for k, v in vars(module).items()
        if k.startswith(("test", "Test"))
        or k == "pytestmark"
        or hasattr(v, "_fixture_function_marker")
        or type(v).__name__ == "FixtureFunctionDefinition"
    }
