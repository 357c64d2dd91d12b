"""kinema.rigid joints through Python: the four formulations on a pendulum and a chain, hinge
limits and motors, sliders, fixed joints, and the errors bad joints get."""

from __future__ import annotations

import math

import numpy as np
import pytest

import kinema
from kinema.rigid import METHODS, Ball, Box, Fixed, Hinge, Slider, Sphere, World


def pendulum(method: str, angle: float) -> World:
    """A 1 kg sphere (r = 0.1 m) 0.5 m below a ball joint at the origin, turned by ``angle``."""
    w = World()
    w.add_body(Sphere(0.1), mass=1.0, position=[0.5 * math.sin(angle), -0.5 * math.cos(angle), 0])
    assert w.add_joint(Ball(0, None, [0, 0, 0]), method) == 0
    return w


def chain(method: str, links: int = 5) -> World:
    """Horizontal boxes 0.4 m long, 0.5 kg, hinged about z to the world and to each other."""
    w = World()
    for i in range(links):
        w.add_body(Box([0.2, 0.02, 0.02]), mass=0.5, position=[0.2 + 0.4 * i, 0, 0])
        w.add_joint(Hinge(i, i - 1 if i else None, [0.4 * i, 0, 0], [0, 0, 1]), method)
    return w


@pytest.mark.parametrize("method", METHODS)
def test_small_angle_period_is_the_physical_pendulum_s(method):
    m, r, d, theta = 1.0, 0.1, 0.5, 0.05
    inertia = 0.4 * m * r * r + m * d * d
    period = 2 * math.pi * math.sqrt(inertia / (m * 9.81 * d)) * (1 + theta**2 / 16)
    w = pendulum(method, theta)
    dt, xs = 1e-3, []
    for _ in range(6000):
        w.step(dt)
        xs.append(w.positions[0, 0])
    x = np.array(xs)
    k = np.nonzero((x[:-1] < 0) & (x[1:] >= 0))[0]
    t = (k + x[k] / (x[k] - x[k + 1])) * dt
    measured = (t[-1] - t[0]) / (len(t) - 1)
    assert measured == pytest.approx(period, rel=2e-3)


@pytest.mark.parametrize(
    ("method", "drift", "dt"),
    # Penalty springs need small steps: this sphere turns easily about the anchor, so the
    # joint rings at ~800 rad/s and a 1 ms step lets it chatter at centimetres.
    [
        ("lagrange", 1e-9, 1e-3),
        ("impulse", 1e-6, 1e-3),
        ("xpbd", 1e-5, 1e-3),
        ("penalty", 3e-3, 2.5e-4),
    ],
)
def test_drift_and_energy_per_formulation(method, drift, dt):
    w = pendulum(method, 0.5)
    e0 = w.kinetic_energy() + w.potential_energy()
    worst, de = 0.0, 0.0
    for _ in range(round(2.0 / dt)):
        w.step(dt)
        worst = max(worst, w.joint_violations[0, 0])
        de = max(de, abs(w.kinetic_energy() + w.potential_energy() - e0))
    assert worst < drift
    # Swing energy m g d (1 - cos 0.5) ≈ 0.6 J: at most a few percent change in 2 s.
    assert de < 2e-2


@pytest.mark.parametrize("method", ["lagrange", "xpbd", "impulse"])
def test_chain_of_five_hinges_stays_connected_at_60_hz(method):
    w = chain(method)
    worst = np.zeros(2)
    for _ in range(600):
        w.step(1 / 60)
        worst = np.maximum(worst, w.joint_violations.max(axis=0))
    assert worst[0] < 0.02 and worst[1] < 0.03


def test_penalty_drift_shrinks_with_stiffness():
    drifts = []
    for k in (1e4, 1e5):
        w = World()
        w.add_body(Sphere(0.1), mass=1.0, position=[0.5 * math.sin(0.5), -0.5 * math.cos(0.5), 0])
        w.add_joint(Ball(0, -1, [0, 0, 0]), "penalty", stiffness=k, damping=2 * math.sqrt(k))
        worst = 0.0
        for _ in range(20):
            w.step(1e-4, 100)
            worst = max(worst, w.joint_violations[0, 0])
        drifts.append(worst)
    assert drifts[1] < drifts[0] / 7


@pytest.mark.parametrize("method", METHODS)
def test_hinge_limit_and_motor(method):
    # A box hinged at its end to the world falls onto the upper limit (the world turns up
    # relative to the box as the box turns down).
    w = World()
    w.add_body(Box([0.2, 0.05, 0.05]), mass=1.0, position=[0.2, 0, 0])
    w.add_joint(Hinge(0, None, [0, 0, 0], [0, 0, 1], limits=(-0.2, 0.3)), method)
    w.step(1e-3, 2000)
    angle, rate = w.joint_coordinates[0]
    tol = 2e-2 if method == "penalty" else 2e-3
    assert angle == pytest.approx(0.3, abs=tol) and abs(rate) < 1e-3
    # A weak motor accelerates a free plate at max_torque / I until its speed is reached.
    m = World(gravity=[0, 0, 0])
    m.add_body(Box([0.2, 0.02, 0.2]), mass=1.0)
    m.add_joint(Hinge(0, None, [0, 0, 0], [0, 1, 0], motor_speed=2.0, max_torque=0.01), method)
    m.step(1e-3, 1000)
    inertia = 0.32 / 12
    assert m.angular_velocities[0, 1] == pytest.approx(-0.01 / inertia, rel=1e-3)
    m.step(1e-3, 5000)  # 2 rad/s is reached after 2 / 0.375 = 5.3 s
    assert m.joint_coordinates[0, 1] == pytest.approx(2.0, abs=1e-6)


