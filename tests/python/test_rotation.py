"""Rotations against scipy.spatial.transform as an independent oracle, plus properties and
the extremes (tiny and near-pi angles, gimbal lock, degenerate slerp, bad input)."""

from __future__ import annotations

import itertools
import pickle
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.spatial.transform import Rotation as SciRotation
from scipy.spatial.transform import Slerp as SciSlerp

import kinema
from kinema import GimbalLockWarning, Rotation, Transform, slerp
from kinema.rotation import gimbal_lock

TAIT_BRYAN = ["".join(p) for p in itertools.permutations("xyz")]
PROPER = [a + b + a for a in "xyz" for b in "xyz" if a != b]
SEQUENCES = [s for base in TAIT_BRYAN + PROPER for s in (base, base.upper())]


def sci(r: Rotation) -> SciRotation:
    return SciRotation.from_quat(r.as_quat(), scalar_first=True)


def angle_between(a: Rotation, b: Rotation) -> np.ndarray:
    return np.atleast_1d((a * b.inv()).magnitude())


@pytest.fixture(scope="module")
def rots() -> Rotation:
    return Rotation.random(500, rng=7)


def test_24_sequences_are_all_the_sequences():
    assert len(SEQUENCES) == 24 and len(set(SEQUENCES)) == 24


def test_quat_and_matrix_agree_with_scipy(rots):
    np.testing.assert_allclose(rots.as_matrix(), sci(rots).as_matrix(), atol=1e-15)
    back = Rotation.from_matrix(sci(rots).as_matrix())
    np.testing.assert_allclose(
        back.as_quat(canonical=True),
        sci(rots).as_quat(canonical=True, scalar_first=True),
        atol=1e-15,
    )


def test_scalar_last_interop(rots):
    q_xyzw = sci(rots).as_quat()
    r = Rotation.from_quat(q_xyzw, scalar_first=False)
    np.testing.assert_allclose(r.as_quat(), rots.as_quat(), atol=1e-16)
    np.testing.assert_allclose(rots.as_quat(scalar_first=False), q_xyzw, atol=1e-16)


def test_rotvec_agrees_with_scipy(rots):
    np.testing.assert_allclose(rots.as_rotvec(), sci(rots).as_rotvec(), atol=1e-14)
    v = sci(rots).as_rotvec()
    np.testing.assert_allclose(
        Rotation.from_rotvec(v).as_matrix(), sci(rots).as_matrix(), atol=1e-15
    )
    np.testing.assert_allclose(rots.as_rotvec(degrees=True), np.rad2deg(rots.as_rotvec()))


@pytest.mark.parametrize(
    "angle", [1e-300, 1e-12, 1e-8, 1e-4, 1.0, np.pi - 1e-6, np.pi - 1e-12, np.pi]
)
def test_rotvec_round_trip_at_tiny_and_near_pi_angles(angle):
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    r = Rotation.from_rotvec(angle * axis)
    back = r.as_rotvec()
    # Near pi the sign of the axis may flip (both describe the same rotation).
    if angle > 3:
        assert angle_between(Rotation.from_rotvec(back), r)[0] < 1e-15
    else:
        np.testing.assert_allclose(back, angle * axis, rtol=1e-15, atol=0)
    assert abs(r.magnitude() - angle) <= 4e-16 * max(angle, 1e-300) + 1e-300 or angle > 3
    ref = SciRotation.from_rotvec(angle * axis)
    np.testing.assert_allclose(r.as_matrix(), ref.as_matrix(), atol=1e-16)


@pytest.mark.parametrize("scale", [1e10, 1e160, 1e300, np.finfo(float).max])
def test_huge_rotation_vectors_give_unit_quaternions(scale):
    # Beyond ~1e154 the squares of the components overflow; the rotation must stay finite.
    q = Rotation.from_rotvec([0.6 * scale, 0.0, -0.8 * scale]).as_quat()
    assert np.all(np.isfinite(q))
    assert abs(np.linalg.norm(q) - 1.0) < 1e-15
    assert abs(0.8 * q[1] + 0.6 * q[3]) < 1e-15  # the axis is along (0.6, 0, -0.8)


