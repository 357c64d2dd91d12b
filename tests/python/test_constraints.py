"""kinema.constraints through Python: the bead on a circle and the double pendulum."""

from __future__ import annotations

import numpy as np
import pytest

import kinema
from kinema.anim import Track
from kinema.constraints import (
    Circle,
    ConstrainedSystem,
    Custom,
    Distance,
    Fixed,
    Helix,
    Line,
    OnCurve,
    OnPlane,
    OnSphere,
    ReducedBead,
    ReducedPendulum,
)
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


def test_solvers_agree_and_projection_converges_at_first_order():
    a, ca = pendulum(10, 5, "cholesky")
    b, cb = pendulum(10, 5, "cg")
    ca.step(1e-3, 500)
    cb.step(1e-3, 500)
    np.testing.assert_allclose(a.positions, b.positions, atol=1e-9)
    # The velocity-level projection against RK4 at 1 ms (both stabilised, 0.5 s): the error
    # halves with the step (first order) and the rods hold at every step size.
    errors = []
    for dt in (4e-3, 2e-3, 1e-3):
        c, cc = pendulum()
        cc.step(dt, round(0.5 / dt), method="projection")
        assert cc.violation()[0] < 1e-10 and cc.violation()[1] < 1e-10
        errors.append(np.abs(c.positions - a.positions).max())
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all((orders > 0.8) & (orders < 1.3)), (errors, orders)


def rope(n):
    xs = np.column_stack([np.zeros(n), -0.01 * np.arange(n), np.zeros(n)])
    vs = np.column_stack([0.2 * np.arange(n) / n, np.zeros(n), np.zeros(n)])
    ps = ParticleSystem(xs, vs, np.r_[np.inf, np.full(n - 1, 0.001)])
    ps.add(Gravity())
    return ps


def rope_system(stabilize=None):
    ps = rope(1000)
    cs = ConstrainedSystem(ps, stabilize=stabilize)
    for i in range(999):
        cs.add(Distance(i, i + 1))
    return ps, cs


def test_rope_rods_hold_1e_6_relative_at_a_sixtieth_of_a_second():
    # 1,000 rods of 1 cm at 1/60 s, where the tension at the top is too stiff for a step
    # without the rods' geometric stiffness (docs/constraints.md): the implicit projection
    # holds every rod, with or without the velocity projection, and the rope swings.
    for stabilize in (None, False):
        ps, cs = rope_system(stabilize=stabilize)
        worst = 0.0
        for _ in range(30):
            cs.step(1 / 60, method="projection")
            worst = max(worst, cs.violation()[0] / 0.01)
        assert worst < 1e-6, stabilize
        assert ps.positions[-1, 0] > 1e-3


def test_a_failed_projection_step_keeps_the_particles():
    ps, cs = rope_system()
    cs.step(1 / 60, method="projection")
    cs.add(Distance(0, 999, length=0.5))  # the rope cannot reach: no point has C = 0
    before = ps.positions.copy(), ps.velocities.copy(), ps.time
    with pytest.raises(kinema.SimulationError, match="projection"):
        cs.step(1 / 60, method="projection")
    np.testing.assert_array_equal(ps.positions, before[0])
    np.testing.assert_array_equal(ps.velocities, before[1])
    assert ps.time == before[2]


def test_bead_at_the_defaults_holds_its_wire_to_1e_10():
    wire = Helix([0, 0, 0], 1.0, 0.7)
    start = ReducedBead(wire, u=0.0, u_dot=2.0)
    drift = {}
    for stabilize in (None, False):
        ps = ParticleSystem(start.positions, start.velocities)
        ps.add(Gravity())
        cs = ConstrainedSystem(ps, stabilize=stabilize)
        cs.add(OnCurve(0, wire))
        for _ in range(20):
            cs.step(1e-3, 1000)
            drift[stabilize] = max(drift.get(stabilize, 0.0), *cs.violation())
    assert drift[None] <= 1e-10 and drift[False] > 100 * drift[None], drift


def test_conflicting_constraints_fail_and_keep_the_state():
    ps, cs = bead_system()
    cs.add(OnPlane(0, [0, 0, 0], [0, 1, 0]))
    cs.add(OnPlane(0, [0, 3, 0], [0, 1, 0]))
    before = ps.positions.copy(), ps.velocities.copy()
    with pytest.raises(kinema.SimulationError, match="conflict"):
        cs.step(1e-3, 10)
    np.testing.assert_array_equal(ps.positions, before[0])
    np.testing.assert_array_equal(ps.velocities, before[1])


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
    with pytest.raises(ValueError, match="stabilize"):
        ConstrainedSystem(ps, stabilize="yes")
    with pytest.raises(ValueError, match="stabilize"):
        ConstrainedSystem(ps, formulation="penalty", stiffness=1.0, stabilize=True)
    assert issubclass(kinema.SimulationError, RuntimeError)


