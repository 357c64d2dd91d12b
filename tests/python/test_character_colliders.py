"""Colliders of articulated bodies from Python: the shared kinema.geometry shapes, resting
on a box at the analytic penetration, a platform moved every frame carrying a capsule,
pickles keeping them, bad input named."""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import pytest

from kinema import character, geometry, mocap
from kinema.rotation import Rotation

DATA = Path(__file__).resolve().parents[1] / "data" / "mocap"


def ball(radius: float = 0.1, height: float = 1.0) -> character.ArticulatedBody:
    """A free ball of water density at ``height`` (m), no ground."""
    m = character.Model()
    mass = 1000.0 * 4.0 / 3.0 * np.pi * radius**3
    m.add_body(
        None,
        "free",
        mass=mass,
        inertia=np.eye(3) * 0.4 * mass * radius**2,
        offset=(0.0, height, 0.0),
        shape=((0, 0, 0), (0, 0, 0), radius),
    )
    return character.ArticulatedBody(m, ground=False)


def test_a_ball_rests_on_a_turned_box_at_the_analytic_penetration():
    """On the top face of a box turned about y (the face stays level), a ball of one contact
    point sinks g/ω² (ω the contact frequency); with a plane of any normal likewise along
    it; without colliders it falls (no ground)."""
    w = 60.0
    top = 0.5
    box = geometry.Box((0.0, top - 0.1, 0.0), (0.5, 0.1, 0.5), Rotation.from_rotvec([0, 0.7, 0]))
    b = ball()
    assert b.add_collider(box) == 0
    b.step(1 / 480, 960)
    assert b.q[1] + 1.0 == pytest.approx(top + 0.1 - 9.81 / w**2, abs=1e-3 * 9.81 / w**2)
    normal = np.array([0.3, 1.0, 0.2]) / np.linalg.norm([0.3, 1.0, 0.2])
    p = ball()
    p.configure(gravity=-9.81 * normal, friction=0.0)
    p.add_collider(geometry.Plane((0.0, 0.2, 0.0), normal))
    p.step(1 / 480, 960)
    centre = np.array([0.0, 1.0, 0.0]) + p.q[:3]
    height = (centre - [0.0, 0.2, 0.0]) @ normal
    assert height == pytest.approx(0.1 - 9.81 / w**2, abs=1e-3 * 9.81 / w**2)
    free = ball()
    free.step(1 / 480, 960)
    assert free.q[1] < -1.0


def test_pickles_keep_the_colliders():
    sk = mocap.read_asf(DATA / "07-walk.asf")
    r = character.Ragdoll.from_skeleton(sk, clearance=0.5)
    r.add_collider(geometry.Box((0.0, 0.2, 0.0), (0.3, 0.2, 0.3), friction=0.4))
    r.add_collider(geometry.Box((0.5, 0.1, 0.0), (0.4, 0.1, 0.4), velocity=(0.3, 0.0, 0.1)))
    r.step(1 / 480, 100)
    back = pickle.loads(pickle.dumps(r))
    for a, b in zip(back.colliders(), r.colliders(), strict=True):  # where they are, moving
        assert geometry.shape_params(a) == geometry.shape_params(b) and a.velocity == b.velocity
    assert r.colliders()[1].center[0] == pytest.approx(0.5 + 0.3 * 100 / 480)
    r.step(1 / 480, 100)
    back.step(1 / 480, 100)
    assert np.array_equal(r.q, back.q) and np.array_equal(r.qd, back.qd)
    b = character.Biped()
    b.add_collider(geometry.Box((3.0, -0.05, 0.0), (1.0, 0.1, 1.0)))
    b.step(1e-3, 200)
    again = pickle.loads(pickle.dumps(b))
    b.step(1e-3, 200)
    again.step(1e-3, 200)
    assert np.array_equal(b.q, again.q)


