"""Crowds on the ground plane: ORCA (van den Berg, Guy, Lin & Manocha 2011, "Reciprocal
n-body collision avoidance") with RVO2's obstacle handling, or social forces (Helbing &
Molnár 1995; Helbing, Farkas & Vicsek 2000).

Build a :class:`Crowd`, add static obstacle polygons (:meth:`Crowd.add_obstacle`) and agents
with goals (:meth:`Crowd.add_agents`), then ``step`` it. Coordinates are 2-D in metres on the
ground (world ``x`` and ``z``). ``positions``, ``velocities`` and ``goals`` are read-only
numpy views of the Rust state, updated in place; once one was taken no more agents can be
added. :meth:`Crowd.metrics` reports collisions, times to goal and path lengths, and
:func:`flow_rate` the flow through a door from crossing times, :func:`fields` the density and
velocity fields; :func:`door_goals` gives goals that lead agents out through a door. See
docs/crowd.md.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

import numpy as np

from kinema import _kinema
from kinema._array import as_batch, real

__all__ = ["RVO2_CIRCLE", "Crowd", "crossings", "door_goals", "fields", "flow_rate"]

RVO2_CIRCLE: Mapping[str, Any] = MappingProxyType(_kinema.crowd_rvo2_circle())
"""The settings of the RVO2 library's circle-crossing example (van den Berg et al.'s
``examples/Circle.cpp``: ``setAgentDefaults(15, 10, 10, 10, 1.5, 2)`` — neighbour distance
15 m, 10 neighbours, horizons 10 s / 10 s, radius 1.5 m, max speed 2 m/s — goal vectors
clipped to 1 m/s, dt 0.25 s), as keyword arguments of :class:`Crowd` (read-only; from the
Rust preset ``kinema::crowd::Settings::rvo2_circle``): ``radius``, ``max_speed``,
``preferred_speed`` 1, ``neighbour_distance``, ``max_neighbours``, ``time_horizon``,
``obstacle_time_horizon``, ``goal_tolerance`` (one radius), ``perturbation`` 0, ``seed`` 0 and
kinema's ``planning_margin`` 0.1. ``Crowd(**RVO2_CIRCLE)``; to change some,
``Crowd(**{**RVO2_CIRCLE, "perturbation": 1e-4})``."""


def _points(value: object, name: str) -> np.ndarray:
    arr, _ = as_batch(value, name, (2,))
    return arr


class Crowd:
    """A crowd of agents of one ``radius`` (m) walking to goals.

    ``model`` is ``"orca"`` (each step every agent takes the collision-free velocity closest
    to its preferred one, against its ``max_neighbours`` nearest agents within
    ``neighbour_distance`` m over ``time_horizon`` s and obstacles over
    ``obstacle_time_horizon`` s) or ``"social_force"`` (driving, exponential, body and
    friction forces with Helbing, Farkas & Vicsek's 2000 parameters ``mass`` kg,
    ``relaxation_time`` s, ``strength`` N, ``range`` m, ``body`` kg/s², ``friction``
    kg/(m s); substeps of at most ``max_substep`` s; agents within ``neighbour_distance``
    interact; ``anisotropy`` λ in [0, 1] weakens the repulsion from behind to λ times that
    from ahead (Helbing & Molnár 1995; 1: isotropic) and ``time_gap`` b s makes the required
    length grow with the speed towards the other, ``d = a + b v`` (Seyfried et al. 2005; 0:
    off), which together give Weidmann's fundamental diagram (docs/crowd.md)). Agents walk at ``preferred_speed`` m/s, never faster than ``max_speed``, and
    have arrived within ``goal_tolerance`` m of their goal. ORCA adds to every preferred
    velocity a ``perturbation`` (m/s) in a direction hashed from ``seed``, the step and the
    agent, which breaks exactly symmetric deadlocks (0 turns it off); with a
    ``planning_margin`` m (default 0.1) its agents plan with the radius ``radius * (1 + m)``:
    a personal space of ``m * radius`` metres round each body that ORCA keeps clear (0: off;
    0.1 matches RVO2's mean time to goal on its 250-agent circle without overlaps and brings
    the ring corridor's speeds nearer Weidmann's, docs/crowd.md). ``navigation`` (m, or
    ``None``: off) turns on the global layer with that clearance (:meth:`set_navigation`).
    After each ORCA step, overlapping agents are pushed apart and out of obstacles (a
    position-based projection, Müller et al. 2007), so no two agents overlap after a step
    unless its 64 neighbour searches run out (seen once, under 1 mm: docs/crowd.md).
    """

    def __init__(
        self,
        model: str = "orca",
        radius: float = 0.25,
        max_speed: float = 2.0,
        preferred_speed: float = 1.34,
        *,
        neighbour_distance: float = 5.0,
        max_neighbours: int = 10,
        time_horizon: float = 5.0,
        obstacle_time_horizon: float = 2.0,
        goal_tolerance: float = 0.25,
        mass: float = 80.0,
        relaxation_time: float = 0.5,
        strength: float = 2000.0,
        range: float = 0.08,
        body: float = 1.2e5,
        friction: float = 2.4e5,
        max_substep: float = 0.005,
        anisotropy: float = 1.0,
        time_gap: float = 0.0,
        perturbation: float = 0.0,
        seed: int = 0,
        planning_margin: float = 0.1,
        navigation: float | None = None,
    ) -> None:
        if not isinstance(model, str):
            raise TypeError("model: expected 'orca' or 'social_force'")
        self._c = _kinema.Crowd(
            model,
            real(radius, "radius"),
            real(max_speed, "max_speed"),
            real(preferred_speed, "preferred_speed"),
            real(neighbour_distance, "neighbour_distance"),
            max_neighbours,
            real(time_horizon, "time_horizon"),
            real(obstacle_time_horizon, "obstacle_time_horizon"),
            real(goal_tolerance, "goal_tolerance"),
            real(mass, "mass"),
            real(relaxation_time, "relaxation_time"),
            real(strength, "strength"),
            real(range, "range"),
            real(body, "body"),
            real(friction, "friction"),
            real(max_substep, "max_substep"),
            real(anisotropy, "anisotropy"),
            real(time_gap, "time_gap"),
            real(perturbation, "perturbation"),
            seed,
            real(planning_margin, "planning_margin"),
        )
        self.set_navigation(navigation)

    def set_navigation(self, clearance: float | None) -> None:
        """Turn the global navigation layer on, its paths keeping ``clearance`` (m, > 0; at
        least ``radius`` is sensible) from the obstacles, or off (``None``). With it each step
        every agent heads for the next waypoint of its shortest path to its goal around the
        obstacles (A* on a visibility graph over the obstacles' convex corners pushed out by
        the clearance), re-planned from where it is; a goal that no path reaches is walked to
        straight, as without navigation."""
        if isinstance(clearance, bool):
            raise TypeError("navigation: expected a clearance in m or None")
        if clearance is None:
            self._c.set_navigation(None)
            return
        c = real(clearance, "navigation")
        if not (np.isfinite(c) and c > 0):
            raise ValueError("navigation: the clearance must be finite and > 0 (or None)")
        self._c.set_navigation(c)

    def add_agents(self, positions: Any, goals: Any) -> None:
        """Add agents at rest at ``positions`` ``(N, 2)`` (m), each walking to its goal in
        ``goals`` ``(N, 2)`` (m). Agents may start overlapping, even on one point."""
        self._c.add_agents(_points(positions, "positions"), _points(goals, "goals"))

    def set_goals(self, goals: Any) -> None:
        """Give the agents new goals ``(N, 2)`` (m), one per agent (e.g. every step, to steer
        them through a door: ``bench/bench_bottleneck.py``)."""
        self._c.set_goals(_points(goals, "goals"))

    def add_obstacle(self, polygon: Any) -> None:
        """Add a static obstacle: a polygon ``(K, 2)`` (m) listed counterclockwise (agents
        stay outside; clockwise keeps them inside), or two points: a wall segment."""
        self._c.add_obstacle(_points(polygon, "polygon"))

    def step(self, dt: float, steps: int = 1) -> None:
        """Advance ``steps`` steps of ``dt`` seconds."""
        self._c.step(real(dt, "dt"), steps)

    def __len__(self) -> int:
        return len(self._c)

    @property
    def positions(self) -> np.ndarray:
        """Read-only view ``(N, 2)`` of the positions (m)."""
        return self._c.positions

    @property
    def velocities(self) -> np.ndarray:
        """Read-only view ``(N, 2)`` of the velocities (m/s)."""
        return self._c.velocities

    @property
    def goals(self) -> np.ndarray:
        """Read-only view ``(N, 2)`` of the goals (m)."""
        return self._c.goals

    @property
    def time(self) -> float:
        """Simulated time (s)."""
        return self._c.time

    @property
    def stats(self) -> dict[str, int]:
        """What the last ``step`` did: ``steps``, ``substeps`` and ``fallbacks`` (agent-steps
        whose ORCA program was infeasible and took the least-penetration velocity)."""
        return self._c.stats()

    def metrics(self) -> dict[str, Any]:
        """Measurements since the agents were added: ``agent_collisions`` (overlapping pairs
        summed over steps), ``obstacle_collisions`` (agent–polygon penetrations summed over
        steps), ``steps_with_collisions``, ``max_overlap`` and ``max_penetration`` (m),
        ``arrival_times`` ``(N,)`` (s, ``inf`` until arrived), ``arrived`` (count),
        ``mean_time_to_goal`` (s, over the arrived; NaN if none), ``path_lengths`` ``(N,)``
        (m) and ``path_ratio`` ``(N,)`` (path over the straight line from start to goal)."""
        m: dict[str, Any] = self._c.metrics()
        arrival = m["arrival_times"]
        done = np.isfinite(arrival)
        m["arrived"] = int(done.sum())
        m["mean_time_to_goal"] = float(arrival[done].mean()) if done.any() else float("nan")
        walked, straight = m.pop("path_lengths"), m.pop("straight_lengths")
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(walked == 0.0, 1.0, walked / straight)
        m["path_lengths"] = walked
        m["path_ratio"] = ratio
        return m


def crossings(frames: Any, times: Any, door: Any) -> np.ndarray:
    """The times (s, sorted) at which agents of the trajectory ``frames`` ``(F, N, 2)`` (m,
    at ``times`` ``(F,)`` s) cross the segment ``door`` ``((x0, y0), (x1, y1))`` (m) from its
    right to its left (the left of the direction from the first point to the second),
    interpolated linearly between frames."""
    f = np.ascontiguousarray(frames, dtype=np.float64)
    if f.ndim != 3 or f.shape[2] != 2:
        raise ValueError(f"frames: expected shape (F, N, 2), got {f.shape}")
    t = np.ascontiguousarray(times, dtype=np.float64).reshape(-1, 1)
    d = np.asarray(door, dtype=np.float64)
    if d.shape != (2, 2):
        raise ValueError(f"door: expected shape (2, 2), got {d.shape}")
    return _kinema.crowd_crossings(f, t, d[0].tolist(), d[1].tolist())


def door_goals(positions: Any, door: Any, radius: float, reach: float = 100.0) -> np.ndarray:
    """Goals ``(N, 2)`` (m) that lead agents at ``positions`` ``(N, 2)`` (m) out through the
    door segment ``((x0, y0), (x1, y1))`` (m) from its right to its left (as
    :func:`crossings` counts them): ``reach`` m along the direction to the nearest point of
    the door narrowed by ``radius`` (m) at each end for agents on its right, along its left
    normal for those through. Set them every step (:meth:`Crowd.set_goals`): the desired
    direction then points to the exit, as in Helbing, Farkas & Vicsek 2000."""
    p = np.ascontiguousarray(positions, dtype=np.float64)
    d = np.asarray(door, dtype=np.float64)
    if d.shape != (2, 2):
        raise ValueError(f"door: expected two points, shape (2, 2), got {d.shape}")
    return _kinema.crowd_door_goals(
        p, d[0].tolist(), d[1].tolist(), real(radius, "radius"), real(reach, "reach")
    )


def flow_rate(times: Any) -> float:
    """The flow (agents/s) of crossings at sorted ``times`` (s): ``(N - 1) / (t_N - t_1)``
    (Seyfried et al. 2009); NaN for fewer than two crossings."""
    t = np.asarray(times, dtype=np.float64)
    if t.size < 2 or not t[-1] > t[0]:
        return float("nan")
    return float((t.size - 1) / (t[-1] - t[0]))


def fields(
    positions: Any, velocities: Any, xs: Any, ys: Any, radius: float
) -> tuple[np.ndarray, np.ndarray]:
    """The local density (agents/m², shape ``(len(ys), len(xs))``) and velocity (m/s,
    ``(len(ys), len(xs), 2)``) of agents at ``positions`` ``(N, 2)`` (m) moving at
    ``velocities`` ``(N, 2)`` (m/s), at the grid points ``(xs[i], ys[j])`` (m, each strictly
    increasing), as Helbing, Johansson & Al-Abideen 2007 (eqs. 1-2) measure crowds: each agent
    spread over the Gaussian ``exp(-d²/R²) / (π R²)`` of ``radius`` ``R`` (m), the velocity the
    same weights' mean (zero where no agent is within ``4 R``; weights beyond ``4 R`` along
    ``x`` or ``y`` are left out). E.g. ``fields(crowd.positions, crowd.velocities, xs, ys,
    0.7)``; the speed field is ``np.linalg.norm(velocity, axis=-1)``."""
    x = np.ascontiguousarray(xs, dtype=np.float64)
    y = np.ascontiguousarray(ys, dtype=np.float64)
    for name, axis in (("xs", x), ("ys", y)):
        if axis.ndim != 1:
            raise ValueError(f"{name}: expected shape (n,), got {axis.shape}")
    density, velocity = _kinema.crowd_fields(
        _points(positions, "positions"),
        _points(velocities, "velocities"),
        x.reshape(-1, 1),
        y.reshape(-1, 1),
        real(radius, "radius"),
    )
    return density.reshape(y.size, x.size), velocity.reshape(y.size, x.size, 2)
