"""Constraints: the same problems in three formulations — Lagrange multipliers (with
post-stabilisation, the default; without it, with and without drift feedback), penalty
springs at several stiffnesses, reduced coordinates — on a bead on a vertical circle and a
double pendulum of rods, all stepped with RK4 at dt = 1 ms.

Measured per formulation: the largest drift max |C| over 10 s, the largest energy error
max |E - E₀| over 10 s, the position error at t = 2 s against reduced coordinates at
dt = 10 µs, the cost per step, and the largest stable step (the largest dt on a grid of
factors √2 for which a 2 s run stays finite with |C| < 0.5 m). The energy is the particles'
kinetic and gravitational energy; with penalty springs the energy they store is the error.

Run: python bench/bench_constraint_formulations.py [--quick | --write] [--figure PATH]
(--write replaces the table in bench/RESULTS.md; --quick times each run once instead of best of
three and writes nothing, no figure either.)
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from kinema.constraints import (
    Circle,
    ConstrainedSystem,
    Distance,
    OnCurve,
    ReducedBead,
    ReducedPendulum,
)
from kinema.particles import Gravity, ParticleSystem

DT, T, T_ERR = 1e-3, 10.0, 2.0
RESULTS = Path(__file__).with_name("RESULTS.md")
BEGIN, END = "<!-- formulations:begin -->", "<!-- formulations:end -->"


class Run:
    """One problem in one formulation: step, drift, energy, the positions compared."""

    def __init__(
        self,
        step: Callable[[float, int], None],
        drift: Callable[[], float],
        energy: Callable[[], float],
        positions: Callable[[], np.ndarray],
    ) -> None:
        self.step, self.drift, self.energy, self.positions = step, drift, energy, positions


def particle_run(ps: ParticleSystem, cs: ConstrainedSystem, pts: list[int]) -> Run:
    return Run(
        lambda dt, n: cs.step(dt, n),
        lambda: cs.violation()[0],
        lambda: ps.kinetic_energy() + ps.potential_energy(),
        lambda: ps.positions[pts].copy(),
    )


def bead(kind: str, k: float = 0.0) -> Run:
    circle = Circle([0, 0, 0], 1.0)
    if kind == "reduced":
        r = ReducedBead(circle, u=0.0, u_dot=2.0)
        return Run(lambda dt, n: r.step(dt, n), lambda: 0.0, r.energy, lambda: r.positions)
    ps = ParticleSystem([[1.0, 0.0, 0.0]], [[0.0, 2.0, 0.0]])
    ps.add(Gravity())
    cs = constrained(ps, kind, k)
    cs.add(OnCurve(0, circle))
    return particle_run(ps, cs, [0])


def double_pendulum(kind: str, k: float = 0.0) -> Run:
    if kind == "reduced":
        r = ReducedPendulum([1.0, 1.0], [1.0, 2.0], [np.pi / 2, 0.0])
        return Run(lambda dt, n: r.step(dt, n), lambda: 0.0, r.energy, lambda: r.positions)
    ps = ParticleSystem([[0, 0, 0], [1, 0, 0], [1, -1, 0]], masses=[np.inf, 1.0, 2.0])
    ps.add(Gravity())
    cs = constrained(ps, kind, k)
    cs.add(Distance(0, 1))
    cs.add(Distance(1, 2))
    return particle_run(ps, cs, [1, 2])


def constrained(ps: ParticleSystem, kind: str, k: float) -> ConstrainedSystem:
    if kind == "stabilized":
        return ConstrainedSystem(ps)
    if kind == "multipliers":
        return ConstrainedSystem(ps, stabilize=False)
    if kind == "feedback":
        return ConstrainedSystem(ps, ks=100.0, kd=20.0, stabilize=False)
    return ConstrainedSystem(ps, formulation="penalty", stiffness=k)


FORMULATIONS = [
    ("multipliers, post-stabilisation (default)", "stabilized", 0.0),
    ("multipliers, no feedback", "multipliers", 0.0),
    ("multipliers, feedback ks=100, kd=20", "feedback", 0.0),
    ("penalty k = 1e3 N/m", "penalty", 1e3),
    ("penalty k = 1e4 N/m", "penalty", 1e4),
    ("penalty k = 1e5 N/m", "penalty", 1e5),
    ("penalty k = 1e6 N/m", "penalty", 1e6),
    ("reduced coordinates", "reduced", 0.0),
]


def stable(make: Callable[[], Run]) -> float:
    """Largest dt = 0.1 · 2^(-j/2) for which 2 s run without error and keep the drift
    below 0.5 m (half the rod length or radius; an unstable run grows without bound)."""
    for j in range(40):
        dt = 0.1 * 0.5 ** (j / 2)
        run = make()
        try:
            run.step(dt, round(2.0 / dt))
            drift = run.drift()
        except Exception:
            continue
        if np.isfinite(drift) and drift < 0.5 and np.isfinite(run.positions()).all():
            return dt
    return float("nan")


def measure(make: Callable[[], Run], reference: np.ndarray, repeat: int) -> dict[str, object]:
    run = make()
    e0 = run.energy()
    samples = round(T / DT) // 10
    times, drift, energy = np.arange(1, samples + 1) * 10 * DT, [], []
    error = float("nan")
    for s in range(samples):
        run.step(DT, 10)
        drift.append(run.drift())
        energy.append(abs(run.energy() - e0))
        if (s + 1) * 10 == round(T_ERR / DT):
            error = float(np.abs(run.positions() - reference).max())
    cost = float("inf")
    for _ in range(repeat):  # best of several against noise from other work on the machine
        timed = make()
        start = time.perf_counter()
        timed.step(DT, round(T / DT))
        cost = min(cost, (time.perf_counter() - start) / round(T / DT))
    return {
        "drift": max(drift),
        "energy": max(energy),
        "error": error,
        "cost_us": 1e6 * cost,
        "stable_dt": stable(make),
        "series": (times, np.array(drift), np.array(energy)),
    }


def main() -> None:
    parser = argparse.ArgumentParser()
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--quick", action="store_true", help="time once, write nothing")
    mode.add_argument("--write", action="store_true", help="update bench/RESULTS.md")
    parser.add_argument(
        "--figure",
        default=str(Path(__file__).parents[1] / "docs" / "images" / "constraint_formulations.png"),
    )
    args = parser.parse_args()
    problems = {"bead on a circle": bead, "double pendulum": double_pendulum}
    lines = [
        "| problem | formulation | max drift (m) | max energy error (J) "
        "| position error at 2 s (m) | µs per step | largest stable dt (s) |",
        "|---|---|---:|---:|---:|---:|---:|",
    ]
    results: dict[str, dict[str, dict[str, object]]] = {}
    for name, make in problems.items():
        ref = make("reduced")
        ref.step(1e-5, round(T_ERR / 1e-5))
        reference = ref.positions()
        results[name] = {}
        for label, kind, k in FORMULATIONS:
            r = measure(
                lambda make=make, kind=kind, k=k: make(kind, k), reference, 1 if args.quick else 3
            )
            results[name][label] = r
            lines.append(
                f"| {name} | {label} | {r['drift']:.1e} | {r['energy']:.1e} | {r['error']:.1e} "
                f"| {r['cost_us']:.1f} | {r['stable_dt']:.1e} |"
            )
            print(lines[-1], flush=True)
    table = "\n".join(lines)
    print()
    print(table)
    if not args.quick:
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

    fig, axes = plt.subplots(2, 2, figsize=(12, 8), sharex=True)
    for col, (name, by_label) in enumerate(results.items()):
        for label, r in by_label.items():
            t, drift, energy = r["series"]  # type: ignore[misc]
            if label != "reduced coordinates":
                axes[0, col].semilogy(t, np.maximum(drift, 1e-17), label=label)
            axes[1, col].semilogy(t, np.maximum(energy, 1e-17), label=label)
        axes[0, col].set_title(f"{name}: drift (RK4, dt = 1 ms)")
        axes[0, col].set_ylabel("|C| (m)")
        axes[1, col].set_title(f"{name}: energy error")
        axes[1, col].set_ylabel("|E - E₀| (J)")
        axes[1, col].set_xlabel("time (s)")
    axes[1, 0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    print(f"figure: {path}")


if __name__ == "__main__":
    main()
