"""kinema.mocap editing through Python: time warp, blend, stitch, warp on a real CMU walk,
and the errors bad input gets."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from kinema import mocap

DATA = Path(__file__).resolve().parents[1] / "data" / "mocap"


def test_editing_keeps_bone_lengths_and_hits_its_targets(walk):
    sk, m = walk
    a, b = m.slice(0, 200), m.slice(250, 450)
    slow = mocap.time_warp(sk, m, np.arange(0, m.frames - 1, 0.5))
    assert slow.frames == 2 * (m.frames - 1)
    np.testing.assert_array_equal(slow.pose(4), m.pose(2))
    ramp = mocap.blend(sk, a, b, np.linspace(0, 1, 200))
    np.testing.assert_array_equal(ramp.pose(0), a.pose(0))
    np.testing.assert_array_equal(ramp.pose(199), b.pose(199))
    joined = mocap.stitch(sk, a, b, transition=12)
    assert joined.frames == 388
    key = m.pose(100).copy()
    key[6:] += 0.05
    warped = mocap.warp(sk, m, {100: key})
    np.testing.assert_array_equal(warped.pose(100), key)
    for motion in (slow, ramp, joined, warped):
        pos, _ = sk.forward_kinematics(motion)
        assert mocap.bone_length_error(sk, pos) < 1e-9


def test_editing_bad_input_names_the_argument(walk):
    sk, m = walk
    with pytest.raises(ValueError, match="times"):
        mocap.time_warp(sk, m, [0.0, 3.0, 2.0])
    with pytest.raises(ValueError, match="weight"):
        mocap.blend(sk, m, m, np.nan)
    with pytest.raises(ValueError, match="weight"):
        mocap.blend(sk, m, m, 1.5)
    with pytest.raises(ValueError, match="b"):
        mocap.blend(sk, m, m.slice(0, 10), 0.5)
    with pytest.raises(ValueError, match="transition"):
        mocap.stitch(sk, m, m, transition=-1)
    with pytest.raises(ValueError, match="keys"):
        mocap.warp(sk, m, {m.frames: m.pose(0)})
    with pytest.raises(ValueError, match="keys"):
        mocap.warp(sk, m, {})
    with pytest.raises(ValueError, match="skeleton"):
        mocap.blend(object(), m, m, 0.5)


def test_warp_displacement_is_scipys_monotone_cubic_and_stays_local(walk):
    from scipy.interpolate import PchipInterpolator

    sk, m = walk
    key = m.pose(150).copy()
    key[6:] += np.linspace(-0.1, 0.2, key.size - 6)
    keys = {120: m.pose(120), 150: key, 200: m.pose(200)}
    warped = mocap.warp(sk, m, keys)
    frames = [0, 120, 150, 200, m.frames - 1]
    disp = np.array(
        [np.zeros(key.size), np.zeros(key.size), key - m.pose(150)] + [np.zeros(key.size)] * 2
    )
    expected = PchipInterpolator(frames, disp)(np.arange(m.frames))
    np.testing.assert_allclose(warped.values() - m.values(), expected, atol=1e-12)
    # Zero outside the keyed swing: the rest of the motion is untouched.
    np.testing.assert_allclose(warped.values()[:121], m.values()[:121], atol=1e-12)
    np.testing.assert_allclose(warped.values()[200:], m.values()[200:], atol=1e-12)


def test_frame_rates(walk):
    sk, m = walk
    assert m.frame_rate == 120.0  # CMU's rate: AMC files store none
    assert mocap.read_amc(DATA / "07_05-walk.amc", sk, frame_rate=60).frame_rate == 60.0
    assert m.resample(30.0).frame_rate == 30.0
    assert m.slice(3, 9).frame_rate == 120.0
    bvh_sk, bvh = mocap.read_bvh(DATA / "01_01.bvh")
    assert bvh.frame_rate == pytest.approx(1.0 / bvh_sk.frame_time, rel=1e-15)
    with pytest.raises(ValueError, match="frame_rate"):
        mocap.read_amc(DATA / "07_05-walk.amc", sk, frame_rate=-1.0)


def test_bvh_motions_are_edited_too():
    sk, m = mocap.read_bvh(DATA / "01_01.bvh")
    m = m.slice(1, 241)
    half = m.resample(m.frame_rate / 2)
    assert half.frames == 120
    np.testing.assert_array_equal(half.pose(3), m.pose(6))
    joined = mocap.stitch(sk, m.slice(0, 120), m.slice(120, 240), transition=8)
    assert joined.frames == 232
    key = m.pose(100) + 0.05
    np.testing.assert_array_equal(mocap.warp(sk, m, {100: key}).pose(100), key)
    with pytest.raises(ValueError, match="skeleton"):
        mocap.time_warp("not a skeleton", m, [0.0])
