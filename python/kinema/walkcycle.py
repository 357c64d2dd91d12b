"""Crowd agents drawn by a motion-captured walk: :class:`WalkCycle` cuts one gait cycle out of
a walking clip (e.g. CMU 07_05, ``kinema.mocap.SAMPLE_DIR``) and poses any number of agents
with it, each at the phase given by the distance it has travelled, turned to its heading and
standing on its position on the ground plane.

Playing the cycle by distance rather than by time is what keeps the feet planted: the clip
advances one stride per stride length walked, so whatever speed ORCA or the social forces
give an agent, the stance foot moves with the ground (the root speed is matched to the clip,
as in motion-graph locomotion: Kovar, Gleicher & Pighin 2002, "Motion graphs", §5, which
also scales a clip's playback by the path's arc length). Agents look natural when they walk
near the clip's own speed: set the crowd's ``preferred_speed`` to :attr:`WalkCycle.speed`.
See docs/crowd.md.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from kinema._array import as_batch, as_scalars

__all__ = ["WalkCycle"]


class WalkCycle:
    """One gait cycle of ``motion`` (a walking clip of ``skeleton``, read by
    :func:`kinema.mocap.read_asf` / :func:`kinema.mocap.read_amc`), in metres.

    The cycle is the span ``[first, first + T)`` frames with ``T`` between ``min_period`` and
    ``max_period`` seconds that repeats best: it minimises the mean squared distance between
    the joints (relative to the root's straight travel) of frames ``f`` and ``f + T``, over
    all ``f`` and ``T``. Attributes: ``period`` (s), ``speed`` (m/s, the root's horizontal
    travel over the cycle divided by the period), ``stride`` (m, the travel over one cycle),
    ``first`` and ``frames`` (the cycle's frames in the clip), ``mismatch`` (m, the root-mean-
    square joint distance between the cycle's two ends), ``joint_names``.
    """

    def __init__(
        self, skeleton: Any, motion: Any, min_period: float = 0.6, max_period: float = 1.6
    ) -> None:
        joints, _ = skeleton.forward_kinematics(motion)
        joints = np.asarray(joints, dtype=float) * skeleton.metres_per_unit
        rate = float(motion.frame_rate)
        lo, hi = round(min_period * rate), round(max_period * rate)
        if not 0 < lo <= hi or hi >= len(joints):
            raise ValueError(
                f"motion: {len(joints)} frames at {rate} Hz hold no cycle of "
                f"{min_period}-{max_period} s (min_period, max_period)"
            )
        # Joints relative to the root's horizontal position: a cycle repeats these.
        local = joints.copy()
        local[:, :, [0, 2]] -= joints[:, :1, [0, 2]]
        best = (np.inf, 0, lo)
        for period in range(lo, hi + 1):
            d2 = ((local[period:] - local[:-period]) ** 2).sum(axis=2).mean(axis=1)
            f = int(np.argmin(d2))
            if d2[f] < best[0]:
                best = (float(d2[f]), f, period)
        mismatch2, first, period = best
        travel = joints[first + period, 0, [0, 2]] - joints[first, 0, [0, 2]]
        self.first, self.frames = first, period
        self.period = period / rate
        self.stride = float(np.linalg.norm(travel))
        self.speed = self.stride / self.period
        self.mismatch = float(np.sqrt(mismatch2))
        self.joint_names = list(skeleton.joint_names)
        # The cycle's joints relative to the root's straight travel from its first frame,
        # turned so that the travel is along +x; one frame more closes the loop.
        heading = travel / self.stride
        span = joints[first : first + period + 1].copy()
        line = joints[first, 0, [0, 2]] + np.outer(np.arange(period + 1) / period, travel)
        span[:, :, [0, 2]] -= line[:, None, :]
        x, z = span[..., 0].copy(), span[..., 2].copy()
        span[..., 0] = x * heading[0] + z * heading[1]
        span[..., 2] = -x * heading[1] + z * heading[0]
        self._cycle = span

    def phase(self, distances: Any) -> np.ndarray:
        """The cycle's phase in ``[0, 1)`` at the travelled ``distances`` (m, a scalar or
        ``(N,)``)."""
        d = as_scalars(distances, "distances")[0].reshape(-1)
        if not np.isfinite(d).all():
            raise ValueError("distances: must be finite")
        return np.mod(d / self.stride, 1.0)

    def pose(self, positions: Any, headings: Any, distances: Any) -> np.ndarray:
        """Joint positions ``(N, joints, 3)`` (m, world, +Y up) of agents at ``positions``
        ``(N, 2)`` (m, world ``x`` and ``z``, as :class:`kinema.crowd.Crowd`'s), walking
        along ``headings`` ``(N, 2)`` (any length; e.g. their velocities; a zero heading
        faces +x), having travelled ``distances`` ``(N,)`` (m; e.g. ``crowd.metrics()
        ["path_lengths"]``). Frames between captured ones are interpolated linearly."""
        p, _ = as_batch(positions, "positions", (2,))
        h, _ = as_batch(headings, "headings", (2,))
        for arr, name in ((p, "positions"), (h, "headings")):
            if len(arr) != len(p) or not np.isfinite(arr).all():
                raise ValueError(f"{name}: expected {len(p)} finite rows, got shape {arr.shape}")
        phase = self.phase(distances)
        if phase.shape != (len(p),):
            raise ValueError(f"distances: expected shape ({len(p)},), got {phase.shape}")
        at = phase * self.frames
        k = np.minimum(at.astype(np.int64), self.frames - 1)
        w = (at - k)[:, None, None]
        local = (1.0 - w) * self._cycle[k] + w * self._cycle[k + 1]
        length = np.linalg.norm(h, axis=1)
        safe = np.where(length > 0.0, length, 1.0)
        c = np.where(length > 0.0, h[:, 0] / safe, 1.0)[:, None]
        s = np.where(length > 0.0, h[:, 1] / safe, 0.0)[:, None]
        out = np.empty_like(local)
        out[..., 0] = p[:, :1] + c * local[..., 0] - s * local[..., 2]
        out[..., 1] = local[..., 1]
        out[..., 2] = p[:, 1:] + s * local[..., 0] + c * local[..., 2]
        return out
