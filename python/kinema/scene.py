"""Scenes: one clock for any mix of systems, with coupling, recording, checkpoints.

A :class:`Scene` steps what was added to it (particle systems, constrained particles, cloth,
rigid worlds, fluids, crowds, flocks) with one clock: every frame of ``dt`` seconds is
``substeps`` steps of ``dt / substeps``. Kinematic objects (an :class:`AnimatedSphere` on a keyframed path, a
motion-captured :class:`Character` whose bones are capsules) and the spheres, capsules and boxes of
rigid worlds are colliders for every cloth, particle system and fluid in the scene (one-way:
cloth, particles and fluids do not push back). A scene models only what it was given: without colliders *and*
something to collide, no collider code runs; an empty scene only counts frames.

Checkpoints (:meth:`Scene.save`, :meth:`Scene.load`) hold the whole model and state — down to
integrator history, contact warm starts and emitters' random numbers — so a resumed run is
bit-for-bit the run that never stopped. The file is written atomically (a temporary file
renamed over the old one) and carries a magic number, a format version, its length and a
SHA-256 checksum, so a damaged, truncated or foreign file is refused with
:class:`CheckpointError`. A checkpoint is data only (a JSON manifest and the Rust snapshots of
the systems, see :mod:`kinema._checkpoint`): loading one cannot run code, and everything in it
is validated before use. Pickling a scene or a system (``pickle.dumps``) remains possible, and
is Python's contract: unpickle only what you trust.
"""

from __future__ import annotations

import contextlib
import math
import os
import signal
import threading
import time
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from kinema import character as _character
from kinema import cloth as _cloth
from kinema import crowd as _crowd
from kinema import flock as _flock
from kinema import fluid as _fluid
from kinema import ode as _ode
from kinema import particles as _particles
from kinema import rigid as _rigid
from kinema import rods as _rods
from kinema._array import as_vector3, real
from kinema._kinema import KinemaError
from kinema.constraints import ConstrainedSystem

__all__ = [
    "FORMAT_VERSION",
    "AnimatedSphere",
    "Character",
    "CheckpointError",
    "Scene",
    "StabilityWarning",
]

FORMAT_VERSION = 3
"""Version of the checkpoint format written by :meth:`Scene.save` (version 1 was a Python
pickle, which can run code; such files are refused; version 2 stored articulated bodies and
bipeds as taking no colliders from the scene)."""

_IMPLICIT = ("implicit_euler", "trapezoidal", "bdf2")  # A-stable: no step limit


class CheckpointError(KinemaError, ValueError):
    """A file is not a readable kinema checkpoint (foreign, truncated, damaged, other version,
    invalid content), or a scene holds something a checkpoint cannot store (a Python
    function)."""


class StabilityWarning(UserWarning):
    """An explicit integrator's step is beyond its stability limit for the scene's stiffest
    spring (see :func:`kinema.ode.max_stable_dt`)."""


# Shapes exchanged between collider sources and receivers: ("sphere", center, radius,
# friction), ("capsule", a, b, radius, friction) or ("box", center, rotation, half, friction).
_Shape = tuple[Any, ...]


@dataclass
class AnimatedSphere:
    """A kinematic sphere of ``radius`` (m) whose centre follows ``center``: a
    :class:`kinema.anim.Track` of 3 channels or any callable ``t -> (3,)`` (m, seconds).
    Cloth and particles collide with it (Coulomb ``friction`` for cloth)."""

    radius: float
    center: Any
    friction: float = 0.5

    def __post_init__(self) -> None:
        if not (math.isfinite(self.radius) and self.radius > 0):
            raise ValueError(f"radius: must be positive and finite, got {self.radius}")
        if not callable(self.center):
            raise ValueError("center: expected a kinema.anim.Track or a callable t -> (3,)")

    def position(self, t: float) -> np.ndarray:
        """Centre at time ``t`` (s), ``(3,)`` m."""
        c = np.asarray(self.center(t), dtype=np.float64).reshape(-1)
        if c.shape != (3,) or not np.isfinite(c).all():
            raise ValueError(f"center: must give 3 finite values at t = {t}, got {c}")
        return c

    def _shapes(self, t: float) -> list[_Shape]:
        return [("sphere", self.position(t), float(self.radius), self.friction)]


