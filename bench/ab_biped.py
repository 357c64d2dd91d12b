"""A/B timing of the 3-D SIMBICON walker between two builds of kinema, interleaved.

Settings: ``Biped(dims=3)`` at its defaults (bench_biped.py's 3-D walker), dt = 1e-3 s,
20 s walked in one ``step`` call, CPU time of that call (``time.process_time``). Each run
is a fresh interpreter whose ``PYTHONPATH`` is one build's Python package directory
(``python/`` of a checkout after ``maturin develop --release``), alternating A, B, A, B, …
so that both builds see the same load. Prints, per build, the best and the median over the
runs (x real time and µs a step), and the walk's x after 20 s and a hash of its final
``q`` and ``q̇`` (equal in every run of a build: the walk is deterministic), so that the two
builds' results can be compared too.

Run: KINEMA_NUM_THREADS=1 python bench/ab_biped.py A_DIR B_DIR [--runs 30] [--seconds 20]
[--coronal-cv 0.4] (e.g. ``/work/main/python /work/wt/biped/python``; ``--coronal-cv``
walks both builds with the same gain when their defaults differ).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys

DT = 1e-3

CHILD = """
import hashlib, json, sys, time
import numpy as np
from kinema.character import Biped
steps = round({seconds} / {dt})
b = Biped(dims=3, **{kw})
t = time.process_time()
b.step({dt}, steps)
cpu = time.process_time() - t
state = np.concatenate([b.q, b.qd]).astype("<f8").tobytes()
print(json.dumps({{"cpu": cpu, "steps": steps, "x": repr(float(b.com[0])),
                  "hash": hashlib.sha256(state).hexdigest()[:16],
                  "module": sys.modules["kinema"].__file__}}))
"""


def run(path: str, seconds: float, kw: dict[str, float]) -> dict:
    """One walk in a fresh interpreter with ``path`` first on ``PYTHONPATH``."""
    env = dict(os.environ, PYTHONPATH=path, KINEMA_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    code = CHILD.format(seconds=seconds, dt=DT, kw=repr(kw))
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit(f"{path}: {out.stderr}")
    return json.loads(out.stdout)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("a")
    parser.add_argument("b")
    parser.add_argument("--runs", type=int, default=30)
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument(
        "--coronal-cv", type=float, help="coronal_cv for both builds (default: each one's own)"
    )
    args = parser.parse_args()
    kw = {} if args.coronal_cv is None else {"coronal_cv": args.coronal_cv}
    results: dict[str, list[dict]] = {"A": [], "B": []}
    for _ in range(args.runs):
        for name, path in (("A", args.a), ("B", args.b)):
            results[name].append(run(path, args.seconds, kw))
    load = os.getloadavg()
    print(
        f"3-D walker, dt = {DT} s, {args.seconds} s walked in one call, CPU time, "
        f"{kw or 'defaults'}, {args.runs} interleaved runs each, load {load[0]:.1f} {load[1]:.1f} {load[2]:.1f}"
    )
    for name in ("A", "B"):
        rs = results[name]
        cpus = [r["cpu"] for r in rs]
        steps = rs[0]["steps"]
        best, median = min(cpus), statistics.median(cpus)
        xs, hashes = {r["x"] for r in rs}, {r["hash"] for r in rs}
        print(
            f"{name} ({rs[0]['module']}): best {args.seconds / best:.0f}x "
            f"({best / steps * 1e6:.2f} µs/step), median {args.seconds / median:.0f}x "
            f"({median / steps * 1e6:.2f} µs/step); x after {args.seconds:g} s "
            f"{' '.join(sorted(xs))} m, hash {' '.join(sorted(hashes))}"
        )


if __name__ == "__main__":
    main()
