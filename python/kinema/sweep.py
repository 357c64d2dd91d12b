"""Parameter sweeps and ensembles: many independent runs, on one machine or a Dask cluster.

A sweep is ``build(**p)`` (make a scene or any system from one parameter set ``p``) followed
by ``run(system)`` (advance it and return a dict of numbers or arrays), for every ``p`` of a
design: :func:`grid` (every combination), :func:`latin_hypercube` (a space-filling random
design, McKay, Beckman & Conover 1979) or any list of dicts. :func:`sweep` runs the design on
Dask distributed (a ``LocalCluster`` of one single-threaded worker process per core by default,
or any cluster a caller connects a ``Client`` to) or in a plain loop (``client="serial"``), and
returns a pandas table with one row per parameter set.

Tasks carry parameter dicts (and the two functions), never systems: each worker builds its own,
so a sweep's numbers do not depend on where or in which order its tasks ran. With a
``results`` directory, every finished batch of tasks is written there at once as a Parquet
file (atomically: a temporary file renamed), and a later sweep with the same directory skips
every task whose result is already there; so a crashed or interrupted (Ctrl-C) sweep resumes
where it stopped. See docs/sweep.md.
"""

from __future__ import annotations

import asyncio
import hashlib
import itertools
import json
import math
import numbers
import os
import time
import uuid
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["grid", "latin_hypercube", "sweep"]

# A batch of tasks aims at this many seconds of work, so Dask's cost per submitted task (a few
# milliseconds of scheduling, messages and, here, writing its Parquet file) stays a few per cent.
_BATCH_SECONDS = 0.5
# Batches kept in flight per worker: enough to hide the round trip. A batch is at most
# _BATCH_SECONDS of work and at most an equal share of what is left among the batches in
# flight, so the last batches (the tail, when workers run out of work) stay short.
_IN_FLIGHT = 2
_SHAPE = "_shape:"  # prefix of the hidden Parquet columns holding array outputs' shapes
_META = ("status", "error", "seconds")


# ---------------------------------------------------------------- designs


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
        items = [_value(v, name) for v in axis]
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
    n = _integer(n, "n", 1)
    seed = _integer(seed, "seed", 0)
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


def _integer(v: Any, name: str, minimum: int) -> int:
    """``v`` as an ``int`` of at least ``minimum``, else a ``ValueError`` naming ``name``."""
    if isinstance(v, bool) or not isinstance(v, numbers.Integral):
        raise ValueError(f"{name}: expected an integer >= {minimum}, got {type(v).__name__}")
    if v < minimum:
        raise ValueError(f"{name}: expected an integer >= {minimum}, got {v}")
    return int(v)


def _value(v: Any, name: str) -> Any:
    """A parameter value as a plain Python scalar (numpy scalars unwrapped)."""
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, (bool, str)) or (isinstance(v, (int, float)) and not isinstance(v, bool)):
        return v
    raise ValueError(f"{name}: values must be numbers, strings or bools, got {type(v).__name__}")


def _design(params: Any) -> list[dict[str, Any]]:
    """Check a design (a list of dicts with the same string keys) and copy it with plain
    scalar values."""
    if isinstance(params, Mapping) or not isinstance(params, Sequence) or isinstance(params, str):
        raise ValueError(
            "params: expected a list of dicts (e.g. from kinema.sweep.grid), "
            f"got {type(params).__name__}"
        )
    if not params:
        raise ValueError("params: the design is empty")
    design = []
    for i, p in enumerate(params):
        if not isinstance(p, Mapping) or not p:
            raise ValueError(f"params[{i}]: expected a non-empty dict of parameter values")
        if set(p) != set(params[0]):
            raise ValueError(f"params[{i}]: has other parameter names than params[0]")
        if not all(isinstance(k, str) and k for k in p):
            raise ValueError(f"params[{i}]: parameter names must be non-empty strings")
        if any(k in _META or k.startswith(_SHAPE) or k == "_key" for k in p):
            raise ValueError(f"params[{i}]: {sorted(_META)} and '_key' are reserved names")
        design.append({k: _value(v, f"params[{i}][{k!r}]") for k, v in p.items()})
    keys = [_key(p) for p in design]
    if len(set(keys)) != len(keys):
        raise ValueError("params: a parameter set appears twice (each task needs its own)")
    return design