def bead_system(**kwargs):
    ps = ParticleSystem([[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    ps.add(Gravity())
    return ps, ConstrainedSystem(ps, **kwargs)


def test_bead_on_curves_matches_reduced_coordinates():
    spline = Track(
        [0, 1, 2, 3],
        [[0, 0, 0], [1, -0.5, 0.3], [2, -0.6, -0.2], [3, -1.5, 0.4]],
        "natural_cubic",
        "linear",
    )
    for curve, u0, udot in [
        (Circle([0, 0, 0], 1.0), 0.0, 1.0),
        (Helix([0, 0, 0], 1.0, 0.7), 0.0, 1.0),
        (Line([0, 0, 0], [1, -1, 0]), 0.0, 0.0),
        (spline, 0.5, 0.0),
    ]:
        reduced = ReducedBead(curve, mass=1.0, u=u0, u_dot=udot)
        ps = ParticleSystem(reduced.positions, reduced.velocities)
        ps.add(Gravity())
        cs = ConstrainedSystem(ps, ks=100.0, kd=20.0)
        cs.add(OnCurve(0, curve))
        assert cs.curve_parameter(0) == pytest.approx(u0, abs=1e-12)
        e0 = reduced.energy()
        cs.step(1e-3, 1000)
        reduced.step(1e-3, 1000)
        np.testing.assert_allclose(ps.positions, reduced.positions, atol=1e-7)
        assert cs.violation()[0] < 1e-7
        assert reduced.energy() == pytest.approx(e0, abs=1e-7)
        assert reduced.time == pytest.approx(1.0)
    assert cs.curve_parameter(0) == pytest.approx(reduced.u, abs=1e-7)


def rod_value(x):
    return np.linalg.norm(x[0] - x[1]) - 1.0


def rod_gradient(x):
    d = (x[0] - x[1]) / np.linalg.norm(x[0] - x[1])
    return np.concatenate([d, -d])


def test_custom_constraint_from_python_callables():
    a, ca = pendulum(10, 5)
    b = ParticleSystem([[0, 0, 0], [1, 0, 0], [1, -1, 0]], masses=[np.inf, 1.0, 2.0])
    b.add(Gravity())
    cb = ConstrainedSystem(b, ks=10, kd=5)
    cb.add(Distance(0, 1))
    cb.add(Custom([1, 2], rod_value, rod_gradient))
    ca.step(1e-3, 500)
    cb.step(1e-3, 500)
    np.testing.assert_allclose(a.positions, b.positions, atol=1e-8)

    class Boom(Exception):
        pass

    calls = []

    def failing(x):
        calls.append(1)
        if len(calls) > 3:
            raise Boom("from the callback")
        return rod_gradient(x)

    c = ParticleSystem([[0, 0, 0], [1, 0, 0]], [[0, 0, 0], [0, 1, 0]], masses=[np.inf, 1.0])
    cc = ConstrainedSystem(c)
    cc.add(Custom([0, 1], rod_value, failing))
    before = c.positions.copy()
    with pytest.raises(Boom, match="from the callback"):
        cc.step(1e-3, 10)
    np.testing.assert_array_equal(c.positions, before)
    with pytest.raises(ValueError, match="gradient"):
        cc.add(Custom([0, 1], rod_value, lambda x: np.zeros(5)))
    with pytest.raises(ValueError, match="indices"):
        cc.add(Custom([0, 9], rod_value, rod_gradient))


def test_penalty_drift_falls_as_stiffness_rises():
    drifts = []
    for k in (1e3, 1e5, 1e7):
        ps, cs = bead_system(formulation="penalty", stiffness=k)
        cs.add(OnCurve(0, Circle([0, 0, 0], 1.0)))
        worst = 0.0
        for _ in range(20):
            cs.step(2e-4, 50)
            worst = max(worst, cs.violation()[0])
        drifts.append(worst)
        f = cs.constraint_forces()[0]
        tangent = np.cross([0, 0, 1], ps.positions[0])
        assert abs(f @ tangent) < 1e-12 * np.linalg.norm(f) * np.linalg.norm(tangent)
    assert drifts[1] < 0.05 * drifts[0] and drifts[2] < 0.05 * drifts[1], drifts
    with pytest.raises(ValueError, match="stiffness"):
        bead_system(formulation="penalty")
    with pytest.raises(ValueError, match="stiffness"):
        bead_system(stiffness=10.0)
    with pytest.raises(ValueError, match="formulation"):
        bead_system(formulation="lagrange")
    ps, cs = bead_system(formulation="penalty", stiffness=1e3)
    cs.add(OnSphere(0, [0, 0, 0], 1.0))
    with pytest.raises(ValueError, match="projection"):
        cs.step(1e-3, method="projection")


def test_reduced_pendulum_matches_the_multipliers():
    ps, cs = pendulum()
    r = ReducedPendulum([1.0, 1.0], [1.0, 2.0], [np.pi / 2, 0.0])
    e0 = r.energy()
    assert e0 == pytest.approx(ps.kinetic_energy() + ps.potential_energy())
    cs.step(1e-3, 1000)
    r.step(1e-3, 1000)
    np.testing.assert_allclose(r.positions, ps.positions[1:], atol=1e-8)
    np.testing.assert_allclose(r.velocities, ps.velocities[1:], atol=1e-7)
    assert np.linalg.norm(r.positions[0]) == pytest.approx(1.0, abs=1e-15)
    assert r.energy() == pytest.approx(e0, abs=1e-7)
    one = ReducedPendulum(2.0, 1.0, 0.1, pivot=[0, 1, 0])
    one.step(1e-3, 1000, method="velocity_verlet")
    # Small swing: θ(t) ≈ 0.1 cos(√(g/l) t).
    assert one.angles[0] == pytest.approx(0.1 * np.cos(np.sqrt(9.81 / 2.0)), abs=2e-4)
    with pytest.raises(ValueError, match="lengths"):
        ReducedPendulum([1, 1, 1], 1.0, [0, 0, 0])
    with pytest.raises(ValueError, match="masses"):
        ReducedPendulum([1, 1], [1, 2, 3], [0, 0])
    with pytest.raises(ValueError, match="curve"):
        ReducedBead("circle")
    with pytest.raises(ValueError, match="radius"):
        ReducedBead(Circle([0, 0, 0], -1.0))


def _helix_and_plane(fail_at: list[int]):
    """A bead on a helix and a particle held on the plane ``y = 1`` by a Python constraint
    whose gradient raises at its ``fail_at[0]``-th call, constrained with CG, in a scene of 4
    substeps per frame; and the gradient's call count."""
    calls = [0]

    def gradient(x):
        calls[0] += 1
        if calls[0] == fail_at[0]:
            raise RuntimeError("on purpose")
        return [0.0, 1.0, 0.0]

    ps = ParticleSystem([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], [[0.0, 0.0, 1.5], [0.5, 0.0, 0.2]])
    ps.add(Gravity())
    cs = ConstrainedSystem(ps, solver="cg")
    cs.add(OnCurve(0, Helix(center=[0, 0, 0], radius=1.0, pitch=0.7)))
    cs.add(Custom([1], lambda x: x[0, 1] - 1.0, gradient))
    scene = kinema.Scene(dt=1 / 60, substeps=4)
    scene.add(cs)
    return scene, cs, ps, calls


def _seen(cs, ps):
    return [ps.positions.copy(), ps.velocities.copy(), cs.curve_parameter(0), cs.iterations]


def test_a_failed_scene_frame_puts_the_constraint_state_back_even_with_a_custom_constraint():
    """A frame whose Python constraint raises in its middle substep puts back the particles
    and the constraint state (the helix's tracked parameter, the CG warm start), so the run
    goes on bit for bit as one that never failed."""
    never = [0]
    scene, cs, ps, calls = _helix_and_plane(never)
    scene.step()
    first, after_one = calls[0], _seen(cs, ps)
    scene.step(3)
    second, want = calls[0] - first, _seen(cs, ps)

    fail_at = [first + second // 6 + 1]  # mid-frame 2, after a substep or two committed
    scene, cs, ps, calls = _helix_and_plane(fail_at)
    scene.step()
    with pytest.raises(RuntimeError, match="on purpose"):
        scene.step()
    got = _seen(cs, ps)
    assert all(np.array_equal(a, b) for a, b in zip(got, after_one, strict=True))
    fail_at[0] = 0
    scene.step(3)
    got = _seen(cs, ps)
    assert all(np.array_equal(a, b) for a, b in zip(got, want, strict=True))
