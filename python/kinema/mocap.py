"""Acclaim ASF/AMC motion capture: read skeletons and motions, compute forward kinematics.

``read_asf(path)`` returns a :class:`Skeleton`; ``read_amc(path, skeleton)`` a motion;
``skeleton.forward_kinematics(motion)`` gives joint positions ``(frames, joints, 3)`` (file
units; ``skeleton.metres_per_unit`` is the CMU reading of ``:units length``, never applied
silently) and orientations ``(frames, joints, 4)`` (``w, x, y, z``). Conventions (bone frames
``C`` from ``axis``, ``R = R_parent C M C⁻¹``) are in ``kinema::mocap``'s docs and
docs/mocap.md. Malformed files raise :class:`kinema.ParseError` with the file and line.

``write_asf`` / ``write_amc`` write them back (read → write → read is the identity).
``skeleton.resample(motion, from_rate, to_rate)`` changes the frame rate (slerp for three-dof
rotations; CMU clips are captured at 120 Hz, which the files do not store);
``skeleton.within_limits(motion)`` checks the ASF limits per frame; ``motion.slice(a, b)``.

Not implemented yet: BVH, inverse kinematics and motion editing.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from kinema import _kinema

__all__ = ["Skeleton", "bone_length_error", "read_amc", "read_asf", "write_amc", "write_asf"]

Skeleton = _kinema.AsfSkeleton
"""An Acclaim skeleton (joint_names, parents, bone_lengths, length_unit, metres_per_unit,
forward_kinematics(motion))."""


def _text(path: str | os.PathLike[str]) -> str:
    with open(path, "rb") as f:
        return f.read().decode("utf-8", errors="replace")


def read_asf(path: str | os.PathLike[str]) -> Any:
    """Read an ASF skeleton file."""
    return _kinema.mocap_parse_asf(_text(path), os.fspath(path))


def read_amc(path: str | os.PathLike[str], skeleton: Any) -> Any:
    """Read an AMC motion file for ``skeleton``; ``.frames`` is its frame count."""
    if not isinstance(skeleton, _kinema.AsfSkeleton):
        raise ValueError("skeleton: expected a skeleton from kinema.mocap.read_asf")
    return _kinema.mocap_parse_amc(_text(path), os.fspath(path), skeleton)


def bone_length_error(skeleton: Any, positions: np.ndarray) -> float:
    """Largest relative deviation of any bone's length from its rest length over all frames of
    forward-kinematics ``positions``."""
    parents = np.asarray(skeleton.parents[1:])
    d = np.linalg.norm(positions[:, 1:] - positions[:, parents], axis=2)
    lengths = np.asarray(skeleton.bone_lengths)
    return float(np.max(np.abs(d - lengths) / np.maximum(lengths, 1.0)))


def write_asf(skeleton: Any, path: str | os.PathLike[str]) -> None:
    """Write ``skeleton`` as an ASF file."""
    with open(path, "w", encoding="utf-8") as f:
        f.write(_kinema.mocap_write_asf(skeleton))


def write_amc(skeleton: Any, motion: Any, path: str | os.PathLike[str]) -> None:
    """Write ``motion`` (of ``skeleton``) as an AMC file."""
    with open(path, "w", encoding="utf-8") as f:
        f.write(_kinema.mocap_write_amc(skeleton, motion))
