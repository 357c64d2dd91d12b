"""kinema.fluid colliders from Python: the shared shapes as obstacles, moved by hand or by a
rigid body of a scene (the physics is tested in tests/fluid_collider.rs)."""

import pickle

import numpy as np
import pytest

import kinema
from kinema import rigid
from kinema.fluid import Fluid
from kinema.geometry import Box, Capsule, Plane, Sphere


def tank(**kw):
    f = Fluid(spacing=0.02, **kw)
    f.add_boundary_box([0, 0, 0], [0.4, 0.4, 0.2])
    return f


def test_colliders_are_sampled_moved_and_keep_the_fluid_out():
    f = tank()
    walls = len(f.boundary_particles)
    assert f.add_collider(Sphere([0.2, 0.1, 0.1], 0.05, velocity=[0.3, 0, 0])) == 0
    assert f.add_collider(Capsule([0.05, 0.3, 0.1], [0.15, 0.3, 0.1], 0.03)) == 1
    assert f.add_collider(Box([0.32, 0.1, 0.1], [0.04, 0.04, 0.04])) == 2
    b0 = f.boundary_particles
    assert len(b0) > walls
    # The block leaves out the lattice points near the colliders.
    n = f.add_block([0, 0, 0], [0.4, 0.2, 0.2])
    assert n == len(f) < 20 * 10 * 10
    f.step(1 / 60, steps=6)
    # The sphere moved 0.1 s at 0.3 m/s; its particles with it.
    moved = f.boundary_particles[walls:] - b0[walls:]
    sphere = np.abs(moved[:, 0] - 0.03) < 1e-9
    assert sphere.sum() > 0 and np.allclose(moved[~sphere], 0.0)
    centre = np.array([0.23, 0.1, 0.1])
    assert np.linalg.norm(f.positions - centre, axis=1).min() > 0.05
    # Moved by hand, a collider keeps its kind and size.
    f.set_collider(0, Sphere([0.2, 0.25, 0.1], 0.05))
    d = np.linalg.norm(f.boundary_particles[walls:][sphere] - [0.2, 0.25, 0.1], axis=1)
    assert np.ptp(d) < 1e-12 and d[0] == pytest.approx(0.05 - 0.6 * 0.02, rel=0.01)


def test_bad_colliders_are_named():
    f = tank()
    f.add_block([0, 0, 0], [0.1, 0.1, 0.1])
    with pytest.raises(TypeError, match="shape"):
        f.add_collider(Plane())
    with pytest.raises(ValueError, match="friction"):
        f.add_collider(Sphere([0.3, 0.3, 0.1], 0.05, friction=0.5))
    with pytest.raises(ValueError, match="inside"):
        f.add_collider(Sphere([0.3, 0.3, 0.1], 0.05, inside=True))
    with pytest.raises(ValueError, match="radius"):
        f.add_collider(Sphere([0.3, 0.3, 0.1], 0.01))
    with pytest.raises(ValueError, match="half_extents"):
        f.add_collider(Box([0.3, 0.3, 0.1], [0.1, 0.005, 0.1]))
    with pytest.raises(ValueError, match="velocity"):
        f.add_collider(Sphere([0.3, 0.3, 0.1], 0.05, velocity=[np.nan, 0, 0]))
    with pytest.raises(ValueError, match="shape"):
        f.add_collider(Sphere([0.05, 0.05, 0.05], 0.03))  # fluid inside
    assert f.add_collider(Sphere([0.3, 0.3, 0.1], 0.05)) == 0
    with pytest.raises(ValueError, match="shape"):
        f.set_collider(0, Sphere([0.3, 0.3, 0.1], 0.06))
    with pytest.raises(ValueError, match="index"):
        f.set_collider(1, Sphere([0.3, 0.3, 0.1], 0.05))
    with pytest.raises(ValueError, match="index"):
        f.set_collider(-1, Sphere([0.3, 0.3, 0.1], 0.05))


def test_a_rigid_ball_sinks_into_the_fluid_of_a_scene():
    """A fixed-velocity rigid ball (no gravity on it) driven down into a fluid in a scene: the
    fluid gets it as a collider that follows the body, no particle gets inside it, and the
    scene's checkpoint resumes the coupled run bit for bit."""
    scene = kinema.Scene(dt=1 / 60)
    world = rigid.World(gravity=(0, 0, 0))
    world.add_body(rigid.Sphere(0.05), position=(0.2, 0.3, 0.1), velocity=(0, -0.6, 0))
    scene.add(world)
    f = tank()
    f.add_block([0, 0, 0], [0.4, 0.16, 0.2])
    scene.add(f)
    for _ in range(20):
        scene.step()
        c = world.positions[0]
        assert np.linalg.norm(f.positions - c, axis=1).min() > 0.05
    assert world.positions[0][1] < 0.15  # in the fluid
    b = f.boundary_particles
    assert np.linalg.norm(b - world.positions[0], axis=1).min() < 0.05
    v0 = f.velocities.copy()
    assert np.abs(v0).max() > 0.05  # the ball pushed the fluid


def test_a_failed_scene_frame_takes_back_the_colliders_it_added():
    scene = kinema.Scene(dt=1 / 60)
    world = rigid.World(gravity=(0, 0, 0))
    world.add_body(rigid.Sphere(0.05), position=(0.2, 0.3, 0.1), velocity=(0, -0.6, 0))
    scene.add(world)
    f = tank(max_substeps=1)
    f.add_block([0, 0, 0], [0.4, 0.16, 0.2])
    scene.add(f)
    walls, before = len(f.boundary_particles), f.positions.copy()
    for _ in range(2):
        with pytest.raises(kinema.SimulationError):
            scene.step()
        assert len(f.boundary_particles) == walls and scene._entries[1].colliders == []
        assert np.array_equal(f.positions, before)


def test_pickled_colliders_resume_bit_for_bit():
    f = tank()
    f.add_collider(Box([0.3, 0.1, 0.1], [0.04, 0.05, 0.04], velocity=[-0.2, 0, 0]))
    f.add_block([0, 0, 0], [0.2, 0.16, 0.2])
    f.step(1 / 60, steps=2)
    g = pickle.loads(pickle.dumps(f))
    f.step(1 / 60, steps=3)
    g.step(1 / 60, steps=3)
    assert np.array_equal(f.positions, g.positions)
    assert np.array_equal(f.boundary_particles, g.boundary_particles)
