"""The ``kinema`` command line.

- ``kinema demo``: the showcase (one scene with cloth, particles, rigid bodies and a
  motion-captured walk); ``kinema demo NAME`` one demo; ``kinema demo all`` every demo.
- ``kinema run SCENE.toml``: run a scene file (see :mod:`kinema.scenefile`). Outputs go
  inside ``--out``; the file's inputs must lie in its folder (or a folder given with
  ``--allow-read``). Failures print one line on stderr and exit with 1 (the simulation failed:
  ``kinema.SimulationError``) or 2 (bad input: a scene file, checkpoint or data file that
  cannot be used, or a file that cannot be read or written).
- ``kinema sweep CONFIG.toml``: a parameter sweep described in a TOML file (see
  :mod:`kinema.sweep.config`); prints the result table; exit 1 if a task failed, 2 for a
  config that cannot be used.
- ``kinema bench``: the peer comparisons of ``bench/`` (quick sizes unless ``--full``).
- ``kinema info``: versions, threads, build flags.
- ``kinema view FILE``: play a scene checkpoint's recorded animation, or a ``.glb`` file, in
  the browser (:mod:`kinema.view`, needs the ``viewer`` extra).

Each demo is a module ``kinema.demos.<name>`` with a function
``run(out_dir: pathlib.Path, quick: bool) -> dict[str, object]`` that writes its pictures into
``out_dir`` and returns the numbers worth printing.
"""

from __future__ import annotations

import argparse
import importlib
import os
import platform
import subprocess
import sys
import time
import warnings
from pathlib import Path
from typing import Any

from kinema.demos import DEMOS


def _run_demo(name: str, out_dir: Path, quick: bool) -> None:
    module = importlib.import_module(f"kinema.demos.{name}")
    start = time.perf_counter()
    summary = module.run(out_dir, quick)
    elapsed = time.perf_counter() - start
    print(f"== demo {name} ({elapsed:.2f} s) ==")
    for key, value in summary.items():
        print(f"  {key}: {value}")


def _info() -> None:
    import numpy

    import kinema
    from kinema import _kinema

    print(f"kinema {kinema.__version__}")
    print(f"python {platform.python_version()} on {platform.machine()} {platform.system()}")
    print(f"numpy {numpy.__version__}")
    print(f"cpu threads available: {os.cpu_count()}, used by kinema: {kinema.num_threads()}")
    print("build: " + ", ".join(f"{k} {v}" for k, v in _kinema.build_info()))
    print(f"demos: {', '.join(DEMOS)}")


def _run_scene(args: argparse.Namespace) -> int:
    import numpy as np

    from kinema import SimulationError, plot, scenefile
    from kinema.scene import Scene

    scene, output = scenefile.load(args.scene, read_dirs=args.allow_read)
    if args.resume is not None:
        scene = Scene.load(args.resume)
        print(f"resumed from {args.resume} at frame {scene.frame}, t = {scene.time:.4g} s")
    frames = args.frames if args.frames is not None else max(output.frames - scene.frame, 0)
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    paths = {
        name: output.path(out, value)
        for name in ("gif", "png", "obj", "checkpoint")
        if (value := getattr(output, name))
    }
    if args.checkpoint is not None:
        paths["checkpoint"] = args.checkpoint

    def export(s: Scene) -> None:
        s.export_obj(paths["obj"])

    on_frame = export if output.obj else None
    start = time.perf_counter()
    steps0 = scene.frame * scene.substeps
    try:
        if output.gif:
            plot.render(scene, paths["gif"], frames, progress=args.progress, on_frame=on_frame)
        else:
            scene.run(frames=frames, progress=args.progress, on_frame=on_frame)
    except SimulationError as e:
        print(
            f"kinema run: {args.scene}: the simulation failed in frame {scene.frame + 1} "
            f"(t = {scene.time:.4g} s): {_line(e)}",
            file=sys.stderr,
        )
        return 1
    seconds = time.perf_counter() - start
    written = []
    if output.png:
        ax = plot.scene(scene)
        ax.figure.savefig(paths["png"], dpi=100)
        written.append(output.png)
    if output.record:
        np.savez(out / "records.npz", **scene.records)  # type: ignore[arg-type]
        written.append("records.npz")
    if "checkpoint" in paths:
        scene.save(paths["checkpoint"])
        written.append(str(args.checkpoint or output.checkpoint))
    if output.gif:
        written.append(output.gif)
    if output.obj:
        written.append(f"{output.obj}/*.obj")
    steps = scene.frame * scene.substeps - steps0
    state = "interrupted (Ctrl-C) at" if scene.interrupted else "ran to"
    print(f"{scene!r}")
    print(f"{state} frame {scene.frame}, t = {scene.time:.4g} s: {steps} steps in {seconds:.2f} s")
    for key, value in scene.diagnostics().items():
        print(f"  {key}: {value:.6g}")
    if written:
        print(f"wrote {', '.join(written)} in {out.resolve()}")
    return 0


