"""A/B of the whole-step landing's Newton iterations (issue #21, session 29) between two
builds of kinema: each interpreter given (a `.venv/bin/python` with kinema installed) runs,
in a child process, the 64² hanging sheet of `bench_cloth.hanging` for `STEPS` steps of 1/60 s
from rest at the default options and reports its CPU seconds a step (`process_time`) and a
hash of the final positions and velocities; the children alternate, `ROUNDS` rounds, and the
best and median of each are printed. Then the 64² landing of `tests/cloth_landing.rs` in
three whole steps (`max_strain_change=inf`): its energy after each step.

    python bench/ab_cloth_newton.py /work/main/.venv/bin/python /work/wt/cloth/.venv/bin/python
"""

import hashlib
import statistics
import subprocess
import sys
from pathlib import Path

STEPS = 30
ROUNDS = 7

CHILD = r"""
import hashlib, sys, time
import numpy as np
sys.path.insert(0, BENCH)
import bench_cloth
from kinema.cloth import Cloth
from kinema.geometry import Sphere

cloth = bench_cloth.hanging(64)
t0 = time.process_time()
for _ in range(STEPS):
    cloth.step(1.0 / 60.0)
cpu = (time.process_time() - t0) / STEPS
state = np.concatenate([cloth.positions.ravel(), cloth.velocities.ravel()])
digest = hashlib.sha256(state.tobytes()).hexdigest()[:16]

sheet = Cloth.grid(64, 64, 1.0, 1.0)
sheet.set_state(sheet.positions + np.array([0.0, 0.605, 0.0]),
                np.tile([0.0, -1.64, 0.0], (len(sheet.positions), 1)))
sheet.add_collider(Sphere((0.0, 0.3, 0.0), 0.3, friction=0.5))
energies = [sum(sheet.energy().values())]
for _ in range(3):
    sheet.step(1.0 / 60.0, max_strain_change=float("inf"))
    energies.append(sum(sheet.energy().values()))
print(cpu, digest, " ".join(f"{e:.3f}" for e in energies))
"""


def run(python: str) -> tuple[float, str, str]:
    code = CHILD.replace("BENCH", repr(str(Path(__file__).parent))).replace("STEPS", str(STEPS))
    out = subprocess.run([python, "-c", code], capture_output=True, text=True, check=True)
    cpu, digest, energies = out.stdout.split(maxsplit=2)
    return float(cpu), digest, energies.strip()


def main() -> None:
    pythons = sys.argv[1:]
    times: dict[str, list[float]] = {p: [] for p in pythons}
    seen: dict[str, tuple[str, str]] = {}
    for _ in range(ROUNDS):
        for p in pythons:
            cpu, digest, energies = run(p)
            times[p].append(cpu)
            seen[p] = (digest, energies)
    load = Path("/proc/loadavg").read_text().split()[:3]
    print(f"64² hang, {STEPS} steps of 1/60 s from rest, defaults; {ROUNDS} interleaved rounds;")
    print(f"load average now {' '.join(load)}; CPU ms a step (process_time)")
    for p in pythons:
        t = times[p]
        digest, energies = seen[p]
        print(
            f"{p}: best {1e3 * min(t):.2f}, median {1e3 * statistics.median(t):.2f} ms; "
            f"hash {digest}; whole-step landing energy (J) {energies}"
        )
    print(
        "hash of the hashes:", hashlib.sha256(repr(sorted(seen.values())).encode()).hexdigest()[:16]
    )


if __name__ == "__main__":
    main()
