"""Designs of a sweep: lists of parameter sets, and the identity of a task.

:func:`grid` (every combination), :func:`latin_hypercube` (a space-filling random design after
McKay, Beckman & Conover 1979, *Technometrics* 21(2)) or any list of dicts; :func:`check`
validates a design and :func:`key` names each parameter set (SHA-256 of its canonical JSON).
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import numbers
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

# Names a parameter may not take: the result table's own columns and hidden Parquet columns.
RESERVED = ("status", "error", "seconds", "_key")
SHAPE = "_shape:"  # prefix of the hidden Parquet columns holding array outputs' shapes


def grid(**axes: Iterable[Any]) -> list[dict[str, Any]]:
    """Every combination of the values of the named ``axes``, the first axis varying slowest:
    ``grid(dt=[0.01, 0.02], k=[1, 10])`` is ``[{dt: 0.01, k: 1}, {dt: 0.01, k: 10},
    {dt: 0.02, k: 1}, {dt: 0.02, k: 10}]``. Each axis is a non-empty sequence of numbers,
    strings or bools."""
    if not axes:
        raise ValueError("grid: expected at least one axis, e.g. grid(dt=[0.01, 0.02])")
    values = {}
    for name, axis in axes.items():
        if isinstance(axis, (str, bytes)) or not isinstance(axis, Iterable):
            raise ValueError(f"{name}: expected a sequence of values, got {type(axis).__name__}")
        items = [value(v, name) for v in axis]
        if not items:
            raise ValueError(f"{name}: expected at least one value, got an empty sequence")
        values[name] = items
    return [dict(zip(values, combo, strict=True)) for combo in itertools.product(*values.values())]


def latin_hypercube(n: int, *, seed: int, **ranges: tuple[float, float]) -> list[dict[str, float]]:
    """``n`` parameter sets in the box given by ``ranges`` (``name=(low, high)``, finite,
    ``low < high``), by Latin hypercube sampling (McKay, Beckman & Conover 1979): each range is
    cut into ``n`` equal strata and every stratum of every parameter holds exactly one point,
    uniformly placed inside it; strata are paired across parameters by independent random
    permutations. The same ``seed`` (a non-negative integer) gives the same design."""
    n = integer(n, "n", 1)
    seed = integer(seed, "seed", 0)
    if not ranges:
        raise ValueError(
            "ranges: expected at least one, e.g. latin_hypercube(8, seed=0, k=(1, 10))"
        )
    bounds = {}
    for name, r in ranges.items():
        try:
            low, high = (float(x) for x in r)
        except (TypeError, ValueError):
            raise ValueError(f"{name}: expected a pair (low, high) of numbers") from None
        if not (math.isfinite(low) and math.isfinite(high) and low < high):
            raise ValueError(f"{name}: expected finite low < high, got ({low}, {high})")
        bounds[name] = (low, high)
    rng = np.random.default_rng(seed)
    columns = {}
    for name, (low, high) in bounds.items():
        u = (rng.permutation(n) + rng.random(n)) / n  # one point per stratum
        columns[name] = low + (high - low) * u
    return [{name: float(c[i]) for name, c in columns.items()} for i in range(n)]


def integer(v: Any, name: str, minimum: int) -> int:
    """``v`` as an ``int`` of at least ``minimum``, else a ``ValueError`` naming ``name``."""
    if isinstance(v, bool) or not isinstance(v, numbers.Integral):
        raise ValueError(f"{name}: expected an integer >= {minimum}, got {type(v).__name__}")
    if v < minimum:
        raise ValueError(f"{name}: expected an integer >= {minimum}, got {v}")
    return int(v)


def value(v: Any, name: str) -> Any:
    """A parameter value as a plain Python scalar (numpy scalars unwrapped)."""
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, (bool, str)) or (isinstance(v, (int, float)) and not isinstance(v, bool)):
        return v
    raise ValueError(f"{name}: values must be numbers, strings or bools, got {type(v).__name__}")


def check(params: Any, name: str = "params") -> list[dict[str, Any]]:
    """Check a design (a list of dicts with the same string keys, each set once) and copy it
    with plain scalar values; errors name ``name`` (the argument)."""
    if isinstance(params, Mapping) or not isinstance(params, Sequence) or isinstance(params, str):
        raise ValueError(
            f"{name}: expected a list of dicts (e.g. from kinema.sweep.grid), "
            f"got {type(params).__name__}"
        )
    if not params:
        raise ValueError(f"{name}: the design is empty")
    design = []
    for i, p in enumerate(params):
        if not isinstance(p, Mapping) or not p:
            raise ValueError(f"{name}[{i}]: expected a non-empty dict of parameter values")
        if set(p) != set(params[0]):
            raise ValueError(f"{name}[{i}]: has other parameter names than {name}[0]")
        if not all(isinstance(k, str) and k for k in p):
            raise ValueError(f"{name}[{i}]: parameter names must be non-empty strings")
        if any(k in RESERVED or k.startswith(SHAPE) for k in p):
            raise ValueError(f"{name}[{i}]: {sorted(RESERVED)} are reserved names")
        design.append({k: value(v, f"{name}[{i}][{k!r}]") for k, v in p.items()})
    keys = [key(p) for p in design]
    if len(set(keys)) != len(keys):
        raise ValueError(f"{name}: a parameter set appears twice (each task needs its own)")
    return design


def key(p: Mapping[str, Any]) -> str:
    """The identity of a task: SHA-256 of its parameters as canonical JSON (sorted names,
    floats written exactly), so it is the same in every process and every run."""
    text = json.dumps(p, sort_keys=True, allow_nan=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()