@pytest.mark.parametrize("method", METHODS)
def test_slider_and_fixed(method):
    axis = np.array([1.0, -1.0, 0.0]) / math.sqrt(2)
    w = World()
    w.add_body(Box([0.1, 0.2, 0.3]), mass=2.0, position=[0, 1, 0], angular_velocity=[0.5, 0, 0])
    w.add_joint(Slider(0, None, axis), method)
    w.add_body(Box([0.1, 0.1, 0.1]), mass=1.0, position=[3, 0, 0], angular_velocity=[0, 0, 2])
    w.add_body(Box([0.2, 0.1, 0.1]), mass=3.0, position=[3.3, 0, 0], angular_velocity=[0, 0, 2])
    w.add_joint(Fixed(1, 2), method)
    d0 = w.positions[2] - w.positions[1]
    w.step(1e-3, 1000)
    tol = 2e-2 if method == "penalty" else 1e-4
    assert (w.joint_violations < tol).all()
    # The slider's body only moved along the axis.
    moved = w.positions[0] - [0, 1, 0]
    assert np.linalg.norm(moved - moved.dot(axis) * axis) < tol
    rel = kinema.Rotation.from_quat(w.orientations[1]).inv().apply(w.positions[2] - w.positions[1])
    np.testing.assert_allclose(rel, d0, atol=2 * tol)


def test_jointed_bodies_do_not_collide_but_the_others_do():
    w = World()
    w.add_body(Sphere(0.2), mass=1.0, position=[0, 0, 0])
    w.add_body(Sphere(0.2), mass=1.0, position=[0.3, 0, 0])  # overlaps the first
    w.add_joint(Fixed(0, 1))
    w.step(1e-3, 100)
    assert w.joint_violations.max() < 1e-6  # no contact pushing them apart


def test_bad_joints_raise_value_errors_naming_the_argument():
    w = World()
    w.add_body(Sphere(0.1), mass=1.0)
    w.add_body(Sphere(0.1), mass=1.0, position=[1, 0, 0])
    with pytest.raises(ValueError, match=r"^b"):
        w.add_joint(Ball(0, 0, [0, 0, 0]))
    with pytest.raises(ValueError, match=r"^a"):
        w.add_joint(Ball(5, None, [0, 0, 0]))
    with pytest.raises(ValueError, match=r"^a"):
        w.add_joint(Ball(-1, None, [0, 0, 0]))
    with pytest.raises(ValueError, match=r"^b"):
        w.add_joint(Ball(0, 9, [0, 0, 0]))
    with pytest.raises(ValueError, match=r"^b"):
        w.add_joint(Ball(0, -2, [0, 0, 0]))
    with pytest.raises(ValueError, match="axis"):
        w.add_joint(Hinge(0, 1, [0, 0, 0], [0, 0, 0]))
    with pytest.raises(ValueError, match="axis"):
        w.add_joint(Slider(0, 1, [0, 0, 0]))
    with pytest.raises(ValueError, match="anchor"):
        w.add_joint(Ball(0, 1, [np.nan, 0, 0]))
    with pytest.raises(ValueError, match="anchor"):
        w.add_joint(Ball(0, 1, [0, 0]))
    with pytest.raises(ValueError, match="limits"):
        w.add_joint(Hinge(0, 1, [0, 0, 0], [0, 0, 1], limits=(0.5, -0.5)))
    with pytest.raises(ValueError, match="max_torque"):
        w.add_joint(Hinge(0, 1, [0, 0, 0], [0, 0, 1], motor_speed=1.0, max_torque=-1.0))
    with pytest.raises(ValueError, match="max_torque"):
        w.add_joint(Hinge(0, 1, [0, 0, 0], [0, 0, 1], max_torque=1.0))
    with pytest.raises(ValueError, match="method"):
        w.add_joint(Fixed(0, 1), "springs")
    with pytest.raises(ValueError, match="stiffness"):
        w.add_joint(Fixed(0, 1), "penalty", stiffness=0.0)
    with pytest.raises(ValueError, match="stiffness"):
        w.add_joint(Fixed(0, 1), "xpbd", stiffness=1e5)
    with pytest.raises(ValueError, match="joint"):
        w.add_joint(Sphere(1.0))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="xpbd_substeps"):
        w.xpbd_substeps = 0
    with pytest.raises(ValueError, match="baumgarte"):
        w.baumgarte = 3.0
    assert w.joint_violations.shape == (0, 2)


def test_a_failed_step_leaves_the_state_and_raises_simulation_error():
    w = chain("lagrange", links=3)
    w.step(1e-3, 10)
    before = (w.positions, w.velocities, w.angular_velocities)
    w.apply_force(1, [0, 1e308, 0])
    w.apply_force(1, [0, 1e308, 0])
    with pytest.raises(kinema.SimulationError):
        w.step(1e-3, 5)
    for a, b in zip(before, (w.positions, w.velocities, w.angular_velocities), strict=True):
        np.testing.assert_array_equal(a, b)
