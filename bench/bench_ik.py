"""Inverse kinematics: solves per second and success rate on a 7-dof arm and a 20-joint chain,
kinema's methods beside ikpy and PyBullet's calculateInverseKinematics, in one process.

Every library gets the same chain (written as URDF for the peers and checked against kinema's
forward kinematics), the same reachable targets (the FK of random poses within the joint
limits), the same start (the middle of the joint ranges), tolerance 1e-4 m and at most 100
iterations (ikpy has no iteration cap; it runs scipy's least_squares to its own tolerance). Errors and limits are judged by kinema's FK of each returned pose. A second table
gives kinema's error against the iteration budget per method (the speed/accuracy trade).

Run: python bench/bench_ik.py [--quick]   (ikpy and pybullet are optional: pip install ikpy pybullet)
(--quick: 20 targets instead of 300; ikpy takes up to ~0.1 s a solve.)
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from collections.abc import Callable

import numpy as np

from kinema import ik

H = np.pi / 2
ARM = (
    [0.3, 0.25, 0.1],
    ["xyz", "z", "xyz"],
    [(-H, H)] * 3 + [(0.0, 2.6), (-H, H), (-0.8, 0.8), (-0.8, 0.8)],
)
CHAIN20 = ([0.05] * 20, ["z", "y"] * 10, [(-np.pi / 4, np.pi / 4)] * 20)
MM = 1e-3


def urdf(lengths, dofs, limits) -> tuple[str, list[int]]:
    """The chain as URDF revolute joints, and for each URDF joint the kinema pose index.

    An ASF bone with dofs "xyz" turns by Rz Ry Rx (first letter innermost), so its URDF joints
    come outer to inner: z, y, x, all at the bone's base (the previous bone's tip)."""
    inertial = '<inertial><mass value="0.1"/><inertia ixx="1e-3" iyy="1e-3" izz="1e-3" ixy="0" ixz="0" iyz="0"/></inertial>'
    links = [f'<link name="base">{inertial}</link>']
    joints, order = [], []
    parent, k, offset = "base", 0, 0.0
    for length, d in zip(lengths, dofs, strict=True):
        index = list(range(k, k + len(d)))
        for letter, i in zip(reversed(d), reversed(index), strict=True):
            child = f"j{i}"
            axis = {"x": "1 0 0", "y": "0 1 0", "z": "0 0 1"}[letter]
            lo, hi = limits[i]
            links.append(f'<link name="{child}">{inertial}</link>')
            joints.append(
                f'<joint name="q{i}" type="revolute"><parent link="{parent}"/><child link="{child}"/>'
                f'<origin xyz="{offset} 0 0"/><axis xyz="{axis}"/>'
                f'<limit lower="{lo}" upper="{hi}" effort="1" velocity="1"/></joint>'
            )
            order.append(i)
            parent, offset = child, 0.0
        k += len(d)
        offset = length
    links.append(f'<link name="tip">{inertial}</link>')
    joints.append(
        f'<joint name="tip" type="fixed"><parent link="{parent}"/><child link="tip"/><origin xyz="{offset} 0 0"/></joint>'
    )
    return '<robot name="chain">' + "".join(links + joints) + "</robot>", order


def problem(spec, seed: int, count: int):
    lengths, dofs, limits = spec
    sk = ik.chain(lengths, dofs, limits)
    lo, hi = np.array(limits).T
    rng = np.random.default_rng(seed)
    goals = lo + (hi - lo) * rng.random((count, len(lo)))
    tip = len(sk.joint_names) - 1
    targets = np.array([sk.forward_kinematics(g)[0][tip] for g in goals])
    return sk, (lo + hi) / 2, targets, lo, hi


def judge(sk, lo, hi, targets, poses, seconds) -> dict:
    tip = len(sk.joint_names) - 1
    err = np.array(
        [
            np.linalg.norm(sk.forward_kinematics(p)[0][tip] - t)
            for p, t in zip(poses, targets, strict=True)
        ]
    )
    outside = np.array([np.any(p < lo - 1e-9) or np.any(p > hi + 1e-9) for p in poses])
    return {
        "rate": len(poses) / seconds,
        "success": np.mean(err <= MM),
        "median": np.median(err),
        "violations": np.mean(outside),
    }


def run_kinema(sk, start, targets, method: str, max_iters: int = 100) -> tuple[list, float]:
    tip = sk.joint_names[-1]
    poses = []
    t0 = time.perf_counter()
    for t in targets:
        pose, _ = ik.solve(sk, start, {tip: t}, method=method, max_iters=max_iters)
        poses.append(pose)
    return poses, time.perf_counter() - t0


def run_ikpy(spec, start, targets) -> tuple[list, float] | None:
    try:
        from ikpy.chain import Chain
    except ImportError:
        return None
    text, order = urdf(*spec)
    with tempfile.NamedTemporaryFile("w", suffix=".urdf", delete=False) as f:
        f.write(text)
    try:
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            chain = Chain.from_urdf_file(f.name, base_elements=["base"])
            chain.active_links_mask = np.array(
                [link.joint_type == "revolute" for link in chain.links]
            )
    finally:
        os.unlink(f.name)
    # ikpy's vector: one entry per link (origin, the revolute joints in URDF order, the tip).
    init = np.zeros(len(chain.links))
    init[1 : 1 + len(order)] = start[order]
    poses = []
    t0 = time.perf_counter()
    for t in targets:
        q = chain.inverse_kinematics(t, initial_position=init)  # its own tolerances
        pose = np.empty(len(order))
        pose[order] = q[1 : 1 + len(order)]
        poses.append(pose)
    return poses, time.perf_counter() - t0


def run_pybullet(spec, start, targets, limits: bool) -> tuple[list, float] | None:
    """PyBullet's DLS; with ``limits`` its null-space variant that takes the joint limits."""
    try:
        import pybullet as p
    except ImportError:
        return None
    text, order = urdf(*spec)
    with tempfile.NamedTemporaryFile("w", suffix=".urdf", delete=False) as f:
        f.write(text)
    client = p.connect(p.DIRECT)
    try:
        body = p.loadURDF(f.name, useFixedBase=True, physicsClientId=client)
    finally:
        os.unlink(f.name)
    n = len(order)
    lo, hi = np.array(spec[2])[order].T
    rest = start[order]
    poses = []
    t0 = time.perf_counter()
    for t in targets:
        for j in range(n):
            p.resetJointState(body, j, rest[j], physicsClientId=client)
        extra = {}
        if limits:
            extra = {
                "lowerLimits": lo.tolist(),
                "upperLimits": hi.tolist(),
                "jointRanges": (hi - lo).tolist(),
                "restPoses": rest.tolist(),
            }
        q = p.calculateInverseKinematics(
            body,
            n,
            t.tolist(),
            maxNumIterations=100,
            residualThreshold=1e-4,
            physicsClientId=client,
            **extra,
        )
        pose = np.empty(n)
        pose[order] = q
        poses.append(pose)
    seconds = time.perf_counter() - t0
    p.disconnect(client)
    return poses, seconds


