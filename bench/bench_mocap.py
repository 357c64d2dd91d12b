"""Motion capture: parsing the largest AMC file (CMU 01_01, 2751 frames) and forward
kinematics of all its frames, kinema against a plain-Python parser with numpy forward
kinematics (the way the popular Python AMC readers do it), in one process. The two give the
same joint positions (checked before timing), so the plain-Python code is also an independent
oracle of kinema's reading of the format.

Run: python bench/bench_mocap.py [--quick]
(--quick: kinema and the parse timed once instead of best of 3; the file is the same.)
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from kinema import mocap

DATA = Path(__file__).resolve().parents[1] / "tests" / "data" / "mocap"


def rotation(axis: str, degrees: float) -> np.ndarray:
    c, s = np.cos(np.radians(degrees)), np.sin(np.radians(degrees))
    if axis == "x":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == "y":
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def compose(axes: str, angles: list[float]) -> np.ndarray:
    """Rotations about fixed axes applied in the written order (x first for "xyz")."""
    m = np.eye(3)
    for a, v in zip(axes, angles, strict=True):
        m = rotation(a, v) @ m
    return m


def parse_asf(text: str) -> dict:
    """Bones with direction, length, axis frame and dofs; children per bone; root order."""
    bones: dict[str, dict] = {"root": {"dof": [], "length": 0.0, "direction": np.zeros(3)}}
    children: dict[str, list[str]] = {}
    lines = iter(text.splitlines())
    section, bone, root_order, root_axis = "", None, [], "xyz"
    for line in lines:
        words = line.split()
        if not words or words[0].startswith("#"):
            continue
        if words[0].startswith(":"):
            section = words[0]
            continue
        if section == ":root":
            if words[0] == "order":
                root_order = [w.lower() for w in words[1:]]
            elif words[0] == "axis":
                root_axis = words[1].lower()
        elif section == ":bonedata":
            if words[0] == "begin":
                bone = {"dof": [], "axis": np.eye(3)}
            elif words[0] == "end":
                bones[bone["name"]] = bone
            elif words[0] == "name":
                bone["name"] = words[1]
            elif words[0] == "direction":
                d = np.array([float(w) for w in words[1:4]])
                bone["direction"] = d / np.linalg.norm(d)  # written to 6 digits
            elif words[0] == "length":
                bone["length"] = float(words[1])
            elif words[0] == "axis":
                bone["axis"] = compose(words[4].lower(), [float(w) for w in words[1:4]])
            elif words[0] == "dof":
                bone["dof"] = words[1:]
        elif section == ":hierarchy" and words[0] not in ("begin", "end"):
            children.setdefault(words[0], []).extend(words[1:])
    return {"bones": bones, "children": children, "order": root_order, "axis": root_axis}


def parse_amc(text: str) -> list[dict[str, list[float]]]:
    frames: list[dict[str, list[float]]] = []
    for line in text.splitlines():
        words = line.split()
        if not words or words[0].startswith(("#", ":")):
            continue
        if words[0].isdigit() and len(words) == 1:
            frames.append({})
        else:
            frames[-1][words[0]] = [float(w) for w in words[1:]]
    return frames


def forward_kinematics(skel: dict, frame: dict[str, list[float]], names: list[str]) -> np.ndarray:
    """Joint positions (bone tips; the root at its translation) in the order of ``names``."""
    bones, out = skel["bones"], {}
    values = frame["root"]
    channels = dict(zip(skel["order"], values, strict=True))
    rot_axes = "".join(c[1] for c in skel["order"] if c.startswith("r"))
    root_r = compose(rot_axes, [channels["r" + a] for a in rot_axes])
    out["root"] = np.array([channels["tx"], channels["ty"], channels["tz"]])
    stack = [("root", root_r)]
    while stack:
        name, parent_r = stack.pop()
        for child in skel["children"].get(name, []):
            b = bones[child]
            angles = frame.get(child, [])
            m = compose("".join(d[1] for d in b["dof"]), angles) if b["dof"] else np.eye(3)
            r = parent_r @ b["axis"] @ m @ b["axis"].T
            out[child] = out[name] + b["length"] * (r @ b["direction"])
            stack.append((child, r))
    return np.array([out[n] for n in names])


def best(fn, k: int) -> float:
    out = float("inf")
    for _ in range(k):
        start = time.perf_counter()
        fn()
        out = min(out, time.perf_counter() - start)
    return 1e3 * out


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="time once instead of best of 3")
    k = 1 if parser.parse_args().quick else 3
    asf, amc = DATA / "01.asf", DATA / "01_01.amc"
    asf_text, amc_text = asf.read_text(), amc.read_text()
    skel = mocap.read_asf(asf)
    motion = mocap.read_amc(amc, skel)
    positions, _ = skel.forward_kinematics(motion)
    py_skel, py_frames = parse_asf(asf_text), parse_amc(amc_text)
    names = skel.joint_names
    for i in (0, motion.frames // 2, motion.frames - 1):
        np.testing.assert_allclose(
            forward_kinematics(py_skel, py_frames[i], names), positions[i], atol=1e-9
        )

    def ours_all():
        m = mocap.read_amc(amc, skel)
        skel.forward_kinematics(m)

    def py_all():
        frames = parse_amc(amc_text)
        for f in frames:
            forward_kinematics(py_skel, f, names)

    rows = [
        (
            "parse 01_01.amc (2751 frames)",
            best(lambda: mocap.read_amc(amc, skel), k),
            best(lambda: parse_amc(amc_text), k),
        ),
        (
            "forward kinematics, all frames",
            best(lambda: skel.forward_kinematics(motion), k),
            best(lambda: [forward_kinematics(py_skel, f, names) for f in py_frames], 1),
        ),
        ("parse + forward kinematics", best(ours_all, k), best(py_all, 1)),
    ]
    print(f"{motion.frames} frames, {len(names)} joints; positions agree to 1e-9")
    print("| operation | kinema (ms) | plain Python (ms) | Python / kinema |")
    print("|---|---:|---:|---:|")
    for name, a, b in rows:
        print(f"| {name} | {a:.1f} | {b:.1f} | {b / a:.0f}x |")


if __name__ == "__main__":
    main()
