"""Accuracy sweeps: error against a reference run and cost, per method and time step, and the
work–precision diagram (Hairer, Nørsett & Wanner, *Solving Ordinary Differential Equations I*,
§II.1: error on one axis, cost on the other, log–log, one line per method)."""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from kinema.sweep.design import RESERVED, grid, integer, value
from kinema.sweep.engine import Build, Run, sweep


def trade(
    build: Build,
    run: Run,
    *,
    reference: Mapping[str, Any],
    dts: Sequence[float],
    methods: Sequence[str],
    cost: str = "seconds",
    repeat: int = 1,
    plot: str | os.PathLike[str] | None = None,
    client: Any = "serial",
    progress: bool = False,
) -> Any:
    """Measure what each method costs for the accuracy it gets: run ``run(build(method=m,
    dt=h))`` for every ``m`` of ``methods`` and ``h`` of ``dts`` (a :func:`sweep` over their
    grid) and once for ``build(**reference)`` (the reference, e.g. ``{"method": "rk4", "dt":
    1e-5}``), and return the sweep's table with two more columns:

    - ``deviation``: the largest absolute difference between any number ``run`` returned and the
      same number of the reference run (in the units of ``run``'s outputs, so return one kind
      of quantity, e.g. positions in m); NaN for a failed (diverged) run;
    - ``cost``: the column named by ``cost``: ``"seconds"`` (default: wall time of ``build``
      plus ``run``, the smallest of ``repeat`` runs of the whole grid, as ``timeit`` does,
      since a busy machine only ever adds time) or a number ``run`` returns, such as a count
      of steps or force evaluations (deterministic; not used for the error).

    With ``plot`` (a file name: ``.png``, ``.svg``, ``.pdf``) the work–precision
    diagram is drawn there: cost against error, log–log, one line per method, failed runs
    left out. ``client`` is as for :func:`sweep`, but defaults to ``"serial"``: wall times
    compare fairly when the runs take turns on one core. The observed order of a method is
    the slope of ``log(deviation)`` against ``log(dt)``.
    """
    import pandas as pd

    if not isinstance(reference, Mapping):
        raise ValueError(
            f"reference: expected a dict of build parameters, got {type(reference).__name__}"
        )
    if not reference or not all(isinstance(k, str) for k in reference):
        raise ValueError("reference: expected a dict of build parameters by name")
    ref_params = {k: value(v, f"reference[{k!r}]") for k, v in reference.items()}
    if not isinstance(methods, Sequence) or isinstance(methods, str) or not methods:
        raise ValueError("methods: expected a non-empty list of method names")
    if not all(isinstance(m, str) for m in methods):
        raise ValueError("methods: expected method names (strings)")
    dts = [float(h) for h in _reals(dts)]
    if not all(np.isfinite(h) and h > 0 for h in dts):
        raise ValueError("dts: expected positive finite time steps")
    if not isinstance(cost, str) or not cost:
        raise ValueError("cost: expected 'seconds' or the name of a number run returns")

    repeat = integer(repeat, "repeat", 1)

    ref = sweep(build, [ref_params], run, client=client, progress=False)
    if ref["status"][0] != "ok":
        raise ValueError(f"reference: the reference run failed ({ref['error'][0]})")
    design = grid(method=list(methods), dt=dts)
    table = sweep(build, design, run, client=client, progress=progress)
    for _ in range(repeat - 1):
        again = sweep(build, design, run, client=client, progress=progress)
        table["seconds"] = np.minimum(table["seconds"], again["seconds"])
    names = [c for c in ref.columns if c not in ref_params and c not in RESERVED and c != cost]
    if cost != "seconds" and cost not in ref.columns:
        raise ValueError("cost: run returned no number of that name")
    if not names:
        raise ValueError("run: returned nothing to compare with the reference but the cost")
    deviations = []
    for i in range(len(table)):
        if table["status"][i] != "ok":
            deviations.append(np.nan)
            continue
        gaps = [np.max(np.abs(_array(table[n][i]) - _array(ref[n][0])), initial=0.0) for n in names]
        deviations.append(float(max(gaps)))
    table["deviation"] = pd.Series(deviations, dtype="float64")
    table["cost"] = table[cost].astype("float64")
    if plot is not None:
        _plot(table, plot, cost)
    return table


def _reals(values: Any) -> list[Any]:
    if isinstance(values, (str, bytes)) or not isinstance(values, (Sequence, np.ndarray)):
        raise ValueError("dts: expected a non-empty list of time steps")
    if len(values) == 0:
        raise ValueError("dts: expected a non-empty list of time steps")
    try:
        return [float(v) for v in values]
    except (TypeError, ValueError):
        raise ValueError("dts: expected numbers") from None


def _array(v: Any) -> np.ndarray:
    return np.asarray(v, dtype=np.float64)


def _plot(table: Any, path: str | os.PathLike[str], cost: str) -> None:
    """The work–precision diagram of ``table`` into ``path`` (no pyplot: no global state)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6, 4.5))
    ax = fig.add_subplot()
    for method in dict.fromkeys(table["method"]):
        rows = table[(table["method"] == method) & (table["status"] == "ok")]
        rows = rows[rows["deviation"] > 0].sort_values("dt")
        ax.plot(rows["deviation"], rows["cost"], "o-", label=method)
    ax.set(xscale="log", yscale="log", xlabel="error: max |output - reference|")
    ax.set_ylabel("wall time (s)" if cost == "seconds" else cost)
    ax.set_title("work–precision")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=100)
