"""Transform (scipy's RigidTransform operations) against closed forms: screw motions,
exp/log round trips near 0 and pi, dual quaternions, composition as 4x4 matrix products,
powers, means, stacks; scipy as an independent oracle; bad input."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from scipy.spatial.transform import RigidTransform as SciRigid
from scipy.spatial.transform import Rotation as SciRotation

from kinema import Rotation, Transform


def rot_z(theta: float) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def test_screw_motion_along_z_is_rotation_plus_pitch():
    theta, h = 0.7, 2.5
    m = Transform.from_exp_coords([0.0, 0.0, theta, 0.0, 0.0, h]).as_matrix()
    expected = np.eye(4)
    expected[:3, :3], expected[2, 3] = rot_z(theta), h
    np.testing.assert_allclose(m, expected, atol=1e-15)


@pytest.mark.parametrize("theta", [1e-9, 0.05, 0.1, 1.0, np.pi - 1e-6])
def test_screw_about_an_offset_axis_fixes_the_axis(theta):
    # Rotation by theta about the line through q with direction w, plus pitch h along w:
    # twist (theta w, -theta w x q + h theta w) (Lynch & Park 2017, sec. 3.3.2).
    w = np.array([1.0, 2.0, -2.0]) / 3.0
    q = np.array([0.5, -1.0, 2.0])
    h = 0.3
    xi = np.concatenate([theta * w, -theta * np.cross(w, q) + h * theta * w])
    tf = Transform.from_exp_coords(xi)
    r = SciRotation.from_rotvec(theta * w).as_matrix()
    expected_t = (np.eye(3) - r) @ q + h * theta * w
    np.testing.assert_allclose(tf.translation, expected_t, atol=1e-14)
    np.testing.assert_allclose(tf.apply(q + 5.0 * w), q + (5.0 + h * theta) * w, atol=1e-13)


@pytest.mark.parametrize(
    "angle", [0.0, 1e-12, 1e-6, 1e-3, 0.0999999, 0.1, 0.1000001, 1.0, 3.0, np.pi - 1e-9]
)
def test_exp_log_round_trip_near_zero_and_pi(angle):
    axis = np.array([0.6, -0.8, 0.0])
    xi = np.concatenate([angle * axis, [0.3, -1.1, 2.0]])
    back = Transform.from_exp_coords(xi).as_exp_coords()
    np.testing.assert_allclose(back, xi, rtol=0, atol=1e-12)


def test_exp_log_against_scipy():
    rng = np.random.default_rng(3)
    xi = rng.standard_normal((50, 6))
    xi[:, :3] *= 1.5
    ours = Transform.from_exp_coords(xi)
    theirs = SciRigid.from_exp_coords(xi)
    np.testing.assert_allclose(ours.as_matrix(), theirs.as_matrix(), atol=1e-13)
    np.testing.assert_allclose(ours.as_exp_coords(), theirs.as_exp_coords(), atol=1e-12)


def test_dual_quaternion_closed_forms_and_round_trip():
    # A pure translation t is (1, 0, 0, 0; 0, t/2), scalar first.
    dq = Transform.from_translation([2.0, 4.0, 6.0]).as_dual_quat()
    np.testing.assert_array_equal(dq, [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 2.0, 3.0])
    # A rotation alone has a zero dual part.
    r = Rotation.from_rotvec([0.0, 0.0, np.pi / 2])
    dq = Transform.from_rotation(r).as_dual_quat(scalar_first=False)
    s = np.sqrt(0.5)
    np.testing.assert_allclose(dq, [0.0, 0.0, s, s, 0.0, 0.0, 0.0, 0.0], atol=1e-16)
    rng = np.random.default_rng(5)
    tf = Transform(Rotation.random(shape=(4, 3), rng=5), rng.standard_normal((4, 3, 3)))
    back = Transform.from_dual_quat(tf.as_dual_quat())
    np.testing.assert_allclose(back.as_matrix(), tf.as_matrix(), atol=1e-14)
    sci = SciRigid.from_matrix(tf.as_matrix())
    np.testing.assert_allclose(tf.as_dual_quat(scalar_first=False), sci.as_dual_quat(), atol=1e-14)


def test_unnormalised_dual_quaternion_is_normalised():
    tf = Transform(Rotation.from_rotvec([0.3, -0.2, 0.5]), [1.0, -2.0, 0.5])
    dq = tf.as_dual_quat()
    # Scaling both halves and adding a component along the real part changes nothing.
    bent = 3.0 * dq + np.concatenate([np.zeros(4), 0.7 * dq[:4]])
    np.testing.assert_allclose(
        Transform.from_dual_quat(bent).as_matrix(), tf.as_matrix(), atol=1e-14
    )


def test_composition_is_the_matrix_product_and_broadcasts():
    rng = np.random.default_rng(7)
    a = Transform(Rotation.random(shape=(2, 1), rng=1), rng.standard_normal((2, 1, 3)))
    b = Transform(Rotation.random(3, rng=2), rng.standard_normal((3, 3)))
    ab = a * b
    assert ab.shape == (2, 3)
    np.testing.assert_allclose(ab.as_matrix(), a.as_matrix() @ b.as_matrix(), atol=1e-14)
    p = rng.standard_normal((2, 3, 3))
    np.testing.assert_allclose(ab.apply(p), a.apply(b.apply(p)), atol=1e-13)
    np.testing.assert_allclose(ab.apply(ab.apply(p), inverse=True), p, atol=1e-13)


def test_power_follows_the_screw():
    tf = Transform.from_exp_coords([0.2, -0.4, 1.1, 0.5, 0.1, -0.3])
    half = tf**0.5
    np.testing.assert_allclose((half * half).as_matrix(), tf.as_matrix(), atol=1e-14)
    np.testing.assert_allclose((tf**2).as_matrix(), (tf * tf).as_matrix(), atol=1e-14)
    np.testing.assert_allclose((tf**-1).as_matrix(), tf.inv().as_matrix(), atol=1e-15)
    np.testing.assert_array_equal((tf**0).as_matrix(), np.eye(4))
    np.testing.assert_allclose((tf**0.3).as_exp_coords(), 0.3 * tf.as_exp_coords(), atol=1e-15)


def test_mean_of_translations_and_rotations():
    r = Rotation.from_rotvec([[0.0, 0.0, 0.4], [0.0, 0.0, -0.4], [0.0, 0.0, 0.0]])
    t = np.array([[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 4.0]])
    tf = Transform(r, t)
    mean = tf.mean(weights=[1.0, 1.0, 2.0])
    assert mean.single
    np.testing.assert_allclose(mean.translation, [0.25, 0.5, 2.0], atol=1e-15)
    assert mean.rotation.magnitude() < 1e-15
    stack = Transform(Rotation.random(shape=(2, 3), rng=4), np.arange(18.0).reshape(2, 3, 3))
    np.testing.assert_allclose(
        stack.mean(axis=-1).translation, np.arange(18.0).reshape(2, 3, 3).mean(axis=1)
    )


def test_stack_container_operations():
    tf = Transform.identity(shape=(2, 3))
    assert tf.shape == (2, 3) and len(tf) == 2 and tf[1, 2].single
    tf[0] = Transform.from_translation([1.0, 2.0, 3.0])
    np.testing.assert_array_equal(tf.translation[0], [[1.0, 2.0, 3.0]] * 3)
    np.testing.assert_array_equal(tf.translation[1], np.zeros((3, 3)))
    assert [t.shape for t in tf] == [(3,), (3,)]
    both = Transform.concatenate([tf, Transform.identity(shape=(1, 3))])
    assert both.shape == (3, 3)
    back = pickle.loads(pickle.dumps(tf))
    assert back.shape == (2, 3)
    np.testing.assert_array_equal(back.as_matrix(), tf.as_matrix())
    translation, rotation = tf.as_components()
    np.testing.assert_array_equal(
        Transform.from_components(translation, rotation).as_matrix(), tf.as_matrix()
    )


def test_bad_input_names_the_argument():
    with pytest.raises(ValueError, match="exp_coords") as e:
        Transform.from_exp_coords([np.nan, 0.0, 0.0, 0.0, 0.0, 1234.5])
    assert "1234.5" not in str(e.value)
    with pytest.raises(ValueError, match=r"dual_quat.*real part"):
        Transform.from_dual_quat(np.zeros(8))
    with pytest.raises(ValueError, match=r"dual_quat.*shape"):
        Transform.from_dual_quat(np.zeros(7))
    scaled = Transform(scale=2.0)
    for rigid_only in (scaled.as_exp_coords, scaled.as_dual_quat, lambda: scaled**0.5):
        with pytest.raises(ValueError, match="matrix"):
            rigid_only()
    with pytest.raises(ValueError, match="weights"):
        Transform.identity(2).mean(weights=[1.0, -1.0])
    with pytest.raises(ValueError, match="other"):
        Transform.identity(2) * Transform.identity(3)
