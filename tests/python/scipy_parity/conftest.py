"""Fixtures and markers scipy's test files expect, and the expected-failure list.

scipy's tests take an ``xp`` fixture (the array namespace); here it is always numpy. The
expected failures are read from the "scipy parity" table of ``docs/rotations.md`` (rows
``| `file::name` | reason |``, ``name`` an fnmatch pattern on the test function's name, or
one parametrised case such as ``test_x[numpy-2]`` exactly) and marked strict, so a test that
starts passing must leave the table.
"""

from __future__ import annotations

import fnmatch
import pathlib
import re
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

DOCS = pathlib.Path(__file__).resolve().parents[3] / "docs" / "rotations.md"
_ROW = re.compile(r"^\|\s*`([\w.]+)::([^`]+)`\s*\|\s*(.+?)\s*\|\s*$")


def known_failures() -> list[tuple[str, str, str]]:
    """``(file, pattern, reason)`` for every row of the parity table in docs/rotations.md."""
    rows = []
    for line in DOCS.read_text(encoding="utf-8").splitlines():
        m = _ROW.match(line)
        if m:
            rows.append((m.group(1), m.group(2), m.group(3)))
    return rows


def pytest_configure(config: pytest.Config) -> None:
    for marker in (
        "array_api_backends",
        "skip_xp_backends",
        "xfail_xp_backends",
        "skip_xp_invalid_arg",
        "thread_unsafe",
        "fail_slow",
        "slow",
    ):
        config.addinivalue_line("markers", f"{marker}: used by scipy's test files")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    rows = known_failures()
    for item in items:
        if "scipy_parity" not in str(item.path):
            continue
        file = item.path.name.removeprefix("test_scipy_")
        file = f"test_{file}"
        for f, pattern, reason in rows:
            name = getattr(item, "originalname", item.name)
            if f == file and (item.name == pattern or fnmatch.fnmatchcase(name, pattern)):
                item.add_marker(pytest.mark.xfail(reason=reason, strict=True))
                break


def _names_numpy(marker: Any) -> bool:
    return "numpy" in marker.args or "numpy" in marker.kwargs.get("backends", ())


@pytest.fixture(params=[pytest.param(np, id="numpy")])
def xp(request: pytest.FixtureRequest) -> Iterator[Any]:
    """numpy, honouring scipy's ``skip_xp_backends`` / ``xfail_xp_backends`` for numpy."""
    for marker in request.node.iter_markers("skip_xp_backends"):
        if _names_numpy(marker):
            pytest.skip(marker.kwargs.get("reason") or "skipped by scipy for numpy")
    for marker in request.node.iter_markers("xfail_xp_backends"):
        if _names_numpy(marker):
            pytest.xfail(marker.kwargs.get("reason") or "xfailed by scipy for numpy")
    yield np
