"""Cloth self-collision: its cost against the cloth solve itself (issue #21: at most 1x at 64²).

A vertical n x n sheet of 1 m, its lower edge 2 cm above a plane, with a slight wave so that it
buckles into folds as it lands (the scene of tests/cloth_self_collision.rs), stepped by implicit
Euler at dt = 1/100 s with the default material and solver settings (PCG, tol 1e-6) and
self-collision at its defaults (thickness a tenth of the mean edge length, 8 impulse passes).
Reports, per phase of the run (falling, landing, folded), the seconds per step spent in the
cloth solve (assembly + linear solve) and in self-collision, their ratio, and self-collision's
counts. One thread, one process.

Run: python bench/bench_cloth_self_collision.py [--n 64] [--steps 150]
"""

from __future__ import annotations

import argparse

import numpy as np

from kinema.demos.cloth import sheet  # the scene of the cloth demo


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--n", type=int, default=64)
    parser.add_argument("--steps", type=int, default=150)
    args = parser.parse_args()
    cloth = sheet(args.n)
    rows = []
    for _ in range(args.steps):
        cloth.step(0.01, max_strain_change=float("inf"))
        s = cloth.stats
        rows.append(
            (
                s["assemble_seconds"] + s["solve_seconds"],
                s["self_collision_seconds"],
                s["proximities"],
                s["ccd_iterations"],
                s["impact_zones"],
            )
        )
    a = np.array(rows)
    print(f"{args.n}² sheet, thickness {cloth.thickness * 1e3:.2f} mm, dt 0.01 s")
    print("steps        solve ms  self ms  ratio  proximities  ccd passes  zones")
    third = max(1, args.steps // 3)
    for name, part in (
        ("falling", a[:third]),
        ("landing", a[third : 2 * third]),
        ("folded", a[2 * third :]),
    ):
        solve, self_ = part[:, 0].mean() * 1e3, part[:, 1].mean() * 1e3
        print(
            f"{name:<12} {solve:8.2f} {self_:8.2f} {self_ / solve:6.2f} "
            f"{part[:, 2].mean():12.0f} {part[:, 3].mean():10.2f} {part[:, 4].sum():6.0f}"
        )
    total = a[:, 1].sum() / a[:, 0].sum()
    print(f"whole run: self-collision / solve = {total:.2f}")


if __name__ == "__main__":
    main()