@dataclass
class Character:
    """A motion-captured character as kinematic capsules: one of ``radius`` (m) around every
    bone (joint to parent joint) of ``skeleton`` played by ``motion`` (Acclaim or BVH, from
    :mod:`kinema.mocap`) at its frame rate, looping after its last frame when ``loop``.

    Joint positions are the skeleton's forward kinematics times ``scale`` (file units to m;
    default: the skeleton's ``metres_per_unit`` for Acclaim files, 1 for BVH) plus ``offset``
    (m). Between frames the root moves linearly and every bone turns at a constant rate in the
    plane of its two frames' directions (the slerp of the bone's vector), so bones keep their
    lengths (a linear blend of joint positions would shorten a turning bone by
    ``1 - cos(θ/2)``). Cloth, particles, articulated bodies and bipeds collide with the
    capsules."""

    skeleton: Any
    motion: Any
    radius: float = 0.05
    scale: float | None = None
    offset: Any = (0.0, 0.0, 0.0)
    loop: bool = True
    friction: float = 0.5
    _joints: np.ndarray = field(init=False, repr=False)
    _bones: np.ndarray = field(init=False, repr=False)
    _chains: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.radius) and self.radius > 0):
            raise ValueError(f"radius: must be positive and finite, got {self.radius}")
        if self.scale is None:
            self.scale = float(getattr(self.skeleton, "metres_per_unit", 1.0))
        if not (math.isfinite(self.scale) and self.scale > 0):
            raise ValueError(f"scale: must be positive and finite, got {self.scale}")
        positions, _ = self.skeleton.forward_kinematics(self.motion)
        offset = np.asarray(as_vector3(self.offset, "offset"))
        self._joints = np.asarray(positions, dtype=np.float64) * self.scale + offset
        parents = np.asarray(self.skeleton.parents)
        self._bones = np.array([(p, j) for j, p in enumerate(parents) if p >= 0], dtype=np.int64)
        # Every joint is its root plus the vectors of the bones from that root to it:
        # _chains[j, k] is 1 when k is j's root or the bone ending at k lies on that path.
        self._chains = np.zeros((len(parents), len(parents)))
        for j in range(len(parents)):
            k = j
            while parents[k] >= 0:
                self._chains[j, k] = 1.0
                k = int(parents[k])
            self._chains[j, k] = 1.0

    def joints(self, t: float) -> np.ndarray:
        """Joint positions at time ``t`` (s), ``(J, 3)`` m."""
        frames = len(self._joints)
        u = t * float(self.motion.frame_rate)
        if self.loop:
            u = u % max(frames - 1, 1)
        u = min(max(u, 0.0), frames - 1.0)
        i = min(int(u), frames - 2) if frames > 1 else 0
        w = u - i if frames > 1 else 0.0
        if frames == 1:
            return self._joints[0]
        j0, j1 = self._joints[i], self._joints[i + 1]
        parent, child = self._bones.T
        d0, d1 = j0[child] - j0[parent], j1[child] - j1[parent]
        # The angle between each bone's two vectors, atan2(|d0 x d1|, d0 . d1) (accurate at
        # small angles), and the slerp weights sin((1 - w) θ) / sin θ, sin(w θ) / sin θ; where
        # sin θ is below 1e-6 the linear weights: a bone that barely turns (shortened by
        # θ² / 8 < 1e-12 relative), of zero length, or turning by half a turn in one frame
        # (no plane to turn in).
        theta = np.arctan2(np.linalg.norm(np.cross(d0, d1), axis=1), np.sum(d0 * d1, axis=1))
        s = np.sin(theta)
        turning = s > 1e-6
        s = np.where(turning, s, 1.0)
        a = np.where(turning, np.sin((1.0 - w) * theta) / s, 1.0 - w)
        b = np.where(turning, np.sin(w * theta) / s, w)
        # The roots blended linearly, the bones' vectors by the slerp, summed along the chains.
        x = (1.0 - w) * j0 + w * j1
        x[child] = a[:, None] * d0 + b[:, None] * d1
        return self._chains @ x

    def _shapes(self, t: float) -> list[_Shape]:
        j = self.joints(t)
        r = float(self.radius)
        return [("capsule", j[a], j[b], r, self.friction) for a, b in self._bones]