def test_axis_angle_round_trip_and_broadcast():
    axes = np.array([[1.0, 0, 0], [0, 2.0, 0], [0, 0, -3.0]])
    r = Rotation.from_axis_angle(axes, 90.0, degrees=True)
    axis, angle = r.as_axis_angle()
    np.testing.assert_allclose(axis, [[1, 0, 0], [0, 1, 0], [0, 0, -1]], atol=1e-16)
    np.testing.assert_allclose(angle, np.pi / 2)
    axis, angle = Rotation.identity().as_axis_angle()
    assert angle == 0.0 and np.array_equal(axis, [1.0, 0.0, 0.0])
    with pytest.raises(ValueError, match=r"axis\[0\].*zero"):
        Rotation.from_axis_angle([0, 0, 0], 1.0)


@pytest.mark.parametrize("seq", SEQUENCES)
def test_euler_agrees_with_scipy(seq, rots):
    angles = sci(rots).as_euler(seq)
    np.testing.assert_allclose(
        Rotation.from_euler(seq, angles).as_matrix(), sci(rots).as_matrix(), atol=1e-15
    )
    ours = rots.as_euler(seq)
    diff = np.angle(np.exp(1j * (ours - angles)))  # compare modulo 2 pi
    np.testing.assert_allclose(diff, 0.0, atol=1e-12)
    proper = seq[0].lower() == seq[2].lower()
    mid = ours[:, 1]
    assert np.all((mid >= 0) & (mid <= np.pi)) if proper else np.all(np.abs(mid) <= np.pi / 2)
    assert np.all(np.abs(ours[:, [0, 2]]) <= np.pi)


@pytest.mark.parametrize("seq", TAIT_BRYAN)
def test_intrinsic_equals_reversed_extrinsic(seq):
    angles = np.random.default_rng(1).uniform(-3, 3, (50, 3))
    a = Rotation.from_euler(seq.upper(), angles)
    b = Rotation.from_euler(seq[::-1], angles[:, ::-1])
    assert np.all(angle_between(a, b) < 1e-15)


@pytest.mark.parametrize("seq", SEQUENCES)
@pytest.mark.parametrize("side", [-1.0, 1.0])
def test_exact_gimbal_lock_warns_and_reproduces_the_rotation(seq, side):
    proper = seq[0].lower() == seq[2].lower()
    middle = (0.0 if side < 0 else np.pi) if proper else side * np.pi / 2
    angles = np.array([0.7, middle, -1.1])
    assert gimbal_lock(seq, angles)
    r = Rotation.from_euler(seq, angles)
    with pytest.warns(GimbalLockWarning):
        out = r.as_euler(seq)
    assert not np.isnan(out).any()
    assert out[2] == 0.0
    assert angle_between(Rotation.from_euler(seq, out), r)[0] < 1e-14


@pytest.mark.parametrize("seq", SEQUENCES)
@pytest.mark.parametrize("offset", [1e-9, -1e-9, 1e-7])
def test_near_gimbal_lock_is_exact_and_silent(seq, offset):
    proper = seq[0].lower() == seq[2].lower()
    middle = abs(offset) if proper else np.pi / 2 - offset
    angles = np.array([0.7, middle, -1.1])
    assert not gimbal_lock(seq, angles)
    assert gimbal_lock(seq, angles, atol=1e-6)
    r = Rotation.from_euler(seq, angles)
    with warnings.catch_warnings():
        warnings.simplefilter("error", GimbalLockWarning)
        out = r.as_euler(seq)
    assert angle_between(Rotation.from_euler(seq, out), r)[0] < 1e-14


def test_gimbal_warning_can_be_silenced():
    r = Rotation.from_euler("XYZ", [0.1, np.pi / 2, 0.2])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warnings.simplefilter("ignore", GimbalLockWarning)
        r.as_euler("XYZ")


def test_apply_matches_matrix_product_and_inverse(rots):
    v = np.random.default_rng(2).standard_normal((len(rots), 3))
    np.testing.assert_allclose(
        rots.apply(v), np.einsum("nij,nj->ni", rots.as_matrix(), v), atol=1e-14
    )
    np.testing.assert_allclose(rots.apply(rots.apply(v), inverse=True), v, atol=1e-14)
    np.testing.assert_allclose(rots.apply(v[0]), sci(rots).apply(v[0]), atol=1e-14)
    assert rots[3].apply(v[0]).shape == (3,)
    np.testing.assert_allclose(rots[3].apply(v), sci(rots[3]).apply(v), atol=1e-14)


