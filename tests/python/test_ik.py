"""kinema.ik on a 7-dof arm, a 20-joint chain and the CMU skeleton (tests/data/mocap)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from kinema import Rotation, ik

H = np.pi / 2
ARM_LIMITS = [(-H, H), (-H, H), (-H, H), (0.0, 2.6), (-H, H), (-0.8, 0.8), (-0.8, 0.8)]


def arm(limits=ARM_LIMITS):
    return ik.chain([0.3, 0.25, 0.1], ["xyz", "z", "xyz"], limits)


def within(limits, pose):
    lo, hi = np.array(limits).T
    return bool(np.all(pose >= lo) and np.all(pose <= hi))


def test_poses_and_forward_kinematics_of_one_pose(walk):
    sk, motion = walk
    pose = motion.pose(100)
    np.testing.assert_array_equal(pose, motion.values()[100])
    assert pose.shape == (sk.stride,)
    p, o = sk.forward_kinematics(pose)
    pa, oa = sk.forward_kinematics(motion)
    np.testing.assert_array_equal(p, pa[100])
    np.testing.assert_array_equal(o, oa[100])
    with pytest.raises(ValueError, match="i"):
        motion.pose(motion.frames)
    with pytest.raises(ValueError, match="motion"):
        sk.forward_kinematics(np.zeros(3))


def test_jacobian_matches_finite_differences(walk):
    sk, motion = walk
    pose = motion.pose(200)
    names = ["ltoes", "rhand", "head"]
    jac, cols = ik.jacobian(sk, pose, names, orientation=True, free_root=True)
    assert jac.shape == (18, sk.stride) and list(cols) == list(range(sk.stride))
    index = [sk.joint_names.index(n) for n in names]
    h = 1e-6
    fd = np.zeros_like(jac)
    for c, k in enumerate(cols):
        qp, qm = pose.copy(), pose.copy()
        qp[k] += h
        qm[k] -= h
        (pp, op), (pm, om) = sk.forward_kinematics(qp), sk.forward_kinematics(qm)
        for e, j in enumerate(index):
            fd[6 * e : 6 * e + 3, c] = (pp[j] - pm[j]) / (2 * h)
            rel = Rotation.from_quat(op[j]) * Rotation.from_quat(om[j]).inv()
            fd[6 * e + 3 : 6 * e + 6, c] = rel.as_rotvec() / (2 * h)
    np.testing.assert_allclose(jac, fd, atol=1e-7)


def reach_rate(sk, start, effector, dofs_limits, method, within_dist, n=150, seed=1):
    """Fraction of random reachable targets (FK of random in-limit poses) reached."""
    rng = np.random.default_rng(seed)
    j = sk.joint_names.index(effector)
    hits = 0
    for _ in range(n):
        goal = start.copy()
        for k, (lo, hi) in dofs_limits.items():
            goal[k] = rng.uniform(lo, hi)
        target = sk.forward_kinematics(goal)[0][j]
        pose, report = ik.solve(sk, start, {effector: target}, method=method)
        err = np.linalg.norm(sk.forward_kinematics(pose)[0][j] - target)
        assert report.error == pytest.approx(err, abs=1e-12)
        assert report.converged == (report.error <= 1e-4)
        hits += err <= within_dist
    return hits / n


@pytest.mark.parametrize(
    ("method", "floor"),
    # Measured on these 150 targets: 100%, 98.7%, 76%, 79% (tests/ik.rs: 300 other targets).
    [("dls", 0.99), ("pseudo_inverse", 0.98), ("transpose", 0.7), ("ccd", 0.7)],
)
def test_reachable_targets_on_the_arm(method, floor):
    sk = arm()
    start = np.array([0.0, 0.0, 0.0, 1.3, 0.0, 0.0, 0.0])  # middle of the ranges
    rate = reach_rate(sk, start, "link3", dict(enumerate(ARM_LIMITS)), method, 1e-3)
    assert rate >= floor, rate


def test_twenty_joint_chain():
    sk = ik.chain([0.05] * 20, ["z", "y"] * 10, [(-np.pi / 4, np.pi / 4)] * 20)
    start = np.zeros(20)
    limits = {k: (-np.pi / 4, np.pi / 4) for k in range(20)}
    assert reach_rate(sk, start, "link20", limits, "dls", 1e-3, n=100) >= 0.99


def test_cmu_arm_reaches_within_the_asf_limits(walk):
    sk, motion = walk
    j = sk.joint_names.index("lradius")
    goal = motion.pose(300)
    start = motion.pose(0)
    start[:6] = goal[:6]  # the root is held fixed: put it where the goal's is
    target = sk.forward_kinematics(goal)[0][j]
    pose, report = ik.solve(sk, start, {"lradius": target})
    assert report.converged and report.error < 1e-4
    # Only the dofs between the root and the left hand move (spine, clavicle, arm): the feet
    # stay where they were.
    feet = [sk.joint_names.index(n) for n in ("ltoes", "rtoes")]
    before, after = sk.forward_kinematics(start)[0], sk.forward_kinematics(pose)[0]
    np.testing.assert_array_equal(after[feet], before[feet])


@pytest.mark.parametrize("method", ["dls", "pseudo_inverse", "transpose", "ccd"])
def test_unreachable_target_ends_at_the_closest_point(method):
    sk = arm()
    target = np.array([0.5, 0.4, -0.3])
    start = np.array([0.0, 0.0, 0.0, 1.3, 0.0, 0.0, 0.0])
    pose, report = ik.solve(sk, start, {"link3": target}, method=method, max_iters=1000)
    gap = np.linalg.norm(target) - 0.65
    assert not report.converged and within(ARM_LIMITS, pose)
    assert gap - 1e-12 <= report.error < gap + 1e-3
    if method == "dls":
        assert report.error == pytest.approx(gap, abs=1e-9)


def test_two_bone_is_exact_in_closed_form():
    sk = arm(limits=None)
    rng = np.random.default_rng(5)
    for _ in range(100):
        goal = np.concatenate([rng.uniform(-np.pi, np.pi, 4), np.zeros(3)])
        target = sk.forward_kinematics(goal)[0][2]
        pose, report = ik.solve(
            sk, rng.uniform(-1, 1, 7), {"link2": target}, method="two_bone", joint_limits=False
        )
        assert report.converged and report.error < 1e-12 and report.iterations == 1
        d = np.linalg.norm(target)
        assert np.cos(pose[3]) == pytest.approx(
            (d**2 - 0.3**2 - 0.25**2) / (2 * 0.3 * 0.25), abs=1e-12
        )


@pytest.mark.parametrize("method", ["dls", "pseudo_inverse", "transpose", "ccd"])
@pytest.mark.parametrize("x", [0.65, 0.7, 0.6499, -0.65])
def test_stretched_arm_stays_finite(method, x):
    sk = arm(limits=None)
    pose, report = ik.solve(sk, np.zeros(7), {"link3": [x, 0.0, 0.0]}, method=method)
    assert np.all(np.isfinite(pose)) and np.isfinite(report.error)
    assert report.error <= abs(x - 0.65) + 1e-12


def test_orientation_target_and_report():
    sk = arm()
    goal = np.array([0.4, -0.3, 0.2, 1.0, 0.3, 0.2, -0.4])
    p, o = sk.forward_kinematics(goal)
    pose, report = ik.solve(sk, [0, 0, 0, 1.3, 0, 0, 0], {"link3": (p[3], o[3])})
    assert report.converged and report.orientation_error < 1e-4
    p2, o2 = sk.forward_kinematics(pose)
    np.testing.assert_allclose(p2[3], p[3], atol=1e-4)
    assert abs(np.dot(o2[3], o[3])) == pytest.approx(1.0, abs=1e-8)
    assert "IkReport(converged=True" in repr(report)


def test_rest_weight_pulls_towards_the_rest_pose():
    sk = arm()
    start = [0.3, -0.4, 0.5, 1.2, 0.3, 0.2, -0.1]
    rest = np.array([0, 0, 0, 1.3, 0, 0, 0.0])
    target = [0.3, 0.35, 0.2]
    plain, r0 = ik.solve(sk, start, {"link3": target})
    near, r1 = ik.solve(sk, start, {"link3": target}, rest_weight=0.2, rest=rest, max_iters=500)
    assert r0.converged and r1.converged
    assert np.linalg.norm(near - rest) < 0.8 * np.linalg.norm(plain - rest)


@settings(max_examples=100, deadline=None)
@given(
    start=st.lists(st.floats(0, 1), min_size=7, max_size=7),
    target=st.lists(st.floats(-1, 1), min_size=3, max_size=3),
    method=st.sampled_from(["dls", "pseudo_inverse", "transpose", "ccd", "two_bone"]),
)
def test_limits_are_never_violated(start, target, method):
    sk = arm()
    lo, hi = np.array(ARM_LIMITS).T
    pose0 = lo + (hi - lo) * np.array(start)
    joint = "link2" if method == "two_bone" else "link3"
    pose, report = ik.solve(sk, pose0, {joint: target}, method=method)
    assert np.isfinite(report.error)
    assert within(ARM_LIMITS, pose)


def test_bad_input_names_the_argument(walk):
    sk = arm()
    start = np.zeros(7)
    with pytest.raises(ValueError, match="targets: unknown joint 'hand'"):
        ik.solve(sk, start, {"hand": [0, 0, 0]})
    with pytest.raises(ValueError, match="targets"):
        ik.solve(sk, start, {"link3": [np.nan, 0, 0]})
    with pytest.raises(ValueError, match="targets"):
        ik.solve(sk, start, {"link3": [0, 0]})
    with pytest.raises(ValueError, match="targets"):
        ik.solve(sk, start, {"link3": ([0, 0, 0], [0, 0, 0, 0])})
    with pytest.raises(ValueError, match="targets"):
        ik.solve(sk, start, {})
    with pytest.raises(ValueError, match="pose"):
        ik.solve(sk, np.zeros(6), {"link3": [0, 0, 0]})
    with pytest.raises(ValueError, match="pose"):
        ik.solve(sk, [np.nan] * 7, {"link3": [0, 0, 0]})
    with pytest.raises(ValueError, match="method"):
        ik.solve(sk, start, {"link3": [0, 0, 0]}, method="newton")
    with pytest.raises(ValueError, match="method"):
        ik.solve(sk, start, {"link3": [0, 0, 0]}, method="two_bone")
    with pytest.raises(ValueError, match="rest_weight"):
        ik.solve(sk, start, {"link3": [0, 0, 0]}, method="ccd", rest_weight=0.1)
    with pytest.raises(ValueError, match="tol"):
        ik.solve(sk, start, {"link3": [0, 0, 0]}, tol=-1.0)
    with pytest.raises(ValueError, match="max_iters"):
        ik.solve(sk, start, {"link3": [0, 0, 0]}, max_iters=-1)
    with pytest.raises(ValueError, match="skeleton"):
        ik.solve(None, start, {"link3": [0, 0, 0]})
    with pytest.raises(ValueError, match="dofs"):
        ik.chain([1.0], ["xw"])
    with pytest.raises(ValueError, match="lengths"):
        ik.chain([np.nan], ["x"])
    with pytest.raises(ValueError, match="limits"):
        ik.chain([1.0], ["x"], [(1.0, 0.0)])
    cmu, _ = walk
    with pytest.raises(ValueError, match="joints"):
        ik.jacobian(cmu, np.zeros(cmu.stride), ["nosuchbone"])
