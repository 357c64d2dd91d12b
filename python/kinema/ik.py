"""Inverse kinematics on Acclaim skeletons (``kinema.mocap.read_asf`` or :func:`chain`).

``solve(skeleton, pose, targets)`` returns a new pose (one frame of values, as
``motion.pose(i)`` gives: root dofs then each bone's dofs, radians and skeleton length units)
that brings each target joint to its target position, or ``(position, orientation)`` with the
orientation a unit quaternion ``(w, x, y, z)`` in world axes, and an :class:`IkReport`
(``converged``, ``error`` in length units, ``orientation_error`` in radians, ``iterations``).

Methods: ``"dls"`` (damped least squares with damping adapted to the smallest singular value,
Nakamura & Hanafusa 1986 / Chiaverini 1997), ``"pseudo_inverse"`` (SVD), ``"transpose"``
(Jacobian transpose, Buss 2004), ``"ccd"`` (cyclic coordinate descent, Wang & Chen 1991) and
``"two_bone"`` (analytic limb IK: one position target on a bone with one rotational dof whose
parent bone has three). Joint limits (the ASF ``limits``) are honoured unless
``joint_limits=False``; ``rest_weight`` and ``limit_weight`` add a null-space objective (stay
near ``rest``, by default the ASF rest pose of zeros; stay away from limits) with ``"dls"`` and
``"pseudo_inverse"``. The root is held fixed unless ``free_root=True``. Equations, sources and
measured accuracy per method: docs/ik.md and the ``kinema::ik`` Rust docs.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from kinema import _kinema
from kinema._array import as_vector3, real

__all__ = ["IkReport", "chain", "jacobian", "solve"]

IkReport = _kinema.IkReport
"""What a solve achieved: ``converged``, ``error`` (largest position error, skeleton length
units), ``orientation_error`` (largest, radians), ``iterations``."""

METHODS = ("dls", "pseudo_inverse", "transpose", "ccd", "two_bone")


def _skeleton(skeleton: object) -> Any:
    if not isinstance(skeleton, _kinema.AsfSkeleton):
        raise ValueError(
            "skeleton: expected a skeleton from kinema.mocap.read_asf or kinema.ik.chain"
        )
    return skeleton


def _pose(value: object, name: str, skeleton: Any) -> np.ndarray:
    try:
        arr = np.ascontiguousarray(value, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{name}: cannot convert to a float64 array ({e})") from None
    if arr.shape != (skeleton.stride,):
        raise ValueError(f"{name}: expected shape ({skeleton.stride},), got {arr.shape}")
    return arr


def _joint(skeleton: Any, name: object, arg: str) -> int:
    names = skeleton.joint_names
    if not isinstance(name, str) or name not in names:
        raise ValueError(f"{arg}: unknown joint {name!r}; the skeleton's joints are {names}")
    return int(names.index(name))


def _quat(value: object) -> list[float]:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"targets: cannot convert an orientation to float64 ({e})") from None
    if arr.shape != (4,):
        raise ValueError(f"targets: an orientation must be (w, x, y, z), got shape {arr.shape}")
    return arr.tolist()


def solve(
    skeleton: Any,
    pose: object,
    targets: Mapping[str, object],
    method: str = "dls",
    joint_limits: bool = True,
    rest_weight: float = 0.0,
    tol: float = 1e-4,
    max_iters: int = 100,
    *,
    limit_weight: float = 0.0,
    rest: object = None,
    free_root: bool = False,
) -> tuple[np.ndarray, Any]:
    """Inverse kinematics: a pose that brings the target joints to their targets.

    ``pose``: the start, one frame of values ``(skeleton.stride,)`` (``motion.pose(i)``, or
    zeros for the rest pose). ``targets``: ``{joint_name: position}`` or
    ``{joint_name: (position, orientation)}``, positions ``(3,)`` in skeleton length units,
    orientations ``(w, x, y, z)`` in world axes. ``tol``: convergence tolerance (length units
    for positions, radians for orientations); ``max_iters``: most Jacobian steps or CCD sweeps.

    Returns ``(new_pose, report)``; only the dofs of bones between the root and a target joint
    change. An unreachable target ends at the closest point found, with
    ``report.converged == False`` and ``report.error`` its distance. Raises ValueError naming
    the argument for bad input (unknown joint, NaN, wrong shapes, a method that cannot serve
    the targets). The solve runs without the GIL.
    """
    sk = _skeleton(skeleton)
    start = _pose(pose, "pose", sk)
    if method not in METHODS:
        raise ValueError(f"method: {method!r} is not one of {', '.join(METHODS)}")
    if not isinstance(targets, Mapping) or not targets:
        raise ValueError(
            "targets: expected a non-empty dict {joint_name: position or (position, orientation)}"
        )
    if not isinstance(max_iters, int | np.integer) or max_iters < 0:
        raise ValueError(f"max_iters: expected a non-negative integer, got {max_iters!r}")
    joints: list[int] = []
    positions: list[list[float]] = []
    orientations: list[list[float] | None] = []
    for name, value in targets.items():
        joints.append(_joint(sk, name, "targets"))
        if isinstance(value, tuple) and len(value) == 2:
            position, orientation = value
            orientations.append(_quat(orientation))
        else:
            position = value
            orientations.append(None)
        positions.append(as_vector3(position, f"targets[{name!r}]"))
    rest_pose = None if rest is None else _pose(rest, "rest", sk)
    return _kinema.ik_solve(
        sk,
        start,
        joints,
        np.array(positions, dtype=np.float64).reshape(-1, 3),
        orientations,
        method,
        bool(joint_limits),
        real(rest_weight, "rest_weight"),
        real(limit_weight, "limit_weight"),
        rest_pose,
        bool(free_root),
        real(tol, "tol"),
        int(max_iters),
    )


def jacobian(
    skeleton: Any,
    pose: object,
    joints: Sequence[str],
    *,
    orientation: bool = False,
    free_root: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """The analytic Jacobian of the joints' world positions (and, with ``orientation``, their
    angular velocities) with respect to the skeleton's dofs at ``pose``.

    Returns ``(J, columns)``: ``J`` of shape ``(3 or 6 per joint, n)`` (position rows in length
    units per radian, then orientation rows in radians per radian), column ``k`` the
    derivative with respect to ``pose[columns[k]]``: every rotational bone dof and, with
    ``free_root``, the root's dofs. Column of a rotation with world axis ``w`` about a joint
    at ``c``: ``w × (p - c)`` and ``w``; zero where the dof does not move the joint.
    """
    sk = _skeleton(skeleton)
    values = _pose(pose, "pose", sk)
    index = [_joint(sk, j, "joints") for j in joints]
    jac, cols = _kinema.ik_jacobian(sk, values, index, bool(orientation), bool(free_root))
    return jac, np.asarray(cols, dtype=np.int64)


def chain(lengths: Sequence[float], dofs: Sequence[str], limits: object = None) -> Any:
    """A serial chain as a skeleton: bone ``i`` (joint ``f"link{i + 1}"``) has length
    ``lengths[i]`` (metres) and rotational dofs ``dofs[i]`` (letters from ``"xyz"``, e.g.
    ``"xyz"`` for a ball joint, ``"z"`` for a hinge, ``""`` for none; ASF order, the first
    letter innermost). At rest (all zeros) the chain lies along +x from the origin; the root is
    fixed there and has no values, so a pose is just the joint angles in bone order
    (``skeleton.stride`` of them). ``limits``: ``(n_dofs, 2)`` radians ``(lo, hi)`` per dof,
    or None for no limits.

    A 7-dof arm: ``chain([0.3, 0.25, 0.1], ["xyz", "z", "xyz"])``.
    """
    lim = None
    if limits is not None:
        try:
            arr = np.asarray(limits, dtype=np.float64)
        except (TypeError, ValueError) as e:
            raise ValueError(f"limits: cannot convert to a float64 array ({e})") from None
        if arr.ndim != 2 or arr.shape[1] != 2:
            raise ValueError(f"limits: expected shape (n_dofs, 2), got {arr.shape}")
        lim = [(float(lo), float(hi)) for lo, hi in arr]
    if isinstance(dofs, str):
        raise ValueError("dofs: expected one string per bone, e.g. ['xyz', 'z']")
    return _kinema.ik_chain([float(x) for x in lengths], [str(d) for d in dofs], lim)
