"""Cloth: Baraff–Witkin (1998) "Large Steps" triangle model and mass-spring, stepped implicitly.

Build a :class:`Cloth` from a grid (:meth:`Cloth.grid`), arrays or an OBJ file, hold vertices
with :meth:`Cloth.pin` / :meth:`Cloth.constrain` / :meth:`Cloth.prescribe` (mass-modification
constraints, Baraff & Witkin §5.3), add colliders (:class:`Plane`, :class:`Sphere`, :class:`Capsule`, :class:`Box`, the shapes of
:mod:`kinema.geometry` re-exported here, which may move at
a constant velocity or be moved with :meth:`Cloth.set_collider`) and moving triangle meshes
(:meth:`Cloth.add_mesh_collider`), and :meth:`Cloth.step`.

Integrators: ``"implicit_euler"`` (the paper's one Newton step per time step), ``"bdf2"``
(Choi & Ko 2002, second order, less numerical damping), or any explicit method of
:mod:`kinema.ode` (``"symplectic_euler"``, ``"rk4"``, ...) for comparison — they need far
smaller steps. Solvers for the implicit step: ``"cholesky"`` (the default: faer's sparse
Cholesky, symbolic analysis done once, exact to rounding; 2–5x faster than multigrid at tol 1e-6
on the hanging sheet and the drape from 32² to 256², docs/cloth.md), ``"multigrid"``
(conjugate gradient with the constraint filter, preconditioned by smoothed aggregation
multigrid, Tamstorf, Jones & McCormick 2015) or ``"block_ssor"`` (the paper's modified
preconditioned conjugate gradient with a block SSOR preconditioner), both to the tolerance
``tol``. After the solve, strain limiting (Provot 1995) shortens
every edge to within ``1 + max_strain`` times its rest length (3 % by default), in sweeps
outward from the held vertices until no edge exceeds it by more than 10⁻⁴ (at most 64 a step;
docs/cloth.md).

Units: metres, kilograms, seconds; ``density`` kg/m², ``stretch`` and ``shear`` N/m (membrane
stiffness, independent of the mesh resolution), ``bend`` N·m, ``damping`` s (stiffness
proportional: ``k_d = damping · k``), ``air_damping`` 1/s (``f = -air_damping · m v``).
``positions`` and ``velocities`` are read-only ``(N, 3)`` numpy views of the Rust state,
updated in place by every step. Self-collision (``self_collision=True``) follows Bridson,
Fedkiw & Anderson (2002); see :class:`Cloth`.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from kinema import _kinema
from kinema._array import as_batch, as_vector3, real
from kinema.geometry import Box, Capsule, Plane, Shape, Sphere, shape_params

__all__ = ["Box", "Capsule", "Cloth", "Plane", "Sphere"]

MODELS = ("baraff_witkin", "mass_spring")

MATERIAL = {
    "density": 1.0,
    "stretch": 1e4,
    "shear": 1e3,
    "bend": 1e-3,
    "damping": 0.1,
    "air_damping": 0.0,
}
"""The default material (the one place it is written in Python), cotton-like: 1 kg/m², stretch
1e4 N/m, shear 1e3 N/m, bending 1e-3 N m, stiffness-proportional damping 0.1 s, no air
damping."""
_CONTACT = ("thickness", "self_collision", "self_friction", "self_iterations")


def _collider(c: Shape) -> tuple[str, list[float]]:
    """The compiled collider's kind and parameters: the shape's, then velocity and friction."""
    kind, p = shape_params(c)
    if c.restitution is not None:
        raise ValueError("restitution: cloth contacts are inelastic; leave it None for cloth")
    if isinstance(c, Sphere) and c.inside:
        raise ValueError("inside: cloth collides with the outside of a sphere only")
    return kind, p + as_vector3(c.velocity, "velocity") + [
        0.5 if c.friction is None else float(c.friction)
    ]


def _material(
    model: str,
    density: float,
    stretch: float,
    shear: float,
    bend: float,
    damping: float,
    air_damping: float,
) -> list[float]:
    if model not in MODELS:
        raise ValueError(f"model: {model!r} is not one of {', '.join(MODELS)}")
    return [float(x) for x in (density, stretch, shear, bend, damping, air_damping)]


def _options(model: str, kwargs: dict[str, Any]) -> tuple[list[float], dict[str, Any]]:
    """The material (the defaults of :data:`MATERIAL` for what ``kwargs`` leaves out) and the
    contact keywords of :class:`Cloth` in ``kwargs``; anything else is a ``TypeError``."""
    unknown = set(kwargs) - set(MATERIAL) - set(_CONTACT)
    if unknown:
        raise TypeError(f"unexpected keyword arguments: {sorted(unknown)}")
    material = {**MATERIAL, **{k: v for k, v in kwargs.items() if k in MATERIAL}}
    contact = {k: v for k, v in kwargs.items() if k in _CONTACT}
    return _material(model, **material), contact


class Cloth:
    """A piece of cloth (see the module docstring for units and methods).

    ``Cloth(vertices, triangles, uv=None, ...)``: ``vertices`` ``(N, 3)`` m, ``triangles``
    ``(M, 3)`` vertex indices (counter-clockwise from the front), optional ``uv`` ``(M, 3, 2)``
    rest coordinates of each triangle corner in metres (default: the initial shape). Vertex
    masses are ``density × area / 3`` summed over each vertex's triangles. Meshes with
    zero-area triangles, repeated indices, edges in more than two triangles, unused vertices or
    non-finite coordinates are rejected with a ``ValueError`` naming the culprit; duplicate
    vertices at one position are a seam (allowed).

    ``thickness`` (m) is the distance contacts keep: from colliders, and between layers of the
    cloth with ``self_collision=True``; default 1 mm, or a tenth of the mean edge length of
    the initial shape with self-collision. ``self_collision`` turns on robust self-collision
    (Bridson, Fedkiw & Anderson 2002: proximity repulsions with Coulomb friction
    ``self_friction`` between layers, continuous collision detection with up to
    ``self_iterations`` passes of impulses, then rigid impact zones) for the implicit
    integrators; no vertex ends a step closer than a quarter of the thickness to a triangle
    it is not a corner of, and no two triangles that share no vertex intersect (when the
    cloth starts without). Off, it costs nothing.
    """

    def __init__(
        self,
        vertices: Any,
        triangles: Any,
        uv: Any = None,
        *,
        model: str = "baraff_witkin",
        density: float = MATERIAL["density"],
        stretch: float = MATERIAL["stretch"],
        shear: float = MATERIAL["shear"],
        bend: float = MATERIAL["bend"],
        damping: float = MATERIAL["damping"],
        air_damping: float = MATERIAL["air_damping"],
        gravity: Any = (0.0, -9.81, 0.0),
        thickness: float | None = None,
        self_collision: bool = False,
        self_friction: float = 0.1,
        self_iterations: int = 8,
        _core: Any = None,
    ) -> None:
        if _core is None:
            x, _ = as_batch(vertices, "vertices", (3,))
            t = np.asarray(triangles)
            if t.ndim != 2 or t.shape[1] != 3 or not np.issubdtype(t.dtype, np.integer):
                raise ValueError(
                    f"triangles: expected integer indices of shape (M, 3), got {t.shape} {t.dtype}"
                )
            tri = np.ascontiguousarray(t, dtype=np.float64)
            corner_uv = None
            if uv is not None:
                u, _ = as_batch(uv, "uv", (3, 2))
                corner_uv = np.ascontiguousarray(u.reshape(-1, 6))
            mat = _material(model, density, stretch, shear, bend, damping, air_damping)
            _core = _kinema.ClothCore(x, tri, corner_uv, model, mat, as_vector3(gravity, "gravity"))
        self._core = _core
        mu = real(self_friction, "self_friction")
        if not mu >= 0.0:
            raise ValueError("self_friction: must be finite and >= 0")
        self._core.set_self_collision(bool(self_collision), mu, self_iterations)
        if thickness is None:
            thickness = 0.1 * self._core.mean_edge_length if self_collision else 1e-3
        self._core.set_thickness(real(thickness, "thickness"))
        self.model = model

    @classmethod
    def grid(
        cls,
        nx: int,
        ny: int,
        width: float = 1.0,
        height: float = 1.0,
        *,
        triangulation: str = "alternating",
        model: str = "baraff_witkin",
        gravity: Any = (0.0, -9.81, 0.0),
        **kwargs: Any,
    ) -> Cloth:
        """An ``nx`` by ``ny`` grid of vertices in the x–z plane at height 0, centred on the origin.

        ``width`` (m) along x, ``height`` (m) along z; vertex ``i + nx*j`` is at
        ``(-width/2 + i·width/(nx-1), 0, -height/2 + j·height/(ny-1))``; rest coordinates
        ``(u, v) = (x, z)``. ``triangulation`` is ``"alternating"`` (checkerboard diagonals, no
        preferred shear direction) or ``"regular"``. Other keyword arguments (material,
        contact) as for :class:`Cloth`.
        """
        mat, contact = _options(model, kwargs)
        g = as_vector3(gravity, "gravity")
        core = _kinema.ClothCore.grid(
            nx, ny, real(width, "width"), real(height, "height"), triangulation, model, mat, g
        )
        return cls(None, None, model=model, _core=core, **contact)

    @classmethod
    def from_obj(cls, path: str | os.PathLike[str], **kwargs: Any) -> Cloth:
        """Read a Wavefront OBJ (``v``, ``vt``, ``f``; polygons split into fans).

        Texture coordinates, when every face corner has one, are the rest ``(u, v)`` in
        metres; otherwise the initial shape is the rest state. Keyword arguments as for
        :class:`Cloth`.
        """
        model = kwargs.pop("model", "baraff_witkin")
        gravity = as_vector3(kwargs.pop("gravity", (0.0, -9.81, 0.0)), "gravity")
        mat, contact = _options(model, kwargs)
        data = Path(path).read_bytes()
        try:
            text = data.decode("utf-8")
        except UnicodeDecodeError as e:
            line = data[: e.start].count(b"\n") + 1
            raise _kinema.ParseError(f"{path}:{line}: not UTF-8 text") from None
        core = _kinema.ClothCore.from_obj(text, str(path), model, mat, gravity)
        return cls(None, None, model=model, _core=core, **contact)

    def to_obj(self, path: str | os.PathLike[str]) -> None:
        """Write the current shape as a Wavefront OBJ."""
        with open(path, "w", encoding="utf-8") as f:
            f.write(self._core.to_obj())

    def pin(self, indices: Any, positions: Any = None) -> None:
        """Hold vertices ``indices`` at ``positions`` ``(K, 3)`` m (default: where they are).

        Call again with new positions to move pinned vertices (they move there in the next step).
        """
        idx = self._indices(indices)
        p = None if positions is None else as_batch(positions, "positions", (3,))[0]
        self._core.pin(idx, p)

    def constrain(
        self, indices: Any, *, plane_normal: Any = None, line_direction: Any = None
    ) -> None:
        """Let vertices move only in a plane (through where they are, with ``plane_normal``) or
        along a line (``line_direction``). Exactly one of the two must be given."""
        if (plane_normal is None) == (line_direction is None):
            raise ValueError("constrain: give exactly one of plane_normal= or line_direction=")
        kind, d = ("plane", plane_normal) if plane_normal is not None else ("line", line_direction)
        self._core.constrain(
            self._indices(indices),
            kind,
            as_vector3(d, "plane_normal" if kind == "plane" else "line_direction"),
        )

    def prescribe(self, indices: Any, velocities: Any) -> None:
        """Make vertices ``indices`` move at ``velocities`` ``(K, 3)`` m/s (or one velocity for
        all): a mass-modification constraint (Baraff & Witkin §5.3) until :meth:`free`."""
        idx = self._indices(indices)
        v, single = as_batch(velocities, "velocities", (3,))
        if single:
            v = np.repeat(v, len(idx), axis=0)
        if v.shape[0] != len(idx):
            raise ValueError(
                f"velocities: expected ({len(idx)}, 3) for {len(idx)} indices, got {v.shape}"
            )
        self._core.prescribe(idx, v)

    def free(self, indices: Any) -> None:
        """Remove the pins and constraints of ``indices``."""
        self._core.constrain(self._indices(indices), "free", [0.0, 0.0, 0.0])

    def add_collider(self, collider: Plane | Sphere | Capsule | Box) -> int:
        """Add a kinematic collider; returns its index (for :meth:`set_collider`)."""
        return int(self._core.add_collider(*_collider(collider)))

    def set_collider(self, index: int, collider: Plane | Sphere | Capsule | Box) -> None:
        """Replace collider ``index`` (move it along any path between steps)."""
        self._core.set_collider(index, *_collider(collider))

    def add_mesh_collider(
        self, vertices: Any, triangles: Any, velocities: Any = None, friction: float = 0.5
    ) -> int:
        """Add a kinematic triangle mesh (a character's body) as a collider; returns its index
        (for :meth:`set_mesh_collider`).

        ``vertices`` ``(V, 3)`` m at the current time, ``triangles`` ``(T, 3)`` integer
        indices, ``velocities`` ``(V, 3)`` m/s (default at rest): over a step of ``h`` each
        vertex moves linearly by ``velocity · h``. Coulomb ``friction`` (>= 0) between the mesh
        and the cloth. The cloth meets the mesh in the collision filter of Bridson, Fedkiw &
        Anderson (2002) after each implicit step — proximity repulsion with friction within
        ``thickness``, continuous collision detection of the cloth's vertices and edges against
        the mesh's moving triangles and edges, rigid impact zones as the fail-safe — so no
        cloth vertex or edge crosses the mesh during a step, however fast it moves, provided
        the cloth does not start the step through it. The mesh need not be closed; it is
        never moved by the cloth. Implicit integrators only.
        """
        x, _ = as_batch(vertices, "vertices", (3,))
        t = np.asarray(triangles)
        if t.ndim != 2 or t.shape[1] != 3 or not np.issubdtype(t.dtype, np.integer):
            raise ValueError(
                f"triangles: expected integer indices of shape (T, 3), got {t.shape} {t.dtype}"
            )
        v = None if velocities is None else as_batch(velocities, "velocities", (3,))[0]
        tri = np.ascontiguousarray(t, dtype=np.float64)
        return int(self._core.add_mesh_collider(x, tri, v, real(friction, "friction")))

    def set_mesh_collider(self, index: int, vertices: Any, velocities: Any = None) -> None:
        """Set the vertices ``(V, 3)`` m of mesh collider ``index`` at the current time and
        their velocities ``(V, 3)`` m/s over the next steps (default at rest). To follow an
        animation at frame ``f``: ``set_mesh_collider(i, pose[f], (pose[f + 1] - pose[f]) / dt)``
        before ``step(dt)``."""
        x, _ = as_batch(vertices, "vertices", (3,))
        v = None if velocities is None else as_batch(velocities, "velocities", (3,))[0]
        self._core.set_mesh_collider(index, x, v)

    @property
    def mesh_colliders(self) -> int:
        """The number of mesh colliders."""
        return int(self._core.mesh_colliders)

    def step(
        self,
        dt: float,
        steps: int = 1,
        *,
        integrator: str = "implicit_euler",
        solver: str = "cholesky",
        tol: float = 1e-6,
        max_iterations: int = 1000,
        max_strain_change: float = 0.01,
        max_strain: float = 0.03,
    ) -> None:
        """Advance ``steps`` steps of ``dt`` seconds (GIL released).

        ``integrator``: ``"implicit_euler"``, ``"bdf2"`` or an explicit method of
        :mod:`kinema.ode`. ``solver``: ``"cholesky"`` (the default, exact to rounding; ``tol``
        and ``max_iterations`` do not apply), ``"multigrid"`` or ``"block_ssor"`` (conjugate gradient
        with that preconditioner; it stops when ``sqrt(rᵀ M⁻¹ r / bᵀ M⁻¹ b) < tol`` for the
        filtered system ``A Δv = b`` of the step's velocity change, or after ``max_iterations``;
        see ``stats["converged"]``; with multigrid, ``M⁻¹ ≈ A⁻¹`` and ``tol`` bounds the
        relative error of ``Δv`` in the energy norm ``‖·‖_A``). After the
        solve edges longer than ``1 + max_strain`` times their rest length are shortened to it
        (strain limiting, Provot 1995, to within 10⁻⁴ in at most 64 sweeps a step; default
        3 %, ``inf`` turns it off). An implicit step that changes any stretch
        ratio by more than ``max_strain_change`` (measured after the strain limit) is redone as
        two half steps (Baraff & Witkin §5; ``stats["substeps"]`` counts them; ``inf`` turns this off). On divergence a
        :class:`kinema.SimulationError` names the step and vertex and the cloth stays at the
        last good step.
        """
        self._core.step(
            real(dt, "dt"),
            steps,
            integrator,
            solver,
            real(tol, "tol"),
            max_iterations,
            real(max_strain_change, "max_strain_change"),
            real(max_strain, "max_strain"),
        )

    def set_state(self, positions: Any, velocities: Any = None) -> None:
        """Overwrite positions (and velocities, default zero), ``(N, 3)``."""
        x, _ = as_batch(positions, "positions", (3,))
        v = np.zeros_like(x) if velocities is None else as_batch(velocities, "velocities", (3,))[0]
        self._core.set_state(x, v)

    @property
    def positions(self) -> np.ndarray:
        """Vertex positions ``(N, 3)`` m (read-only view, updated in place)."""
        return self._core.positions

    @property
    def velocities(self) -> np.ndarray:
        """Vertex velocities ``(N, 3)`` m/s (read-only view, updated in place)."""
        return self._core.velocities

    @property
    def masses(self) -> np.ndarray:
        """Vertex masses ``(N,)`` kg."""
        return self._core.masses

    @property
    def triangles(self) -> np.ndarray:
        """Triangles ``(M, 3)`` as int64 vertex indices."""
        return self._core.triangles.astype(np.int64)

    @property
    def time(self) -> float:
        """Simulated time (s)."""
        return float(self._core.time)

    @property
    def stats(self) -> dict[str, Any]:
        """Numbers of the last step: ``iterations`` (PCG), ``residual`` (relative),
        ``converged``, ``contacts``, ``substeps``, ``newton_iterations`` (solves beyond the
        first where the linearised solve added energy), self-collision's ``proximities`` (pairs
        closer than the thickness), ``ccd_iterations`` (passes that found collisions) and
        ``impact_zones``, and seconds spent in ``assemble_seconds``, ``solve_seconds``,
        ``collide_seconds``, ``self_collision_seconds``."""
        return dict(self._core.stats())

    @property
    def thickness(self) -> float:
        """Contact thickness (m), see :class:`Cloth`."""
        return float(self._core.thickness)

    @property
    def self_collision(self) -> bool:
        """Whether self-collision is on."""
        return self._core.self_collision is not None

    def self_intersections(self) -> np.ndarray:
        """The pairs ``(K, 2)`` (int64, ``i < j``) of triangles that share no vertex and intersect
        in the current shape, by an exact all-pairs test (a sweep along x, each candidate pair
        decided with exact orientation predicates after Shewchuk 1997). Empty for a cloth that
        does not pass through itself."""
        return np.asarray(self._core.self_intersections()).astype(np.int64).reshape(-1, 2)

    def forces(self) -> np.ndarray:
        """Net force ``(N, 3)`` N on each vertex (gravity, elastic, damping; not constraints)."""
        return np.asarray(self._core.forces())

    @property
    def material(self) -> dict[str, float]:
        """``density`` (kg/m²), ``stretch``, ``shear`` (N/m), ``bend`` (N m), ``damping`` (s),
        ``air_damping`` (1/s), as given at construction."""
        names = ("density", "stretch", "shear", "bend", "damping", "air_damping")
        return dict(zip(names, self._core.material, strict=True))

    def fastest_mode(self) -> tuple[float, float]:
        """The fastest mode of small vibrations about the current shape: ``(ω, c)``, the highest
        angular frequency (rad/s) and the highest damping rate (1/s), by power iteration. Its
        eigenvalues ``(-c ± √(c² - 4ω²)) / 2`` must lie in an explicit integrator's stability
        region (:func:`kinema.ode.max_stable_dt`); ``kinema.Scene`` checks that before a run."""
        omega, c = self._core.fastest_mode()
        return real(omega, "omega"), float(c)

    def energy(self) -> dict[str, float]:
        """``kinetic``, ``potential`` (gravity, ``-Σ m g·x``) and ``elastic`` energy in J."""
        k, p, e = self._core.energy()
        return {"kinetic": k, "potential": p, "elastic": e}

    def __len__(self) -> int:
        return int(self._core.positions.shape[0])

    def __repr__(self) -> str:
        return f"Cloth({len(self)} vertices, {self.triangles.shape[0]} triangles, model={self.model!r})"

    def _indices(self, indices: Any) -> list[int]:
        a = np.atleast_1d(np.asarray(indices))
        if a.ndim != 1 or (a.size and not np.issubdtype(a.dtype, np.integer)):
            raise ValueError(
                f"indices: expected a 1-D array of integer vertex indices, got {a.dtype} {a.shape}"
            )
        return [int(i) for i in a]