def _rigid_shapes(world: _rigid.World) -> list[_Shape]:
    """The spheres, capsules and boxes of a rigid world at its current pose, each with its
    body's friction coefficient (cylinders and meshes are not mirrored: cloth and particles
    have no such colliders yet)."""
    from kinema.rotation import Rotation

    shapes: list[_Shape] = []
    x = world.positions
    q = world.orientations
    for i, (s, body) in enumerate(zip(world.shapes, world.bodies, strict=True)):
        mu = body.friction
        if isinstance(s, _rigid.Sphere):
            shapes.append(("sphere", x[i], float(s.radius), mu))
        elif isinstance(s, _rigid.Capsule):
            axis = Rotation.from_quat(q[i]).apply([0.0, 0.5 * float(s.height), 0.0])
            shapes.append(("capsule", x[i] - axis, x[i] + axis, float(s.radius), mu))
        elif isinstance(s, _rigid.Box):
            shapes.append(("box", x[i], Rotation.from_quat(q[i]), s.half_extents, mu))
    return shapes


#: The systems that take the scene's colliders (the rigid worlds' bodies and the kinematic
#: objects) as their moving colliders.
RECEIVERS = (
    _cloth.Cloth,
    _particles.ParticleSystem,
    _fluid.Fluid,
    _character.ArticulatedBody,
    _character.Biped,
)


class _Entry:
    """A system in a scene: how to step it and whether it receives colliders."""

    __slots__ = ("colliders", "obj", "options", "receives")

    def __init__(self, obj: Any, options: dict[str, Any]) -> None:
        self.obj = obj
        self.options = options
        self.receives = isinstance(obj, RECEIVERS)
        self.colliders: list[int] = []  # indices of the scene's colliders in obj


