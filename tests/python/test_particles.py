"""kinema.particles through Python: physics against scipy, zero-copy views, bad input."""

from __future__ import annotations

import gc
import pickle
import re

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import kinema
from kinema.particles import (
    Attractor,
    Damping,
    Drag,
    Emitter,
    Field,
    Gravity,
    NeighborRepulsion,
    ParticleSystem,
    Plane,
    Sphere,
    Springs,
    Turbulence,
    Vortex,
)


def test_projectile_with_quadratic_drag_matches_scipy():
    k, m = 0.05, 0.5
    ps = ParticleSystem([[0.0, 0.0, 0.0]], [[20.0, 15.0, 0.0]], masses=m)
    ps.add(Gravity())
    ps.add(Drag(quadratic=k))
    ps.step(1e-3, 2000, method="rk4")

    def f(t, y):
        v = y[3:]
        return np.concatenate([v, [0.0, -9.81, 0.0] - k / m * np.linalg.norm(v) * v])

    ref = solve_ivp(f, (0, 2), [0, 0, 0, 20, 15, 0], method="DOP853", rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(ps.positions[0], ref.y[:3, -1], atol=1e-9)
    np.testing.assert_allclose(ps.velocities[0], ref.y[3:, -1], atol=1e-9)


def test_state_views_are_zero_copy_read_only_and_outlive_the_system():
    ps = ParticleSystem(np.zeros((4, 3)), masses=[1, 2, 3, 4])
    ps.add(Gravity())
    view = ps.positions
    assert np.shares_memory(view, ps.positions)
    ps.step(0.1)
    assert view[0, 1] < 0.0  # updated in place, no copy
    with pytest.raises(ValueError, match="read-only"):
        view[0, 0] = 1.0
    del ps
    gc.collect()
    assert view.shape == (4, 3) and np.isfinite(view).all()


def test_springs_conserve_momentum_and_energy_is_reported():
    rng = np.random.default_rng(0)
    x = rng.uniform(-1, 1, (20, 3))
    v = rng.normal(size=(20, 3))
    m = rng.uniform(0.5, 2.0, 20)
    ps = ParticleSystem(x, v, m)
    pairs = np.array([[i, i + 1] for i in range(19)])
    ps.add(Springs(pairs, stiffness=30.0))
    ps.add(NeighborRepulsion(radius=0.5, stiffness=20.0))
    p0 = (m[:, None] * ps.velocities).sum(axis=0)
    e0 = ps.kinetic_energy() + ps.potential_energy()
    assert ps.potential_energy() == pytest.approx(0.0)  # rest lengths from the initial state
    ps.step(1e-4, 2000, method="velocity_verlet")
    np.testing.assert_allclose((m[:, None] * ps.velocities).sum(axis=0), p0, atol=1e-10)
    assert (
        ps.kinetic_energy() + ps.potential_energy() < 1.1 * e0 + 1.0
    )  # repulsion energy is not reported


def test_ground_bounce_and_rest():
    ps = ParticleSystem([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    ps.add(Gravity())
    ps.add(Plane(restitution=0.5, friction=0.2))
    ps.step(1 / 240, 240 * 4)
    assert np.all(np.abs(ps.positions[:, 1]) < 1e-12)
    assert ps.kinetic_energy() == 0.0


def test_fountain_with_emitter_vortex_turbulence_and_sphere():
    ps = ParticleSystem(np.zeros((0, 3)), capacity=500)
    ps.add(Emitter(rate=400, velocity=[0, 6, 0], velocity_spread=1.0, lifespan=1.0, seed=3))
    ps.add(Gravity())
    ps.add(Vortex(center=[0, 0, 0], strength=2.0))
    ps.add(Turbulence(strength=1.0, scale=0.5))
    ps.add(Damping(0.1))
    ps.add(Attractor(center=[0, 3, 0], strength=0.5))
    ps.add(Sphere(center=[0, 0, 0], radius=5.0, inside=True, restitution=0.3))
    ps.add(Plane())
    for _ in range(120):
        ps.step(1 / 120)
    alive = ps.alive
    assert 350 < alive.sum() <= 401
    assert np.all(np.linalg.norm(ps.positions[alive], axis=1) <= 5.0 + 1e-12)
    assert np.all(ps.positions[alive, 1] >= 0.0)
    assert np.all(ps.ages[alive] <= 1.0)


def test_bad_input_names_the_argument_and_failures_roll_back():
    with pytest.raises(ValueError, match=r"masses\[1\]"):
        ParticleSystem(np.zeros((2, 3)), masses=[1.0, -1.0])
    with pytest.raises(ValueError, match=r"positions\[0\]"):
        ParticleSystem([[np.nan, 0, 0]])
    with pytest.raises(ValueError, match="positions: expected shape"):
        ParticleSystem(np.zeros((2, 2)))
    ps = ParticleSystem(np.zeros((2, 3)))
    with pytest.raises(ValueError, match="pairs"):
        ps.add(Springs([[0, 5]], stiffness=1.0))
    with pytest.raises(ValueError, match="restitution"):
        ps.add(Plane(restitution=2.0))
    with pytest.raises(ValueError, match="item"):
        ps.add("gravity")
    with pytest.raises(ValueError, match="method"):
        ps.step(0.1, method="rk45")
    boom = ParticleSystem([[0.0, 0.0, 0.0]], [[1e300, 0.0, 0.0]])
    boom.add(Drag(quadratic=1e10))
    before = boom.velocities.copy()
    with pytest.raises(kinema.SimulationError, match="step 0, element 0"):
        boom.step(0.1, 3, method="explicit_euler")
    np.testing.assert_array_equal(boom.velocities, before)


def test_one_step_calls_still_roll_back_a_failed_step():
    # After a first call, calls of one step from a bounded state are certified not to go
    # non-finite and take no copy of the state; a step the certificate cannot vouch for (a
    # field of 1e300 N) copies again, and when it does go non-finite it is undone.
    rng = np.random.default_rng(3)
    ps = ParticleSystem(rng.uniform(0.0, 1.0, (100, 3)), rng.normal(size=(100, 3)))
    ps.add(Gravity())
    ps.add(Plane(restitution=0.5, friction=0.3))
    for _ in range(10):
        ps.step(1e-3)
    x, v, ages = ps.positions.copy(), ps.velocities.copy(), ps.ages.copy()
    age = 0.0
    for _ in range(10):
        age += 1e-3  # the steps added one by one
    np.testing.assert_array_equal(ages, np.full(100, age))
    ps.add(Field(lambda t, x, v: np.full_like(x, 1e300)))
    with pytest.raises(kinema.SimulationError, match="step 0"):
        ps.step(1e10)
    np.testing.assert_array_equal(ps.positions, x)
    np.testing.assert_array_equal(ps.velocities, v)
    np.testing.assert_array_equal(ps.ages, ages)


def test_python_field_acts_like_the_builtin_force():
    x0, v0 = [[0.0, 0.0, 0.0], [1.0, 2.0, 0.0]], [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
    a = ParticleSystem(x0, v0, masses=[1.0, 2.0])
    a.add(Gravity())
    b = ParticleSystem(x0, v0, masses=[1.0, 2.0])
    b.add(Field(lambda t, x, v: np.array([[0, -9.81, 0], [0, -2 * 9.81, 0]])))
    a.step(0.01, 50)
    b.step(0.01, 50)
    np.testing.assert_allclose(a.positions, b.positions, atol=1e-12)
    assert b.time == pytest.approx(0.5)
    c = ParticleSystem(x0, v0)
    c.add(Field(lambda t, x, v: np.zeros((3, 3))))
    with pytest.raises(ValueError, match="shape"):
        c.step(0.01)
    d = ParticleSystem(x0, v0)
    d.add(Field(lambda t, x, v: np.full((2, 3), np.nan)))
    with pytest.raises(ValueError, match="forces"):
        d.step(0.01)


def test_capsule_and_moving_colliders():
    from kinema.particles import Capsule

    # A particle dropped on a horizontal capsule rests on its top, at radius above the axis.
    ps = ParticleSystem([[0.3, 1.0, 0.0]])
    ps.add(Gravity())
    ps.add(Capsule([-1, 0, 0], [1, 0, 0], 0.2, restitution=0.0, friction=1.0))
    ps.step(1e-3, 2000)
    assert ps.positions[0] == pytest.approx([0.3, 0.2, 0.0], abs=1e-6)
    # A sphere moving at 1 m/s into a resting particle (no gravity) sends it off at
    # (1 + e) times the sphere's speed, as an elastic wall would.
    ps = ParticleSystem([[0.5, 0.0, 0.0]])
    ps.add(Sphere([0.0, 0.0, 0.0], 0.45, restitution=1.0))
    for k in range(1, 200):
        center = [k * 1e-3, 0.0, 0.0]  # where the sphere is at the end of this step
        ps.set_collider(0, Sphere(center, 0.45, restitution=1.0, velocity=[1.0, 0.0, 0.0]))
        ps.step(1e-3)
        if ps.velocities[0, 0] > 0:
            break
    assert 45 <= k <= 60  # it met the particle after ~0.05 m
    assert ps.velocities[0, 0] == pytest.approx(2.0, rel=1e-9)
    assert ps.positions[0, 0] >= center[0] + 0.45 - 1e-12
    with pytest.raises(ValueError, match="velocity"):
        ps.set_collider(0, Sphere([0, 0, 0], 1.0, velocity=[np.nan, 0, 0]))


@pytest.mark.parametrize("method", kinema.ode.METHODS)
def test_a_pinned_particle_stays_put_with_every_method(method):
    # Infinite mass pins a particle even when it was given a velocity, with gravity and a
    # spring pulling on it: the drift of the second-order methods must not move it either.
    ps = ParticleSystem(
        np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]),
        velocities=np.array([[1.0, 2.0, 3.0], [0.0, 0.0, 0.0]]),
        masses=np.array([np.inf, 1.0]),
    )
    ps.add(Gravity())
    ps.add(Springs([[0, 1]], stiffness=10.0, rest=[0.5]))
    ps.step(0.01, steps=20, method=method)
    assert np.array_equal(ps.positions[0], [0.0, 0.0, 0.0])
    assert np.array_equal(ps.velocities[0], [1.0, 2.0, 3.0])
    assert ps.positions[1, 1] < 0.0  # the free end falls


def two_emitter_fountain(speed: float | None = None) -> ParticleSystem:
    """Red particles fly to +y, blue ones (colour and size spread) to -y; both live 0.25 s.
    With ``speed``, one more particle (slot 0, lives forever) flies along +x at that speed."""
    x = np.zeros((0 if speed is None else 1, 3))
    v = np.array([[speed or 0.0, 0.0, 0.0]])[: len(x)]
    s = ParticleSystem(x, v, capacity=400)
    s.add(Emitter(rate=200, velocity=(0, 1, 0), lifespan=0.25, color=(1, 0, 0), size=0.02))
    s.add(
        Emitter(
            rate=200,
            velocity=(0, -1, 0),
            velocity_spread=0.2,
            lifespan=0.25,
            color=(0.0, 0.0, 1.0, 0.5),
            color_spread=0.1,
            size=0.05,
            size_spread=0.01,
            seed=3,
        )
    )
    return s


def test_particle_colours_and_sizes_follow_their_emitter():
    s = two_emitter_fountain()
    colors, sizes = s.colors, s.sizes  # views: read once, updated in place
    assert colors.shape == (400, 4) and colors.dtype == np.float64 and not colors.flags.writeable
    assert sizes.shape == (400,) and sizes.dtype == np.float64 and not sizes.flags.writeable
    np.testing.assert_array_equal(colors, 1.0)  # empty slots: opaque white, 1 cm
    np.testing.assert_array_equal(sizes, 0.01)
    blue_sizes = []
    for _ in range(60):  # 1 s: every slot dies and is reused about four times
        s.step(1 / 60)
        alive, vy = s.alive, s.velocities[:, 1]
        red, blue = alive & (vy > 0), alive & (vy < 0)
        assert red.sum() >= 3 and blue.sum() >= 3
        # Each live slot carries the colour and size of the emitter that made it, however
        # the slots were recycled.
        np.testing.assert_array_equal(colors[red], [[1.0, 0.0, 0.0, 1.0]] * int(red.sum()))
        np.testing.assert_array_equal(sizes[red], 0.02)
        c = colors[blue]
        assert (c[:, :2] >= 0.0).all() and (c[:, :2] <= 0.1).all()
        assert (c[:, 2] >= 0.9).all() and (c[:, 2] <= 1.0).all()
        np.testing.assert_array_equal(c[:, 3], 0.5)
        assert (np.abs(sizes[blue] - 0.05) <= 0.01).all()
        blue_sizes.extend(sizes[blue])
    # The spreads are drawn (uniform: mean 0.05 m, standard deviation 0.01/√3 m).
    assert np.mean(blue_sizes) == pytest.approx(0.05, abs=1e-3)
    assert np.std(blue_sizes) == pytest.approx(0.01 / np.sqrt(3), rel=0.15)
    assert len(blue_sizes) > 1000
    assert np.ptp(colors[s.alive & (s.velocities[:, 1] < 0), 0]) > 0.0


def test_constant_appearance_leaves_the_motion_unchanged():
    a = ParticleSystem(np.zeros((0, 3)), capacity=100)
    b = ParticleSystem(np.zeros((0, 3)), capacity=100)
    a.add(Emitter(rate=300, velocity=(0, 2, 0), velocity_spread=1.0, lifespan=0.2, seed=5))
    b.add(
        Emitter(
            rate=300,
            velocity=(0, 2, 0),
            velocity_spread=1.0,
            lifespan=0.2,
            seed=5,
            color=(0.2, 0.4, 0.6, 1.0),
            size=0.3,
        )
    )
    a.step(0.01, 50)
    b.step(0.01, 50)
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(b.colors[b.alive], [[0.2, 0.4, 0.6, 1.0]] * int(b.alive.sum()))


def test_colours_and_sizes_survive_save_resume_and_a_failed_step():
    s = two_emitter_fountain()
    s.step(1 / 60, 10)
    copy = pickle.loads(pickle.dumps(s))
    np.testing.assert_array_equal(copy.colors, s.colors)
    np.testing.assert_array_equal(copy.sizes, s.sizes)
    s.step(1 / 60, 7)
    copy.step(1 / 60, 7)
    np.testing.assert_array_equal(copy.colors, s.colors)
    np.testing.assert_array_equal(copy.sizes, s.sizes)
    np.testing.assert_array_equal(copy.positions, s.positions)
    # A call that fails part-way through is left at its last good step: colours and sizes as
    # in a system that took just those steps.
    # The fast particle's position overflows after about 18 steps of 1 s; the emitted ones
    # die and are replaced at every step, so each step rewrites colours and sizes.
    a, b = two_emitter_fountain(speed=1e307), two_emitter_fountain(speed=1e307)
    with pytest.raises(kinema.SimulationError, match=r"step (\d+)") as failed:
        a.step(1.0, 40)
    good = int(re.search(r"step (\d+)", str(failed.value)).group(1))
    assert good > 3
    b.step(1.0, good)
    np.testing.assert_array_equal(a.colors, b.colors)
    np.testing.assert_array_equal(a.sizes, b.sizes)
    np.testing.assert_array_equal(a.positions, b.positions)


def test_initial_particles_take_given_colours_and_sizes():
    s = ParticleSystem(np.zeros((3, 3)), capacity=5, colors=[[1, 0, 0], [0, 1, 0], [0, 0, 1]])
    np.testing.assert_array_equal(s.colors[:3, :3], np.eye(3))
    np.testing.assert_array_equal(s.colors[:, 3], 1.0)
    np.testing.assert_array_equal(s.colors[3:], 1.0)
    np.testing.assert_array_equal(s.sizes, 0.01)
    s = ParticleSystem(np.zeros((2, 3)), colors=(0.5, 0.5, 0.5, 0.2), sizes=[0.1, 0.2])
    np.testing.assert_array_equal(s.colors, [[0.5, 0.5, 0.5, 0.2]] * 2)
    np.testing.assert_array_equal(s.sizes, [0.1, 0.2])


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"color": (1.5, 0, 0)}, "color"),
        ({"color": (1, 0)}, "color"),
        ({"color_spread": -0.1}, "color_spread"),
        ({"size": 0.0}, "size"),
        ({"size": float("nan")}, "size"),
        ({"size": 0.1, "size_spread": 0.1}, "size_spread"),
    ],
)
def test_bad_appearance_names_the_argument(kwargs, match):
    s = ParticleSystem(np.zeros((0, 3)), capacity=10)
    with pytest.raises(ValueError, match=match):
        s.add(Emitter(rate=1.0, **kwargs))
    with pytest.raises(ValueError, match="colors"):
        ParticleSystem(np.zeros((2, 3)), colors=[[2.0, 0, 0]] * 2)
    with pytest.raises(ValueError, match="sizes"):
        ParticleSystem(np.zeros((2, 3)), sizes=[0.1, -1.0])
