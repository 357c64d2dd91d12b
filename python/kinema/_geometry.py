"""What a scene looks like: triangle meshes, point clouds and line segments in world
coordinates (m), shared by :mod:`kinema.plot` (pictures) and :meth:`kinema.Scene.export_obj`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from kinema import character as _character
from kinema import cloth as _cloth
from kinema import fluid as _fluid
from kinema import particles as _particles
from kinema import rigid as _rigid
from kinema.rotation import Rotation


@dataclass
class Geometry:
    """One frame of a scene: named ``meshes`` (vertices ``(V, 3)``, triangles ``(T, 3)``),
    ``points`` ``(P, 3)`` and ``segments`` ``(S, 2, 3)``."""

    meshes: dict[str, tuple[np.ndarray, np.ndarray]]
    points: dict[str, np.ndarray]
    segments: dict[str, np.ndarray]


def uv_sphere(
    radius: float, rings: int = 8, sectors: int = 16, stretch: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """A sphere of ``radius`` around the origin, or a capsule along Y when ``stretch`` (m) moves
    the upper hemisphere up and the lower down by ``stretch / 2``."""
    theta = np.linspace(0.0, np.pi, rings + 1)
    phi = np.linspace(0.0, 2 * np.pi, sectors, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    v = radius * np.stack([np.sin(t) * np.cos(p), np.cos(t), np.sin(t) * np.sin(p)], axis=-1)
    v = v.reshape(-1, 3)
    v[:, 1] += np.where(v[:, 1] >= 0, 0.5, -0.5) * stretch
    tris = []
    for i in range(rings):
        for j in range(sectors):
            a, b = i * sectors + j, i * sectors + (j + 1) % sectors
            c, d = a + sectors, b + sectors
            tris += [(a, b, d), (a, d, c)]
    return v, np.array(tris, dtype=np.int64)


def box(half: Any) -> tuple[np.ndarray, np.ndarray]:
    """A box of half extents ``half`` (m) around the origin."""
    signs = np.array(
        [[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=np.float64
    )
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    tris = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
    return signs * np.asarray(half, dtype=np.float64), np.array(tris, dtype=np.int64)


def cylinder(radius: float, height: float, sectors: int = 16) -> tuple[np.ndarray, np.ndarray]:
    """A closed cylinder along Y, centred at the origin."""
    phi = np.linspace(0.0, 2 * np.pi, sectors, endpoint=False)
    ring = np.stack([radius * np.cos(phi), np.zeros(sectors), radius * np.sin(phi)], axis=1)
    lift = np.array([0.0, height / 2, 0.0])
    top, bottom = ring + lift, ring - lift
    v = np.vstack([bottom, top, [[0, -height / 2, 0], [0, height / 2, 0]]])
    n, cb, ct = sectors, 2 * sectors, 2 * sectors + 1
    tris = []
    for j in range(n):
        k = (j + 1) % n
        tris += [(j, k, n + k), (j, n + k, n + j), (cb, k, j), (ct, n + j, n + k)]
    return v, np.array(tris, dtype=np.int64)


PLANE_SIZE = 10.0
"""Side (m) of the square drawn for an (infinite) plane collider, centred at its point."""


def turn_y_to(direction: Any) -> np.ndarray:
    """The shortest turn ``(w, x, y, z)`` taking +Y onto ``direction`` (the identity for a
    zero vector, half a turn about X for -Y)."""
    d = np.asarray(direction, dtype=np.float64)
    n = float(np.linalg.norm(d))
    if n == 0.0:
        return np.array([1.0, 0.0, 0.0, 0.0])
    d = d / n
    if d[1] < -1.0 + 1e-12:
        return np.array([0.0, 1.0, 0.0, 0.0])
    q = np.array([1.0 + d[1], d[2], 0.0, -d[0]])  # (1 + Y·d, Y × d)
    return q / np.linalg.norm(q)


def shape_frame(shape: Any) -> tuple[np.ndarray, np.ndarray]:
    """The frame of a :mod:`kinema.geometry` shape: position (m) and orientation
    ``(w, x, y, z)``; :func:`shape_mesh` is the shape in that frame. A plane's frame sits at
    its point with +Y along its normal, a capsule's at its axis's midpoint with +Y along it."""
    from kinema import geometry

    kind, p = geometry.shape_params(shape)
    if kind == "plane":
        return np.array(p[:3]), turn_y_to(p[3:6])
    if kind == "sphere":
        return np.array(p[:3]), np.array([1.0, 0.0, 0.0, 0.0])
    if kind == "capsule":
        a, b = np.array(p[:3]), np.array(p[3:6])
        return 0.5 * (a + b), turn_y_to(b - a)
    return np.array(p[:3]), np.array(p[3:7])


def shape_mesh(shape: Any) -> tuple[np.ndarray, np.ndarray]:
    """The triangle mesh of a :mod:`kinema.geometry` shape in its :func:`shape_frame`: a
    square of side :data:`PLANE_SIZE` in the x–z plane for a plane, a sphere, a capsule along
    Y, a box."""
    from kinema import geometry

    kind, p = geometry.shape_params(shape)
    if kind == "plane":
        h = 0.5 * PLANE_SIZE
        v = np.array([[-h, 0.0, -h], [h, 0.0, -h], [h, 0.0, h], [-h, 0.0, h]])
        return v, np.array([[0, 2, 1], [0, 3, 2]], dtype=np.int64)
    if kind == "sphere":
        return uv_sphere(p[3])
    if kind == "capsule":
        return uv_sphere(p[6], stretch=float(np.linalg.norm(np.subtract(p[3:6], p[:3]))))
    return box(p[7:10])


def capsule(a: Any, b: Any, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """The triangle mesh of the capsule of ``radius`` (m) around the segment ``a``–``b`` (m),
    in the frame of ``a`` and ``b``."""
    from kinema import geometry

    c = geometry.Capsule(a, b, radius)
    x, q = shape_frame(c)
    v, t = shape_mesh(c)
    return Rotation.from_quat(q).apply(v) + x, t


def body_mesh(shape: Any) -> tuple[np.ndarray, np.ndarray]:
    """The body-frame triangle mesh of a :mod:`kinema.rigid` shape."""
    if isinstance(shape, _rigid.Sphere):
        return uv_sphere(float(shape.radius))
    if isinstance(shape, _rigid.Box):
        return box(shape.half_extents)
    if isinstance(shape, _rigid.Capsule):
        return uv_sphere(float(shape.radius), stretch=float(shape.height))
    if isinstance(shape, _rigid.Cylinder):
        return cylinder(float(shape.radius), float(shape.height))
    return np.asarray(shape.vertices, dtype=np.float64), np.asarray(shape.triangles, dtype=np.int64)


def of_scene(scene: Any) -> Geometry:
    """The geometry of ``scene`` (a :class:`kinema.Scene`) at its current time."""
    from kinema.scene import AnimatedSphere, Character

    g = Geometry({}, {}, {})
    for i, s in enumerate(scene.systems):
        if isinstance(s, _cloth.Cloth):
            g.meshes[f"cloth{i}"] = (s.positions.copy(), s.triangles.astype(np.int64))
        elif isinstance(s, _fluid.Fluid):
            v, t = s.surface_mesh()
            g.meshes[f"fluid{i}"] = (v, t.astype(np.int64))
        elif isinstance(s, _particles.ParticleSystem):
            g.points[f"particles{i}"] = s.positions[s.alive].copy()
        elif hasattr(s, "_particles"):  # a constrained system
            p = s._particles
            g.points[f"particles{i}"] = p.positions[p.alive].copy()
        elif isinstance(s, _rigid.World):
            x, q = s.positions, s.orientations
            for b, shape in enumerate(s.shapes):
                v, t = body_mesh(shape)
                g.meshes[f"body{i}_{b}"] = (Rotation.from_quat(q[b]).apply(v) + x[b], t)
        elif isinstance(s, AnimatedSphere):
            v, t = uv_sphere(float(s.radius))
            g.meshes[f"sphere{i}"] = (v + s.position(scene.time), t)
        elif isinstance(s, Character):
            j = s.joints(scene.time)
            g.segments[f"character{i}"] = np.stack([j[s._bones[:, 0]], j[s._bones[:, 1]]], axis=1)
        elif isinstance(s, (_character.ArticulatedBody, _character.Tracker)):
            x, q = s.positions(), s.orientations()
            for b, (name, c) in enumerate(zip(s.names, s.capsules(), strict=True)):
                if c is not None:
                    v, t = capsule(*c)
                    g.meshes[f"ragdoll{i}_{b}_{name}"] = (
                        Rotation.from_quat(q[b]).apply(v) + x[b],
                        t,
                    )
            colliders = s.colliders() if isinstance(s, _character.ArticulatedBody) else []
            for k, collider in enumerate(colliders):
                (p, r), (v, t) = shape_frame(collider), shape_mesh(collider)
                g.meshes[f"ragdoll{i}_collider{k}"] = (Rotation.from_quat(r).apply(v) + p, t)
    return g


def write_obj(path: Any, meshes: dict[str, tuple[np.ndarray, np.ndarray]]) -> None:
    """Write ``meshes`` as one Wavefront OBJ file with one object (``o``) per mesh."""
    lines = ["# kinema scene frame"]
    base = 1
    for name, (v, t) in meshes.items():
        lines.append(f"o {name}")
        lines += [f"v {a:.9g} {b:.9g} {c:.9g}" for a, b, c in v]
        lines += [f"f {a + base} {b + base} {c + base}" for a, b, c in t]
        base += len(v)
    with open(path, "w", encoding="utf-8") as f:
        f.write("\n".join(lines) + "\n")
