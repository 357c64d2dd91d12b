"""A sweep's checkpoint directory: finished results, finished tasks, and task checkpoints.

``DIR/part-*.parquet``: finished rows, one file per batch, written by the process that called
:func:`kinema.sweep.sweep` (so the workers need no shared file system for results).
``DIR/tasks/KEY.parquet``: the row of one task, written by the worker the moment the task
finishes and deleted once its batch is in a part file; a batch run again after its worker was
lost reads it instead of running the task again. ``DIR/tasks/KEY.scene``: the last
:func:`checkpoint` of an unfinished task (a :meth:`kinema.Scene.save` file); a task run again
starts from it instead of calling ``build``. Every file is written to a temporary name and
renamed, so a crash never leaves half a file. Task keys are SHA-256 digests of the parameters
(:func:`kinema.sweep.design.key`).
"""

from __future__ import annotations

import contextvars
import math
import os
import time
import uuid
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from kinema.sweep.design import SHAPE, integer

_TASKS = "tasks"


class Task:
    """Where one task's finished row and last scene checkpoint live inside ``directory``."""

    def __init__(self, directory: str | os.PathLike[str], key: str) -> None:
        folder = Path(directory) / _TASKS
        self.row = folder / f"{key}.parquet"
        self.scene = folder / f"{key}.scene"


# The task running in this process (set by the engine around build and run), for checkpoint().
current: contextvars.ContextVar[Task | None] = contextvars.ContextVar(
    "kinema_sweep_task", default=None
)


def checkpoint(scene: Any, every: int = 1) -> bool:
    """Save ``scene`` (a :class:`kinema.Scene`) as the running sweep task's checkpoint when
    ``scene.frame`` is a multiple of ``every``; return whether it saved.

    Call it from ``run`` as the scene advances, e.g.
    ``scene.run(frames=N - scene.frame, on_frame=lambda s: checkpoint(s, every=50))``. If the
    task is lost (its worker killed, say), its next attempt calls ``run`` on the scene loaded
    from the last checkpoint instead of on ``build(**p)``, so ``run`` must advance the scene to
    a fixed end (``N - scene.frame`` frames), not by a fixed amount. A scene loaded from a
    checkpoint continues bit for bit (:meth:`kinema.Scene.load`), so the result is the same
    as a run that was never interrupted. Outside a sweep with a ``checkpoint_dir`` it does
    nothing and returns ``False``."""
    from kinema.scene import Scene

    if not isinstance(scene, Scene):
        raise ValueError(f"scene: expected a kinema.Scene, got {type(scene).__name__}")
    every = integer(every, "every", 1)
    task = current.get()
    if task is None or scene.frame % every != 0:
        return False
    task.scene.parent.mkdir(parents=True, exist_ok=True)
    scene.save(task.scene)
    return True


def finish(task: Task, row: dict[str, Any]) -> None:
    """Record a finished task: its row, then drop its scene checkpoint."""
    task.row.parent.mkdir(parents=True, exist_ok=True)
    write(task.row, [row])
    task.scene.unlink(missing_ok=True)


def finished(task: Task) -> dict[str, Any] | None:
    """The row of a task that finished before (its batch lost after it), or ``None``."""
    if not task.row.exists():
        return None
    rows = read(task.row)
    return rows[0] if rows else None


def forget(directory: Path, keys: Iterable[str]) -> None:
    """Delete the task rows of ``keys`` (their batch's part file now holds them)."""
    for key in keys:
        Task(directory, key).row.unlink(missing_ok=True)


def save_part(directory: Path, rows: list[dict[str, Any]]) -> None:
    """Write a batch's finished rows as one new part file."""
    write(directory / f"part-{time.time_ns():020d}-{uuid.uuid4().hex[:8]}.parquet", rows)


def write(path: Path, rows: list[dict[str, Any]]) -> None:
    """``rows`` as a Parquet file at ``path``, atomically (a reader never sees half a file)."""
    import pandas as pd

    tmp = path.parent / f".{path.name}.{uuid.uuid4().hex[:8]}.tmp"
    pd.DataFrame(rows).to_parquet(tmp, index=False)
    os.replace(tmp, path)


def read(path: Path) -> list[dict[str, Any]]:
    """The rows of a Parquet file written by :func:`write`, arrays still flat."""
    import pandas as pd

    try:
        table = pd.read_parquet(path)
    except Exception as e:
        raise ValueError(f"checkpoint_dir: cannot read {path.name} ({type(e).__name__})") from None
    if "_key" not in table.columns or "status" not in table.columns:
        raise ValueError(f"checkpoint_dir: {path.name} is not a kinema sweep result file")
    return table.to_dict("records")  # type: ignore[no-any-return]


def load(directory: Path) -> dict[str, dict[str, Any]]:
    """Every finished row of the part files in ``directory``, by task key (the first file wins
    for a task written twice), arrays reshaped."""
    found: dict[str, dict[str, Any]] = {}
    for path in sorted(directory.glob("part-*.parquet")):
        for row in read(path):
            found.setdefault(row["_key"], restore(row))
    return found


def restore(row: Mapping[Any, Any]) -> dict[str, Any]:
    """A row as the engine made it: arrays given back their shapes, missing outputs dropped."""
    out = {}
    for name, value in row.items():
        if name.startswith(SHAPE):
            continue
        shape = row.get(SHAPE + name)
        if shape is not None and not _missing(shape):
            value = np.asarray(value).reshape(tuple(int(s) for s in shape))
        elif _missing(value):
            continue
        out[name] = value
    return out


def _missing(v: Any) -> bool:
    return v is None or (isinstance(v, float) and math.isnan(v))