def test_composition_and_inverse(rots):
    a, b = rots[:250], rots[250:]
    np.testing.assert_allclose((a * b).as_matrix(), a.as_matrix() @ b.as_matrix(), atol=1e-14)
    np.testing.assert_allclose((a * b[0]).as_matrix(), a.as_matrix() @ b[0].as_matrix(), atol=1e-14)
    assert np.all((a * a.inv()).magnitude() < 1e-15)
    np.testing.assert_allclose(a.magnitude(), sci(a).magnitude(), atol=1e-14)


def test_container_behaviour(rots):
    assert len(rots) == 500 and not rots.single
    assert rots[0].single and len(rots[1:4]) == 3 and len(rots[[0, 2]]) == 2
    with pytest.raises(TypeError):
        len(rots[0])
    assert len(list(rots[:5])) == 5
    assert Rotation.identity().single and len(Rotation.identity(4)) == 4
    assert Rotation.concatenate([rots[:2], rots[5:7]]).approx_equal(rots[[0, 1, 5, 6]]).all()
    r2 = pickle.loads(pickle.dumps(rots))
    np.testing.assert_array_equal(r2.as_quat(), rots.as_quat())


def test_random_is_repeatable_and_uniform():
    a, b = Rotation.random(20000, rng=3), Rotation.random(20000, rng=3)
    np.testing.assert_array_equal(a.as_quat(), b.as_quat())
    # Uniform rotations: the rotated z axis is uniform on the sphere, E[z_i] = 0, E[z_i^2] = 1/3.
    z = a.apply([0.0, 0.0, 1.0])
    np.testing.assert_allclose(z.mean(axis=0), 0.0, atol=0.02)
    np.testing.assert_allclose((z**2).mean(axis=0), 1 / 3, atol=0.01)


def test_canonical_and_normalisation():
    r = Rotation.from_quat([[-2.0, 0.0, 0.0, 0.0], [0.0, -1.0, 1.0, 0.0], [1e-200, 1e-200, 0, 0]])
    np.testing.assert_allclose(np.linalg.norm(r.as_quat(), axis=1), 1.0, rtol=1e-15)
    c = r.as_quat(canonical=True)
    np.testing.assert_allclose(c[0], [1, 0, 0, 0])
    np.testing.assert_allclose(c[1], [0, 1 / np.sqrt(2), -1 / np.sqrt(2), 0])


# ---------------------------------------------------------------- slerp
def test_slerp_endpoints_speed_and_scipy():
    r0, r1 = Rotation.random(rng=4), Rotation.random(rng=5)
    t = np.linspace(0, 1, 101)
    path = slerp(r0, r1, t)
    assert angle_between(path[0], r0)[0] < 1e-15 and angle_between(path[100], r1)[0] < 1e-14
    steps = (path[1:] * path[:-1].inv()).magnitude()
    np.testing.assert_allclose(steps, steps[0], rtol=1e-9)
    ref = SciSlerp([0, 1], SciRotation.concatenate([sci(r0), sci(r1)]))(t)
    np.testing.assert_allclose(path.as_matrix(), ref.as_matrix(), atol=1e-14)


def test_slerp_extrapolates_on_the_same_circle():
    r0, r1 = Rotation.from_rotvec([0, 0, 0.2]), Rotation.from_rotvec([0, 0, 0.5])
    np.testing.assert_allclose(slerp(r0, r1, 2.0).as_rotvec(), [0, 0, 0.8], atol=1e-15)
    np.testing.assert_allclose(slerp(r0, r1, -1.0).as_rotvec(), [0, 0, -0.1], atol=1e-15)


def test_slerp_shortest_and_long_way():
    r0 = Rotation.identity()
    r1 = Rotation.from_quat([-np.cos(0.1), 0, 0, -np.sin(0.1)])  # 0.2 rad about z, given as -q
    mid = slerp(r0, r1, 0.5)
    np.testing.assert_allclose(mid.as_rotvec(), [0, 0, 0.1], atol=1e-15)
    long_mid = slerp(r0, r1, 0.5, shortest=False)
    np.testing.assert_allclose(long_mid.magnitude(), np.pi - 0.1, atol=1e-14)


