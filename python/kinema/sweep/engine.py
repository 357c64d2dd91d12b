"""The sweep itself: tasks run in batches on Dask distributed or in a plain loop.

Tasks carry parameter dicts (and the two functions), never systems: each worker builds its own,
so a sweep's numbers do not depend on where or in which order its tasks ran. Tiny tasks are
sent in batches sized from the measured time per task, so Dask's cost per submission stays a
few per cent. With a ``checkpoint_dir`` every finished batch is written there at once
(:mod:`kinema.sweep.store`) and a later sweep with the same directory runs only what is
missing. See docs/sweep.md.
"""

from __future__ import annotations

import asyncio
import numbers
import os
import pickle
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from kinema.sweep import store
from kinema.sweep.design import RESERVED, SHAPE, check, integer, key

# A batch of tasks aims at this many seconds of work, so Dask's cost per submitted batch (its
# messages, scheduling and the worker's bookkeeping) stays under a per cent of the work. On a
# loaded machine a batch cost up to 25 ms of worker CPU, and 2 s batches took the workers' CPU
# outside 0.45 ms tasks from 16.5 % to 11.4 %; on a quiet one 0.5 s and 2 s measure the same
# (docs/sweep.md).
_BATCH_SECONDS = 2.0
# Batches kept in flight per worker: enough to hide the round trip. A batch is at most
# _BATCH_SECONDS of work and at most an equal share of what is left among the batches in
# flight, so the last batches (the tail, when workers run out of work) stay short.
_IN_FLIGHT = 2
# But no batch is shorter than this many seconds of work unless that would leave a worker
# without any of what is left: the shares of what is left shrink geometrically, and without a
# floor the tail of 10,000 tasks of 0.4 ms was cut into 30 batches, of which 20 under 0.1 s,
# each paying the batch's cost.
_TAIL_SECONDS = 0.1
_META = ("status", "error", "seconds")
_INT64 = (-(2**63), 2**63)  # the Python ints an int64 column holds

Build = Callable[..., Any]
Run = Callable[[Any], Mapping[str, Any]]


# ---------------------------------------------------------------- one batch, on a worker


def _run_batch(
    build: Build,
    run: Run,
    tasks: list[tuple[str, dict[str, Any]]],
    single_thread: bool,
    directory: str | None,
) -> list[dict[str, Any]]:
    """Run ``tasks`` (key, parameters) one after the other and return one row per task. An
    exception raised by ``build`` or ``run`` makes that task's row ``failed`` with the error's
    text; the batch goes on. With a checkpoint ``directory``, a task that finished in an
    earlier attempt of this batch is read back, not run; one that saved a checkpoint restarts
    from it; each finished task is recorded there at once."""
    if single_thread:
        import kinema

        if kinema.num_threads() != 1:  # the worker processes are the parallelism
            kinema.set_num_threads(1)
    rows = []
    for k, p in tasks:
        task = None if directory is None else store.Task(directory, k)
        earlier = None if task is None else store.finished(task)
        if earlier is not None:
            rows.append(earlier)
            continue
        start = time.perf_counter()
        token = store.current.set(task)
        try:
            if task is not None and task.scene.exists():
                from kinema.scene import Scene

                system = Scene.load(task.scene)
            else:
                system = build(**p)
            row = _outputs(run(system), {"status": "ok", "error": None})
        except Exception as e:
            row = {"status": "failed", "error": f"{type(e).__name__}: {e}"}
        finally:
            store.current.reset(token)
        row["seconds"] = time.perf_counter() - start
        row["_key"] = k
        if task is not None:
            store.finish(task, row)
        rows.append(row)
    return rows


def _run_packed(
    build: Build,
    run: Run,
    tasks: list[tuple[str, dict[str, Any]]],
    directory: str | None,
) -> bytes:
    """:func:`_run_batch` on a Dask worker, its rows returned pickled as one ``bytes``. Dask
    sends a result's bytes as they are, but serialises a list of rows one row at a time on the
    worker's event loop: 16 µs of CPU a row against 0.2 µs as bytes (900 rows through Dask's
    ``dumps``, measured in one process, docs/sweep.md) — a few per cent of a tiny task."""
    return pickle.dumps(_run_batch(build, run, tasks, True, directory), pickle.HIGHEST_PROTOCOL)


