"""kinema.constraints through Python: the bead on a circle and the double pendulum."""

from __future__ import annotations

import numpy as np
import pytest

import kinema
from kinema.constraints import ConstrainedSystem, Distance, Fixed, OnPlane, OnSphere
from kinema.particles import Gravity, ParticleSystem


def pendulum(ks=0.0, kd=0.0, solver="cholesky"):
    ps = ParticleSystem([[0, 0, 0], [1, 0, 0], [1, -1, 0]], masses=[np.inf, 1.0, 2.0])
    ps.add(Gravity())
    cs = ConstrainedSystem(ps, ks=ks, kd=kd, solver=solver)
    cs.add(Distance(0, 1))
    cs.add(Distance(1, 2))
    return ps, cs


def test_bead_on_a_circle_keeps_its_wire():
    ps = ParticleSystem([[1.0, 0.0, 0.0]], [[0.0, 2.0, 0.0]])
    ps.add(Gravity())
    cs = ConstrainedSystem(ps, ks=100.0, kd=20.0)
    cs.add(OnSphere(0, [0, 0, 0], 1.0))
    cs.add(OnPlane(0, [0, 0, 0], [0, 0, 1]))
    cs.step(1e-3, 5000)
    c, cdot = cs.violation()
    assert c < 1e-8 and cdot < 1e-8
    assert np.linalg.norm(ps.positions[0]) == pytest.approx(1.0, abs=1e-8)
    e = ps.kinetic_energy() + ps.potential_energy()
    assert e == pytest.approx(0.5 * 4.0, rel=1e-6)  # started at height 0 with speed 2


def test_double_pendulum_energy_and_no_work():
    ps, cs = pendulum()
    e0 = ps.kinetic_energy() + ps.potential_energy()
    cs.step(1e-3, 1000)
    assert abs(ps.kinetic_energy() + ps.potential_energy() - e0) < 1e-7
    f = cs.constraint_forces()
    v = ps.velocities
    power = float(np.sum(f * v))
    assert abs(power) < 1e-9 * np.abs(f).max() * np.abs(v).max()


def test_solvers_and_projection_agree_roughly():
    a, ca = pendulum(10, 5, "cholesky")
    b, cb = pendulum(10, 5, "cg")
    ca.step(1e-3, 500)
    cb.step(1e-3, 500)
    np.testing.assert_allclose(a.positions, b.positions, atol=1e-9)
    c, cc = pendulum(solver="cholesky")
    cc.step(1e-3, 500, method="projection")
    assert cc.violation()[0] < 1e-8
    np.testing.assert_allclose(c.positions, a.positions, atol=0.05)  # first order, same motion


def test_bad_input():
    ps = ParticleSystem([[0, 0, 0], [0, 0, 0]])
    cs = ConstrainedSystem(ps)
    with pytest.raises(ValueError, match="coincide"):
        cs.add(Distance(0, 1, 1.0))
    with pytest.raises(ValueError, match="radius"):
        cs.add(OnSphere(0, [0, 0, 0], 0.0))
    with pytest.raises(ValueError, match="out of range"):
        cs.add(Fixed(7, [0, 0, 0]))
    with pytest.raises(ValueError, match="solver"):
        ConstrainedSystem(ps, solver="lu")
    with pytest.raises(ValueError, match="method"):
        cs.step(0.1, method="rk45")
    with pytest.raises(ValueError, match="ks"):
        ConstrainedSystem(ps, ks=-1.0)
    assert issubclass(kinema.SimulationError, RuntimeError)
