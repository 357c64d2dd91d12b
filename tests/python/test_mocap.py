"""kinema.mocap on the CMU files in tests/data/mocap."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import kinema
from kinema import mocap

DATA = Path(__file__).resolve().parents[1] / "data" / "mocap"


def test_forward_kinematics_of_a_walk(walk):
    sk, motion = walk
    pos, ori = sk.forward_kinematics(motion)
    assert motion.frames == 517
    assert pos.shape == (517, 31, 3) and ori.shape == (517, 31, 4)
    assert sk.joint_names[0] == "root" and "ltoes" in sk.joint_names
    assert mocap.bone_length_error(sk, pos) < 1e-12
    np.testing.assert_allclose(np.linalg.norm(ori, axis=2), 1.0, atol=1e-14)
    assert sk.length_unit == 0.45
    assert sk.metres_per_unit == pytest.approx(0.0254 / 0.45)


def test_parse_errors_carry_file_and_line(tmp_path, walk):
    sk, _ = walk
    bad = tmp_path / "bad.amc"
    bad.write_text("1\nroot 0 0 0 0 0 0\nlfemur 1 2\n")
    with pytest.raises(kinema.ParseError, match=r"bad.amc:3: expected 3 values for \"lfemur\""):
        mocap.read_amc(bad, sk)
    with pytest.raises(ValueError, match="skeleton"):
        mocap.read_amc(bad, None)


def test_read_write_read(tmp_path, walk):
    sk, motion = walk
    mocap.write_asf(sk, tmp_path / "w.asf")
    mocap.write_amc(sk, motion, tmp_path / "w.amc")
    sk2 = mocap.read_asf(tmp_path / "w.asf")
    m2 = mocap.read_amc(tmp_path / "w.amc", sk2)
    p1, _ = sk.forward_kinematics(motion)
    p2, _ = sk2.forward_kinematics(m2)
    np.testing.assert_allclose(p1, p2, atol=1e-10)
    assert sk2.joint_names == sk.joint_names


def test_slices_values_and_limits(walk):
    sk, motion = walk
    part = motion.slice(10, 20)
    assert part.frames == 10
    np.testing.assert_array_equal(part.values(), motion.values()[10:20])
    p_all, _ = sk.forward_kinematics(motion)
    p_part, _ = sk.forward_kinematics(part)
    np.testing.assert_array_equal(p_part, p_all[10:20])
    ok = sk.within_limits(motion)
    # CMU captures are not bound by their ASF limits (frame 100 has lowerneck at -20.4° against
    # a limit of -20°); the check must see that.
    assert ok.shape == (517,) and ok.dtype == np.bool_ and not ok.all()
    with pytest.raises(ValueError, match="start < end"):
        motion.slice(5, 5)


def test_resample_to_30_hz(walk):
    sk, motion = walk
    slow = motion.resample(30.0)
    assert slow.frames == 130 and slow.frame_rate == 30.0
    p, _ = sk.forward_kinematics(motion)
    q, _ = sk.forward_kinematics(slow)
    np.testing.assert_allclose(q, p[::4], atol=1e-9)
    with pytest.raises(ValueError, match="rate"):
        motion.resample(-1.0)


def test_within_limits_takes_a_motion_a_pose_or_a_batch_of_poses(walk):
    sk, motion = walk
    per_frame = sk.within_limits(motion)
    assert not per_frame[100]  # lowerneck at -20.4° against -20°
    rest = np.zeros(sk.stride)  # the rest pose is within every limit
    # One pose (stride,): a bool; a batch (N, stride): (N,) bools, the same answers.
    assert sk.within_limits(motion.pose(100)) is False
    assert sk.within_limits(rest) is True
    nudged = rest.copy()
    nudged[sk.stride - 1] = 1e3  # far outside the last bone's last limit
    assert sk.within_limits(nudged) is False
    batch = sk.within_limits(np.vstack([rest, motion.pose(100), nudged, rest]))
    assert batch.shape == (4,) and batch.dtype == np.bool_
    np.testing.assert_array_equal(batch, [True, False, False, True])
    np.testing.assert_array_equal(sk.within_limits(motion.values()[90:110]), per_frame[90:110])
    assert sk.within_limits(np.zeros((0, sk.stride))).shape == (0,)
    with pytest.raises(ValueError, match=r"motion.*62 values, got 3"):
        sk.within_limits([0.0, 1.0, 2.0])
    bad = motion.values()[:3].copy()
    bad[1, 7] = np.nan
    with pytest.raises(ValueError, match=r"motion\[1\].*NaN"):
        sk.within_limits(bad)
    with pytest.raises(ValueError, match="motion"):
        sk.within_limits(np.zeros((2, 2, sk.stride)))


def test_mass_unit_survives_write_and_read(tmp_path, walk):
    sk, _ = walk
    assert sk.mass_unit == 1.0
    text = (DATA / "07-walk.asf").read_text().replace("mass 1.0", "mass 2.5")
    (tmp_path / "heavy.asf").write_text(text)
    heavy = mocap.read_asf(tmp_path / "heavy.asf")
    assert heavy.mass_unit == 2.5
    mocap.write_asf(heavy, tmp_path / "again.asf")
    assert mocap.read_asf(tmp_path / "again.asf").mass_unit == 2.5


def test_unpickling_validates_skeletons(tmp_path):
    import pickle
    import struct

    asf = tmp_path / "one.asf"
    asf.write_text(
        ":version 1.10\n:name one\n:units\n  length 1\n  angle deg\n:root\n"
        "  order TX TY TZ RX RY RZ\n  axis XYZ\n  position 0 0 0\n  orientation 0 0 0\n"
        ":bonedata\n  begin\n    id 1\n    name arm\n    direction 1 0 0\n    length 2.625\n"
        "    axis 0 0 0 XYZ\n    dof rz\n  end\n:hierarchy\n  begin\n    root arm\n  end\n"
    )
    sk = mocap.read_asf(asf)
    func, (data, *extra) = sk.__reduce__()
    assert pickle.loads(pickle.dumps(sk)).joint_names == sk.joint_names
    length = struct.pack("<d", 2.625)
    assert data.count(length) == 1
    for bad in [-1.0, float("nan")]:
        spoiled = data.replace(length, struct.pack("<d", bad))
        with pytest.raises(ValueError, match=r"arm.*length"):
            func(spoiled, *extra)