@pytest.mark.parametrize("gap", [0.0, 1e-15, 1e-12, 1e-9])
def test_slerp_between_equal_and_nearly_equal(gap):
    r0 = Rotation.from_rotvec([0.3, -0.2, 0.9])
    r1 = Rotation.from_rotvec([0.3, -0.2, 0.9 + gap])
    out = slerp(r0, r1, np.linspace(-1, 2, 13))
    q = out.as_quat()
    assert np.isfinite(q).all()
    assert np.all(angle_between(out, r0) <= 2 * gap + 1e-15)


def test_slerp_antipodal_quaternions():
    r0 = Rotation.from_rotvec([0.4, 0.1, -0.3])
    r1 = Rotation.from_quat(-r0.as_quat())
    out = slerp(r0, r1, np.linspace(0, 1, 7))
    assert np.all(angle_between(out, r0) < 1e-15)
    full = slerp(r0, r1, np.linspace(0, 1, 7), shortest=False)
    assert np.isfinite(full.as_quat()).all()
    np.testing.assert_allclose(angle_between(full[3], r0), np.pi, atol=1e-14)


def test_slerp_broadcasting():
    a = Rotation.random(5, rng=1)
    b = Rotation.random(rng=2)
    assert len(slerp(a, b, 0.3)) == 5
    assert len(slerp(a, b, np.linspace(0, 1, 5))) == 5
    assert len(slerp(a[0], b, np.linspace(0, 1, 9))) == 9
    assert slerp(a[0], b, 0.5).single
    with pytest.raises(ValueError, match="t"):
        slerp(a, b, np.linspace(0, 1, 4))
    with pytest.raises(ValueError, match="t"):
        slerp(a[0], b, np.nan)


# ---------------------------------------------------------------- transforms
def test_transform_apply_compose_invert():
    rng = np.random.default_rng(9)
    r = Rotation.random(20, rng=9)
    t = rng.standard_normal((20, 3))
    s = rng.uniform(0.5, 2.0, (20, 3))
    tf = Transform(r, t, s)
    m = tf.as_matrix()
    np.testing.assert_allclose(m[:, :3, :3], r.as_matrix() * s[:, None, :], atol=1e-15)
    np.testing.assert_allclose(m[:, 3], [[0, 0, 0, 1]] * 20)
    p = rng.standard_normal((20, 3))
    np.testing.assert_allclose(tf.apply(p), r.apply(p * s) + t, atol=1e-14)
    np.testing.assert_allclose(tf.apply_directions(p), r.apply(p * s), atol=1e-14)
    np.testing.assert_allclose(
        (tf.inv() * tf).as_matrix(), np.broadcast_to(np.eye(4), (20, 4, 4)), atol=1e-13
    )
    np.testing.assert_allclose((tf * tf[0]).as_matrix(), m @ m[0], atol=1e-14)
    np.testing.assert_allclose(tf.translation, t)
    single = Transform(translation=[1.0, 2.0, 3.0], scale=2.0)
    assert single.single
    np.testing.assert_allclose(single.apply([1.0, 1.0, 1.0]), [3.0, 4.0, 5.0])
    np.testing.assert_allclose(Transform.from_matrix(m[0]).as_matrix(), m[0])


def test_transform_bad_input():
    with pytest.raises(ValueError, match="last row"):
        Transform.from_matrix(np.ones((4, 4)))
    with pytest.raises(ValueError, match="singular"):
        Transform(scale=[1.0, 0.0, 1.0]).inv()
    with pytest.raises(ValueError, match=r"vector.*shape"):
        Transform().apply(np.zeros((2, 4)))
    with pytest.raises(ValueError, match="translation"):
        Transform(translation=[np.nan, 0, 0])


# ---------------------------------------------------------------- bad input and N = 0
def test_zero_and_non_finite_quaternions_name_the_item():
    with pytest.raises(ValueError, match=r"quat\[1\]: is zero"):
        Rotation.from_quat([[1, 0, 0, 0], [0, 0, 0, 0]])
    with pytest.raises(ValueError, match=r"quat\[0\].*NaN"):
        Rotation.from_quat([np.nan, 0, 0, 1])
    with pytest.raises(ValueError, match=r"quat\[0\].*NaN"):
        Rotation.from_quat([np.inf, 0, 0, 1])


