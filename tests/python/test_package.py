"""The package itself: submodules load on attribute access (PEP 562), in a fresh interpreter
so that no earlier import hides a missing one."""

from __future__ import annotations

import pkgutil
import subprocess
import sys

import pytest

import kinema

# Every public module in the package folder, found independently of kinema's own list.
SUBMODULES = sorted(
    m.name for m in pkgutil.iter_modules(kinema.__path__) if not m.name.startswith("_")
)


def fresh(code: str) -> str:
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False
    )
    assert done.returncode == 0, done.stderr
    return done.stdout


def test_submodules_load_on_attribute_access_in_a_fresh_interpreter():
    # `mocap` and `ik` are not imported by `import kinema` itself: before PEP 562 loading,
    # `kinema.mocap` raised AttributeError here.
    out = fresh(
        "import sys, kinema\n"
        "print('kinema.mocap' in sys.modules, 'matplotlib' in sys.modules)\n"
        "print(kinema.mocap.read_asf.__module__, kinema.ik.__name__)\n"
        f"print(all(getattr(kinema, n).__name__ == 'kinema.' + n for n in {SUBMODULES!r}))\n"
    )
    assert out.split() == ["False", "False", "kinema.mocap", "kinema.ik", "True"]


def test_dir_lists_the_submodules_and_unknown_names_still_fail():
    listed = dir(kinema)
    assert all(name in listed for name in SUBMODULES)
    assert "Rotation" in listed and "Scene" in listed
    with pytest.raises(AttributeError, match="no attribute 'nonsense'"):
        _ = kinema.nonsense


def test_package_docstring_describes_the_package():
    doc = kinema.__doc__ or ""
    assert "so far" not in doc
    assert all(f"kinema.{name}" in doc for name in SUBMODULES)
