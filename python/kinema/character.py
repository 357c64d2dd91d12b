"""Articulated characters in reduced coordinates (issue #27, first slice).

A :class:`Model` is a kinematic tree of rigid bodies joined by revolute (hinge), ball,
free (6 DOF), planar (x, y, turn about z) and fixed joints, built body by body (parents first). An
:class:`ArticulatedBody` steps it with Featherstone's articulated-body algorithm (forward
dynamics in O(n); the CRBA and RNEA for stable PD), semi-implicit Euler or RK4, joint limits
as stiff one-sided springs, penalty contact with friction on the plane y = 0 and on static
colliders (:meth:`ArticulatedBody.add_collider`: planes, spheres, capsules, boxes), PD or
stable PD servos (Tan, Liu & Turk 2011) and timed pushes. :meth:`Ragdoll.from_skeleton`
builds a limp ragdoll from an ASF or BVH skeleton; :class:`Tracker` makes the ragdoll of a
CMU skeleton follow a clip with PD servos and a measured root assistance. :class:`Biped`
is the planar 7-link biped of SIMBICON (Yin, Loken & van de Panne 2007) walking under its
controller, or with ``dims=3`` its 3-D biped (ball hips and ankles) under 3-D SIMBICON.

Coordinates ``q``: per joint, a hinge angle (rad), a ball joint's quaternion ``(w, x, y,
z)``, a free joint's position (m) and quaternion; rates ``qd``: hinge rate, a ball joint's
angular velocity in body axes, a free joint's ``[ω (body axes); v (parent axes)]``. SI
units, +Y up. See docs/character.md.
"""

from __future__ import annotations

import operator
from typing import Any, SupportsIndex

import numpy as np

from kinema import _kinema
from kinema._array import as_vector3, real
from kinema.geometry import Box, Capsule, Plane, Sphere, shape_params

__all__ = ["ArticulatedBody", "Biped", "Model", "Ragdoll", "Tracker"]

_JOINTS = ("revolute", "ball", "free", "planar", "fixed")


def _index(value: object, name: str) -> int:
    """An integer argument as an ``int`` (``TypeError`` naming ``name`` otherwise)."""
    if isinstance(value, bool) or not isinstance(value, SupportsIndex):
        raise TypeError(f"{name}: expected an integer, got {type(value).__name__}")
    return operator.index(value)


def _collider(c: Any) -> tuple[str, list[float], float | None, list[float]]:
    """A :mod:`kinema.geometry` shape as an articulated collider: its kind, parameters,
    friction (``None``: the body's) and velocity (m/s). Penalty contacts have no
    restitution."""
    kind, params = shape_params(c)
    if c.restitution is not None:
        raise ValueError(
            "restitution: articulated contacts are damped springs without restitution; "
            "leave it None"
        )
    if isinstance(c, Sphere) and c.inside:
        raise ValueError("inside: articulated bodies collide with the outside of a sphere only")
    friction = None if c.friction is None else real(c.friction, "friction")
    return kind, params, friction, as_vector3(c.velocity, "velocity")


def _shape(
    kind: str, p: list[float], friction: float | None, velocity: list[float]
) -> Plane | Sphere | Capsule | Box:
    """A compiled collider ``(kind, parameters, friction, velocity)`` as a
    :mod:`kinema.geometry` shape."""
    from kinema.rotation import Rotation

    if kind == "plane":
        return Plane(p[:3], p[3:6], friction=friction, velocity=velocity)
    if kind == "sphere":
        return Sphere(p[:3], p[3], friction=friction, velocity=velocity)
    if kind == "capsule":
        return Capsule(p[:3], p[3:6], p[6], friction=friction, velocity=velocity)
    orientation = Rotation.from_quat(p[3:7])
    return Box(p[:3], p[7:10], orientation, friction=friction, velocity=velocity)


