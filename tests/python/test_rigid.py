"""kinema.rigid: mass properties, conservation laws and the Dzhanibekov flip through Python,
and the errors bad input gets."""

from __future__ import annotations

import numpy as np
import pytest

import kinema
from kinema import Rotation
from kinema.rigid import Box, Capsule, Cylinder, Mesh, Sphere, World

CUBE_V = np.array([[x, y, z] for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)], dtype=float)
CUBE_T = np.array(
    [
        q
        for f in [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ]
        for q in ([f[0], f[1], f[2]], [f[0], f[2], f[3]])
    ]
)


def test_mass_properties_of_primitives_and_meshes():
    w = World()
    s = w.add_body(Sphere(0.5), density=2.0)
    b = w.add_body(Box([1.0, 2.0, 3.0]), density=1.0)
    c = w.add_body(Cylinder(0.5, 2.0), mass=3.0)
    k = w.add_body(Capsule(0.7, 0.0), density=3.0)
    m = w.add_body(Mesh(CUBE_V * [1.0, 2.0, 3.0] + [5.0, 0.0, 0.0], CUBE_T), density=1.0)
    bodies = w.bodies
    ms = 2.0 * 4 / 3 * np.pi * 0.125
    assert bodies[s].mass == pytest.approx(ms, rel=1e-14)
    np.testing.assert_allclose(bodies[s].inertia, np.eye(3) * 0.4 * ms * 0.25, rtol=1e-14)
    np.testing.assert_allclose(np.diag(bodies[b].inertia), [208.0, 160.0, 80.0], rtol=1e-14)
    assert bodies[c].mass == 3.0
    np.testing.assert_allclose(
        np.diag(bodies[c].inertia), [3 / 12 * (0.75 + 4), 1.5 * 0.25, 3 / 12 * (0.75 + 4)]
    )
    assert bodies[k].mass == pytest.approx(
        3.0 * 4 / 3 * np.pi * 0.343, rel=1e-14
    )  # zero-length capsule
    np.testing.assert_allclose(bodies[m].inertia, bodies[b].inertia, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(bodies[m].center_of_mass, [5.0, 0.0, 0.0], atol=1e-13)


def test_bad_input_names_the_argument():
    w = World()
    with pytest.raises(ValueError, match="mass"):
        w.add_body(Sphere(1.0), mass=0.0)
    with pytest.raises(ValueError, match="not both"):
        w.add_body(Sphere(1.0), mass=1.0, density=1.0)
    with pytest.raises(ValueError, match="radius"):
        w.add_body(Sphere(-1.0))
    with pytest.raises(ValueError, match="not closed"):
        w.add_body(Mesh(CUBE_V, CUBE_T[:-1]))
    with pytest.raises(ValueError, match="must be positive"):
        w.add_body(Mesh(CUBE_V, CUBE_T[:, ::-1]))
    with pytest.raises(ValueError, match=r"triangles\[0\]"):
        w.add_body(Mesh(CUBE_V, CUBE_T + 0.5))
    with pytest.raises(ValueError, match="position"):
        w.add_body(Sphere(1.0), position=[np.nan, 0, 0])
    with pytest.raises(ValueError, match="shape"):
        w.add_body("sphere")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="integrator"):
        World(integrator="rk4")
    with pytest.raises(ValueError, match="dt"):
        w.step(-1.0)
    assert len(w) == 0


def spin(integrator: str, w0, steps=4000, dt=5e-3):
    world = World(gravity=[0, 0, 0], integrator=integrator)
    world.add_body(Box([1.0, 0.6, 0.2]), mass=1.0, angular_velocity=w0)
    l0, e0 = world.angular_momentum(), world.kinetic_energy()
    body_w = []
    for _ in range(steps):
        world.step(dt)
        r = Rotation.from_quat(world.orientations[0])
        body_w.append(r.apply(world.angular_velocities[0], inverse=True))
    return world, l0, e0, np.array(body_w)


def test_dzhanibekov_flip_and_conservation():
    world, l0, e0, w = spin("splitting", [1e-3, 8.0, 1e-3])
    flips = np.count_nonzero(np.diff(np.sign(w[:, 1])))
    assert flips >= 2
    np.testing.assert_allclose(world.angular_momentum(), l0, rtol=1e-10, atol=1e-12)
    assert abs(world.kinetic_energy() / e0 - 1) < 1e-3
    for axis, w0 in [(0, [8.0, 1e-3, 1e-3]), (2, [1e-3, 1e-3, 8.0])]:
        _, _, _, w = spin("splitting", w0, steps=1000)
        assert np.all(np.sign(w[:, axis]) == 1.0)