def test_bad_colliders_name_the_argument():
    b = ball()
    nan = float("nan")
    cases = [
        (geometry.Box((nan, 0, 0), (1, 1, 1)), "center"),
        (geometry.Box((0, 0, 0), (1, 0, 1)), "half_extents"),
        (geometry.Box((0, 0, 0), (1, float("inf"), 1)), "half_extents"),
        (geometry.Plane((0, 0, 0), (0, 0, 0)), "normal"),
        (geometry.Sphere((0, 0, 0), -1.0), "radius"),
        (geometry.Box((0, 0, 0), (1, 1, 1), friction=-0.5), "friction"),
        (geometry.Box((0, 0, 0), (1, 1, 1), restitution=0.5), "restitution"),
        (geometry.Box((0, 0, 0), (1, 1, 1), velocity=(nan, 0, 0)), "velocity"),
        (geometry.Sphere((0, 0, 0), 1.0, inside=True), "inside"),
    ]
    for shape, name in cases:
        with pytest.raises(ValueError, match=name):
            b.add_collider(shape)
        with pytest.raises(ValueError, match=name):
            character.Biped().add_collider(shape)
    with pytest.raises(TypeError, match="collider"):
        b.add_collider((0, 0, 0))
    b.step(1 / 480, 480)
    assert b.q[1] < -1.0  # none of them was added
    b.add_collider(geometry.Box((0, -3, 0), (1, 1, 1), velocity=(0, -1, 0)))
    for shape, name in [
        (geometry.Box((0, 0, 0), (1, 2, 1)), "shape"),
        (geometry.Sphere((0, 0, 0), 1.0), "shape"),
        (geometry.Box((0, 0, 0), (1, 1, 1), velocity=(0, nan, 0)), "velocity"),
    ]:
        with pytest.raises(ValueError, match=name):
            b.set_collider(0, shape)
    with pytest.raises(ValueError, match="angular_velocity"):
        b.set_collider(0, geometry.Box((0, 0, 0), (1, 1, 1)), angular_velocity=(0, nan, 0))
    with pytest.raises(ValueError, match="index"):
        b.set_collider(1, geometry.Box((0, 0, 0), (1, 1, 1)))
    (box,) = b.colliders()  # as it was: at (0, -3, 0) when added, moving down
    np.testing.assert_allclose(box.center, (0.0, -3.0, 0.0), atol=1e-12)
    np.testing.assert_allclose(box.velocity, (0.0, -1.0, 0.0))
    # The walkers take moving colliders with the same arguments, and refuse the same.
    w = character.Biped(dims=3)
    w.add_collider(geometry.Box((3, -0.5, 0), (1, 0.5, 1), velocity=(0.5, 0, 0)), (0, 0.1, 0))
    for shape, name in [
        (geometry.Box((0, 0, 0), (1, 2, 1)), "shape"),
        (geometry.Box((0, 0, 0), (1, 0.5, 1), velocity=(0, nan, 0)), "velocity"),
    ]:
        with pytest.raises(ValueError, match=name):
            w.set_collider(0, shape)
    with pytest.raises(ValueError, match="angular_velocity"):
        w.add_collider(geometry.Box((0, 0, 0), (1, 1, 1)), angular_velocity=(0, nan, 0))
    with pytest.raises(ValueError, match="index"):
        w.set_collider(1, geometry.Box((0, 0, 0), (1, 0.5, 1)))
    w.set_collider(0, geometry.Box((3, -0.5, 0), (1, 0.5, 1), velocity=(0.4, 0, 0)))


def test_a_capsule_on_a_platform_moved_every_frame_follows_it():
    """A level capsule lying on a box whose pose is set every frame on the path
    ``x(t) = 0.2 sin(π t)`` (peak acceleration 2 m/s², below μ g: it sticks), with the
    velocity to the next frame's pose, is carried with it: its offset from the platform
    changes by less than 12 mm over the last 2.5 s of 3 s (measured 9 mm: below the slip
    speed friction is viscous, so it lags the platform by ``τ v``, ``τ = v_s / (μ g)`` = 5 ms,
    ±3.2 mm, and creeps at the turns). A platform set every frame without its velocity
    slides under it: the offset then swings by most of the path's 0.4 m."""

    def offsets(with_velocity: bool) -> np.ndarray:
        c = character.Model()
        mass = 1000.0 * np.pi * 0.05**2 * 0.4
        inertia = np.diag([0.001, 0.02, 0.02])
        c.add_body(
            None,
            "free",
            mass=mass,
            inertia=inertia,
            offset=(0.0, 0.05, 0.0),
            shape=((-0.2, 0, 0), (0.2, 0, 0), 0.05),
        )
        body = character.ArticulatedBody(c, ground=False)
        dt, half = 1 / 60, (1.0, 0.1, 1.0)

        def deck(t: float) -> geometry.Box:
            x, x1 = 0.2 * np.sin(np.pi * t), 0.2 * np.sin(np.pi * (t + dt))
            v = (x1 - x) / dt if with_velocity else 0.0
            return geometry.Box((x, -0.1, 0.0), half, velocity=(v, 0.0, 0.0))

        body.add_collider(deck(0.0))
        out = []
        for frame in range(180):
            body.set_collider(0, deck(frame * dt))
            body.step(dt / 8, 8)
            out.append(body.positions()[0, 0] - body.colliders()[0].center[0])
        return np.array(out[30:])

    assert np.ptp(offsets(True)) < 0.012
    assert np.ptp(offsets(False)) > 0.2


def test_a_turning_box_turns_and_drags_from_python():
    """A box added with an angular velocity is reported turned at the body's time (its
    orientation ``exp(ω t)``, its centre fixed), and drags a ball resting on it off the axis
    into motion along the table's surface velocity ``Ω × x`` (the ball rolls, at 2/7 of it:
    tests/character_moving_colliders.rs)."""
    b = ball(radius=0.1, height=0.1 - 9.81 / 60.0**2)
    m = b.q.copy()
    m[0] = 0.5
    b.q = m
    b.add_collider(geometry.Box((0.0, -0.2, 0.0), (3.0, 0.2, 3.0)), angular_velocity=(0, 2.0, 0))
    b.step(1e-3, 100)
    (box,) = b.colliders()
    np.testing.assert_allclose(box.center, (0.0, -0.2, 0.0), atol=1e-12)
    turn = box.orientation.as_rotvec()
    np.testing.assert_allclose(turn, (0.0, 2.0 * b.time, 0.0), atol=1e-9)
    v = b.qd[3:6]
    assert v[2] < -0.1 and abs(v[2]) > 5 * abs(v[0])  # along Ω × x = (0, 0, -1) at x = 0.5