def check_models(spec) -> None:
    """The URDF chain and kinema's chain agree on the tip position (validates the mapping)."""
    try:
        import pybullet as p
    except ImportError:
        return
    sk = ik.chain(*spec)
    text, order = urdf(*spec)
    with tempfile.NamedTemporaryFile("w", suffix=".urdf", delete=False) as f:
        f.write(text)
    client = p.connect(p.DIRECT)
    body = p.loadURDF(f.name, useFixedBase=True, physicsClientId=client)
    os.unlink(f.name)
    q = np.random.default_rng(3).uniform(-1, 1, len(order))
    for j, i in enumerate(order):
        p.resetJointState(body, j, q[i], physicsClientId=client)
    tip = p.getLinkState(body, len(order), computeForwardKinematics=True, physicsClientId=client)[4]
    p.disconnect(client)
    np.testing.assert_allclose(tip, sk.forward_kinematics(q)[0][-1], atol=1e-6)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="20 targets instead of 300")
    count = 20 if parser.parse_args().quick else 300
    for name, spec in [("7-dof arm", ARM), ("20-joint chain", CHAIN20)]:
        check_models(spec)
        sk, start, targets, lo, hi = problem(spec, seed=0, count=count)
        rows: list[tuple[str, dict]] = []
        for method in ["dls", "pseudo_inverse", "transpose", "ccd"]:
            rows.append(
                (
                    f"kinema {method}",
                    judge(sk, lo, hi, targets, *run_kinema(sk, start, targets, method)),
                )
            )
        peers: list[tuple[str, Callable]] = [
            ("ikpy", run_ikpy),
            ("PyBullet (limits, null space)", lambda *a: run_pybullet(*a, limits=True)),
            ("PyBullet (no limits)", lambda *a: run_pybullet(*a, limits=False)),
        ]
        for peer, run in peers:
            out = run(spec, start, targets)
            if out is None:
                print(f"{peer}: not installed")
                continue
            rows.append((peer, judge(sk, lo, hi, targets, *out)))
        dls = rows[0][1]["rate"]
        print(f"\n### {name} ({count} reachable targets, start: middle of the ranges)\n")
        print(
            "| solver | solves/s | kinema dls / solver | within 1 mm | median error (m) | limits violated |"
        )
        print("|---|---:|---:|---:|---:|---:|")
        for label, r in rows:
            print(
                f"| {label} | {r['rate']:.0f} | {dls / r['rate']:.1f}x | {100 * r['success']:.1f}% "
                f"| {r['median']:.1e} | {100 * r['violations']:.1f}% |"
            )
        print(f"\n{name}: kinema, error against the iteration budget\n")
        budgets = [1, 3, 10, 30, 100]
        print(
            "| method | "
            + " | ".join(f"{b} it: within 1 mm / median error / µs" for b in budgets)
            + " |"
        )
        print("|---|" + "---:|" * len(budgets))
        for method in ["dls", "pseudo_inverse", "transpose", "ccd"]:
            cells = []
            for b in budgets:
                poses, s = run_kinema(sk, start, targets[:100], method, max_iters=b)
                r = judge(sk, lo, hi, targets[:100], poses, s)
                cells.append(
                    f"{100 * r['success']:.0f}% / {r['median']:.0e} / {1e6 / r['rate']:.0f}"
                )
            print(f"| {method} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
