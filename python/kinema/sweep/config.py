"""``kinema sweep CONFIG.toml``: a sweep described in a TOML file.

The file names the user's own ``build`` and ``run`` functions as ``module:function``, found in a
*code directory* (the config file's folder, or the one given with ``--code``), the design
(``[grid]``, ``[latin_hypercube]`` or ``[[params]]``), the client and the checkpoint directory.
Trust model: like a Makefile, a config runs the code of the module it names, so run only
configs and code you trust; nothing in the file itself is evaluated (no ``eval``), and only a
module whose file lies inside the code directory is accepted (not an installed module of the
same name). See docs/sweep.md.
"""

from __future__ import annotations

import importlib
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from kinema.sweep.design import check, grid, integer, latin_hypercube

_SWEEP_KEYS = {"build", "run", "client", "checkpoint_dir", "retries"}
_DESIGNS = ("grid", "latin_hypercube", "params")


@dataclass
class Config:
    """A parsed config: the functions, the design and the options of :func:`sweep`."""

    build: Any
    run: Any
    params: list[dict[str, Any]]
    client: str  # "local", "serial" or a scheduler address
    checkpoint_dir: Path | None
    retries: int


def load(path: Path, code: Path | None = None) -> Config:
    """Read the config at ``path``; import its functions from ``code`` (default: the config's
    folder). Raises ``ValueError`` naming the key at fault, ``OSError`` for an unreadable
    file."""
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib

    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as e:
        raise ValueError(f"{path.name}: not valid TOML ({e})") from None
    except UnicodeDecodeError:
        raise ValueError(f"{path.name}: not a UTF-8 text file") from None
    if set(doc) - {"sweep", *_DESIGNS}:
        raise ValueError(
            f"{path.name}: an unknown table; expected [sweep] and one of [grid], "
            "[latin_hypercube], [[params]]"
        )
    table = doc.get("sweep")
    if not isinstance(table, dict):
        raise ValueError(f"{path.name}: expected a [sweep] table with build and run")
    if set(table) - _SWEEP_KEYS:
        raise ValueError(f"sweep: an unknown key; expected some of {sorted(_SWEEP_KEYS)}")
    folder = path.resolve().parent
    code = folder if code is None else code.resolve()
    if not code.is_dir():
        raise ValueError("code: expected a directory")
    client = table.get("client", "local")
    if not isinstance(client, str) or not (client in ("local", "serial") or "://" in client):
        raise ValueError(
            "sweep.client: expected 'local', 'serial' or a scheduler address tcp://..."
        )
    where = table.get("checkpoint_dir")
    if where is not None and (not isinstance(where, str) or not where):
        raise ValueError("sweep.checkpoint_dir: expected a directory name")
    params = _design(doc)
    retries = integer(table.get("retries", 2), "sweep.retries", 0)
    return Config(  # the user's code is imported last, once the file is known to be good
        build=function(table.get("build"), code, "sweep.build"),
        run=function(table.get("run"), code, "sweep.run"),
        params=params,
        client=client,
        checkpoint_dir=None if where is None else folder / where,
        retries=retries,
    )


def function(spec: Any, code: Path, name: str) -> Any:
    """The function ``module:function`` of a module file inside ``code``, imported with
    ``code`` first on ``sys.path``; ``name`` is the config key, for errors."""
    if not isinstance(spec, str) or spec.count(":") != 1:
        raise ValueError(f"{name}: expected 'module:function'")
    module_name, attr = spec.split(":")
    if not all(part.isidentifier() for part in module_name.split(".")) or not attr.isidentifier():
        raise ValueError(f"{name}: expected 'module:function' with Python identifiers")
    if str(code) not in sys.path:
        sys.path.insert(0, str(code))
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError:
        raise ValueError(f"{name}: no such module in the code directory") from None
    file = getattr(module, "__file__", None)
    if file is None or not Path(file).resolve().is_relative_to(code):
        raise ValueError(f"{name}: the module is not a file inside the code directory")
    fn = getattr(module, attr, None)
    if not callable(fn):
        raise ValueError(f"{name}: the module has no function of that name")
    return fn


def _design(doc: dict[str, Any]) -> list[dict[str, Any]]:
    given = [d for d in _DESIGNS if d in doc]
    if len(given) != 1:
        raise ValueError("design: expected exactly one of [grid], [latin_hypercube], [[params]]")
    kind = given[0]
    spec = doc[kind]
    if kind == "grid":
        if not isinstance(spec, dict):
            raise ValueError("grid: expected a table of name = [values]")
        return grid(**spec)
    if kind == "latin_hypercube":
        if not isinstance(spec, dict):
            raise ValueError(
                "latin_hypercube: expected a table with n, seed and name = [low, high]"
            )
        ranges = {k: v for k, v in spec.items() if k not in ("n", "seed")}
        return latin_hypercube(spec.get("n"), seed=spec.get("seed"), **ranges)  # type: ignore[arg-type]
    return check(spec, "params")


def main(config: Path, code: Path | None, progress: bool) -> int:
    """Run a config; print the table. Exit status 0 when every task ran, 1 when any failed."""
    from kinema.sweep.engine import sweep

    cfg = load(config, code)
    client: Any = {"local": None, "serial": "serial"}.get(cfg.client)
    own = None
    if client is None and cfg.client != "local":
        import cloudpickle
        from dask.distributed import Client

        for fn in (cfg.build, cfg.run):  # the workers need not see the code directory
            cloudpickle.register_pickle_by_value(sys.modules[fn.__module__])
        own = client = Client(cfg.client)
    try:
        table = sweep(
            cfg.build,
            cfg.params,
            cfg.run,
            client=client,
            checkpoint_dir=cfg.checkpoint_dir,
            retries=cfg.retries,
            progress=progress,
        )
    finally:
        if own is not None:
            own.close()
    scalars = [c for c in table.columns if table[c].dtype != object or c in ("status", "error")]
    print(table[scalars].to_string())
    failed = int((table["status"] == "failed").sum())
    print(f"{len(table)} tasks: {len(table) - failed} ok, {failed} failed")
    if cfg.checkpoint_dir is not None:
        print(f"results in {cfg.checkpoint_dir}")
    return 1 if failed else 0