def test_shape_and_type_errors_name_the_argument():
    with pytest.raises(ValueError, match=r"quat: expected shape \(\.\.\., 4\), got \(3,\)"):
        Rotation.from_quat([1, 0, 0])
    with pytest.raises(ValueError, match="matrix: expected shape"):
        Rotation.from_matrix(np.eye(4))
    with pytest.raises(ValueError, match="rotvec: cannot convert"):
        Rotation.from_rotvec(["a", "b", "c"])
    with pytest.raises(ValueError, match="angles"):
        Rotation.from_euler("xyz", [1.0, 2.0])
    with pytest.raises(ValueError, match="seq"):
        Rotation.from_euler("xyy", [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="seq"):
        Rotation.from_euler("xYz", [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match=r"vectors"):
        Rotation.identity(3).apply(np.zeros((2, 3)))
    with pytest.raises(ValueError, match=r"vectors\[1\].*NaN"):
        Rotation.identity().apply([[0, 0, 0], [np.nan, 0, 0]])
    with pytest.raises(ValueError, match="n:"):
        Rotation.identity(-1)


def test_matrices_that_are_not_rotations():
    reflection = np.diag([1.0, 1.0, -1.0])
    with pytest.raises(ValueError, match=r"matrix\[0\]: is not a rotation"):
        Rotation.from_matrix(reflection)
    with pytest.raises(ValueError, match="not a rotation"):
        Rotation.from_matrix(2 * np.eye(3))
    r = Rotation.random(rng=11)
    noisy = r.as_matrix() + 1e-3 * np.random.default_rng(0).standard_normal((3, 3))
    fixed = Rotation.from_matrix(noisy, orthonormalize=True)
    m = fixed.as_matrix()
    np.testing.assert_allclose(m.T @ m, np.eye(3), atol=1e-15)
    # The nearest rotation (polar factor) of the noisy matrix.
    u, _, vt = np.linalg.svd(noisy)
    np.testing.assert_allclose(m, u @ vt, atol=1e-14)
    assert angle_between(fixed, r)[0] < 1e-2
    with pytest.raises(ValueError, match="rank"):
        Rotation.from_matrix(np.zeros((3, 3)), orthonormalize=True)
    with pytest.raises(ValueError, match="NaN"):
        Rotation.from_matrix(np.full((3, 3), np.nan), orthonormalize=True)


def test_empty_batches():
    empty = Rotation.from_quat(np.zeros((0, 4)))
    assert len(empty) == 0
    assert empty.as_matrix().shape == (0, 3, 3)
    assert empty.as_euler("xyz").shape == (0, 3)
    assert empty.as_rotvec().shape == (0, 3)
    assert empty.magnitude().shape == (0,)
    assert empty.apply(np.zeros((0, 3))).shape == (0, 3)
    assert (empty * empty).as_quat().shape == (0, 4)
    assert Rotation.from_matrix(np.zeros((0, 3, 3))).as_quat().shape == (0, 4)
    assert Rotation.from_euler("XYZ", np.zeros((0, 3))).as_quat().shape == (0, 4)
    assert len(slerp(empty, Rotation.identity(), 0.5)) == 0
    assert Transform.from_matrix(np.zeros((0, 4, 4))).as_matrix().shape == (0, 4, 4)


def test_top_level_names():
    assert kinema.Rotation is Rotation and kinema.slerp is slerp and kinema.Transform is Transform
    assert issubclass(kinema.GimbalLockWarning, UserWarning)
    assert issubclass(kinema.SimulationError, RuntimeError)


# ---------------------------------------------------------------- properties
finite = st.floats(-1e3, 1e3, allow_nan=False)
quats = arrays(np.float64, 4, elements=st.floats(-1, 1, allow_nan=False)).filter(
    lambda q: np.linalg.norm(q) > 1e-3
)


@settings(max_examples=200, deadline=None)
@given(q=quats, seq=st.sampled_from(SEQUENCES))
def test_property_euler_round_trip(q, seq):
    r = Rotation.from_quat(q)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GimbalLockWarning)
        back = Rotation.from_euler(seq, r.as_euler(seq))
    assert angle_between(back, r)[0] < 1e-13


@settings(max_examples=200, deadline=None)
@given(q=quats, p=quats, v=arrays(np.float64, 3, elements=finite))
def test_property_apply_and_compose(q, p, v):
    a, b = Rotation.from_quat(q), Rotation.from_quat(p)
    np.testing.assert_allclose(
        (a * b).apply(v), a.apply(b.apply(v)), atol=1e-12 * (1 + np.abs(v).max())
    )
    # Norms compared after scaling: squares of components below 1e-154 are subnormal, where
    # numpy's own norm loses its precision (found by hypothesis with |v| ~ 1e-162). Vectors of
    # subnormal components (below 2.2e-308) have fewer than 53 bits, and the products inside
    # any rotation lose what is left: there the length is kept to an absolute 1e-320 (found by
    # hypothesis with v = 5e-324 in every component, rotated to 0).
    scale = max(float(np.abs(v).max()), 1e-300)
    n_out, n_in = np.linalg.norm(a.apply(v) / scale), np.linalg.norm(v / scale)
    assert abs(n_out - n_in) * scale <= 1e-14 * n_in * scale + 1e-320
    r = Rotation.from_matrix(a.as_matrix())
    assert angle_between(r, a)[0] < 1e-14
    assert angle_between(Rotation.from_rotvec(a.as_rotvec()), a)[0] < 1e-14


@settings(max_examples=100, deadline=None)
@given(q=quats, p=quats, t=st.floats(-2, 3))
def test_property_slerp_is_on_the_arc(q, p, t):
    a, b = Rotation.from_quat(q), Rotation.from_quat(p)
    s = slerp(a, b, t)
    total = angle_between(b, a)[0]
    # The rotation from a to slerp(t) is t times the way to b (modulo a full turn).
    assert abs(angle_between(s, a)[0] - abs(((t * total + np.pi) % (2 * np.pi)) - np.pi)) < 1e-9


def test_unpickling_validates_rotations():
    r = Rotation.from_euler("xyz", [[0.1, 0.2, 0.3], [1.0, -2.0, 0.5]])
    back = pickle.loads(pickle.dumps(r))
    assert np.array_equal(back.as_quat(), r.as_quat()) and len(back) == 2
    single = pickle.loads(pickle.dumps(r[0]))
    assert single.as_quat().shape == (4,)
    for quat, match in [
        (np.array([[2.0, 0.0, 0.0, 0.0]]), "not unit"),
        (np.array([[np.nan, 0.0, 0.0, 0.0]]), "not unit"),
        (np.array([1.0, 0.0, 0.0, 0.0]), "shape"),
    ]:
        bad = Rotation.identity()
        bad._quat = quat  # what a tampered or damaged pickle would carry
        with pytest.raises(ValueError, match=match):
            pickle.loads(pickle.dumps(bad))


def test_orthonormalize_of_a_reflected_matrix_flips_its_smallest_direction():
    # m = U diag(σ) Vᵀ with one negative σ of the smallest magnitude, in every slot: the
    # nearest rotation (Kabsch / polar with the sign fix) is U Vᵀ, whichever slot it sits in.
    u, v = Rotation.random(2, rng=7).as_matrix()
    for sigma in ([-1.0, 3.0, 2.0], [3.0, -1.0, 2.0], [3.0, 2.0, -1.0], [5.0, 4.0, -3.9]):
        m = u @ np.diag(sigma) @ v.T
        got = Rotation.from_matrix(m, orthonormalize=True).as_matrix()
        np.testing.assert_allclose(got, u @ v.T, atol=1e-12, err_msg=str(sigma))


def test_from_matrix_orthonormalizes_huge_and_tiny_matrices():
    r = Rotation.from_rotvec([0.3, -0.2, 0.9])
    # 1e-315 is subnormal (~25 significant bits left): close, not exact.
    for scale, tol in [(1e160, 1e-14), (1e300, 1e-14), (1e-160, 1e-14), (1e-315, 1e-6)]:
        got = Rotation.from_matrix(scale * r.as_matrix(), orthonormalize=True)
        assert abs(abs(np.dot(got.as_quat(), r.as_quat())) - 1.0) < tol, scale
    eye = Rotation.from_matrix(1e160 * np.eye(3), orthonormalize=True)
    assert np.array_equal(eye.as_quat(), [1.0, 0.0, 0.0, 0.0])
    for bad in [np.inf, np.nan]:
        m = np.eye(3)
        m[1, 1] = bad
        with pytest.raises(ValueError, match="matrix"):
            Rotation.from_matrix(m, orthonormalize=True)
