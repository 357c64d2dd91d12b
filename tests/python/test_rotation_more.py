"""Stacks of any shape, means, alignment, groups, MRPs, powers and short Euler sequences,
checked against analytic answers and scipy as an independent oracle."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation as SciRotation

from kinema import Rotation


def sci(r: Rotation) -> SciRotation:
    return SciRotation.from_quat(r.as_quat(scalar_first=False))


def same(a: np.ndarray, b: np.ndarray, tol: float = 1e-14) -> bool:
    """Quaternions equal up to sign, row by row."""
    d = np.abs(np.sum(np.asarray(a) * np.asarray(b), axis=-1))
    return bool(np.all(np.abs(d - 1.0) < tol))


def test_quarter_turn_matrices_have_exact_zeros():
    # Quarter turns about the axes and the 1/3 turn about the diagonal (a permutation): their
    # normalised quaternions have equal components, so every zero entry must be exactly 0
    # (1 - 2(y² + z²) left 2.2e-16), the others 1 ulp from ±1 at most.
    quats = [[1, 1, 0, 0], [1, 0, -1, 0], [1, 0, 0, 1], [1, 1, 1, 1], [0, 1, 1, 0]]
    m = Rotation.from_quat(quats).as_matrix()
    exact = np.round(m)
    assert np.array_equal(m[exact == 0], np.zeros(np.sum(exact == 0)))
    assert np.allclose(m, exact, rtol=0, atol=2.3e-16)


def test_stacks_of_any_shape_broadcast_like_numpy():
    r = Rotation.random(shape=(3, 4), rng=1)
    assert r.shape == (3, 4) and len(r) == 3 and r[1].shape == (4,) and r[1, 2].single
    assert r.as_matrix().shape == (3, 4, 3, 3) and r.magnitude().shape == (3, 4)
    v = np.random.default_rng(2).normal(size=(4, 3))
    got = r.apply(v)
    want = sci(r).apply(v)
    assert got.shape == (3, 4, 3) and np.allclose(got, want, atol=1e-14)
    col = Rotation.random(shape=(3, 1), rng=3)
    prod = col * Rotation.random(4, rng=4)
    assert prod.shape == (3, 4)
    want = (sci(col) * sci(Rotation.random(4, rng=4))).as_quat(scalar_first=True)
    assert same(prod.as_quat(), want)
    r[0] = Rotation.identity()
    assert np.all(r[0].magnitude() == 0.0) and np.all(r[1].magnitude() > 0.0)
    assert Rotation.identity(shape=(2, 0)).shape == (2, 0)
    with pytest.raises(ValueError, match="n, shape"):
        Rotation.identity(2, shape=3)
    with pytest.raises(ValueError, match="other"):
        Rotation.random(3, rng=0) * Rotation.random(4, rng=0)


def test_short_euler_sequences_and_powers_match_scipy():
    for seq, angles in [("z", 0.3), ("X", [0.3]), ("xy", [0.1, -2.0]), ("ZX", [[0.4, 0.5]])]:
        got = Rotation.from_euler(seq, angles).as_quat(scalar_first=False)
        assert same(got, SciRotation.from_euler(seq, angles).as_quat()), seq
    with pytest.raises(ValueError, match="seq"):
        Rotation.from_euler("xx", [0.1, 0.2])
    r = Rotation.random(50, rng=5)
    for p in (-2.5, -1, 0, 0.5, 1, 3):
        assert same((r**p).as_quat(scalar_first=False), (sci(r) ** p).as_quat()), p
    # Exactly twice the angle, same axis (for angles below pi/2).
    small = Rotation.from_rotvec([0.2, -0.1, 0.3])
    assert np.allclose((small**2).as_rotvec(), 2 * small.as_rotvec(), atol=1e-15)


def test_mean_matches_scipy_with_weights_and_axis_and_ignores_signs():
    r = Rotation.random(shape=(5, 7), rng=6)
    w = np.random.default_rng(7).uniform(0.1, 2.0, size=(5, 7))
    got = r.mean(w, axis=1)
    assert got.shape == (5,)
    for i in range(5):
        assert same(got[i].as_quat(scalar_first=False), sci(r[i]).mean(w[i]).as_quat(), 1e-12)
    flipped = Rotation.from_quat(-r.as_quat())
    assert same(flipped.mean(w).as_quat(), r.mean(w).as_quat(), 1e-13)
    # Two rotations by +-a about one axis average to the identity.
    pm = Rotation.from_rotvec([[0, 0, 0.7], [0, 0, -0.7]])
    assert pm.mean().magnitude() < 1e-15
    with pytest.raises(ValueError, match="weights"):
        r.mean(-w)
    with pytest.raises(ValueError, match="axis"):
        r.mean(axis=2)


def test_align_vectors_matches_scipy_and_pins_the_primary_pair():
    rng = np.random.default_rng(8)
    for weights in ([1.0, 1.0, 1.0, 1.0], [100.0, 1.0, 2.0, 0.5], [1e10, 1.0, 1.0, 1.0]):
        a, b = rng.normal(size=(4, 3)), rng.normal(size=(4, 3))
        c, rssd, sens = Rotation.align_vectors(a, b, weights, return_sensitivity=True)
        sc, srssd, ssens = SciRotation.align_vectors(a, b, weights, return_sensitivity=True)
        assert np.allclose(c.as_matrix(), sc.as_matrix(), atol=1e-7), weights
        assert abs(rssd - srssd) <= 1e-9 * max(1.0, srssd)
        assert np.allclose(sens, ssens, rtol=1e-6, atol=1e-12 * np.abs(ssens).max())
    # Exact data: the rotation is recovered and the residual vanishes.
    truth = Rotation.from_rotvec([0.3, -1.1, 2.0])
    b = rng.normal(size=(6, 3))
    c, rssd = Rotation.align_vectors(truth.apply(b), b)
    assert c.approx_equal(truth, 1e-14) and rssd < 1e-12
    # A huge finite weight and an infinite one agree (regression: nalgebra's SVD was 0.4 off).
    a, b = rng.normal(size=(2, 3)), rng.normal(size=(2, 3))
    pinned, _ = Rotation.align_vectors(a, b, [np.inf, 1.0])
    heavy, _ = Rotation.align_vectors(a, b, [1e10, 1.0])
    assert np.allclose(pinned.as_matrix(), heavy.as_matrix(), atol=1e-8)
    direction = pinned.apply(b[0]) / np.linalg.norm(b[0])
    assert np.allclose(direction, a[0] / np.linalg.norm(a[0]), atol=1e-15)
    with pytest.warns(UserWarning, match="not uniquely"):
        Rotation.align_vectors([[1, 0, 0], [2, 0, 0]], [[0, 1, 0], [0, 2, 0]])
    with pytest.raises(ValueError, match="weights"):
        Rotation.align_vectors(a, b, [np.inf, np.inf])


@pytest.mark.parametrize(("name", "order"), [("I", 60), ("O", 24), ("T", 12), ("C5", 5), ("D4", 8)])
def test_groups_are_closed_and_reduce_to_the_identity(name, order):
    g = Rotation.create_group(name, "X")
    assert len(g) == order
    products = (g[:, None] * g[None, :]).as_quat()
    dots = np.abs(np.einsum("abk,ck->abc", products, g.as_quat()))
    assert np.all(np.sum(dots > 1 - 1e-12, axis=2) == 1)  # every product is one element
    reduced, left, right = g.reduce(g, g, return_indices=True)
    assert np.all(reduced.magnitude() < 1e-14) and left.shape == right.shape == (order,)
    p = Rotation.random(20, rng=9)
    ours = p.reduce(g)
    theirs = sci(p).reduce(SciRotation.from_quat(g.as_quat(scalar_first=False)))
    assert np.allclose(ours.magnitude(), theirs.magnitude(), atol=1e-14)
    with pytest.raises(ValueError, match="group"):
        Rotation.create_group("C0")


def test_mrps_round_trip_and_match_scipy():
    r = Rotation.random(shape=(4, 5), rng=10)
    p = r.as_mrp()
    assert p.shape == (4, 5, 3) and np.all(np.linalg.norm(p, axis=-1) <= 1.0 + 1e-15)
    flat = Rotation.from_quat(r.as_quat().reshape(-1, 4))
    assert np.allclose(flat.as_mrp(), sci(flat).as_mrp(), atol=1e-15)
    assert same(Rotation.from_mrp(p).as_quat(), r.as_quat())
    with pytest.raises(ValueError, match="mrp"):
        Rotation.from_mrp([np.nan, 0, 0])


def test_approx_equal_follows_scipy():
    r = Rotation.from_rotvec([0, 0, 1e-9])
    assert r.approx_equal(Rotation.identity())
    assert not r.approx_equal(Rotation.identity(), atol=1e-10)
    assert r.approx_equal(Rotation.identity(), atol=1e-6, degrees=True)
    with pytest.warns(UserWarning, match="atol"):
        r.approx_equal(Rotation.identity(), degrees=True)


def test_spline_rates_in_the_body_frame_match_scipy():
    from scipy.spatial.transform import RotationSpline

    from kinema.anim import RotationTrack

    t = [0.0, 1.0, 2.0, 3.5]
    r = Rotation.random(4, rng=11)
    ours = RotationTrack(t, r, "spline")
    theirs = RotationSpline(t, sci(r))
    ts = np.linspace(0.1, 3.4, 7)
    # scipy stops iterating at 1e-9, kinema converges to 1e-13 (docs/anim.md).
    assert np.allclose(ours.angular_velocity(ts, frame="body"), theirs(ts, 1), atol=1e-8)
    assert np.allclose(ours.angular_acceleration(ts, frame="body"), theirs(ts, 2), atol=1e-8)
    world = ours.angular_velocity(ts)
    assert np.allclose(world, ours(ts).apply(theirs(ts, 1)), atol=1e-8)
    with pytest.raises(ValueError, match="frame"):
        ours.angular_velocity(0.5, frame="space")


def test_davenport_angles_match_scipy_for_oblique_and_per_rotation_axes():
    rng = np.random.default_rng(5)
    r = Rotation.random(200, rng=rng)
    # Oblique axes: n1, n2 orthonormal, n3 = R_n2(λ) n1 for λ on both sides of 0.
    frame = SciRotation.from_rotvec([0.3, -1.1, 0.7]).as_matrix().T
    for lam in (-2.5, -0.4, 0.0, 0.9, 2.8):
        n3 = SciRotation.from_rotvec(lam * frame[1]).apply(frame[0])
        axes = np.array([frame[0], frame[1], n3])
        for order in ("e", "i"):
            got = r.as_davenport(axes, order)
            assert np.allclose(got, sci(r).as_davenport(axes, order), atol=1e-12)
            assert same(Rotation.from_davenport(axes, order, got).as_quat(), r.as_quat(), 1e-13)
    # One set of axes per rotation, broadcast against a (2, 1) stack.
    per = SciRotation.random(3, rng=6).as_matrix()  # rows of each matrix are orthonormal
    s = Rotation.random(shape=(2, 1), rng=7)
    got = s.as_davenport(per, "extrinsic")
    assert got.shape == (2, 3, 3)
    want = np.stack(
        [sci(s[i, 0]).as_davenport(per[j], "extrinsic") for i in range(2) for j in range(3)]
    )
    assert np.allclose(got.reshape(6, 3), want, atol=1e-12)
    back = Rotation.from_davenport(per, "extrinsic", got)
    assert back.shape == (2, 3) and same(
        back.as_quat(), np.broadcast_to(s.as_quat(), (2, 3, 4)), 1e-13
    )


def test_davenport_refuses_bad_axes_naming_them():
    r = Rotation.random(2, rng=0)
    with pytest.raises(ValueError, match=r"^axes: consecutive axes must be orthogonal"):
        r.as_davenport([[1, 0, 0], [1, 1, 0], [0, 0, 1]], "e")
    with pytest.raises(ValueError, match=r"^axes: expected shape \(\.\.\., 3, 3\)"):
        r.as_davenport([[1, 0, 0], [0, 1, 0]], "e")
    with pytest.raises(ValueError, match=r"^axes: must be finite and non-zero"):
        r.as_davenport([[0, 0, 0], [0, 1, 0], [0, 0, 1]], "e")
    with pytest.raises(ValueError, match=r"^order:"):
        r.as_davenport(np.eye(3), "sideways")
