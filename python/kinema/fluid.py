"""Particle fluids by SPH: DFSPH (Bender & Koschier 2015, 2017), PBF (Macklin & Müller
2013) or WCSPH (Becker & Teschner 2007), walls sampled as boundary particles (Akinci et al.
2012), XSPH or implicit viscosity (Weiler et al. 2018), CFL substeps, emitters and a kill box.

Build a :class:`Fluid`, add tanks (:meth:`Fluid.add_boundary_box`) or floors
(:meth:`Fluid.add_boundary_plane`), solid obstacles of the shared shapes, fixed or moving
(:meth:`Fluid.add_collider`, :meth:`Fluid.set_collider`), fluid (:meth:`Fluid.add_block`) and
nozzles
(:meth:`Fluid.add_emitter`), then ``step`` it by frames: each frame is split into substeps
of the CFL condition. ``positions`` and ``velocities`` are read-only numpy views of the Rust
state, updated in place (no copy); once one was taken no more blocks, emitters or kill box
can be added (the views must stay valid). With emitters or a kill box the particle count
changes, and they are copies instead. Every per-particle array is in the order the particles
were added (the solver sorts its own copy by cell each frame and writes back in that order).
See docs/fluid.md.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from kinema import _kinema
from kinema._array import as_vector3, real
from kinema.geometry import Box, Capsule, Sphere, shape_params

__all__ = ["Fluid"]


class Fluid:
    """A fluid of particles ``spacing`` apart at rest (m; the kernel's support is twice it).

    ``rest_density`` in kg/m³; ``viscosity_model`` ``"xsph"`` (``viscosity`` the XSPH
    coefficient in [0, 1], default 0.01: the fraction by which a substep moves a velocity
    towards its neighbours' mean) or ``"implicit"`` (``viscosity`` the kinematic viscosity
    in m²/s, default 1e-6 for water; honey is about 1e-2: Weiler, Koschier, Brochard & Bender
    2018's implicit solve by preconditioned conjugate gradients, no-slip walls, stable at any
    substep); ``solver`` ``"dfsph"``
    (stops when the mean density error is below ``density_tolerance`` percent and the
    divergence error below ``divergence_tolerance`` percent, at most ``max_iterations``
    iterations per solve), ``"pbf"`` (position-based fluids: iterations until the mean
    density error is below ``density_tolerance`` percent, at most ``max_iterations``, with
    the tensile-instability term of strength ``tensile`` in [0, 1]) or ``"wcsph"`` (Tait
    equation with speed of sound ``sound_speed`` m/s); ``kernel`` ``"cubic"`` or ``"wendland"``;
    ``surface_tension`` Akinci, Akinci & Teschner's (2013) ``γ`` (0: off; cohesion and
    curvature terms, see docs/fluid.md for its units: not a surface tension in N/m). Substeps move no particle
    more than ``cfl`` spacings and last at most ``max_dt`` s; a frame needing more than
    ``max_substeps`` fails with :class:`kinema.SimulationError` (the fluid unchanged).
    """

    def __init__(
        self,
        spacing: float,
        rest_density: float = 1000.0,
        viscosity: float | None = None,
        solver: str = "dfsph",
        *,
        viscosity_model: str = "xsph",
        surface_tension: float = 0.0,
        kernel: str = "cubic",
        density_tolerance: float = 0.05,
        divergence_tolerance: float = 0.1,
        max_iterations: int = 100,
        sound_speed: float = 30.0,
        tensile: float = 0.1,
        cfl: float = 0.4,
        max_dt: float = 0.005,
        max_substeps: int = 10_000,
        gravity: Any = (0.0, -9.81, 0.0),
    ) -> None:
        if not isinstance(solver, str):
            raise TypeError("solver: expected 'dfsph', 'pbf' or 'wcsph'")
        if not isinstance(viscosity_model, str):
            raise TypeError("viscosity_model: expected 'xsph' or 'implicit'")
        if viscosity is None:
            viscosity = 1e-6 if viscosity_model == "implicit" else 0.01
        if not isinstance(kernel, str):
            raise TypeError("kernel: expected 'cubic' or 'wendland'")
        self._f = _kinema.Fluid(
            real(spacing, "spacing"),
            real(rest_density, "rest_density"),
            kernel,
            real(viscosity, "viscosity"),
            viscosity_model,
            real(surface_tension, "surface_tension"),
            solver,
            real(density_tolerance, "density_tolerance"),
            real(divergence_tolerance, "divergence_tolerance"),
            max_iterations,
            real(sound_speed, "sound_speed"),
            real(tensile, "tensile"),
            real(cfl, "cfl"),
            real(max_dt, "max_dt"),
            max_substeps,
            as_vector3(gravity, "gravity"),
        )

    def add_block(self, lower: Any, upper: Any, velocity: Any = (0.0, 0.0, 0.0)) -> int:
        """Fill the box ``[lower, upper]`` (m) with particles on a cubic lattice of the
        spacing (the first half a spacing inside ``lower``), moving at ``velocity`` (m/s).
        Returns the number added. The block must lie inside a tank if there is one and not
        overlap fluid already added."""
        lo, hi = as_vector3(lower, "lower"), as_vector3(upper, "upper")
        return self._f.add_block(lo, hi, as_vector3(velocity, "velocity"))

    def add_boundary_box(self, lower: Any, upper: Any) -> None:
        """Add a closed tank: the inside of the box ``[lower, upper]`` (m)."""
        self._f.add_boundary_box(as_vector3(lower, "lower"), as_vector3(upper, "upper"))

    def add_boundary_plane(self, point: Any, normal: Any, half_extent: float) -> None:
        """Add a floor: the square of half side ``half_extent`` (m) about ``point`` in the
        plane of ``normal`` (made unit), the fluid on the side it points to."""
        n = np.asarray(as_vector3(normal, "normal"))
        length = float(np.linalg.norm(n))
        if not length > 0.0:
            raise ValueError("normal: must be a non-zero vector")
        self._f.add_boundary_plane(
            as_vector3(point, "point"), (n / length).tolist(), real(half_extent, "half_extent")
        )

    def add_collider(self, shape: Sphere | Capsule | Box) -> int:
        """Add a solid obstacle (a :class:`kinema.geometry.Sphere`, ``Capsule`` or ``Box``
        of radius or half extents at least the spacing) moving at its ``velocity`` (m/s):
        sampled by boundary particles (Akinci et al. 2012) which carry that velocity, moved
        by ``velocity · dt`` every substep; the fluid feels it, it does not feel the fluid
        (one-way). Returns its index for :meth:`set_collider`. Add colliders before the
        fluid: :meth:`add_block` leaves out the lattice points within half a spacing of one,
        and a collider with fluid inside it is refused. A plane is refused (use
        :meth:`add_boundary_plane`); so are ``friction``, ``restitution`` and ``inside``."""
        return int(self._f.add_collider(*_collider(shape)))

    def set_collider(self, index: int, shape: Sphere | Capsule | Box) -> None:
        """Move collider ``index`` to ``shape``'s pose and velocity between steps (e.g. a
        rigid body's, each frame): the same kind and size as the collider added (a capsule
        may change its length, as a motion-captured bone does)."""
        self._f.set_collider(index, *_collider(shape))

    def add_emitter(self, position: Any, direction: Any, speed: float, radius: float) -> None:
        """Add a nozzle: a disc of ``radius`` (m, at least half a spacing) about ``position``
        (m) facing ``direction`` (made unit), emitting fluid at ``speed`` (m/s) in layers on
        the lattice of the spacing, one each time the fluid has moved a spacing: the mass
        flow is ``rest_density * A * speed`` with ``A`` about ``pi radius**2`` (the lattice's
        share of the disc). Points with fluid closer than half a spacing are skipped."""
        d = np.asarray(as_vector3(direction, "direction"))
        length = float(np.linalg.norm(d))
        if not length > 0.0:
            raise ValueError("direction: must be a non-zero vector")
        self._f.add_emitter(
            as_vector3(position, "position"),
            (d / length).tolist(),
            real(speed, "speed"),
            real(radius, "radius"),
        )

    def kill_box(self, lower: Any, upper: Any) -> None:
        """Remove every particle that is outside the box ``[lower, upper]`` (m) at the end of
        a substep (replacing an earlier kill box)."""
        self._f.kill_box(as_vector3(lower, "lower"), as_vector3(upper, "upper"))

    def step(self, dt: float, steps: int = 1) -> None:
        """Advance ``steps`` frames of ``dt`` seconds, each in CFL substeps (a frame ten
        times the CFL limit takes ten substeps or more)."""
        self._f.step(real(dt, "dt"), steps)

    def __len__(self) -> int:
        return len(self._f)

    @property
    def positions(self) -> np.ndarray:
        """Read-only view ``(N, 3)`` of the positions (m); a copy with emitters or a kill
        box."""
        return self._f.positions

    @property
    def velocities(self) -> np.ndarray:
        """Read-only view ``(N, 3)`` of the velocities (m/s); a copy with emitters or a kill
        box."""
        return self._f.velocities

    @property
    def densities(self) -> np.ndarray:
        """Densities ``(N,)`` (kg/m³) of the particles as they are now (a new array)."""
        return self._f.densities()

    @property
    def pressures(self) -> np.ndarray:
        """Pressures ``(N,)`` (Pa) of the last substep (a new array)."""
        return self._f.pressures()

    def surface_mesh(self, resolution: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The fluid's surface: vertices ``(V, 3)`` (m) and outward triangles ``(T, 3)``, the
        level ½ of the smoothed colour field ``Σ V W(x - x_j)`` (Müller et al. 2003) sampled
        every ``resolution`` m (default half the spacing) by marching tetrahedra: closed on
        a block or a settled column. Empty arrays for an empty fluid."""
        if resolution is None:
            resolution = 0.5 * self._f.spacing
        return self._f.surface_mesh(real(resolution, "resolution"))

    @property
    def boundary_particles(self) -> np.ndarray:
        """The boundary particles ``(B, 3)`` (m, a new array): the walls', then every
        collider's where it is now."""
        return self._f.boundary_particles()

    @property
    def particle_mass(self) -> float:
        """The mass of one particle (kg)."""
        return self._f.particle_mass

    @property
    def time(self) -> float:
        """Simulated time (s)."""
        return self._f.time

    @property
    def stats(self) -> dict[str, float]:
        """What the last ``step`` did: ``substeps``, ``density_iterations`` and
        ``divergence_iterations`` (summed over substeps), ``density_error`` (the largest
        mean compression over the substeps, percent), ``max_density_error`` (of any
        particle, percent), ``divergence_error`` (percent per substep),
        ``viscosity_iterations`` (conjugate-gradient iterations of the implicit viscosity,
        summed) and ``viscosity_error`` (its largest relative residual, percent)."""
        return self._f.stats()


def _collider(shape: Any) -> tuple[str, list[float]]:
    """The compiled collider's kind and parameters: the shape's, then its velocity."""
    if not isinstance(shape, (Sphere, Capsule, Box)):
        raise TypeError(
            "shape: expected a kinema.geometry Sphere, Capsule or Box (for a plane use "
            "add_boundary_plane)"
        )
    if shape.friction is not None or shape.restitution is not None:
        raise ValueError("friction: fluid colliders take no friction or restitution")
    if isinstance(shape, Sphere) and shape.inside:
        raise ValueError("inside: the fluid stays outside a collider")
    kind, p = shape_params(shape)
    return kind, p + as_vector3(shape.velocity, "velocity")
