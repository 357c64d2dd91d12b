"""Integrators demo: stability regions of the methods and a work-precision diagram.

Writes ``integrators.png``: the stability boundaries ``|R(hλ)| = 1`` and, for the Kepler
orbit (eccentricity 0.5, one period), the final-state error against the number of
f-evaluations for each method.
"""

from __future__ import annotations

from pathlib import Path

from kinema import ode, plot


def run(out_dir: Path, quick: bool) -> dict[str, object]:
    """Draw the two panels into ``out_dir/integrators.png`` and return key numbers."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    dts = [0.05, 0.02, 0.01] if quick else [0.05, 0.02, 0.01, 0.005, 0.002, 0.001]
    methods = [
        "explicit_euler",
        "symplectic_euler",
        "heun",
        "velocity_verlet",
        "rk4",
        "trapezoidal",
    ]
    rows = ode.work_precision("kepler", methods, dts)
    rows += ode.work_precision(
        "kepler", ["dopri5"], [1e-4, 1e-6, 1e-8] if quick else [1e-4, 1e-6, 1e-8, 1e-10]
    )

    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(13, 5.5))
    plot.stability_regions(ax=ax0, resolution=151 if quick else 401)
    plot.work_precision(rows, ax=ax1)
    fig.tight_layout()
    path = out_dir / "integrators.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)

    summary: dict[str, object] = {"picture": str(path)}
    for method in ["explicit_euler", "heun", "rk4"]:
        summary[f"max stable dt, {method}, λ = -1"] = f"{ode.max_stable_dt(method, [-1.0]):.6f}"
    summary["max stable dt, rk4, λ = ±i"] = f"{ode.max_stable_dt('rk4', [1j, -1j]):.6f}"
    best = {
        m: min(r.error for r in rows if r.method == m)
        for m in dict.fromkeys(r.method for r in rows)
    }
    for m, err in best.items():
        summary[f"Kepler error, {m} (finest)"] = f"{err:.2e}"
    return summary
