"""kinema.particles with the implicit methods: the sparse Newton path on large stiff systems,
against the dense path, and its argument checks."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from kinema.particles import Drag, Gravity, ParticleSystem, Springs

DT = 1.0 / 60.0


def hanging_chain(n: int, k: float) -> ParticleSystem:
    """``n`` particles of 1 g hanging from a pinned first one, 1 cm links at rest length,
    pushed sideways by a velocity growing along the chain."""
    x = np.zeros((n, 3))
    x[:, 1] = -0.01 * np.arange(n)
    v = np.zeros((n, 3))
    v[:, 0] = 0.5 * np.arange(n) / n
    masses = np.full(n, 1e-3)
    masses[0] = np.inf
    ps = ParticleSystem(x, v, masses=masses)
    pairs = np.stack([np.arange(n - 1), np.arange(1, n)], axis=1)
    ps.add(Springs(pairs, stiffness=k, damping=1e-4))
    ps.add(Gravity())
    return ps


def spring_net(side: int, k: float) -> ParticleSystem:
    """A vertical ``side x side`` net of 10 g particles 2 cm apart (structural and shear
    springs), pinned at its two top corners, swinging out of its plane."""
    i, j = np.meshgrid(np.arange(side), np.arange(side), indexing="ij")
    x = np.stack([0.02 * j.ravel(), -0.02 * i.ravel(), np.zeros(side * side)], axis=1)
    v = np.zeros_like(x)
    v[:, 2] = 0.5 * i.ravel() / side
    idx = (i * side + j).ravel()
    pairs = []
    for di, dj in [(1, 0), (0, 1), (1, 1), (1, -1)]:
        ok = ((i + di < side) & (j + dj >= 0) & (j + dj < side)).ravel()
        pairs.append(np.stack([idx[ok], idx[ok] + di * side + dj], axis=1))
    masses = np.full(side * side, 0.01)
    masses[[0, side - 1]] = np.inf
    ps = ParticleSystem(x, v, masses=masses)
    ps.add(Springs(np.concatenate(pairs), stiffness=k, damping=0.01))
    ps.add(Gravity())
    ps.add(Drag(linear=1e-3))
    return ps


@pytest.mark.parametrize("k", [1.0, 1e9])
def test_implicit_euler_on_a_5000_particle_stiff_chain_stays_bounded(k):
    # 30 000 unknowns per Newton solve: the dense matrix alone would take 7 GB.
    n = 5000
    ps = hanging_chain(n, k)
    e0 = ps.kinetic_energy() + ps.potential_energy()
    for _ in range(20):
        ps.step(DT, method="implicit_euler")
        e = ps.kinetic_energy() + ps.potential_energy()
        assert e <= e0 + 1e-9 * abs(e0)
    x = ps.positions
    assert np.all(np.isfinite(x)) and np.abs(x).max() < 100.0
    np.testing.assert_array_equal(x[0], [0.0, 0.0, 0.0])
    assert x[-1, 0] > 0.01  # the chain swung
    if k >= 1e6:
        strain = np.abs(np.linalg.norm(np.diff(x, axis=0), axis=1) / 0.01 - 1.0).max()
        assert strain < 1e5 / k  # 49 N (5 kg) on the top link: a static strain of 4.9e3 / k


@pytest.mark.parametrize("method", ["implicit_euler", "trapezoidal", "bdf2"])
def test_sparse_and_dense_newton_give_the_same_steps(method):
    start = spring_net(6, 1e3)
    sparse, dense = spring_net(6, 1e3), spring_net(6, 1e3)
    sparse.step(DT, 10, method=method)
    dense.step(DT, 10, method=method, sparse_jacobian=False)
    assert np.abs(sparse.positions - start.positions).max() > 1e-2
    np.testing.assert_allclose(sparse.positions, dense.positions, rtol=0, atol=1e-8)
    np.testing.assert_allclose(sparse.velocities, dense.velocities, rtol=0, atol=1e-6)


@pytest.mark.parametrize("method", ["implicit_euler", "bdf2"])
def test_a_large_soft_net_steps_with_the_sparse_path(method):
    # 2500 particles, 15 000 unknowns; k = 100 N/m (stiffer nets need substeps: docs/ode.md).
    ps = spring_net(50, 100.0)
    ps.step(DT, 20, method=method)
    x = ps.positions
    assert np.all(np.isfinite(x)) and x[-1, 2] > 0.01
    np.testing.assert_array_equal(x[49], [0.02 * 49, 0.0, 0.0])


def test_sparse_jacobian_must_be_a_bool():
    ps = spring_net(3, 1.0)
    with pytest.raises(ValueError, match="sparse_jacobian"):
        ps.step(DT, method="implicit_euler", sparse_jacobian="dense")  # type: ignore[arg-type]
    np.testing.assert_array_equal(ps.positions, spring_net(3, 1.0).positions)


@pytest.mark.parametrize("method", ["implicit_euler", "trapezoidal"])
def test_a_linear_chain_is_factorised_once_per_call(method):
    """Zero-length undamped springs are linear: the Newton matrix keeps its factorisation,
    and the steps are bitwise those of a system unpickled before each step (a fresh solver,
    which factorises again)."""
    n, steps = 300, 20
    x = np.zeros((n, 3))
    x[:, 1] = -0.01 * np.arange(n)
    v = np.zeros((n, 3))
    v[:, 0] = 0.5 * np.arange(n) / n
    masses = np.full(n, 1e-3)
    masses[0] = np.inf
    pairs = np.stack([np.arange(n - 1), np.arange(1, n)], axis=1)
    systems = []
    for _ in range(2):
        ps = ParticleSystem(x, v, masses=masses)
        ps.add(Springs(pairs, stiffness=1e4, rest=np.zeros(n - 1)))
        ps.add(Gravity())
        systems.append(ps)
    once, each = systems
    once.step(DT, steps, method)
    assert once.stats["factorizations"] == 1
    for _ in range(steps):
        each = pickle.loads(pickle.dumps(each))
        each.step(DT, 1, method)
        assert each.stats["factorizations"] == 1
    np.testing.assert_array_equal(once.positions, each.positions)
    np.testing.assert_array_equal(once.velocities, each.velocities)
    swinging = hanging_chain(n, 1e4)
    swinging.step(DT, steps, method)
    assert swinging.stats["factorizations"] >= steps
