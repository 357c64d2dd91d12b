"""Joints: the four formulations (penalty springs, Lagrange multipliers, sequential impulses,
XPBD) on a hinge pendulum and a chain of five hinges, at 1 ms and at 60 Hz.

Both problems are thin boxes (0.4 m x 4 cm x 4 cm, 0.5 kg) hinged about z, released
horizontal (the pendulum is the chain's first link alone), links not colliding. Measured per formulation over 10 s:
the largest anchor separation (drift, m), the largest tilt of a hinge axis (rad), the largest
change of kinetic plus gravitational energy and its value at the end (J; a penalty joint's
spring energy is left out, so its stretch shows up here; total energy scale: 1 J for the
pendulum, 25 J for the chain), the cost per step, and the largest step (on a grid of factors
√2 from 0.1 s) for which 2 s keep the problem together (best of three runs of the whole 10 s in
one call, so no Python overhead per step). XPBD takes ``World.xpbd_substeps`` (20) substeps
per step, impulses ``World.joint_iterations`` (20) sweeps.

Run: python bench/bench_joints.py [--write] [--figure PATH] [--quick: 1 s runs, nothing written]
(--write replaces the table in bench/RESULTS.md.)
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import kinema
from kinema.rigid import Box, Hinge, World

T = 10.0
STEPS = {"1 ms": 1e-3, "60 Hz": 1 / 60}
FORMULATIONS = [
    ("penalty k = 1e3/s²", "penalty", 1e3),
    ("penalty k = 1e4/s²", "penalty", 1e4),
    ("penalty k = 1e5/s²", "penalty", 1e5),
    ("lagrange", "lagrange", 0.0),
    ("impulse", "impulse", 0.0),
    ("xpbd", "xpbd", 0.0),
]
RESULTS = Path(__file__).with_name("RESULTS.md")
BEGIN, END = "<!-- joints:begin -->", "<!-- joints:end -->"


def chain(links: int, method: str, k: float) -> World:
    """``links`` boxes in a horizontal line from a hinge at the origin, hinged about z. The
    links do not collide with each other (inelastic knocks would hide the joints' energy
    behaviour)."""
    w = World(collisions=False)
    for i in range(links):
        w.add_body(Box([0.2, 0.02, 0.02]), mass=0.5, position=[0.2 + 0.4 * i, 0.0, 0.0])
        joint = Hinge(i, i - 1 if i else None, [0.4 * i, 0.0, 0.0], [0.0, 0.0, 1.0])
        if method == "penalty":
            w.add_joint(joint, method, stiffness=k, damping=2.0 * np.sqrt(k))
        else:
            w.add_joint(joint, method)
    return w


def energy(w: World) -> float:
    return w.kinetic_energy() + w.potential_energy()


def measure(links: int, method: str, k: float, dt: float, duration: float = T) -> dict[str, object]:
    w = chain(links, method, k)
    e0 = energy(w)
    every = max(1, round(0.01 / dt))
    samples = round(duration / dt) // every
    times = np.arange(1, samples + 1) * every * dt
    drift, tilt, de = np.full(samples, np.nan), np.full(samples, np.nan), np.full(samples, np.nan)
    failed = False
    for s in range(samples):
        try:
            w.step(dt, every)
        except kinema.SimulationError:
            failed = True
            break
        v = w.joint_violations.max(axis=0)
        drift[s], tilt[s], de[s] = v[0], v[1], energy(w) - e0
    # A run whose anchors end up farther apart than a link is long has come apart.
    failed = failed or not np.nanmax(drift) < 0.4
    cost = float("inf")
    for _ in range(3):  # best of three against noise from other work on the machine
        timed = chain(links, method, k)
        start = time.perf_counter()
        try:
            timed.step(dt, round(duration / dt))
        except kinema.SimulationError:
            pass
        cost = min(cost, (time.perf_counter() - start) / round(duration / dt))
    return {
        "failed": failed,
        "drift": float(np.nanmax(drift)),
        "tilt": float(np.nanmax(tilt)),
        "energy": float(np.nanmax(np.abs(de))),
        "final": float(de[-1]),
        "cost_us": 1e6 * cost,
        "series": (times, drift, de),
    }


def stable(links: int, method: str, k: float) -> float:
    """Largest dt = 0.1 · 2^(-j/2) for which 2 s run without error and without coming apart
    (every joint's anchors within a link length, 0.4 m; an unstable run grows without
    bound)."""
    for j in range(30):
        dt = 0.1 * 0.5 ** (j / 2)
        w = chain(links, method, k)
        try:
            worst = 0.0
            for _ in range(round(2.0 / dt)):
                w.step(dt)
                worst = max(worst, float(w.joint_violations[:, 0].max()))
                if not worst < 0.4:
                    break
        except kinema.SimulationError:
            continue
        if worst < 0.4:
            return dt
    return float("nan")


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--write", action="store_true", help="update bench/RESULTS.md")
    parser.add_argument(
        "--quick", action="store_true", help="1 s runs, no stability search, nothing written"
    )
    parser.add_argument(
        "--figure", default=str(Path(__file__).parents[1] / "docs" / "images" / "joints.png")
    )
    args = parser.parse_args()
    if args.quick and args.write:
        parser.error("--quick results are not for RESULTS.md")
    duration = 1.0 if args.quick else T
    problems = {"hinge pendulum": 1, "chain of 5 hinges": 5}
    lines = [
        "| problem | formulation | dt | max drift (m) | max axis tilt (rad) "
        "| max energy error (J) | energy change at 10 s (J) | µs per step "
        "| largest dt holding together for 2 s (s) |",
        "|---|---|---|---:|---:|---:|---:|---:|---:|",
    ]
    results: dict[str, dict[str, dict[str, object]]] = {}
    for name, links in problems.items():
        stable_dt: dict[str, float] = {}
        for step_name, dt in STEPS.items():
            key = f"{name}, {step_name}"
            results[key] = {}
            for label, method, k in FORMULATIONS:
                r = measure(links, method, k, dt, duration)
                if label not in stable_dt:
                    stable_dt[label] = float("nan") if args.quick else stable(links, method, k)
                results[key][label] = r
                if r["failed"]:
                    cells = "comes apart | – | – | – "
                else:
                    cells = (
                        f"{r['drift']:.1e} | {r['tilt']:.1e} | {r['energy']:.1e} "
                        f"| {r['final']:+.1e} "
                    )
                lines.append(
                    f"| {name} | {label} | {step_name} | {cells}| {r['cost_us']:.1f} "
                    f"| {stable_dt[label]:.1e} |"
                )
                print(lines[-1], flush=True)
    table = "\n".join(lines)
    print()
    print(table)
    if args.quick:
        return
    figure(results, Path(args.figure))
    if args.write:
        text = RESULTS.read_text()
        head, rest = text.split(BEGIN)
        _, tail = rest.split(END)
        RESULTS.write_text(f"{head}{BEGIN}\n{table}\n{END}{tail}")


def figure(results: dict[str, dict[str, dict[str, object]]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = list(results)
    fig, axes = plt.subplots(2, len(keys), figsize=(4 * len(keys), 7), sharex=True)
    for col, key in enumerate(keys):
        for label, r in results[key].items():
            t, drift, de = r["series"]  # type: ignore[misc]
            axes[0, col].semilogy(t, np.clip(drift, 1e-17, 1e3), label=label)
            axes[1, col].semilogy(t, np.clip(np.abs(de), 1e-17, 1e3), label=label)
        axes[0, col].set_title(f"{key}: drift", fontsize=9)
        axes[1, col].set_title(f"{key}: energy error", fontsize=9)
        axes[1, col].set_xlabel("time (s)")
    axes[0, 0].set_ylabel("max anchor separation (m)")
    axes[1, 0].set_ylabel("|E - E₀| (J)")
    axes[0, 0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    print(f"figure: {path}")


if __name__ == "__main__":
    main()
