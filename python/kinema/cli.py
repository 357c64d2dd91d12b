"""The ``kinema`` command line: ``kinema demo [NAME]``, ``kinema info``.

Each demo is a module ``kinema.demos.<name>`` with a function
``run(out_dir: pathlib.Path, quick: bool) -> dict[str, object]`` that writes its pictures into
``out_dir`` and returns the numbers worth printing.
"""

from __future__ import annotations

import argparse
import importlib
import os
import platform
import sys
import time
from pathlib import Path

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

    print(f"kinema {kinema.__version__}")
    print(f"python {platform.python_version()} on {platform.machine()} {platform.system()}")
    print(f"numpy {numpy.__version__}")
    print(f"cpu threads available: {os.cpu_count()}, used by kinema: {kinema.num_threads()}")
    print(f"demos: {', '.join(DEMOS)}")


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``kinema`` command (also ``python -m kinema``)."""
    parser = argparse.ArgumentParser(prog="kinema", description="Physically based animation.")
    sub = parser.add_subparsers(dest="command", required=True)
    demo = sub.add_parser("demo", help="run a demo: write pictures and print numbers")
    demo.add_argument("name", nargs="?", choices=sorted(DEMOS), help="one demo (default: all)")
    demo.add_argument("--out", type=Path, default=Path("kinema-out"), help="output folder")
    demo.add_argument("--quick", action="store_true", help="smaller, faster runs (for tests)")
    sub.add_parser("info", help="versions, threads and available demos")
    args = parser.parse_args(argv)

    if args.command == "info":
        _info()
        return 0
    args.out.mkdir(parents=True, exist_ok=True)
    for name in [args.name] if args.name else list(DEMOS):
        _run_demo(name, args.out, args.quick)
    print(f"pictures written to {args.out.resolve()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