@pytest.mark.parametrize(
    ("integrator", "lo", "hi"),
    [
        ("explicit_euler", 1e-2, np.inf),
        ("implicit_gyroscopic", -0.5, 0.0),
        ("splitting", -1e-3, 1e-3),
    ],
)
def test_energy_behaviour_per_integrator(integrator, lo, hi):
    world, _, e0, _ = spin(integrator, [0.3, 5.0, 0.2], steps=1000, dt=1e-2)
    assert lo < world.kinetic_energy() / e0 - 1 < hi


def test_projectile_and_divergence():
    world = World()
    world.add_body(Sphere(0.1), velocity=[3.0, 4.0, 0.0])
    world.step(0.01, 100)
    np.testing.assert_allclose(world.positions[0], [3.0, 4.0 - 9.81 / 2, 0.0], atol=1e-12)
    bad = World(integrator="explicit_euler")
    with pytest.raises(ValueError, match=r"angular_velocity.*overflow"):
        bad.add_body(Box([1.0, 0.6, 0.2]), angular_velocity=[1e300, 1e300, 1e300])
    # 1e150 rad/s has a finite energy; an explicit Euler step's overflows: divergence.
    bad.add_body(Box([1.0, 0.6, 0.2]), angular_velocity=[1e150, 1e150, 1e150])
    before = bad.orientations.copy()
    with pytest.raises(kinema.SimulationError, match="step 0, element 0"):
        bad.step(1.0, 3)
    np.testing.assert_array_equal(bad.orientations, before)


def test_applied_force_makes_torque():
    world = World(gravity=[0, 0, 0])
    world.add_body(Box([1.0, 1.0, 1.0]), mass=1.0)
    world.apply_force(0, [1.0, 0.0, 0.0])
    world.step(0.1)
    np.testing.assert_allclose(world.angular_velocities[0], 0.0, atol=1e-15)
    world.apply_force(0, [1.0, 0.0, 0.0], point=world.positions[0] + [0.0, 1.0, 0.0])
    world.step(0.1)
    np.testing.assert_allclose(world.angular_velocities[0], [0, 0, -0.15], atol=1e-12)


def test_ground_contact_bounce_rest_and_bad_material():
    from kinema.rigid import Box, Sphere, World

    w = World()
    w.add_ground(0.0, restitution=0.5)
    ball = w.add_body(Sphere(0.1), mass=1.0, position=[0, 1.1, 0], restitution=0.5)
    crate = w.add_body(Box([0.2, 0.1, 0.2]), mass=2.0, position=[1, 0.15, 0])
    heights = []
    for _ in range(4000):
        w.step(2.5e-4)
        heights.append(w.positions[ball, 1] - 0.1)
    h = np.array(heights)
    assert h.min() > -1e-9  # never through the floor
    # First apex after the bounce: e² of the drop height (within the O(v dt) of the step).
    after = h[np.argmin(h[:2000]) :]
    assert abs(after.max() - 0.25) < 0.01
    assert abs(w.positions[crate, 1] - 0.1) < 1e-6
    assert np.linalg.norm(w.velocities[crate]) < 1e-9
    with pytest.raises(ValueError, match="restitution"):
        w.add_body(Sphere(0.1), restitution=1.5)
    with pytest.raises(ValueError, match="friction"):
        w.add_ground(friction=-0.1)


def test_contact_iterations_setting():
    w = World()
    assert w.contact_iterations == 40
    w.contact_iterations = 320
    assert w.contact_iterations == 320
    with pytest.raises(ValueError, match="contact_iterations"):
        w.contact_iterations = -1


def test_damping_decays_velocity_and_spin_at_the_analytic_rate():
    # A free body: v(t) = e^{-ct} v0 + (1 - e^{-ct})/c g exactly; a sphere's spin e^{-c_w t}.
    c, cw, t = 0.5, 1.5, 1.0
    w = World()
    i = w.add_body(
        Sphere(0.2),
        mass=1.0,
        velocity=[2.0, 0.0, -1.0],
        angular_velocity=[0.0, 4.0, 0.0],
        linear_damping=c,
        angular_damping=cw,
    )
    assert (w.bodies[i].linear_damping, w.bodies[i].angular_damping) == (c, cw)
    w.step(0.01, 100)
    s = -np.expm1(-c * t) / c
    v = np.exp(-c * t) * np.array([2.0, 0.0, -1.0]) + s * np.array([0.0, -9.81, 0.0])
    np.testing.assert_allclose(w.velocities[i], v, rtol=0, atol=1e-13)
    np.testing.assert_allclose(w.angular_velocities[i], [0, 4 * np.exp(-cw * t), 0], atol=1e-13)


def test_damping_is_named_when_bad_and_leaves_the_world_unchanged():
    w = World()
    for name, kwargs in [
        ("linear_damping", {"linear_damping": -1.0}),
        ("angular_damping", {"angular_damping": float("nan")}),
        ("linear_damping", {"linear_damping": "fast"}),
    ]:
        with pytest.raises(ValueError, match=name):
            w.add_body(Sphere(0.1), **kwargs)
    assert len(w) == 0
