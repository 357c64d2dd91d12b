"""Fixtures shared by the Python tests: the CMU walk every motion-capture test reads."""

from __future__ import annotations

from pathlib import Path

import pytest

from kinema import mocap

MOCAP = Path(__file__).resolve().parents[1] / "data" / "mocap"


@pytest.fixture(scope="module")
def walk():
    """CMU subject 07, trial 05 (a walk at 120 Hz): ``(skeleton, motion)``, read once a module."""
    assert MOCAP.is_dir(), f"motion-capture data expected at {MOCAP}"
    skeleton = mocap.read_asf(MOCAP / "07-walk.asf")
    return skeleton, mocap.read_amc(MOCAP / "07_05-walk.amc", skeleton)
