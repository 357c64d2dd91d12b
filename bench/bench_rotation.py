"""Batched rotation kernels at N = 10^6 against scipy.spatial.transform, numpy-quaternion (when
installed) and the plain numpy a user would write, timed in one process. Prints a markdown
table of best-of-k wall times and the speed-up ratios (peer time / kinema time).

Run: python bench/bench_rotation.py [--quick] [--n 1000000] [--repeat 5]
(--quick: N = 10^5, best of 3.)
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from collections.abc import Callable

import numpy as np

import kinema
from kinema import Rotation, Transform, slerp

try:
    from scipy import __version__ as scipy_version
    from scipy.spatial.transform import RigidTransform, Slerp
    from scipy.spatial.transform import Rotation as R
except ImportError:
    R = None
try:
    import quaternion as npq  # numpy-quaternion
except ImportError:
    npq = None


def best(fn: Callable[[], object], repeat: int) -> float:
    """Best wall time of ``repeat`` calls, in milliseconds (after one warm-up call)."""
    fn()
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return 1e3 * min(times)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="small sizes, for a fast check")
    parser.add_argument("--n", type=int, help="rotations (default 10^6, 10^5 with --quick)")
    parser.add_argument("--repeat", type=int, help="best of (default 5, 3 with --quick)")
    args = parser.parse_args()
    n = args.n or (100_000 if args.quick else 1_000_000)
    k = args.repeat or (3 if args.quick else 5)
    if R is None:
        print("scipy: not installed, nothing to compare with")
        return

    rng = np.random.default_rng(0)
    q = rng.standard_normal((n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q_xyzw = np.ascontiguousarray(q[:, [1, 2, 3, 0]])
    v = rng.standard_normal((n, 3))
    t = np.linspace(0.0, 1.0, n)

    q_raw, q_raw_xyzw = 2.5 * q, 2.5 * q_xyzw  # not unit: from_quat must normalise
    ours, theirs = Rotation.from_quat(q), R.from_quat(q_xyzw)
    ours2, theirs2 = Rotation.from_quat(q[::-1].copy()), R.from_quat(q_xyzw[::-1].copy())
    mats = theirs.as_matrix()
    eul = theirs.as_euler("xyz")
    rv = theirs.as_rotvec()
    b_vec = rng.standard_normal((n, 3))
    a_vec = theirs.apply(b_vec) + 0.01 * rng.standard_normal((n, 3))
    mrp = theirs.as_mrp()
    axes = np.array([[1.0, 0.0, 0.0], [0.0, 0.6, 0.8], [1.0, 0.0, 0.0]])  # Davenport n1 n2 n1
    dav = theirs.as_davenport(axes, "extrinsic")
    tr = rng.standard_normal((n, 3))
    ours_t = Transform.from_components(tr, ours)
    ours_t2 = Transform.from_components(tr[::-1].copy(), ours2)
    theirs_t = RigidTransform.from_components(tr, theirs)
    theirs_t2 = RigidTransform.from_components(tr[::-1].copy(), theirs2)
    key = R.from_quat(q_xyzw[:2])
    sl = Slerp([0.0, 1.0], key)
    o0, o1 = ours[0], ours[1]

    cases: list[
        tuple[str, Callable[[], object], Callable[[], object], Callable[[], object] | None]
    ] = [
        (
            "from_quat (normalise)",
            lambda: Rotation.from_quat(q_raw),
            lambda: R.from_quat(q_raw_xyzw),
            None,
        ),
        ("as_matrix", ours.as_matrix, theirs.as_matrix, None),
        ("from_matrix", lambda: Rotation.from_matrix(mats), lambda: R.from_matrix(mats), None),
        ("as_euler('xyz')", lambda: ours.as_euler("xyz"), lambda: theirs.as_euler("xyz"), None),
        (
            "from_euler('xyz')",
            lambda: Rotation.from_euler("xyz", eul),
            lambda: R.from_euler("xyz", eul),
            None,
        ),
        ("as_rotvec", ours.as_rotvec, theirs.as_rotvec, None),
        ("from_rotvec", lambda: Rotation.from_rotvec(rv), lambda: R.from_rotvec(rv), None),
        ("apply (N rotations, N vectors)", lambda: ours.apply(v), lambda: theirs.apply(v), None),
        ("compose r1 * r2", lambda: ours * ours2, lambda: theirs * theirs2, None),
        ("slerp (2 keys, N times)", lambda: slerp(o0, o1, t), lambda: sl(t), None),
        ("as_mrp", ours.as_mrp, theirs.as_mrp, None),
        ("from_mrp", lambda: Rotation.from_mrp(mrp), lambda: R.from_mrp(mrp), None),
        (
            "as_davenport (n1 n2 n1)",
            lambda: ours.as_davenport(axes, "extrinsic"),
            lambda: theirs.as_davenport(axes, "extrinsic"),
            None,
        ),
        (
            "from_davenport (n1 n2 n1)",
            lambda: Rotation.from_davenport(axes, "extrinsic", dav),
            lambda: R.from_davenport(axes, "extrinsic", dav),
            None,
        ),
        ("power r ** 0.5", lambda: ours**0.5, lambda: theirs**0.5, None),
        ("Transform compose t1 * t2", lambda: ours_t * ours_t2, lambda: theirs_t * theirs_t2, None),
        ("Transform apply", lambda: ours_t.apply(v), lambda: theirs_t.apply(v), None),
        ("Transform inv", ours_t.inv, theirs_t.inv, None),
        ("Transform as_matrix", ours_t.as_matrix, theirs_t.as_matrix, None),
        # Unweighted: numpy-quaternion's mean and alignment take no weights.
        ("mean", ours.mean, theirs.mean, None),
        (
            "align_vectors (N pairs)",
            lambda: Rotation.align_vectors(a_vec, b_vec),
            lambda: R.align_vectors(a_vec, b_vec),
            None,
        ),
    ]
    plain = plain_numpy(q, v, a_vec, b_vec)
    if npq is not None:
        qa, qb = npq.as_quat_array(q), npq.as_quat_array(q[::-1].copy())
        extra = {
            "as_matrix": lambda: npq.as_rotation_matrix(qa),
            "from_matrix": lambda: npq.from_rotation_matrix(mats),
            # rotate_vectors would rotate every vector by every rotation (N x N); this is the
            # element-wise q v q* that the other libraries compute.
            "apply (N rotations, N vectors)": lambda: npq.as_vector_part(
                qa * npq.from_vector_part(v) * qa.conjugate()
            ),
            "compose r1 * r2": lambda: qa * qb,
            "as_rotvec": lambda: npq.as_rotation_vector(qa),
            "from_rotvec": lambda: npq.from_rotation_vector(rv),
            "slerp (2 keys, N times)": lambda: npq.slerp(qa[0], qa[1], 0.0, 1.0, t),
            "mean": lambda: npq.mean_rotor_in_chordal_metric(qa),
            "align_vectors (N pairs)": lambda: npq.optimal_alignment_in_Euclidean_metric(
                a_vec, b_vec
            ),
        }
        cases = [(name, a, b, extra.get(name)) for name, a, b, _ in cases]

    print(
        f"N = {n}, best of {k}; kinema {kinema.__version__}, scipy {scipy_version}, "
        f"numpy {np.__version__}, numpy-quaternion {'yes' if npq else 'not installed'}; "
        f"{platform.machine()}, {os.cpu_count()} threads\n"
    )
    header = "| operation | kinema (ms) | scipy (ms) | scipy / kinema |"
    sep = "|---|---:|---:|---:|"
    if npq is not None:
        header += " numpy-quaternion (ms) | npq / kinema |"
        sep += "---:|---:|"
    header += " numpy (ms) | numpy / kinema |"
    sep += "---:|---:|"
    print(header)
    print(sep)
    for name, mine, scipy_fn, npq_fn in cases:
        a, b = best(mine, k), best(scipy_fn, k)
        row = f"| {name} | {a:.1f} | {b:.1f} | {b / a:.1f}x |"
        peers = [npq_fn] if npq is not None else []
        for fn in [*peers, plain.get(name)]:
            if fn is None:
                row += " – | – |"
            else:
                c = best(fn, k)
                row += f" {c:.1f} | {c / a:.1f}x |"
        print(row)


def plain_numpy(
    q: np.ndarray, v: np.ndarray, a_vec: np.ndarray, b_vec: np.ndarray
) -> dict[str, Callable[[], object]]:
    """The operations as a numpy user writes them (scalar-first quaternions ``q``)."""
    q2 = q[::-1].copy()

    def as_matrix() -> np.ndarray:
        qw, qx, qy, qz = q.T
        return np.stack(
            [
                1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw),
                2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw),
                2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy),
            ],
            axis=-1,
        ).reshape(-1, 3, 3)  # fmt: skip

    def apply() -> np.ndarray:
        u, s = q[:, 1:], q[:, :1]
        t = 2.0 * np.cross(u, v)
        return v + s * t + np.cross(u, t)

    def compose() -> np.ndarray:
        aw, ax, ay, az = q.T
        bw, bx, by, bz = q2.T
        return np.stack(
            [
                aw * bw - ax * bx - ay * by - az * bz,
                aw * bx + ax * bw + ay * bz - az * by,
                aw * by - ax * bz + ay * bw + az * bx,
                aw * bz + ax * by - ay * bx + az * bw,
            ],
            axis=-1,
        )

    def mean() -> np.ndarray:
        m = q.T @ q
        return np.linalg.eigh(m)[1][:, -1]

    def align() -> np.ndarray:
        u, _, vt = np.linalg.svd(a_vec.T @ b_vec)
        d = np.sign(np.linalg.det(u @ vt))
        return u @ np.diag([1.0, 1.0, d]) @ vt

    return {
        "from_quat (normalise)": lambda: q / np.linalg.norm(q, axis=1, keepdims=True),
        "as_matrix": as_matrix,
        "apply (N rotations, N vectors)": apply,
        "compose r1 * r2": compose,
        "mean": mean,
        "align_vectors (N pairs)": align,
    }


if __name__ == "__main__":
    main()