class Scene:
    """A simulation: systems and kinematic objects stepped together with one clock.

    ``dt`` is the frame interval (s); each frame is ``substeps`` steps of ``dt / substeps``.
    """

    def __init__(self, dt: float = 1.0 / 60.0, substeps: int = 1) -> None:
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f"dt: must be positive and finite, got {dt}")
        if int(substeps) != substeps or substeps < 1:
            raise ValueError(f"substeps: must be an integer >= 1, got {substeps}")
        self._dt = real(dt, "dt")
        self._substeps = int(substeps)
        self._h = self._dt / self._substeps
        self._entries: list[_Entry] = []
        self._kinematic: list[AnimatedSphere | Character] = []
        self._steps = 0  # steps taken; time is steps * h, exactly as the systems count it
        self._recorders: dict[str, Callable[[], Any] | None] = {}
        self._records: dict[str, list[Any]] = {}
        self._previous: list[_Shape] | None = None
        self.interrupted = False

    # ------------------------------------------------------------------ composition
    def add(self, item: Any, **options: Any) -> Any:
        """Add a system or a kinematic object and return it.

        Systems: :class:`kinema.particles.ParticleSystem`, :class:`kinema.cloth.Cloth`,
        :class:`kinema.rigid.World`, :class:`kinema.fluid.Fluid` (the scene's colliders as
        its moving colliders, each of radius or half extents at least its spacing),
        :class:`kinema.crowd.Crowd`, :class:`kinema.flock.Flock` (their own
        obstacles only), :class:`kinema.character.Biped` and
        :class:`kinema.character.ArticulatedBody` (a :class:`~kinema.character.Ragdoll` too;
        their own ground and colliders, and the scene's colliders as moving colliders,
        one-way: the rigid bodies do not feel them), :class:`kinema.character.Tracker`
        (its own ground only; no options; each
        step ``dt / substeps`` must be a whole number of the clip's frames, e.g. ``dt=1/120``
        for a CMU clip),
        :class:`kinema.rods.Rod` and :class:`kinema.rods.Hair` (their own static colliders
        only; move a hair's head with ``set_head`` between frames),
        :class:`kinema.constraints.ConstrainedSystem` (which steps
        its particles: do not add those too). ``options`` are passed to the system's ``step``
        every step, e.g. ``method="rk4"`` or ``integrator="bdf2", solver="cholesky"``.
        Kinematic objects: :class:`AnimatedSphere`, :class:`Character` (no options)."""
        if any(e.obj is item for e in self._entries) or any(k is item for k in self._kinematic):
            raise ValueError("item: already in the scene")
        if isinstance(item, (AnimatedSphere, Character)):
            if options:
                raise ValueError(f"options: a kinematic object takes none, got {sorted(options)}")
            self._kinematic.append(item)
            return item
        if isinstance(item, ConstrainedSystem):
            if any(e.obj is item._particles for e in self._entries):
                raise ValueError("item: its particle system is already in the scene")
        elif isinstance(item, _particles.ParticleSystem):
            if any(
                isinstance(e.obj, ConstrainedSystem) and e.obj._particles is item
                for e in self._entries
            ):
                raise ValueError("item: it is stepped by a constrained system in the scene")
        elif isinstance(item, _character.Tracker):
            if options:
                raise ValueError(f"options: a Tracker takes none, got {sorted(options)}")
            frames = self._h * item.frame_rate
            if round(frames) < 1 or abs(frames - round(frames)) > 1e-9 * frames:
                raise ValueError(
                    f"dt: a Tracker steps whole frames of 1/{item.frame_rate:g} s; "
                    f"dt / substeps = {self._h} s is {frames:.6g} frames"
                )
        elif not isinstance(
            item,
            (
                _cloth.Cloth,
                _rigid.World,
                _fluid.Fluid,
                _crowd.Crowd,
                _flock.Flock,
                _character.Biped,
                _character.ArticulatedBody,
                _rods.Rod,
                _rods.Hair,
            ),
        ):
            raise ValueError(
                "item: expected a ParticleSystem, ConstrainedSystem, Cloth, World, Fluid, "
                "Crowd, Flock, Biped, ArticulatedBody, Tracker, Rod, Hair, AnimatedSphere or "
                "Character, "
                f"got {type(item).__name__}"
            )
        self._entries.append(_Entry(item, dict(options)))
        return item

    @property
    def systems(self) -> list[Any]:
        """What was added (systems and kinematic objects), in order of kind then addition."""
        return [e.obj for e in self._entries] + list(self._kinematic)

    @property
    def dt(self) -> float:
        """Frame interval (s)."""
        return self._dt

    @property
    def substeps(self) -> int:
        """Steps per frame."""
        return self._substeps

    @property
    def time(self) -> float:
        """Simulated time (s)."""
        return self._steps * self._h

    @property
    def frame(self) -> int:
        """Frames completed (a run interrupted inside a frame counts the frame as started)."""
        return self._steps // self._substeps

    # ------------------------------------------------------------------ stepping
    def _sources(self, t: float) -> list[_Shape]:
        shapes: list[_Shape] = []
        for e in self._entries:
            if isinstance(e.obj, _rigid.World):
                shapes += _rigid_shapes(e.obj)
        for k in self._kinematic:
            shapes += k._shapes(t)
        return shapes

    def _couple(self, receivers: list[_Entry], t: float) -> None:
        """Hand every receiver the colliders of the step that ends at ``t``: each moves at the
        constant velocity that takes it from its pose at ``t - h`` to its pose at ``t``.
        Particles collide after their step, so they get the pose at ``t``. A cloth's collider
        is its pose at the cloth's own time, the start of the step, which the cloth moves by
        ``velocity · h`` to find its end-of-step contacts (implicit Euler and BDF2 solve for
        the end of the step), so it gets the pose at ``t - h``: both meet the collider where
        it is at ``t``. A fluid moves its colliders by ``velocity`` over its substeps, so it
        gets the pose at ``t - h`` too (without friction: its colliders take none), and so
        does an articulated body or a biped, whose collider is at its pose at the body's
        time, the start of the step, and moves at ``velocity`` within it. Without poses from the previous step (the first step, or a collider
        added since), the kinematic objects' are evaluated at ``t - h``; rigid worlds have
        already stepped, so their bodies count as at rest for that one step."""
        h = self._h
        shapes = self._sources(t)
        previous = self._previous
        if previous is None or len(previous) != len(shapes):
            previous = self._sources(t - h)
        for e in receivers:
            is_cloth = isinstance(e.obj, _cloth.Cloth)
            is_fluid = isinstance(e.obj, _fluid.Fluid)
            is_body = isinstance(e.obj, (_character.ArticulatedBody, _character.Biped))
            module: Any = _cloth if is_cloth else _particles
            # From the pose at t to the receiver's.
            back = h if is_cloth or is_fluid or is_body else 0.0
            for k, (s, p) in enumerate(zip(shapes, previous, strict=True)):
                friction = None if is_fluid else s[-1]
                if s[0] == "sphere":
                    v = (s[1] - p[1]) / h
                    c: Any = module.Sphere(s[1] - back * v, s[2], friction=friction, velocity=v)
                elif s[0] == "box":
                    v = (s[1] - p[1]) / h
                    c = module.Box(
                        s[1] - back * v, s[3], orientation=s[2], friction=friction, velocity=v
                    )
                else:
                    v = 0.5 * ((s[1] - p[1]) + (s[2] - p[2])) / h
                    a, b = s[1] - back * v, s[2] - back * v
                    c = module.Capsule(a, b, s[3], friction=friction, velocity=v)
                if k < len(e.colliders):
                    e.obj.set_collider(e.colliders[k], c)
                elif is_cloth or is_fluid or is_body:
                    e.colliders.append(e.obj.add_collider(c))
                else:
                    e.obj.add(c)
                    e.colliders.append(e.obj._colliders - 1)
        self._previous = shapes

    def _step(self) -> None:
        """One step of ``dt / substeps`` for everything, in a fixed order: rigid worlds, then
        colliders moved to the end of the step, then the other systems in the order added."""
        h = self._h
        receivers = []
        for e in self._entries:
            if isinstance(e.obj, _rigid.World):
                e.obj.step(h, **e.options)
            elif e.receives:
                receivers.append(e)
        if receivers and (
            self._kinematic or any(isinstance(e.obj, _rigid.World) for e in self._entries)
        ):
            self._couple(receivers, (self._steps + 1) * h)
        for e in self._entries:
            if isinstance(e.obj, _character.Tracker):
                e.obj.step(round(h * e.obj.frame_rate))
            elif not isinstance(e.obj, _rigid.World):
                e.obj.step(h, **e.options)
        self._steps += 1

    def _frame(self, stop: Callable[[], bool] | None = None) -> bool:
        """One frame of ``substeps`` steps; ``False`` when ``stop()`` ended it early (checked
        between steps, so no system is ever half-stepped).

        All or nothing: when a system fails, every system is put back from a snapshot taken
        before the frame (in place, so views of their state stay valid), together with the
        clock and the colliders, and the error propagates. Only a frame of one step of one
        system that receives no colliders takes no snapshot: a failed step of a single system
        already changes nothing."""
        if not self._entries:
            self._steps += self._substeps
            return True
        alone = (
            len(self._entries) == 1
            and self._substeps == 1
            and not (self._entries[0].receives and self._kinematic)
        )
        undo = [] if alone else [_checkpoint(e) for e in self._entries]
        steps, previous = self._steps, self._previous
        try:
            for _ in range(self._substeps):
                self._step()
                if stop is not None and stop():
                    return False
        except BaseException:
            for restore in undo:
                restore()
            self._steps, self._previous = steps, previous
            raise
        return True

    def step(self, frames: int = 1) -> None:
        """Advance ``frames`` frames (no progress bar, no Ctrl-C handling; see :meth:`run`).

        Each frame is all or nothing: a :class:`kinema.SimulationError` (or any error) in any
        system leaves the whole scene at the end of the last completed frame."""
        for _ in range(_count(frames, "frames")):
            self._frame()
            self._collect()

    def run(
        self,
        duration: float | None = None,
        *,
        frames: int | None = None,
        progress: bool = True,
        on_frame: Callable[[Scene], Any] | None = None,
    ) -> int:
        """Run ``duration`` seconds or ``frames`` frames; return the frames completed.

        ``on_frame(scene)`` is called after every completed frame (to draw, export or check).
        Each frame is all or nothing, as in :meth:`step`.

        With ``progress`` a bar shows frames, simulated time and steps per second. Ctrl-C
        stops the run cleanly after the step in progress: the state is the last completed step,
        ``scene.interrupted`` is set, and the run returns. Before the run a
        :class:`StabilityWarning` is issued for an explicit integrator whose step is beyond
        its stability limit on the stiffest spring of a particle system or the fastest
        vibration of a cloth (:meth:`kinema.cloth.Cloth.fastest_mode`)."""
        if (duration is None) == (frames is None):
            raise ValueError("duration: give either duration (s) or frames, not both")
        if duration is not None:
            if not (math.isfinite(duration) and duration >= 0):
                raise ValueError(f"duration: must be finite and >= 0, got {duration}")
            frames = round(duration / self._dt)
        n = _count(frames, "frames")
        self._check_stability()
        self.interrupted = False
        bar = _progress(n) if progress else None
        start, done = time.perf_counter(), 0
        with _sigint_flag() as stop:
            for _ in range(n):
                if not self._frame(stop) or stop():
                    self.interrupted = True
                    break
                self._collect()
                done += 1
                if on_frame is not None:
                    on_frame(self)
                if bar is not None:
                    rate = done * self._substeps / max(time.perf_counter() - start, 1e-9)
                    bar.set_postfix(
                        t=f"{self.time:.3f} s", steps_per_s=f"{rate:.0f}", refresh=False
                    )
                    bar.update(1)
        if bar is not None:
            bar.close()
        return done

    def _check_stability(self) -> None:
        """Warn when an explicit method's step is beyond the stability limit of the fastest
        mode: the stiffest particle spring (undamped), or the cloth's fastest vibration and
        damping (:meth:`kinema.cloth.Cloth.fastest_mode`)."""
        for e in self._entries:
            if isinstance(e.obj, _particles.ParticleSystem):
                method = e.options.get("method", "symplectic_euler")
                if method in _IMPLICIT or method not in _ode.METHODS or e.obj.stiffest_spring <= 0:
                    continue
                omega, c, what = math.sqrt(e.obj.stiffest_spring), 0.0, "the stiffest spring"
            elif isinstance(e.obj, _cloth.Cloth):
                method = e.options.get("integrator", "implicit_euler")
                if method in _IMPLICIT or method not in _ode.METHODS:
                    continue
                (omega, c), what = e.obj.fastest_mode(), "the cloth's fastest vibration"
            else:
                continue
            if omega <= 0:
                continue
            limit = _ode.max_stable_dt_oscillator(method, omega, c)
            if self._h > limit:
                fix = (
                    f"raise substeps to at least {math.ceil(self._dt / limit)} or use an implicit method"
                    if limit > 0
                    else "no step is stable for it: use another method"
                )
                warnings.warn(
                    f"step {self._h:.3g} s is beyond {method}'s stability limit {limit:.3g} s "
                    f"for {what} (ω = {omega:.3g} rad/s, damping {c:.3g} 1/s): {fix}",
                    StabilityWarning,
                    stacklevel=3,
                )

    # ------------------------------------------------------------------ diagnostics
    def diagnostics(self) -> dict[str, float]:
        """Numbers describing the current state, keyed ``"<index>.<name>"`` by system index
        in :attr:`systems`: energies (J), momenta (kg m/s), constraint violation (m, m/s),
        solver iterations; a crowd's summed agent collisions and agents arrived, a flock's
        polarisation. Also ``"time"`` (s)."""
        out: dict[str, float] = {"time": self.time}
        for i, e in enumerate(self._entries):
            o = e.obj
            if isinstance(o, _particles.ParticleSystem):
                out[f"{i}.kinetic_energy"] = o.kinetic_energy()
                out[f"{i}.potential_energy"] = o.potential_energy()
            elif isinstance(o, ConstrainedSystem):
                p = o._particles
                out[f"{i}.kinetic_energy"] = p.kinetic_energy()
                out[f"{i}.potential_energy"] = p.potential_energy()
                pos, vel = o.violation()
                out[f"{i}.violation"] = pos
                out[f"{i}.velocity_violation"] = vel
                out[f"{i}.iterations"] = float(o.iterations)
            elif isinstance(o, _cloth.Cloth):
                energy = o.energy()
                for k, v in energy.items():
                    out[f"{i}.{k}_energy"] = v
                out[f"{i}.iterations"] = float(o.stats["iterations"])
            elif isinstance(o, _rigid.World):
                out[f"{i}.kinetic_energy"] = o.kinetic_energy()
                for name, vec in (
                    ("linear_momentum", o.linear_momentum()),
                    ("angular_momentum", o.angular_momentum()),
                ):
                    out[f"{i}.{name}"] = float(np.linalg.norm(vec))
            elif isinstance(o, _crowd.Crowd):
                m = o.metrics()
                out[f"{i}.agent_collisions"] = float(m["agent_collisions"])
                out[f"{i}.arrived"] = float(m["arrived"])
            elif isinstance(o, _flock.Flock):
                out[f"{i}.polarisation"] = o.polarisation()
            elif isinstance(o, _rods.Rod):
                out[f"{i}.elastic_energy"] = o.energy()
                out[f"{i}.iterations"] = float(o.stats["iterations"])
            elif isinstance(o, _rods.Hair):
                out[f"{i}.iterations"] = float(o.stats["iterations"])
        return out

    def record(self, name: str, quantity: Callable[[], Any] | None = None) -> None:
        """Collect ``quantity()`` (any array-like) after every frame under ``name``; without
        ``quantity``, ``name`` is a key of :meth:`diagnostics`, or ``"animation"``: the state of
        the systems :meth:`export` writes. Read them from :attr:`records`."""
        if quantity is not None and not callable(quantity):
            raise ValueError("quantity: expected a callable returning an array-like")
        if name == "animation" and quantity is None:  # what export() writes
            from kinema.io.scene import frame_state

            quantity = lambda: frame_state(self)  # noqa: E731
        if quantity is None and name not in self.diagnostics():
            raise ValueError(f"name: {name!r} is not one of {sorted(self.diagnostics())}")
        self._recorders[name] = quantity
        self._records.setdefault(name, [])

    def _collect(self) -> None:
        if not self._recorders:
            return
        diag = self.diagnostics() if None in self._recorders.values() else {}
        for name, fn in self._recorders.items():
            self._records[name].append(
                np.array(diag[name] if fn is None else fn(), dtype=np.float64)
            )

    @property
    def records(self) -> dict[str, np.ndarray]:
        """Each recorded quantity stacked over frames: ``(frames, *shape)``."""
        return {k: np.array(v) for k, v in self._records.items()}

    # ------------------------------------------------------------------ output
    def export_obj(self, directory: str | os.PathLike[str], prefix: str = "frame") -> Path:
        """Write the current frame's meshes (cloth, rigid bodies, animated spheres, fluid
        surfaces, the capsules and colliders of articulated bodies and trackers; one OBJ
        object each, in metres) to ``directory/<prefix>_<frame:05d>.obj`` and return the path.
        Call it from ``run(on_frame=...)`` for an OBJ sequence (Blender imports them as
        a sequence)."""
        from kinema import _geometry

        folder = Path(directory)
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / f"{prefix}_{self.frame:05d}.obj"
        _geometry.write_obj(path, _geometry.of_scene(self).meshes)
        return path

    def export(self, path: str | os.PathLike[str]) -> None:
        """Write the animation this scene recorded (``record("animation")`` before running) as
        glTF (``.glb``) or USD (``.usd``, ``.usdc``, ``.usda``): every system, as deforming
        meshes, moving meshes, polylines and points (:mod:`kinema.io.scene`). Needs the
        ``export`` extra."""
        from kinema.io.scene import export_scene

        export_scene(self, path)

    def view(self, port: int = 8080, block: bool = True) -> Any:
        """Play the animation this scene recorded in the browser (:mod:`kinema.view`)."""
        from kinema.view import view

        return view(self, port=port, block=block)

    # ------------------------------------------------------------------ checkpoints
    def __getstate__(self) -> dict[str, Any]:
        state = dict(self.__dict__)
        # Recorders are functions (often lambdas): the data is kept, the functions are not;
        # register them again after loading to go on recording.
        state["_recorders"] = {k: None for k, v in self._recorders.items() if v is None}
        return state

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write a checkpoint of the whole scene to ``path``, atomically: a crash part-way
        leaves the previous file as it was. Raises :class:`CheckpointError` naming the object
        if the scene holds what cannot be stored as data: a Python function as a force
        (``particles.Field``), a constraint (``constraints.Custom``) or the path of an
        :class:`AnimatedSphere`. Recorders given as functions are not stored (their records
        are): register them again after :meth:`load` to go on recording."""
        from kinema import _checkpoint

        _write_atomic(Path(path), _checkpoint.dumps(self))

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Scene:
        """Read a checkpoint written by :meth:`save`; raise :class:`CheckpointError` if the file
        is not one, is truncated or damaged, has another format version, or holds anything
        invalid (every index, length and value is checked before use; nothing in the file
        can run code)."""
        from kinema import _checkpoint

        return _checkpoint.loads(Path(path).read_bytes(), str(path))

    def __repr__(self) -> str:
        kinds = ", ".join(type(s).__name__ for s in self.systems) or "empty"
        return f"Scene(dt={self._dt}, substeps={self._substeps}, time={self.time:.4g} s: {kinds})"


def _checkpoint(entry: _Entry) -> Callable[[], None]:
    """A function that puts ``entry``'s system (and the scene's record of its colliders) back
    as it is now: each compiled object keeps an undo point (``_mark``) and goes back to it in
    place (``_rollback``), so views of its state stay valid; a constrained system marks its
    particles' state and its constraint state (tracked curves, warm starts, history)."""
    obj, colliders = entry.obj, list(entry.colliders)
    cores: list[Any]
    if isinstance(obj, ConstrainedSystem):
        cores = [obj._particles._sys, obj._sys]
    elif isinstance(obj, _cloth.Cloth):
        cores = [obj._core]
    elif isinstance(obj, _particles.ParticleSystem):
        cores = [obj._sys]
    elif isinstance(obj, (_fluid.Fluid, _flock.Flock)):
        cores = [obj._f]
    elif isinstance(obj, _crowd.Crowd):
        cores = [obj._c]
    elif isinstance(obj, _character.Biped):
        cores = [obj._w]
    elif isinstance(obj, _character.ArticulatedBody):
        cores = [obj._b]
    elif isinstance(obj, _character.Tracker):
        cores = [obj._t]
    elif isinstance(obj, _rods.Rod):
        cores = [obj._r]
    elif isinstance(obj, _rods.Hair):
        cores = [obj._h]
    else:
        cores = [obj._world]
    for core in cores:
        core._mark()
    count = getattr(obj, "_colliders", None)

    def restore() -> None:
        for core in cores:
            core._rollback()
        entry.colliders[:] = colliders
        if count is not None:
            obj._colliders = count

    return restore