def _key(p: Mapping[str, Any]) -> str:
    """The identity of a task: SHA-256 of its parameters as canonical JSON (sorted names,
    floats written exactly), so it is the same in every process and every run."""
    text = json.dumps(p, sort_keys=True, allow_nan=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


# ---------------------------------------------------------------- one batch, on a worker


def _run_batch(
    build: Callable[..., Any],
    run: Callable[[Any], Mapping[str, Any]],
    tasks: list[tuple[str, dict[str, Any]]],
    single_thread: bool,
) -> list[dict[str, Any]]:
    """Run ``tasks`` (key, parameters) one after the other and return one row per task. An
    exception raised by ``build`` or ``run`` makes that task's row ``failed`` with the error's
    text; the batch goes on."""
    if single_thread:
        import kinema

        if kinema.num_threads() != 1:  # the worker processes are the parallelism
            kinema.set_num_threads(1)
    rows = []
    for key, p in tasks:
        start = time.perf_counter()
        try:
            out = _outputs(run(build(**p)))
            row: dict[str, Any] = {"status": "ok", "error": None, **out}
        except Exception as e:
            row = {"status": "failed", "error": f"{type(e).__name__}: {e}"}
        row["seconds"] = time.perf_counter() - start
        row["_key"] = key
        rows.append(row)
    return rows


def _outputs(out: Any) -> dict[str, Any]:
    """What ``run`` returned as columns: numbers stay scalars, arrays are stored flat (float64,
    int64 or bool) with their shape in a hidden column, restored by :func:`_load`."""
    if not isinstance(out, Mapping):
        raise TypeError(f"run: must return a dict of numbers or arrays, got {type(out).__name__}")
    row: dict[str, Any] = {}
    for name, value in out.items():
        if not isinstance(name, str) or name in _META or name == "_key" or name.startswith(_SHAPE):
            raise TypeError(f"run: result names must be strings other than {sorted(_META)}")
        a = np.asarray(value)
        if a.dtype.kind not in "biuf":
            raise TypeError(f"run: result {name!r} must be numbers, got dtype {a.dtype}")
        a = a.astype(np.bool_ if a.dtype.kind == "b" else np.result_type(a.dtype, np.int64))
        if a.ndim == 0:
            row[name] = a.item()
        else:
            row[name] = a.ravel()
            row[_SHAPE + name] = np.array(a.shape, dtype=np.int64)
    return row


# ---------------------------------------------------------------- results on disk


def _save(directory: Path, rows: list[dict[str, Any]]) -> None:
    """Write finished rows as one Parquet file, atomically (a reader never sees half a file)."""
    import pandas as pd

    name = f"part-{time.time_ns():020d}-{uuid.uuid4().hex[:8]}.parquet"
    tmp = directory / f".{name}.tmp"
    pd.DataFrame(rows).to_parquet(tmp, index=False)
    os.replace(tmp, directory / name)


def _load(directory: Path) -> dict[str, dict[str, Any]]:
    """Every finished row in ``directory``, by task key (the first file wins for a task written
    twice), arrays reshaped."""
    import pandas as pd

    found: dict[str, dict[str, Any]] = {}
    for path in sorted(directory.glob("part-*.parquet")):
        try:
            table = pd.read_parquet(path)
        except Exception as e:
            raise ValueError(f"results: cannot read {path.name} ({type(e).__name__})") from None
        if "_key" not in table.columns or "status" not in table.columns:
            raise ValueError(f"results: {path.name} is not a kinema sweep result file")
        for row in table.to_dict("records"):
            found.setdefault(row["_key"], _restore(row))
    return found


def _restore(row: Mapping[Any, Any]) -> dict[str, Any]:
    """A row as :func:`_run_batch` made it: arrays given back their shapes, missing outputs
    dropped."""
    out = {}
    for name, value in row.items():
        if name.startswith(_SHAPE):
            continue
        shape = row.get(_SHAPE + name)
        if shape is not None and not _missing(shape):
            value = np.asarray(value).reshape(tuple(int(s) for s in shape))
        elif _missing(value):
            continue
        out[name] = value
    return out


def _missing(v: Any) -> bool:
    return v is None or (isinstance(v, float) and math.isnan(v))


# ---------------------------------------------------------------- the sweep


def sweep(
    build: Callable[..., Any],
    params: Sequence[Mapping[str, Any]],
    run: Callable[[Any], Mapping[str, Any]],
    *,
    client: Any = None,
    results: str | os.PathLike[str] | None = None,
    retries: int = 2,
    progress: bool = True,
) -> Any:
    """Run ``run(build(**p))`` for every parameter set ``p`` of ``params`` and return a pandas
    ``DataFrame`` with one row per ``p``, in the design's order: the parameters, then one column
    per name ``run`` returned (a number, or a numpy array with its shape), then ``status``
    (``"ok"`` or ``"failed"``), ``error`` (``"ExceptionType: message"`` of a failed task, else
    ``None``) and ``seconds`` (wall time of ``build`` plus ``run`` on its worker).

    ``client``: ``None`` starts a Dask ``LocalCluster`` of one single-threaded worker process per
    core for this call (and stops it after); a ``dask.distributed.Client`` uses its cluster (a
    ``LocalCluster``, dask-jobqueue on Slurm/PBS, Kubernetes...); ``"serial"`` runs every task in
    this process, in order, with no Dask. On Dask workers kinema's own thread pool is set to one
    thread (the workers are the parallelism). Tiny tasks are sent in batches sized from the
    measured time per task (about half a second of work per batch, at most an equal share of
    what is left among the batches in flight); the numbers never depend on batching or order.

    ``results``: a directory (made if missing) where each finished batch is written as a
    Parquet file at once; tasks whose result is already there (``ok`` or ``failed``) are not run
    again, so a crashed or interrupted sweep resumes where it stopped. Without it, results live
    only in memory.

    An exception raised by ``build`` or ``run`` (say a diverging step,
    ``kinema.SimulationError``) fails that task only, recorded with its parameters and error; it
    is not retried, since a simulation gives the same error again. ``retries`` is how many
    times a batch is submitted again when Dask could not run it (a worker lost or killed); after
    that its tasks are recorded as failed. ``progress`` shows a tqdm bar (done, failed,
    running). Ctrl-C stops the sweep (``KeyboardInterrupt``) with every finished result kept.
    """
    import pandas as pd

    if not callable(build):
        raise ValueError("build: expected a callable build(**params) -> system")
    if not callable(run):
        raise ValueError("run: expected a callable run(system) -> dict of numbers or arrays")
    retries = _integer(retries, "retries", 0)
    if not isinstance(progress, bool):
        raise ValueError(f"progress: expected a bool, got {type(progress).__name__}")
    if not (client is None or client == "serial" or hasattr(client, "submit")):
        raise ValueError("client: expected None, 'serial' or a dask.distributed.Client")
    design = _design(params)
    keys = [_key(p) for p in design]
    directory = None if results is None else Path(results)
    if directory is not None:
        if directory.exists() and not directory.is_dir():
            raise ValueError("results: expected a directory, got an existing file")
        directory.mkdir(parents=True, exist_ok=True)
    done = {} if directory is None else _load(directory)
    done = {k: done[k] for k in keys if k in done}
    todo = [(k, p) for k, p in zip(keys, design, strict=True) if k not in done]

    bar = _bar(len(design), len(done), progress)
    failed = [sum(r["status"] == "failed" for r in done.values())]
    bar.set_postfix(failed=failed[0])

    def finished(rows: list[dict[str, Any]], running: int) -> None:
        if directory is not None:
            _save(directory, rows)
        done.update((r["_key"], r) for r in rows)
        failed[0] += sum(r["status"] == "failed" for r in rows)
        bar.set_postfix(failed=failed[0], running=running, refresh=False)
        bar.update(len(rows))

    try:
        if client == "serial":
            for task in todo:
                finished(_run_batch(build, run, [task], single_thread=False), 0)
        elif todo:
            _on_dask(client, build, run, todo, retries, finished)
    finally:
        bar.close()

    frame = pd.DataFrame(design)
    rows = [_restore(done[k]) for k in keys]
    outputs = list(dict.fromkeys(n for r in rows for n in r if n not in _META and n != "_key"))
    for name in outputs:
        frame[name] = pd.Series([r.get(name) for r in rows], dtype=_dtype(rows, name))
    for name in _META:
        frame[name] = pd.Series([r.get(name) for r in rows], dtype=object)
    frame["seconds"] = frame["seconds"].astype("float64")
    return frame


def _dtype(rows: list[dict[str, Any]], name: str) -> Any:
    """The column type of output ``name``: ``bool`` or ``int64`` when every task gave one and
    none failed, ``float64`` for numbers (a failed task's value is NaN), else ``object``
    (arrays; a failed task's is ``None``)."""
    values = [r[name] for r in rows if name in r]
    complete = len(values) == len(rows)
    flags = [isinstance(v, (bool, np.bool_)) for v in values]
    if complete and all(flags):
        return "bool"
    if complete and all(
        isinstance(v, numbers.Integral) and not f for v, f in zip(values, flags, strict=True)
    ):
        return "int64"
    numeric = all(isinstance(v, numbers.Real) and not f for v, f in zip(values, flags, strict=True))
    return "float64" if numeric else object


def _lost(future: Any) -> str:
    """Why Dask could not give a batch's result, as ``"ExceptionType: message"``."""
    try:
        future.result()
    except (
        Exception,
        asyncio.CancelledError,
    ) as e:  # a lost worker, a cancelled task, a result that cannot travel
        return f"{type(e).__name__}: {e}"
    return "the batch was lost"


def _bar(total: int, initial: int, enabled: bool) -> Any:
    from tqdm.auto import tqdm

    return tqdm(total=total, initial=initial, unit="task", desc="sweep", disable=not enabled)


def _on_dask(
    client: Any,
    build: Callable[..., Any],
    run: Callable[[Any], Mapping[str, Any]],
    todo: list[tuple[str, dict[str, Any]]],
    retries: int,
    finished: Callable[[list[dict[str, Any]], int], None],
) -> None:
    """Run ``todo`` on Dask: batches sized from the measured time per task, ``_IN_FLIGHT`` per
    worker at a time, results handed to ``finished`` as they arrive."""
    from dask.distributed import Client, LocalCluster, as_completed

    own = None
    if client is None:
        cluster = LocalCluster(
            n_workers=os.cpu_count() or 1,
            threads_per_worker=1,
            processes=True,
            dashboard_address=":0",
            env={"KINEMA_NUM_THREADS": "1"},
        )
        own = client = Client(cluster)
    try:
        workers = max(1, sum(client.nthreads().values()))
        queue = list(reversed(todo))  # pop() takes the next task
        timing = [0.0, 0]  # seconds and tasks measured so far
        tries: dict[Any, tuple[list[tuple[str, dict[str, Any]]], int]] = {}
        pending = as_completed()

        def submit(batch: list[tuple[str, dict[str, Any]]], attempt: int) -> None:
            future = client.submit(_run_batch, build, run, batch, True, pure=False)
            tries[future] = (batch, attempt)
            pending.add(future)

        def next_batch() -> list[tuple[str, dict[str, Any]]]:
            per_task = max(timing[0] / timing[1], 1e-6) if timing[1] else _BATCH_SECONDS
            share = -(-len(queue) // (_IN_FLIGHT * workers))  # ceil: every slot gets some
            size = max(1, min(int(_BATCH_SECONDS / per_task), share))
            return [queue.pop() for _ in range(min(size, len(queue)))]

        for _ in range(_IN_FLIGHT * workers):
            if queue:
                submit([queue.pop()], 0)  # one task each until the time per task is known
        for future in pending:
            batch, attempt = tries.pop(future)
            if future.status == "finished":
                rows = future.result()
                timing[0] += sum(r["seconds"] for r in rows)
                timing[1] += len(rows)
                finished(rows, len(tries))
            elif attempt < retries:
                submit(batch, attempt + 1)
                continue
            else:
                error = _lost(future)
                finished(
                    [{"status": "failed", "error": error, "_key": k} for k, _ in batch], len(tries)
                )
            while queue and len(tries) < _IN_FLIGHT * workers:
                submit(next_batch(), 0)
    except BaseException:
        for future in list(tries):
            future.cancel()
        raise
    finally:
        if own is not None:
            own.close()
            own.cluster.close()