def _outputs(out: Any, row: dict[str, Any]) -> dict[str, Any]:
    """Add what ``run`` returned to ``row`` as columns and return ``row``: numbers stay scalars,
    arrays are stored flat (float64, int64 or bool) with their shape in a hidden column,
    restored by :func:`store.restore`."""
    if type(out) is not dict and not isinstance(out, Mapping):  # a dict skips the ABC's check
        raise TypeError(f"run: must return a dict of numbers or arrays, got {type(out).__name__}")
    for name, value in out.items():
        if not isinstance(name, str) or name in RESERVED or name.startswith(SHAPE):
            raise TypeError(f"run: result names must be strings other than {sorted(RESERVED)}")
        kind = type(value)
        if kind is float or kind is bool or (kind is int and _INT64[0] <= value < _INT64[1]):
            row[name] = value  # what the numpy path gives for these, at a tenth of its cost
            continue
        a = np.asarray(value)
        if a.dtype.kind not in "biuf":
            raise TypeError(f"run: result {name!r} must be numbers, got dtype {a.dtype}")
        a = a.astype(np.bool_ if a.dtype.kind == "b" else np.result_type(a.dtype, np.int64))
        if a.ndim == 0:
            row[name] = a.item()
        else:
            row[name] = a.ravel()
            row[SHAPE + name] = np.array(a.shape, dtype=np.int64)
    return row


# ---------------------------------------------------------------- the local cluster

# Dask's background work on each worker, slowed for the workers kinema starts itself. With
# Dask's defaults an idle worker's event loop takes 2-4 % of a core, and 8 % while a task
# holds the GIL (measured, docs/sweep.md); with these, 0.3 % and under 2 %. They cost only
# resolution: no profile in the dashboard, its CPU and memory plots every 2 s, a blocked
# event loop noticed after 0.5 s, and the memory limit checked every second.
QUIET_WORKERS = {
    "distributed.worker.profile.enabled": False,  # a stack sample every 10 ms
    "distributed.admin.tick.interval": "500ms",  # the event loop's watchdog, 20 ms
    "distributed.admin.system-monitor.interval": "2s",  # the dashboard's CPU, memory, I/O: 500 ms
    "distributed.worker.memory.monitor-interval": "1s",  # the memory limit's check, 100 ms
}


def local_client(n_workers: int | None = None) -> Any:
    """A ``dask.distributed.Client`` on a new ``LocalCluster`` of ``n_workers`` worker
    processes (default: one per core) of one thread each, with kinema's own thread pool set
    to one thread in every worker (``KINEMA_NUM_THREADS=1``) and Dask's background monitors
    slowed (:data:`QUIET_WORKERS`). What :func:`sweep` starts when given no client; start it
    yourself to run many sweeps on one cluster. ``client.close()`` stops the cluster too
    (or use it as a context manager)."""
    from dask.distributed import Client

    n = (os.cpu_count() or 1) if n_workers is None else integer(n_workers, "n_workers", 1)
    return Client(
        n_workers=n,
        threads_per_worker=1,
        processes=True,
        dashboard_address=":0",
        env={"KINEMA_NUM_THREADS": "1"},
        config=QUIET_WORKERS,
    )


# ---------------------------------------------------------------- the sweep


