"""Motion capture (Acclaim ASF/AMC and Biovision BVH): read skeletons and motions, compute
forward kinematics, write them back.

``read_asf(path)`` returns a :class:`Skeleton`; ``read_amc(path, skeleton)`` a motion;
``skeleton.forward_kinematics(motion)`` gives joint positions ``(frames, joints, 3)`` (file
units; ``skeleton.metres_per_unit`` is the CMU reading of ``:units length``, never applied
silently) and orientations ``(frames, joints, 4)`` (``w, x, y, z``). Conventions (bone frames
``C`` from ``axis``, ``R = R_parent C M C⁻¹``) are in ``kinema::mocap``'s docs and
docs/mocap.md. Malformed files raise :class:`kinema.ParseError` with the file and line.

``write_asf`` / ``write_amc`` write them back (read → write → read is the identity).
``motion.frame_rate`` is in Hz (``read_amc(..., frame_rate=120.0)``: AMC files store none;
CMU is 120 Hz). ``motion.resample(to_rate)`` changes the frame rate (slerp for three-dof
rotations; CMU clips are captured at 120 Hz, which the files do not store);
``skeleton.within_limits(x)`` checks the ASF limits of a motion (``(frames,)`` bools), one
pose (``(stride,)`` values: a bool) or a batch of poses (``(N, stride)``: ``(N,)`` bools);
``motion.slice(a, b)``. ``skeleton.length_unit`` and ``skeleton.mass_unit`` keep ``:units``
as read. Bone ``dof`` lines may list ``tx ty tz`` (a slide along the bone frame's axes) and
``l`` (a change of length) besides rotations; forward kinematics applies them.

``read_bvh(path)`` returns ``(skeleton, motion)`` from one BVH file: a :class:`BvhSkeleton`
(``joint_names``, ``parents``, ``offsets``, ``channels``, ``end_sites``, ``frame_time``,
``forward_kinematics(motion)``) and a motion of the same class as ``read_amc``'s (channel
values in file order, rotations in radians, positions in file units). Rotation channels
compose intrinsically in the order listed (``Zrotation Yrotation Xrotation`` is
``Rz @ Ry @ Rx``); position channels replace the matching ``OFFSET`` component. ``write_bvh``
writes them back (read → write → read is the identity); ``asf_to_bvh(skeleton, motion)`` converts
an ASF/AMC clip to a BVH hierarchy and motion (to write with it). Details in docs/mocap.md.

``motion.pose(i)`` is frame ``i`` as a pose (its values), which ``forward_kinematics`` also
accepts (then returning ``(joints, 3)`` and ``(joints, 4)``) and ``kinema.ik.solve`` takes.
Inverse kinematics is in :mod:`kinema.ik`.

Editing (Acclaim and BVH motions; rotations by slerp of each 3-dof joint, shorter arc):
``time_warp(skeleton, motion, times)`` samples at fractional frame positions,
``blend(skeleton, a, b, weight)`` mixes two motions frame by frame (``weight`` the share of
``b``, one or per frame), ``stitch(skeleton, a, b, transition)`` appends ``b`` turned and moved
to continue from ``a`` with a smooth blend over ``transition`` frames, ``warp(skeleton,
motion, {frame: pose})`` bends the motion smoothly through key poses (Witkin & Popović 1995).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from kinema import _kinema
from kinema._array import real

__all__ = [
    "SAMPLE_DIR",
    "BvhSkeleton",
    "Skeleton",
    "asf_to_bvh",
    "blend",
    "bone_length_error",
    "read_amc",
    "read_asf",
    "read_bvh",
    "stitch",
    "time_warp",
    "warp",
    "write_amc",
    "write_asf",
    "write_bvh",
]

SAMPLE_DIR = Path(__file__).resolve().parent / "data"
"""Sample motion shipped with kinema: ``07-walk.asf`` and ``07_05-walk.amc`` (CMU subject 7,
slow walk, 120 Hz; see ``README.md`` in that folder for the source and licence)."""

Skeleton = _kinema.AsfSkeleton
"""An Acclaim skeleton (joint_names, parents, bone_lengths, length_unit, mass_unit,
metres_per_unit, stride, within_limits(motion or poses), forward_kinematics(motion))."""

BvhSkeleton = _kinema.BvhSkeleton
"""A BVH hierarchy (joint_names, parents, offsets, channels, end_sites, frame_time,
forward_kinematics(motion))."""


def _text(path: str | os.PathLike[str]) -> str:
    with open(path, "rb") as f:
        return f.read().decode("utf-8", errors="replace")


def read_asf(path: str | os.PathLike[str]) -> Any:
    """Read an ASF skeleton file."""
    return _kinema.mocap_parse_asf(_text(path), os.fspath(path))


def read_amc(path: str | os.PathLike[str], skeleton: Any, frame_rate: float = 120.0) -> Any:
    """Read an AMC motion file for ``skeleton``; ``.frames`` is its frame count and
    ``.frame_rate`` the ``frame_rate`` given here (Hz): AMC files do not store one, and the
    CMU database was captured at 120 Hz."""
    if not isinstance(skeleton, _kinema.AsfSkeleton):
        raise ValueError("skeleton: expected a skeleton from kinema.mocap.read_asf")
    return _kinema.mocap_parse_amc(
        _text(path), os.fspath(path), skeleton, real(frame_rate, "frame_rate")
    )


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


def read_bvh(path: str | os.PathLike[str]) -> tuple[Any, Any]:
    """Read a BVH file: ``(skeleton, motion)``; ``skeleton.frame_time`` is its Frame Time in
    seconds, ``motion.frames`` its frame count."""
    return _kinema.mocap_parse_bvh(_text(path), os.fspath(path))


def asf_to_bvh(skeleton: Any, motion: Any) -> tuple[Any, Any]:
    """The BVH ``(skeleton, motion)`` of an ASF ``skeleton`` and its ``motion``: a joint
    ``root`` and one per bone at the bone's base, turned as the bone (three rotation channels
    ``Z Y X`` where the bone has rotation dofs), lengths in the ASF's units, at the motion's
    frame rate; forward kinematics agree. :func:`write_bvh` stores them. Bones with
    translation or length dofs raise ``ValueError`` naming ``skeleton``."""
    if not isinstance(skeleton, _kinema.AsfSkeleton):
        raise ValueError("skeleton: expected a skeleton from kinema.mocap.read_asf")
    if not isinstance(motion, _kinema.AmcMotion):
        raise ValueError("motion: expected a motion from kinema.mocap.read_amc")
    return _kinema.mocap_asf_to_bvh(skeleton, motion)


def write_bvh(skeleton: Any, motion: Any, path: str | os.PathLike[str]) -> None:
    """Write ``motion`` (of the BVH ``skeleton``) as a BVH file."""
    if not isinstance(skeleton, _kinema.BvhSkeleton):
        raise ValueError("skeleton: expected a skeleton from kinema.mocap.read_bvh")
    if not isinstance(motion, _kinema.AmcMotion):
        raise ValueError("motion: expected a motion from kinema.mocap.read_bvh")
    text = _kinema.mocap_write_bvh(skeleton, motion)
    with open(path, "w", encoding="utf-8", newline="\n") as f:
        f.write(text)


def _floats(value: Any, name: str) -> list[float]:
    try:
        arr = np.asarray(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{name}: cannot convert to float64 numbers ({e})") from None
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: contains NaN or infinity")
    return arr.tolist()


def time_warp(skeleton: Any, motion: Any, times: Any) -> Any:
    """The motion sampled at fractional frame positions ``times`` (non-decreasing, within
    ``[0, frames - 1]``), one frame per entry: slow motion, speed-ups, any time warp."""
    return _kinema.mocap_time_warp(skeleton, motion, _floats(times, "times"))


def blend(skeleton: Any, a: Any, b: Any, weight: Any) -> Any:
    """Frame-by-frame blend of motions ``a`` and ``b`` of equal length; ``weight`` in [0, 1]
    is the share of ``b``: one number, or one per frame (a ramp makes a transition)."""
    return _kinema.mocap_blend(skeleton, a, b, _floats(weight, "weight"))


def stitch(skeleton: Any, a: Any, b: Any, transition: int = 0) -> Any:
    """``b`` after ``a``: turned about +Y and moved on the ground so that it starts with the
    heading and position of ``a``'s frame where the transition starts (its last frame when
    ``transition`` is 0), the last ``transition`` frames of ``a`` blended
    into the first of ``b`` (smoothstep ramp). ``a.frames + b.frames - transition`` frames."""
    if not isinstance(transition, (int, np.integer)) or transition < 0:
        raise ValueError(f"transition: expected a non-negative integer, got {transition!r}")
    return _kinema.mocap_stitch(skeleton, a, b, int(transition))


def warp(skeleton: Any, motion: Any, keys: dict[int, Any]) -> Any:
    """Motion warping (Witkin & Popović 1995): the motion plus a smooth displacement that
    makes it pass exactly through ``keys`` ``{frame: pose}`` while keeping its detail. The
    displacement (``pose - frame`` per value; rotation dofs as angle differences in radians,
    wrapped to (-π, π] so that an edit across the ±π seam turns the short way) is zero at the first and last frame unless keyed and is interpolated over frames by the
    monotone cubic of Fritsch & Carlson 1980 (scipy's ``PchipInterpolator``), so it stays
    within the keyed span."""
    if not isinstance(keys, dict) or not keys:
        raise ValueError("keys: expected a non-empty dict {frame: pose}")
    pairs = []
    for frame, pose in keys.items():
        if not isinstance(frame, (int, np.integer)) or frame < 0:
            raise ValueError(f"keys: frame {frame!r} is not a non-negative integer")
        pairs.append((int(frame), _floats(pose, f"keys[{frame}]")))
    return _kinema.mocap_warp(skeleton, motion, pairs)
