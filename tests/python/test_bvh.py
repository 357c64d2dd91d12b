"""kinema.mocap BVH reader and writer, on the CMU 01_01 conversion in tests/data/mocap
(from facebookresearch/fairmotion; data from mocap.cs.cmu.edu, created with funding from NSF
EIA-0196217) and on hand-made files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import kinema
from kinema import mocap

DATA = Path(__file__).resolve().parents[1] / "data" / "mocap"

CHAIN = """HIERARCHY
ROOT r
{
\tOFFSET 0 0 0
\tCHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
\tJOINT a
\t{
\t\tOFFSET 0 1 0
\t\tCHANNELS 3 Zrotation Xrotation Yrotation
\t\tEnd Site
\t\t{
\t\t\tOFFSET 0 2 0
\t\t}
\t}
}
MOTION
Frames: 2
Frame Time: 0.04
0 0 0 0 0 0 0 0 0
1 2 3 90 0 0 0 0 0
"""


@pytest.fixture(scope="module")
def clip():
    assert DATA.is_dir(), f"motion-capture data expected at {DATA}"
    return mocap.read_bvh(DATA / "01_01.bvh")


def test_cmu_clip_matches_its_header(clip):
    sk, motion = clip
    assert isinstance(sk, mocap.BvhSkeleton)
    assert motion.frames == 2752
    assert sk.frame_time == 0.0083333
    assert len(sk.joint_names) == 31 and sk.joint_names[0] == "Hips"
    assert sk.parents[0] == -1 and all(0 <= p < j for j, p in enumerate(sk.parents) if j)
    assert sk.offsets.shape == (31, 3)
    assert sk.channels[0] == [
        "Xposition",
        "Yposition",
        "Zposition",
        "Zrotation",
        "Yrotation",
        "Xrotation",
    ]
    assert sum(e is not None for e in sk.end_sites) == 7
    values = motion.values()
    assert values.shape == (2752, 96)
    np.testing.assert_allclose(values[1, :4], [9.3722, 17.8693, -17.3198, np.radians(-3.2316)])
    pos, ori = sk.forward_kinematics(motion)
    assert pos.shape == (2752, 31, 3) and ori.shape == (2752, 31, 4)
    np.testing.assert_allclose(np.linalg.norm(ori, axis=2), 1.0, atol=1e-12)
    # Joints without position channels keep their distance to the parent.
    parents = np.array(sk.parents[1:])
    d = np.linalg.norm(pos[:, 1:] - pos[:, parents], axis=2)
    lengths = np.linalg.norm(sk.offsets[1:], axis=1)
    assert np.max(np.abs(d - lengths)) < 1e-9


def test_read_write_read(tmp_path, clip):
    sk, motion = clip
    mocap.write_bvh(sk, motion, tmp_path / "w.bvh")
    sk2, m2 = mocap.read_bvh(tmp_path / "w.bvh")
    assert sk2.joint_names == sk.joint_names and sk2.parents == sk.parents
    assert sk2.channels == sk.channels and sk2.end_sites == sk.end_sites
    assert sk2.frame_time == sk.frame_time
    np.testing.assert_array_equal(sk2.offsets, sk.offsets)
    np.testing.assert_array_equal(m2.values(), motion.values())
    p1, o1 = sk.forward_kinematics(motion)
    p2, o2 = sk2.forward_kinematics(m2)
    np.testing.assert_allclose(p2, p1, atol=1e-9)
    np.testing.assert_allclose(o2, o1, atol=1e-12)
    # A slice writes as a shorter clip.
    mocap.write_bvh(sk, motion.slice(10, 20), tmp_path / "part.bvh")
    _, part = mocap.read_bvh(tmp_path / "part.bvh")
    assert part.frames == 10
    np.testing.assert_array_equal(part.values(), motion.values()[10:20])


def test_hand_made_chain(tmp_path):
    path = tmp_path / "chain.bvh"
    path.write_bytes(CHAIN.replace("\n", "\r\n").encode())
    sk, motion = mocap.read_bvh(path)
    assert sk.joint_names == ["r", "a"] and sk.parents == [-1, 0]
    assert sk.end_sites == [None, [0.0, 2.0, 0.0]]
    pos, ori = sk.forward_kinematics(motion)
    np.testing.assert_allclose(pos[0], [[0, 0, 0], [0, 1, 0]], atol=1e-15)
    # Frame 1: root moved to (1, 2, 3) and turned 90° about z, so the child's offset (0, 1, 0)
    # points along -x.
    np.testing.assert_allclose(pos[1], [[1, 2, 3], [0, 2, 3]], atol=1e-12)
    s = np.sqrt(0.5)
    np.testing.assert_allclose(ori[1, 0], [s, 0, 0, s], atol=1e-15)


def test_parse_errors_carry_file_and_line(tmp_path):
    bad = tmp_path / "bad.bvh"
    bad.write_text(CHAIN.replace("1 2 3 90 0 0 0 0 0", "1 2 3 90 0 0 0 0"))
    with pytest.raises(
        kinema.ParseError, match=r"bad.bvh:20: expected 9 values in frame 2, found 8"
    ):
        mocap.read_bvh(bad)
    bad.write_text(CHAIN.replace("OFFSET 0 1 0", "OFFSET 0 one 0"))
    with pytest.raises(kinema.ParseError, match=r"bad.bvh:8: expected three numbers after OFFSET"):
        mocap.read_bvh(bad)
    bad.write_text(CHAIN.replace("\t}\n}\n", "\t}\n"))
    with pytest.raises(kinema.ParseError, match=r"bad.bvh:15: expected } to close joint \"r\""):
        mocap.read_bvh(bad)


def test_write_checks_its_arguments(tmp_path):
    path = tmp_path / "chain.bvh"
    path.write_text(CHAIN)
    sk, motion = mocap.read_bvh(path)
    with pytest.raises(ValueError, match="skeleton"):
        mocap.write_bvh(None, motion, tmp_path / "x.bvh")
    with pytest.raises(ValueError, match="motion"):
        mocap.write_bvh(sk, None, tmp_path / "x.bvh")
    asf = mocap.read_asf(DATA / "07-walk.asf")
    amc = mocap.read_amc(DATA / "07_05-walk.amc", asf)
    with pytest.raises(ValueError, match="values per frame"):
        mocap.write_bvh(sk, amc, tmp_path / "x.bvh")
    with pytest.raises(ValueError, match="values per frame"):
        sk.forward_kinematics(amc)


def test_an_asf_clip_converted_to_bvh_poses_its_joints_as_the_bones(tmp_path):
    # CMU 07_05 through asf_to_bvh and write_bvh: every joint of the file read back at its
    # bone's base (the parent's tip) to 1e-9 units, on every frame; it is the repository's
    # 07_05-walk.bvh; arguments of the wrong kind are named.
    sk = mocap.read_asf(DATA / "07-walk.asf")
    motion = mocap.read_amc(DATA / "07_05-walk.amc", sk)
    mocap.write_bvh(*mocap.asf_to_bvh(sk, motion), tmp_path / "walk.bvh")
    assert (tmp_path / "walk.bvh").read_bytes() == (DATA / "07_05-walk.bvh").read_bytes()
    bvh, clip = mocap.read_bvh(tmp_path / "walk.bvh")
    pos, _ = sk.forward_kinematics(motion)
    ours, _ = bvh.forward_kinematics(clip)
    row = {name: i for i, name in enumerate(sk.joint_names)}
    for j, (name, parent) in enumerate(zip(bvh.joint_names, bvh.parents, strict=True)):
        base = 0 if parent < 0 else row[bvh.joint_names[parent]]
        assert name in row
        np.testing.assert_allclose(ours[:, j], pos[:, base], atol=1e-9)
    with pytest.raises(ValueError, match="skeleton"):
        mocap.asf_to_bvh(bvh, clip)
    with pytest.raises(ValueError, match="motion"):
        mocap.asf_to_bvh(sk, None)