def sweep(
    build: Build,
    params: Sequence[Mapping[str, Any]],
    run: Run,
    *,
    client: Any = None,
    checkpoint_dir: str | os.PathLike[str] | None = None,
    retries: int = 2,
    progress: bool = True,
) -> Any:
    """Run ``run(build(**p))`` for every parameter set ``p`` of ``params`` and return a pandas
    ``DataFrame`` with one row per ``p``, in the design's order: the parameters, then one column
    per name ``run`` returned (a number, or a numpy array with its shape), then ``status``
    (``"ok"`` or ``"failed"``), ``error`` (``"ExceptionType: message"`` of a failed task, else
    ``None``) and ``seconds`` (wall time of ``build`` plus ``run`` on its worker). The
    parameters' names are in ``table.attrs["params"]`` (for :func:`to_xarray`).

    ``client``: ``None`` starts a Dask ``LocalCluster`` of one single-threaded worker process per
    core for this call (and stops it after); a ``dask.distributed.Client`` uses its cluster (a
    ``LocalCluster``, dask-jobqueue on Slurm/PBS, Kubernetes...); ``"serial"`` runs every task in
    this process, in order, with no Dask. On Dask workers kinema's own thread pool is set to one
    thread (the workers are the parallelism). Tiny tasks are sent in batches sized from the
    measured time per task (about two seconds of work per batch, at most an equal share of
    what is left among the batches in flight, at least 0.1 s while every worker still gets
    some); the numbers never depend on batching or order.

    ``checkpoint_dir``: a directory (made if missing) where each finished batch is written as a
    Parquet file at once; tasks whose result is already there (``ok`` or ``failed``) are not
    run again, so a crashed or interrupted sweep resumes where it stopped. Workers record each
    finished task there too, and save the checkpoints of :func:`checkpoint`, so a batch whose
    worker was lost neither runs its finished tasks again nor restarts its running task from
    zero (for that the workers must see the directory: a local cluster, or a shared file
    system). Without it, results live only in memory and a lost batch runs again in full.

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
    retries = integer(retries, "retries", 0)
    if not isinstance(progress, bool):
        raise ValueError(f"progress: expected a bool, got {type(progress).__name__}")
    if not (client is None or client == "serial" or hasattr(client, "submit")):
        raise ValueError("client: expected None, 'serial' or a dask.distributed.Client")
    design = check(params)
    keys = [key(p) for p in design]
    directory = None if checkpoint_dir is None else Path(checkpoint_dir).resolve()
    if directory is not None:
        if directory.exists() and not directory.is_dir():
            raise ValueError("checkpoint_dir: expected a directory, got an existing file")
        directory.mkdir(parents=True, exist_ok=True)
    done = {} if directory is None else store.load(directory)
    done = {k: done[k] for k in keys if k in done}
    todo = [(k, p) for k, p in zip(keys, design, strict=True) if k not in done]

    bar = _bar(len(design), len(done), progress)
    failed = [sum(r["status"] == "failed" for r in done.values())]
    bar.set_postfix(failed=failed[0])

    def finished(rows: list[dict[str, Any]], running: int) -> None:
        if directory is not None:
            store.save_part(directory, rows)
            store.forget(directory, (r["_key"] for r in rows))
        done.update((r["_key"], store.restore(r)) for r in rows)
        failed[0] += sum(r["status"] == "failed" for r in rows)
        bar.set_postfix(failed=failed[0], running=running, refresh=False)
        bar.update(len(rows))

    where = None if directory is None else str(directory)
    try:
        if client == "serial":
            for task in todo:
                finished(_run_batch(build, run, [task], False, where), 0)
        elif todo:
            _on_dask(client, build, run, todo, retries, where, finished)
    finally:
        bar.close()

    frame = pd.DataFrame(design)
    rows = [done[k] for k in keys]
    outputs = list(dict.fromkeys(n for r in rows for n in r if n not in RESERVED))
    for name in outputs:
        frame[name] = pd.Series([r.get(name) for r in rows], dtype=_dtype(rows, name))
    for name in _META:
        frame[name] = pd.Series([r.get(name) for r in rows], dtype=object)
    frame["seconds"] = frame["seconds"].astype("float64")
    frame.attrs["params"] = list(design[0])
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
    build: Build,
    run: Run,
    todo: list[tuple[str, dict[str, Any]]],
    retries: int,
    directory: str | None,
    finished: Callable[[list[dict[str, Any]], int], None],
) -> None:
    """Run ``todo`` on Dask: batches sized from the measured time per task, ``_IN_FLIGHT`` per
    worker at a time, results handed to ``finished`` as they arrive."""
    from dask.distributed import as_completed

    own = None
    if client is None:
        own = client = local_client()
    try:
        workers = max(1, sum(client.nthreads().values()))
        queue = list(reversed(todo))  # pop() takes the next task
        timing = [0.0, 0]  # seconds and tasks measured so far
        tries: dict[Any, tuple[list[tuple[str, dict[str, Any]]], int]] = {}
        pending = as_completed()

        def submit(batch: list[tuple[str, dict[str, Any]]], attempt: int) -> None:
            future = client.submit(_run_packed, build, run, batch, directory, pure=False)
            tries[future] = (batch, attempt)
            pending.add(future)

        def next_batch() -> list[tuple[str, dict[str, Any]]]:
            per_task = max(timing[0] / timing[1], 1e-6) if timing[1] else _BATCH_SECONDS
            share = -(-len(queue) // (_IN_FLIGHT * workers))  # ceil: every slot gets some
            tail = min(int(_TAIL_SECONDS / per_task), -(-len(queue) // workers))
            size = max(1, min(int(_BATCH_SECONDS / per_task), max(share, tail)))
            return [queue.pop() for _ in range(min(size, len(queue)))]

        for _ in range(_IN_FLIGHT * workers):
            if queue:
                submit([queue.pop()], 0)  # one task each until the time per task is known
        for future in pending:
            batch, attempt = tries.pop(future)
            if future.status == "finished":
                rows = pickle.loads(future.result())
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
            own.close()  # and its cluster, which the client started
