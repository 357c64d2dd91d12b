"""Plotting helpers (matplotlib, imported only when a function is called).

- :func:`stability_regions`: where ``|R(z)| ≤ 1`` in the complex ``z = hλ`` plane;
- :func:`work_precision`: error against cost from :func:`kinema.ode.work_precision`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from kinema import ode

__all__ = ["stability_regions", "work_precision"]


def stability_regions(
    methods: Sequence[str] = (
        "explicit_euler",
        "heun",
        "rk4",
        "implicit_euler",
        "trapezoidal",
        "bdf2",
    ),
    extent: float = 4.0,
    resolution: int = 301,
    ax: Any = None,
) -> Any:
    """Draw the boundary ``|R(z)| = 1`` of each method over ``[-extent, extent]²`` (stable
    side shaded for explicit methods); returns the matplotlib Axes."""
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(6, 6))
    x = np.linspace(-extent, extent, resolution)
    zr, zi = np.meshgrid(x, x)
    z = zr + 1j * zi
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for k, method in enumerate(methods):
        r = np.abs(ode.stability_function(method, z))
        color = colors[k % len(colors)]
        ax.contour(zr, zi, r, levels=[1.0], colors=[color], linewidths=1.5)
        ax.plot([], [], color=color, label=method)
    ax.axhline(0, color="0.6", lw=0.5)
    ax.axvline(0, color="0.6", lw=0.5)
    ax.set_xlabel("Re(hλ)")
    ax.set_ylabel("Im(hλ)")
    ax.set_title("stability boundaries |R(hλ)| = 1")
    ax.set_aspect("equal")
    ax.legend(fontsize=8, loc="upper left")
    return ax


def work_precision(rows: Sequence[ode.WorkPrecisionRow], cost: str = "nfev", ax: Any = None) -> Any:
    """Log-log error against cost (``"nfev"`` or ``"seconds"``) per method; returns the Axes."""
    import matplotlib.pyplot as plt

    if cost not in ("nfev", "seconds"):
        raise ValueError(f"cost: expected 'nfev' or 'seconds', got {cost!r}")
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 5))
    for method in dict.fromkeys(r.method for r in rows):
        sel = [r for r in rows if r.method == method]
        ax.loglog(
            [getattr(r, cost) for r in sel],
            [max(r.error, 1e-17) for r in sel],
            marker="o",
            label=method,
        )
    ax.set_xlabel("f evaluations" if cost == "nfev" else "wall time (s)")
    ax.set_ylabel("error at the final time")
    if rows:
        ax.set_title(f"work-precision: {rows[0].problem}")
    ax.legend(fontsize=8)
    return ax