def _count(n: Any, name: str) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
        raise ValueError(f"{name}: expected a non-negative integer, got {n!r}")
    return int(n)


def _progress(total: int) -> Any:
    from tqdm.auto import tqdm

    return tqdm(total=total, unit="frame", dynamic_ncols=True, leave=False)


@contextlib.contextmanager
def _sigint_flag() -> Iterator[Callable[[], bool]]:
    """Within the block, Ctrl-C sets a flag (read by the yielded function) instead of raising,
    so a run stops between steps, never inside one. Off the main thread (where Python delivers
    no signals) the flag stays down."""
    hit = [False]
    if threading.current_thread() is not threading.main_thread():
        yield lambda: False
        return

    def handler(signum: int, frame: Any) -> None:
        hit[0] = True

    previous = signal.signal(signal.SIGINT, handler)
    try:
        yield lambda: hit[0]
    finally:
        signal.signal(signal.SIGINT, previous)


def _write_atomic(path: Path, *chunks: bytes) -> None:
    """Write ``chunks`` to a temporary file next to ``path``, flush it to disk, then rename it
    over ``path`` (atomic on POSIX and Windows), so readers see the old file or the new one."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as f:
            for chunk in chunks:
                f.write(chunk)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    if hasattr(os, "O_DIRECTORY"):
        with contextlib.suppress(OSError):
            fd = os.open(path.parent, os.O_DIRECTORY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
