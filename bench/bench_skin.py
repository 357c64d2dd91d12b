"""Skinning speed: kinema's linear blend and dual quaternion skinning of V vertices over F
frames (k = 4 influences per vertex) against a numpy implementation of linear blend skinning
(one einsum per frame block), in one process, on the same bones, weights and poses.

Run: python bench/bench_skin.py [--quick]   (default 10,000 vertices x 1,000 frames; --quick:
2,000 x 200). Prints the wall and CPU times (CPU: summed over the process's threads, the
fair figure on a shared machine), their ratios, the agreement of the two LBS results, the
thread count and ``uptime`` (the machine's load). numpy's einsum runs on one thread. Each is
timed ``--repeat`` times (default 3) and the fastest run kept: the first run of each pays the
kernel's zeroing of its fresh 240 MB output (about 0.4 s of CPU here), later runs much less.
"""

from __future__ import annotations

import argparse
import subprocess
import time

import numpy as np

import kinema
from kinema import _kinema


def numpy_lbs(rest, bones, weights, rotations, translations):
    """LBS with numpy: per frame, every bone's 3x4 matrix, gathered per influence and blended
    (``rotations (F, B, 3, 3)``, ``translations (F, B, 3)``) -> ``(F, V, 3)``."""
    out = np.empty((len(rotations), len(rest), 3))
    for f in range(len(rotations)):
        r = rotations[f][bones]  # (V, k, 3, 3)
        t = translations[f][bones]  # (V, k, 3)
        moved = np.einsum("vkij,vj->vki", r, rest) + t
        out[f] = np.einsum("vk,vki->vi", weights, moved)
    return out


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="2,000 vertices x 200 frames")
    parser.add_argument("--repeat", type=int, default=3, help="runs of each; the fastest is kept")
    args = parser.parse_args()
    v, frames, joints, k = (2_000, 200, 30, 4) if args.quick else (10_000, 1_000, 30, 4)
    rng = np.random.default_rng(0)
    rest = rng.normal(size=(v, 3))
    bones = np.stack([rng.choice(joints, k, replace=False) for _ in range(v)]).astype(np.uint32)
    weights = rng.random((v, k))
    weights /= weights.sum(axis=1, keepdims=True)
    identity = np.tile([1.0, 0.0, 0.0, 0.0], (joints, 1))
    skin = _kinema.Skin(
        rest,
        k,
        bones.ravel(),
        weights.ravel(),
        list(range(joints)),
        np.zeros((joints, 3)),
        identity,
    )
    q = rng.normal(size=(frames, joints, 4))
    q /= np.linalg.norm(q, axis=2, keepdims=True)
    p = rng.normal(size=(frames, joints, 3))
    from scipy.spatial.transform import Rotation as R

    rot = R.from_quat(q.reshape(-1, 4), scalar_first=True).as_matrix().reshape(frames, joints, 3, 3)

    def timed(run):
        """The result of ``run()`` and its fastest (wall, CPU) seconds over the repeats."""
        best = (np.inf, np.inf)
        for _ in range(args.repeat):
            start = time.perf_counter(), time.process_time()
            out = run()
            t = time.perf_counter() - start[0], time.process_time() - start[1]
            best = (min(best[0], t[0]), min(best[1], t[1]))
        return out, best

    timings = {}
    reference, timings["numpy einsum LBS"] = timed(
        lambda: numpy_lbs(rest, bones.astype(np.int64), weights, rot, p)
    )
    results = {}
    for method in ("lbs", "dqs"):
        results[method], timings[f"kinema {method}"] = timed(
            lambda method=method: skin.deform(p.reshape(-1, 3), q.reshape(-1, 4), method)
        )
    error = np.abs(results["lbs"].reshape(frames, v, 3) - reference).max()
    print(f"skinning {v} vertices x {frames} frames, {k} influences, {joints} bones")
    print(f"fastest of {args.repeat} runs each")
    print(f"threads: {kinema.num_threads()}; kinema LBS - numpy LBS: max |diff| = {error:.2e}")
    wall, cpu = timings["numpy einsum LBS"]
    for name, (w, c) in timings.items():
        print(
            f"  {name:18s} wall {w:7.3f} s ({wall / w:5.1f}x numpy)"
            f"   CPU {c:7.3f} s ({cpu / c:5.1f}x numpy)"
        )
    print(subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip())


if __name__ == "__main__":
    main()