def _bench(args: argparse.Namespace) -> int:
    folder = args.dir or Path(__file__).resolve().parents[2] / "bench"
    scripts = sorted(folder.glob("bench_*.py")) if folder.is_dir() else []
    if not scripts:
        print(
            f"no benchmarks in {folder}: they live in bench/ of the source repository; "
            "pass --dir PATH/TO/bench",
            file=sys.stderr,
        )
        return 2
    names = {p.stem.removeprefix("bench_"): p for p in scripts}
    unknown = [n for n in args.names if n not in names]
    if unknown:
        print(f"unknown benchmarks {unknown}; choose from {sorted(names)}", file=sys.stderr)
        return 2
    failed = 0
    for name in args.names or sorted(names):
        print(f"== bench {name} ==", flush=True)
        cmd = [sys.executable, str(names[name])] + ([] if args.full else ["--quick"])
        failed += subprocess.run(cmd).returncode != 0
    return 1 if failed else 0


def _line(e: BaseException) -> str:
    """An error as one line: its message (for a file that cannot be opened, the reason and
    the file name only), newlines folded."""
    text = f"{e.strerror}: {e.filename}" if isinstance(e, OSError) and e.strerror else str(e)
    return " ".join(text.split())


def _show_warning(
    message: Warning | str, category: type[Warning], *args: Any, **kwargs: Any
) -> None:
    """Warnings of ``kinema run`` as one line each on stderr, without source lines."""
    print(f"kinema run: {category.__name__}: {_line(Exception(message))}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``kinema`` command (also ``python -m kinema``)."""
    parser = argparse.ArgumentParser(prog="kinema", description="Physically based animation.")
    sub = parser.add_subparsers(dest="command", required=True)
    demo = sub.add_parser("demo", help="run a demo: write pictures and print numbers")
    demo.add_argument(
        "name",
        nargs="?",
        default="showcase",
        choices=["all", *sorted(DEMOS)],
        help="one demo (default: the showcase; 'all' runs every demo)",
    )
    demo.add_argument("--out", type=Path, default=Path("kinema-out"), help="output folder")
    demo.add_argument("--quick", action="store_true", help="smaller, faster runs (for tests)")
    run = sub.add_parser("run", help="run a scene described in a TOML file")
    run.add_argument("scene", type=Path, help="the scene file (see kinema.scenefile)")
    run.add_argument("--out", type=Path, default=Path("kinema-out"), help="output folder")
    run.add_argument("--frames", type=int, help="frames to run (default: the file's)")
    run.add_argument("--resume", type=Path, help="continue from this checkpoint")
    run.add_argument("--checkpoint", type=Path, help="write the final checkpoint here (any path)")
    run.add_argument(
        "--allow-read",
        type=Path,
        action="append",
        default=[],
        metavar="DIR",
        help="a folder the scene file may read from besides its own (repeatable)",
    )
    run.add_argument("--no-progress", dest="progress", action="store_false", help="no progress bar")
    sw = sub.add_parser("sweep", help="run a parameter sweep described in a TOML file")
    sw.add_argument("config", type=Path, help="the sweep file (see docs/sweep.md)")
    sw.add_argument(
        "--code", type=Path, help="the folder of the build/run module (default: the file's)"
    )
    sw.add_argument("--no-progress", dest="progress", action="store_false", help="no progress bar")
    bench = sub.add_parser("bench", help="compare kinema with its peers (bench/*.py)")
    bench.add_argument("names", nargs="*", help="benchmarks to run (default: all)")
    bench.add_argument("--full", action="store_true", help="full sizes (default: quick)")
    bench.add_argument("--dir", type=Path, help="the bench/ folder of a source checkout")
    sub.add_parser("info", help="versions, threads, build flags and available demos")
    vw = sub.add_parser("view", help="play a recorded animation or a .glb file in a browser")
    vw.add_argument(
        "checkpoint", type=Path, help='a Scene.save file that recorded "animation", or a .glb file'
    )
    vw.add_argument("--port", type=int, default=8080, help="the port to serve on")
    args = parser.parse_args(argv)

    if args.command == "info":
        _info()
        return 0
    if args.command == "run":
        try:
            with warnings.catch_warnings():
                warnings.showwarning = _show_warning
                return _run_scene(args)
        except (ValueError, OSError) as e:
            print(f"kinema run: {_line(e)}", file=sys.stderr)
            return 2
    if args.command == "sweep":
        from kinema.sweep import config

        try:
            return config.main(args.config, args.code, args.progress)
        except (ValueError, OSError) as e:
            print(f"kinema sweep: {_line(e)}", file=sys.stderr)
            return 2
    if args.command == "bench":
        return _bench(args)
    if args.command == "view":
        from kinema.view import view

        try:
            view(args.checkpoint, port=args.port)
        except (ValueError, OSError, ImportError) as e:
            print(f"kinema view: {_line(e)}", file=sys.stderr)
            return 2
        return 0
    args.out.mkdir(parents=True, exist_ok=True)
    for name in list(DEMOS) if args.name == "all" else [args.name]:
        _run_demo(name, args.out, args.quick)
    print(f"pictures written to {args.out.resolve()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
