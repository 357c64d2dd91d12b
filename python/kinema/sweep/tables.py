"""A sweep's table as an ``xarray.Dataset`` with the parameters as coordinates."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np


def to_xarray(table: Any, dims: Sequence[str] | None = None) -> Any:
    """The table of :func:`sweep` (or :func:`trade`) as an ``xarray.Dataset``.

    ``dims``: the parameter columns (default: ``table.attrs["params"]``, set by
    :func:`sweep`). When the design is a full grid of them (as made by :func:`grid`: every
    combination once), each becomes a dimension whose coordinate is its values in the order
    they first appear, and every output is an array over those dimensions — plus
    ``NAME_dim0, NAME_dim1...`` for an array output (every task's of one shape). Otherwise
    (a Latin hypercube, a list of dicts) the dimension is ``task`` and the parameters are
    coordinates along it. Numbers of failed tasks are NaN; ``status``, ``error`` and
    ``seconds`` are variables like the outputs. Needs ``xarray`` (the ``sweep`` extra).
    """
    import pandas as pd
    import xarray as xr

    if not isinstance(table, pd.DataFrame):
        raise ValueError(f"table: expected the DataFrame of a sweep, got {type(table).__name__}")
    names = list(table.attrs.get("params", []) if dims is None else dims)
    if not names or not all(isinstance(n, str) and n in table.columns for n in names):
        raise ValueError("dims: expected the names of the table's parameter columns")
    codes, levels = [], []
    for name in names:
        c, values = pd.factorize(table[name], sort=False)
        codes.append(c)
        levels.append(np.asarray(values))
    if math.prod(len(v) for v in levels) == len(table) and len(
        set(zip(*codes, strict=True))
    ) == len(table):
        shape = tuple(len(v) for v in levels)
        index = tuple(codes)
        coords: dict[str, Any] = dict(zip(names, levels, strict=True))
        axes = names
    else:
        shape, index = (len(table),), (np.arange(len(table)),)
        coords = {n: ("task", table[n].to_numpy()) for n in names}
        axes = ["task"]
    variables = {}
    for column in table.columns:
        if column in names:
            continue
        values = list(table[column])
        arrays = [v for v in values if isinstance(v, np.ndarray)]
        if arrays:
            inner = arrays[0].shape
            if any(a.shape != inner for a in arrays):
                raise ValueError(f"table: the arrays of {column!r} differ in shape")
            data = np.full(shape + inner, np.nan)
            for i, v in enumerate(values):
                if isinstance(v, np.ndarray):
                    data[tuple(ix[i] for ix in index)] = v
            extra = [f"{column}_dim{d}" for d in range(len(inner))]
            variables[column] = (axes + extra, data)
        else:
            column_values = table[column].to_numpy()
            data = np.empty(shape, dtype=column_values.dtype)  # one cell per row: all filled
            data[index] = column_values
            variables[column] = (axes, data)
    return xr.Dataset(variables, coords=coords, attrs={"params": names})