def _floats(value: Any, name: str, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` as a float64 array of ``shape`` (``ValueError`` naming ``name``)."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected numbers of shape {shape}") from None
    if arr.shape != shape:
        raise ValueError(f"{name}: expected shape {shape}, got {arr.shape}")
    return arr


class Model:
    """An articulated model being built: add bodies with :meth:`add_body`, parents first,
    then make an :class:`ArticulatedBody` of it."""

    def __init__(self) -> None:
        self._m = _kinema.ArticulatedModel()

    def add_body(
        self,
        parent: int | None,
        joint: str,
        *,
        mass: float,
        inertia: Any,
        offset: Any = (0.0, 0.0, 0.0),
        com: Any = (0.0, 0.0, 0.0),
        axis: Any = (0.0, 0.0, 1.0),
        shape: tuple[Any, Any, float] | None = None,
        limits: Any = None,
        limit_frame: Any = (1.0, 0.0, 0.0, 0.0),
        damping: float = 0.0,
        name: str = "",
    ) -> int:
        """Append a body and return its index.

        ``parent``: index of a body added before, or ``None`` (the world). ``joint``:
        ``"revolute"`` (about ``axis``), ``"ball"``, ``"free"``, ``"planar"`` (x, y, and a
        turn about z: coordinates ``[x, y, θ]``) or ``"fixed"``. ``offset``
        (m): the joint's position in the parent's frame (the world's for a root); the body's
        frame has its origin at the joint and the parent's axes at the zero pose. ``mass``
        (kg), ``com`` (m, body frame), ``inertia`` (3x3, kg m², about the centre of mass).
        ``shape``: a capsule ``(a, b, radius)`` (ends in m, body frame) colliding with the
        ground, or ``None``. ``limits``: for a hinge one ``(lower, upper)`` (rad), for a ball
        joint three, on the rotation vector's components about the axes of ``limit_frame``
        (a quaternion ``(w, x, y, z)`` from limit axes to body axes). ``damping``: joint
        damping (N m s/rad).
        """
        if joint not in _JOINTS:
            raise ValueError("joint: expected 'revolute', 'ball', 'free', 'planar' or 'fixed'")
        p = None if parent is None else _index(parent, "parent")
        if p is not None and p < 0:
            raise ValueError("parent: expected a body index >= 0 or None")
        shp = None
        if shape is not None:
            if len(shape) != 3:
                raise ValueError("shape: expected (a, b, radius)")
            shp = (
                as_vector3(shape[0], "shape"),
                as_vector3(shape[1], "shape"),
                real(shape[2], "shape"),
            )
        lims = None
        if limits is not None:
            arr = np.asarray(limits, dtype=np.float64)
            if arr.ndim == 1:
                arr = arr[None, :]
            if arr.ndim != 2 or arr.shape[1] != 2 or not 1 <= arr.shape[0] <= 3:
                raise ValueError(f"limits: expected 1 to 3 (lower, upper) pairs, got {arr.shape}")
            lims = [(float(lo), float(hi)) for lo, hi in arr]
        return self._m.add_body(
            str(name),
            p,
            joint,
            as_vector3(axis, "axis"),
            as_vector3(offset, "offset"),
            real(mass, "mass"),
            as_vector3(com, "com"),
            _floats(inertia, "inertia", (3, 3)).tolist(),
            shp,
            lims,
            _floats(limit_frame, "limit_frame", (4,)).tolist(),
            real(damping, "damping"),
        )

    def __len__(self) -> int:
        return len(self._m)


class ArticulatedBody:
    """A :class:`Model` (copied) with its state, in the zero pose at time 0.

    Settings (keywords, changeable later with :meth:`configure`): ``gravity`` (m/s²);
    ``integrator`` ``"symplectic"`` (semi-implicit Euler, order 1) or ``"rk4"`` (order 4);
    ``servo_mode`` ``"stable"`` (stable PD) or ``"explicit"``; ``ground`` (collide the
    capsules with y = 0); ``self_collision`` (collide the capsules with each other, all pairs
    but a body and its parent, siblings and capsules that overlap in the zero pose; default
    off); ``contact_frequency`` ω (rad/s: contact stiffness ``m ω²`` per
    body, resting penetration ``g / ω²``), ``contact_damping`` (ratio ζ), ``friction`` (μ),
    ``slip_speed`` (m/s, below which friction is viscous), ``limit_frequency`` (rad/s) and
    ``limit_damping`` (ratio) of the joint-limit springs.
    """

    _b: Any

    def __init__(self, model: Model, **settings: Any) -> None:
        if not isinstance(model, Model):
            raise TypeError(f"model: expected a kinema.character.Model, got {type(model).__name__}")
        self._b = _kinema.ArticulatedBody(model._m)
        if settings:
            self.configure(**settings)

    def configure(self, **settings: Any) -> None:
        """Change settings (the keywords of :class:`ArticulatedBody`); the others keep
        their values."""
        current = self._b.settings()
        unknown = set(settings) - set(current)
        if unknown:
            raise TypeError(f"configure: unknown setting(s) {sorted(unknown)}")
        current.update(settings)
        for key in ("integrator", "servo_mode"):
            if not isinstance(current[key], str):
                raise TypeError(f"{key}: expected a string")
        numbers = [
            real(current[k], k)
            for k in (
                "contact_frequency",
                "contact_damping",
                "friction",
                "slip_speed",
                "limit_frequency",
                "limit_damping",
            )
        ]
        self._b.configure(
            as_vector3(current["gravity"], "gravity"),
            current["integrator"],
            current["servo_mode"],
            bool(current["ground"]),
            bool(current["self_collision"]),
            *numbers,
        )

    @property
    def settings(self) -> dict[str, Any]:
        """The current settings."""
        return dict(self._b.settings())

    def step(self, dt: float, steps: int = 1) -> None:
        """Advance ``steps`` steps of ``dt`` seconds. A step that diverges raises
        :class:`kinema.SimulationError` and leaves the body as it was."""
        self._b.step(real(dt, "dt"), steps)

    @property
    def q(self) -> np.ndarray:
        """Joint coordinates ``(nq,)`` (read-only view, updated in place)."""
        return self._b.q

    @q.setter
    def q(self, value: Any) -> None:
        self._b.set_q(_floats(value, "q", (self.nq,)).tolist())

    @property
    def qd(self) -> np.ndarray:
        """Joint rates ``(nv,)`` (read-only view, updated in place)."""
        return self._b.qd

    @qd.setter
    def qd(self, value: Any) -> None:
        self._b.set_qd(_floats(value, "qd", (self.nv,)).tolist())

    @property
    def targets(self) -> np.ndarray:
        """Servo targets ``(nq,)``, laid out as ``q`` (read-only view)."""
        return self._b.targets

    @targets.setter
    def targets(self, value: Any) -> None:
        self._b.set_targets(_floats(value, "targets", (self.nq,)).tolist())

    def set_torques(self, torques: Any) -> None:
        """Apply joint torques ``(nv,)`` (N m; N on free joints' linear rows) during the
        later steps, until changed."""
        self._b.set_torques(_floats(torques, "torques", (self.nv,)).tolist())

    def set_servo(
        self, body: int, kp: float | None, kd: float = 0.0, max_torque: float = np.inf
    ) -> None:
        """Drive body ``body``'s joint (hinge or ball) towards ``targets`` with a PD servo
        ``τ = kp (q̄ ⊖ q) − kd q̇`` (N m/rad, N m s/rad), clamped to ``±max_torque`` (N m);
        ``kp=None`` removes it."""
        gain = None if kp is None else real(kp, "kp")
        self._b.set_servo(
            _index(body, "body"), gain, real(kd, "kd"), real(max_torque, "max_torque")
        )

    def add_collider(
        self, collider: Plane | Sphere | Capsule | Box, angular_velocity: Any = (0.0, 0.0, 0.0)
    ) -> int:
        """Add a collider (a :mod:`kinema.geometry` shape: a plane of any normal, a sphere, a
        capsule or an oriented box; a staircase is a list of boxes) touched by every capsule
        with the ground's contact spring, damping and regularised friction along the shape's
        closest-point normal (docs/character.md, "Colliders"); returns its index (for
        :meth:`set_collider`). The shape's ``friction`` (``None``: the ``friction`` setting)
        is its Coulomb μ; its ``velocity`` (m/s) and ``angular_velocity`` (rad/s, world,
        about its centre: a plane's point, a capsule's midpoint; both default 0: static) make
        it kinematic: it is where given at the body's current time and moves so from then
        on, and the contacts' damping and friction act on the velocity relative to its
        surface's. It takes no ``restitution``. Bad shapes raise ``ValueError`` naming the
        argument."""
        spin = as_vector3(angular_velocity, "angular_velocity")
        return int(self._b.add_collider(*_collider(collider), spin))

    def set_collider(
        self,
        index: int,
        collider: Plane | Sphere | Capsule | Box,
        angular_velocity: Any = (0.0, 0.0, 0.0),
    ) -> None:
        """Move collider ``index``: ``collider`` (a shape of the same kind and size: radius,
        half extents, a capsule's length) is its pose at the body's current time, its
        ``velocity`` (m/s) and ``angular_velocity`` (rad/s, about its centre) how it moves
        from then on, its ``friction`` its μ. To carry a body on a platform following any
        path, set it every frame:
        ``set_collider(i, Box(path(t), half, velocity=(path(t + dt) - path(t)) / dt))``
        before ``step``. A shape of another kind or size raises ``ValueError`` naming
        ``shape``."""
        spin = as_vector3(angular_velocity, "angular_velocity")
        self._b.set_collider(_index(index, "index"), *_collider(collider), spin)

    def colliders(self) -> list[Plane | Sphere | Capsule | Box]:
        """The colliders, in the order added, as :mod:`kinema.geometry` shapes where they are
        at the body's current time (m, world), each with its ``friction`` (``None``: the
        setting's) and ``velocity`` (m/s)."""
        return [_shape(*c) for c in self._b.colliders()]

    def push(self, body: int, force: Any, duration: float) -> None:
        """Apply ``force`` (N, world axes) at body ``body``'s centre of mass during the next
        ``duration`` seconds."""
        self._b.push(_index(body, "body"), as_vector3(force, "force"), real(duration, "duration"))

    @property
    def com(self) -> np.ndarray:
        """Centre of mass of the whole body (m, world)."""
        return np.array(self._b.com)

    def energy(self) -> tuple[float, float]:
        """Kinetic and gravitational potential energy (J); springs of contacts and limits
        are not counted."""
        return self._b.energy()

    @property
    def time(self) -> float:
        """Simulated time (s)."""
        return self._b.time

    @property
    def nq(self) -> int:
        """Number of joint coordinates."""
        return int(self._b.sizes()[0])

    @property
    def nv(self) -> int:
        """Number of degrees of freedom."""
        return int(self._b.sizes()[1])

    @property
    def names(self) -> list[str]:
        """Body names, in order."""
        return list(self._b.names())

    @property
    def masses(self) -> np.ndarray:
        """Body masses (kg), in order."""
        return np.array(self._b.masses())

    def capsules(self) -> list[tuple[np.ndarray, np.ndarray, float] | None]:
        """Each body's collision capsule ``(a, b, radius)``: its axis's ends (m, body frame:
        world ``positions()[i] + R_i a``) and radius (m); ``None`` for a body without one."""
        return [
            None if c is None else (np.array(c[0]), np.array(c[1]), float(c[2]))
            for c in self._b.capsules()
        ]

    def positions(self) -> np.ndarray:
        """World positions of the body frames ``(n, 3)`` (m)."""
        return self._b.positions()

    def orientations(self) -> np.ndarray:
        """World orientations of the body frames ``(n, 4)`` as ``(w, x, y, z)``."""
        return self._b.orientations()

    def __len__(self) -> int:
        return len(self._b)


class Ragdoll(ArticulatedBody):
    """A limp ragdoll: one capsule body per bone of a skeleton (see :meth:`from_skeleton`)."""

    def __init__(self, body: Any) -> None:
        self._b = body

    @classmethod
    def from_skeleton(
        cls,
        skeleton: Any,
        density: float = 1000.0,
        *,
        scale: float | None = None,
        radius_ratio: float = 0.15,
        min_radius: float = 0.02,
        damping: float = 2.0,
        clearance: float = 0.0,
        **settings: Any,
    ) -> Ragdoll:
        """The ragdoll of an ASF skeleton (:func:`kinema.mocap.read_asf`) or a BVH skeleton
        (:func:`kinema.mocap.read_bvh`).

        ASF: the root is a free sphere; every bone a capsule from its base to its tip of
        radius ``max(min_radius, radius_ratio × length)`` (m) and ``density`` (kg/m³), hinged
        where its ASF ``dof`` line has one rotation, a ball joint where it has two or three
        (fixed with none), with the ASF limits. BVH: every joint a body, its capsule from the
        joint to the mean of its children's offsets (and end site), radius from its longest
        segment; a root is free, other joints are fixed, hinges or ball joints for 0, 1 or
        2–3 rotation channels, without limits (BVH has none). ``scale``: metres per file
        unit (``None``: for ASF the CMU reading, ``skeleton.metres_per_unit()``; required for
        BVH, whose files do not say). ``damping``: joint damping rate (1/s; a body's damping
        is this times its moment of inertia about its capsule's axis). The ragdoll is lifted
        so that its lowest point is ``clearance`` (m) above the ground. ``settings`` as for
        :class:`ArticulatedBody`.
        """
        numbers = (
            real(density, "density"),
            real(radius_ratio, "radius_ratio"),
            real(min_radius, "min_radius"),
            real(damping, "damping"),
            real(clearance, "clearance"),
        )
        if isinstance(skeleton, _kinema.AsfSkeleton):
            d, ratio, rmin, damp, clear = numbers
            body = _kinema.ArticulatedBody.ragdoll(
                skeleton,
                d,
                None if scale is None else real(scale, "scale"),
                ratio,
                rmin,
                damp,
                clear,
            )
        elif isinstance(skeleton, _kinema.BvhSkeleton):
            if scale is None:
                raise ValueError("scale: a BVH file has no length unit; give metres per file unit")
            d, ratio, rmin, damp, clear = numbers
            body = _kinema.ArticulatedBody.ragdoll_bvh(
                skeleton, d, real(scale, "scale"), ratio, rmin, damp, clear
            )
        else:
            raise TypeError(
                "skeleton: expected an ASF or BVH skeleton (kinema.mocap.read_asf, read_bvh), "
                f"got {type(skeleton).__name__}"
            )
        out = cls(body)
        if settings:
            out.configure(**settings)
        return out


_POSE = (
    "cd",
    "cv",
    "torso",
    "swing_hip",
    "swing_knee",
    "swing_ankle",
    "stance_knee",
    "stance_ankle",
)
_WALK = {  # the defaults of kinema::character::Gait (the paper's walk, Table 1)
    "cd": (0.0, 2.2),
    "cv": (0.2, 0.0),
    "torso": (0.0, 0.0),
    "swing_hip": (0.4, -0.7),
    "swing_knee": (-1.1, -0.05),
    "swing_ankle": (0.2, 0.2),
    "stance_knee": (-0.05, -0.1),
    "stance_ankle": (0.2, 0.2),
}


_CORONAL = {"coronal_cd": 0.0, "coronal_cv": 0.3, "coronal_swing_hip": 0.0}


class Biped:
    """A SIMBICON biped walking (Yin, Loken & van de Panne 2007; docs/character.md): planar
    (``dims=2``, the default) or 3-D (``dims=3``).

    Seven links in the x–y plane (x forward, y up): a torso on a planar root, and per leg a
    thigh, a shin and a foot on hinges about z, with the paper's masses and lengths; feet
    touch the ground y = 0 at heel and toe. The SIMBICON controller runs every step: a
    four-state machine (states 0/2 last ``duration`` s while a leg lifts, states 1/3 end when
    the swing foot strikes), PD servos towards each state's pose, the swing hip's target
    ``θ = swing_hip + cd·d + cv·v`` (``d``: stance ankle to centre of mass, m; ``v``: centre
    of mass velocity, m/s), the torso servoed in the world frame through the stance hip.

    Gait parameters are pairs ``(states 0/2, states 1/3)``: ``cd`` (rad/m), ``cv``
    (rad s/m), ``torso`` (rad from vertical, negative leans forward), ``swing_hip`` (rad,
    world frame, positive forward), ``swing_knee``, ``swing_ankle``, ``stance_knee``,
    ``stance_ankle`` (rad, relative; a bent knee is negative). ``duration`` (s); ``kp``
    (N m/rad), ``kd`` (N m s/rad) of the joints, ``torso_kp``, ``torso_kd`` of the torso
    (default 300 and 30; 1000 and 100 with ``dims=3``);
    ``max_torque`` (N m) per joint. The defaults are the paper's walk (Table 1; 1.14 m/s).
    ``speed``: initial forward speed (m/s). ``contact_frequency`` (rad/s) and ``friction``
    of the ground (see :class:`ArticulatedBody`). ``slope`` (rad, positive climbs): the
    ground stays y = 0 and gravity turns by it; the controller takes the vertical from
    gravity and the swing hip's target from the ground's normal. The knees and ankles are
    stable PD servos: step with ``dt`` ≤ 2e-3 s (it walks up to 3.5e-3 s; ``dims=3``: 1e-3 s
    documented, it walks up to 3.5e-3 s too).

    Coordinates ``q`` (9,): torso ``x, y`` (m, at the hips) and angle (rad), then hip, knee
    and ankle angles of the right leg, then of the left.

    ``dims=3``: the 3-D biped of §5 of the paper (x forward, y up, z to the right): the torso
    on a free root, ball hips 0.2 m apart, hinge knees, ball ankles, each foot a heel and a
    toe half with a capsule across the sole (nine bodies: torso, then right and left thigh,
    shin, foot, toes). The same gait keywords act in the sagittal plane; the coronal plane
    has its own balance feedback, the swing thigh's sideways angle ``coronal_swing_hip·(±1)
    + coronal_cd·d_z + coronal_cv·v_z`` (rad, rad/m, rad s/m; positive puts the foot to +z;
    ``coronal_swing_hip`` abducts). The torso's world orientation (upright, heading +x) is
    servoed through the stance hip, which so holds the twist; the stance hip's torque about the
    stance leg's axis (hip to the foot's centre of pressure) is capped at half of what the
    foot's friction holds (none in the air), or the leg spins on a lightly loaded foot. Coordinates ``q`` (25,): the
    torso's position (m) and quaternion ``(w, x, y, z)``, then per leg the hip's quaternion,
    the knee's angle, the ankle's quaternion; rates ``qd`` (20,). The coronal keywords are
    refused with ``dims=2``. One class for both: the controller, its gait keywords and
    every method are the same; only the model differs.
    """

    def __init__(
        self,
        *,
        duration: float = 0.3,
        kp: float = 300.0,
        kd: float = 30.0,
        torso_kp: float | None = None,
        torso_kd: float | None = None,
        max_torque: float = 400.0,
        speed: float = 0.3,
        contact_frequency: float = 200.0,
        friction: float = 1.0,
        slope: float = 0.0,
        dims: int = 2,
        **pose: Any,
    ) -> None:
        unknown = sorted(set(pose) - set(_POSE) - set(_CORONAL))
        if unknown:
            raise TypeError(f"unexpected keyword arguments: {', '.join(unknown)}")
        dims = _index(dims, "dims")
        if dims not in (2, 3):
            raise ValueError(f"dims: expected 2 or 3, got {dims}")
        given = sorted(set(pose) & set(_CORONAL))
        if dims == 2 and given:
            raise TypeError(f"{given[0]}: only for dims=3")
        coronal = [real(pose.pop(n, v), n) for n, v in _CORONAL.items()]
        if torso_kp is None:
            torso_kp = 300.0 if dims == 2 else 1000.0
        if torso_kd is None:
            torso_kd = 30.0 if dims == 2 else 100.0
        values = []
        for name in _POSE:
            pair = pose.get(name, _WALK[name])
            values.append(_floats(pair, name, (2,)))
        lift = [float(v[0]) for v in values]
        strike = [float(v[1]) for v in values]
        control = [
            real(v, n)
            for v, n in (
                (duration, "duration"),
                (kp, "kp"),
                (kd, "kd"),
                (torso_kp, "torso_kp"),
                (torso_kd, "torso_kd"),
                (max_torque, "max_torque"),
            )
        ]
        ground = (
            real(speed, "speed"),
            real(contact_frequency, "contact_frequency"),
            real(friction, "friction"),
            real(slope, "slope"),
        )
        self._w: Any
        if dims == 2:
            self._w = _kinema.Walker(lift, strike, control, *ground)
        else:
            self._w = _kinema.Walker3d(lift, strike, control, coronal, *ground)

    @property
    def dims(self) -> int:
        """2 for the planar biped, 3 for the 3-D one."""
        return 3 if isinstance(self._w, _kinema.Walker3d) else 2

    @property
    def gait(self) -> dict[str, Any]:
        """The gait parameters as keywords of :class:`Biped` (pairs for the poses)."""
        lift, strike, control = self._w.gait()
        out: dict[str, Any] = {n: (a, b) for n, a, b in zip(_POSE, lift, strike, strict=True)}
        names = ("duration", "kp", "kd", "torso_kp", "torso_kd", "max_torque")
        out.update(zip(names, control, strict=True))
        if self.dims == 3:
            out.update(zip(_CORONAL, self._w.coronal(), strict=True))
        return out

    def step(self, dt: float, steps: int = 1) -> None:
        """Advance ``steps`` steps of ``dt`` seconds (controller, then dynamics, per step).
        Raises :class:`kinema.SimulationError` on divergence, leaving the biped as it was."""
        self._w.step(real(dt, "dt"), _index(steps, "steps"))

    def add_collider(
        self, collider: Plane | Sphere | Capsule | Box, angular_velocity: Any = (0.0, 0.0, 0.0)
    ) -> int:
        """Add a collider under the feet, static or moving (its ``velocity``, m/s, and
        ``angular_velocity``, rad/s about its centre: a platform), as
        :meth:`ArticulatedBody.add_collider`; the controller takes a foot in it for a foot on
        the ground, and its balance feedback takes the centre of mass's velocity relative
        to the surface under the stance foot (docs/character.md, "Moving colliders").
        Returns its index (for :meth:`set_collider`)."""
        spin = as_vector3(angular_velocity, "angular_velocity")
        return int(self._w.add_collider(*_collider(collider), spin))

    def set_collider(
        self,
        index: int,
        collider: Plane | Sphere | Capsule | Box,
        angular_velocity: Any = (0.0, 0.0, 0.0),
    ) -> None:
        """Move collider ``index`` to ``collider`` (same kind and size) at the biped's current
        time, moving from then on at its ``velocity`` and ``angular_velocity``, as
        :meth:`ArticulatedBody.set_collider`."""
        spin = as_vector3(angular_velocity, "angular_velocity")
        self._w.set_collider(_index(index, "index"), *_collider(collider), spin)

    def push(self, force: Any, duration: float, body: str | int = "torso") -> None:
        """Push ``body`` (a name or index; default the torso) with ``force`` (N, world, 3
        values or a number for x) at its centre of mass for ``duration`` seconds."""
        names = self.names
        if isinstance(body, str):
            if body not in names:
                raise ValueError(f"body: expected one of {', '.join(names)}")
            index = names.index(body)
        else:
            index = _index(body, "body")
        vector = (real(force, "force"), 0.0, 0.0) if np.ndim(force) == 0 else force
        self._w.push(index, as_vector3(vector, "force"), real(duration, "duration"))

    @property
    def com(self) -> np.ndarray:
        """Centre of mass (m, world), shape (3,)."""
        return np.array(self._w.com)

    @property
    def feet_in_contact(self) -> tuple[bool, bool]:
        """Whether the right and left feet touch the ground."""
        return self._w.feet_in_contact

    @property
    def state(self) -> int:
        """The controller's FSM state (0, 1: the right leg swings; 2, 3: the left)."""
        return self._w.phase()[0]

    @property
    def steps(self) -> int:
        """Foot strikes so far (FSM transitions 1 → 2 and 3 → 0)."""
        return self._w.phase()[2]

    @property
    def q(self) -> np.ndarray:
        """Read-only view of the coordinates (9,; 25, with ``dims=3``), updated in place by
        :meth:`step`."""
        return self._w.q

    @property
    def qd(self) -> np.ndarray:
        """Read-only view of the rates (9,; 20, with ``dims=3``)."""
        return self._w.qd

    @property
    def time(self) -> float:
        """Simulated time (s)."""
        return self._w.time

    @property
    def names(self) -> list[str]:
        """Body names: torso, then right and left thigh, shin, foot (and toes, ``dims=3``)."""
        return self._w.names()

    def positions(self) -> np.ndarray:
        """World positions (m) of the body frames (7, 3; 9, 3 with ``dims=3``): the hips
        (torso and thighs; the torso's between the hips in 3-D), knees (shins), ankles (feet
        and toes)."""
        return self._w.positions()

    def orientations(self) -> np.ndarray:
        """World orientations of the body frames (7, 4; 9, 4 with ``dims=3``) as ``(w, x, y,
        z)``."""
        return self._w.orientations()

    def link_boxes(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """The box drawn for each body, in its body frame: ``(centre (3,), half extents (3,))``
        (m). The torso, thighs and shins are the uniform boxes of the model's inertias
        (length along y); a foot is laid along x from heel to toe (in 3-D its heel half and
        its toe half) and reaches from the ankle down to the sole."""
        return [(np.array(c), np.array(h)) for c, h in self._w.link_boxes()]

    def __repr__(self) -> str:
        return (
            f"Biped(dims={self.dims}, time={self.time:.4g} s, x={self.com[0]:.3g} m, "
            f"steps={self.steps})"
        )


class Tracker:
    """The ragdoll of an ASF ``skeleton`` tracking ``motion`` (an AMC clip of it), or of a
    BVH ``skeleton`` tracking its motion (both from :func:`kinema.mocap.read_bvh`; ``scale``,
    metres per file unit, is then required), frame by frame (docs/character.md, "Mocap
    tracking").

    Every hinge and ball joint gets a stable PD servo (``kp`` N m/rad, ``kd`` N m s/rad,
    ``max_torque`` N m; ``kp=0``: limp) towards the clip's next frame; the root gets a
    "hand of God", a critically damped spring (``assist_frequency`` ω rad/s, 0 for none,
    ``assist_damping`` ζ) towards the clip's root, force ``m (ω² e + 2ζω ė)`` with ``m``
    the total mass and torque likewise with the body's rotational inertia about the root.
    Each frame is ``substeps`` steps of ``1 / (frame rate × substeps)`` s (default 4 at the
    CMU 120 Hz: 1/480 s). The clip is lifted onto the ground and looped (between its two
    most alike frames, see :attr:`loop_span`) when tracked longer than it lasts. The ragdoll
    starts at clip frame ``start_frame`` (its pose, rates and servo targets; below the loop's
    end, ``loop_span[1]``); the lift and the loop are the whole clip's, so it tracks what a
    tracker started at frame 0 tracks from that frame on. Ragdoll options (``density``,
    ``scale``, ...) as :meth:`Ragdoll.from_skeleton`.
    """

    def __init__(
        self,
        skeleton: Any,
        motion: Any,
        *,
        kp: float = 300.0,
        kd: float = 30.0,
        max_torque: float = np.inf,
        assist_frequency: float = 40.0,
        assist_damping: float = 1.0,
        substeps: int = 4,
        density: float = 1000.0,
        scale: float | None = None,
        radius_ratio: float = 0.15,
        min_radius: float = 0.02,
        damping: float = 2.0,
        start_frame: int = 0,
    ) -> None:
        if not isinstance(skeleton, (_kinema.AsfSkeleton, _kinema.BvhSkeleton)):
            raise TypeError(
                "skeleton: expected an ASF or a BVH skeleton (kinema.mocap.read_asf, "
                f"read_bvh), got {type(skeleton).__name__}"
            )
        if not isinstance(motion, _kinema.AmcMotion):
            raise TypeError(
                "motion: expected a motion (kinema.mocap.read_amc, read_bvh), "
                f"got {type(motion).__name__}"
            )
        if scale is None and isinstance(skeleton, _kinema.BvhSkeleton):
            raise ValueError("scale: required for a BVH skeleton (metres per file unit)")
        ragdoll = [
            real(density, "density"),
            real(radius_ratio, "radius_ratio"),
            real(min_radius, "min_radius"),
            real(damping, "damping"),
            0.0,
        ]
        self._t = _kinema.Tracker(
            skeleton,
            motion,
            ragdoll,
            None if scale is None else real(scale, "scale"),
            real(kp, "kp"),
            real(kd, "kd"),
            real(max_torque, "max_torque"),
            real(assist_frequency, "assist_frequency"),
            real(assist_damping, "assist_damping"),
            _index(substeps, "substeps"),
            _index(start_frame, "start_frame"),
        )

    def step(self, frames: int = 1) -> dict[str, np.ndarray]:
        """Track ``frames`` frames; return per frame ``time`` (s, at the frame's end),
        ``root_error`` (m, root to the clip's root), ``joint_error`` (rad, RMS over hinge and
        ball joints of the angle to the clip's), ``assist_force`` (N) and
        ``assist_torque`` (N m) (means over the frame's steps). A frame that diverges raises
        :class:`kinema.SimulationError` and is undone; the frames before it stay done."""
        rows = self._t.step(_index(frames, "frames"))
        keys = ("time", "root_error", "joint_error", "assist_force", "assist_torque")
        return {k: rows[:, i].copy() for i, k in enumerate(keys)}

    @property
    def q(self) -> np.ndarray:
        """The ragdoll's coordinates ``(nq,)`` (a copy; layout of :class:`ArticulatedBody`)."""
        return np.array(self._t.q)

    @property
    def reference_q(self) -> np.ndarray:
        """The clip's coordinates for the current frame ``(nq,)`` (a copy)."""
        return np.array(self._t.reference_q)

    @property
    def frame(self) -> int:
        """The clip frame the ragdoll is at: ``start_frame`` plus the frames tracked."""
        return int(self._t.frame)

    @property
    def time(self) -> float:
        """Simulated time (s)."""
        return float(self._t.time)

    @property
    def frame_rate(self) -> float:
        """The clip's frame rate (Hz); a frame lasts its inverse."""
        return float(self._t.frame_rate)

    @property
    def loop_span(self) -> tuple[int, int]:
        """``(a, b)``: after frame ``b - 1`` the clip goes on from frame ``a``."""
        a, b = self._t.loop_span
        return int(a), int(b)

    @property
    def mass(self) -> float:
        """Total mass of the ragdoll (kg)."""
        return float(self._t.mass)

    @property
    def names(self) -> list[str]:
        """Body names, in order."""
        return list(self._t.names())

    def positions(self) -> np.ndarray:
        """World positions of the body frames ``(n, 3)`` (m)."""
        return self._t.positions()

    def orientations(self) -> np.ndarray:
        """World orientations of the body frames ``(n, 4)`` as ``(w, x, y, z)``."""
        return self._t.orientations()

    def capsules(self) -> list[tuple[np.ndarray, np.ndarray, float] | None]:
        """Each body's capsule ``(a, b, radius)`` (m, body frame), as
        :meth:`ArticulatedBody.capsules`."""
        return [
            None if c is None else (np.array(c[0]), np.array(c[1]), float(c[2]))
            for c in self._t.capsules()
        ]
