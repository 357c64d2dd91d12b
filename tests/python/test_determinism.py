"""The same inputs give bitwise the same results with 1 and with 2 threads (CONVENTIONS:
determinism). Each run is a fresh process so the thread pool is sized by KINEMA_NUM_THREADS."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

SCRIPT = r"""
import sys
import numpy as np
from kinema import Rotation
from kinema.anim import Track
from kinema.constraints import ConstrainedSystem, Distance
from kinema.particles import Drag, Gravity, NeighborRepulsion, ParticleSystem, Plane, Sphere, Turbulence

rng = np.random.default_rng(0)
out = {}
ps = ParticleSystem(rng.uniform(-1, 1, (20000, 3)) + [0, 2, 0], rng.normal(size=(20000, 3)))
for item in [Gravity(), Drag(quadratic=0.01), Turbulence(2.0, 0.5), NeighborRepulsion(0.05, 50.0), Plane(), Sphere([0, 0, 0], 0.5)]:
    ps.add(item)
ps.step(1e-3, 20, method="velocity_verlet")
out["particles"] = ps.positions.copy()
fused = ParticleSystem(rng.uniform(-1, 1, (50000, 3)), rng.normal(size=(50000, 3)))
fused.add(Gravity())
fused.add(Plane(restitution=0.5, friction=0.3))
fused.step(1e-2, 20)
out["fused"] = fused.positions.copy()
r = Rotation.random(100000, rng=1)
out["euler"] = r.as_euler("ZXZ")
out["matrix"] = (r * r[::-1]).as_matrix()
t = np.cumsum(rng.uniform(0.1, 1.0, 1000))
out["track"] = Track(t, rng.normal(size=(1000, 2)), "natural_cubic")(rng.uniform(t[0], t[-1], 200000))
n = 300
rope = ParticleSystem(np.column_stack([np.arange(n) * 0.05, np.zeros(n), np.zeros(n)]), masses=np.r_[np.inf, np.full(n - 1, 0.01)])
rope.add(Gravity())
cs = ConstrainedSystem(rope, solver="cg")
for i in range(n - 1):
    cs.add(Distance(i, i + 1))
cs.step(1 / 60, 10, method="projection")
out["rope"] = rope.positions.copy()
from kinema.cloth import Cloth, Sphere as ClothSphere
cloth = Cloth.grid(24, 24, 1.2, 1.2)
cloth.set_state(cloth.positions + np.array([0.0, 0.5, 0.0]))
cloth.add_collider(ClothSphere([0, 0.2, 0], 0.25))
cloth.step(1 / 60, 20)
cloth.step(1 / 60, 5, integrator="bdf2", solver="cholesky")
out["cloth"] = cloth.positions.copy()
np.savez(sys.argv[1], **out)
"""


def run(threads: int, path: Path) -> dict[str, np.ndarray]:
    env = dict(os.environ, KINEMA_NUM_THREADS=str(threads))
    subprocess.run(
        [sys.executable, "-c", SCRIPT, str(path), str(threads)], env=env, check=True, timeout=300
    )
    with np.load(path) as data:
        return {k: data[k] for k in data.files}


def test_one_and_two_threads_agree_bitwise(tmp_path: Path):
    one, two = run(1, tmp_path / "one.npz"), run(2, tmp_path / "two.npz")
    assert one.keys() == two.keys()
    for key in one:
        assert np.array_equal(one[key], two[key]), key


def threads_at_import(env_value: str | None) -> tuple[str, str]:
    """``kinema.num_threads()`` after ``import kinema`` in a fresh process with
    ``KINEMA_NUM_THREADS=env_value`` (unset for None), and the RuntimeWarnings it issued."""
    env = {k: v for k, v in os.environ.items() if k != "KINEMA_NUM_THREADS"}
    if env_value is not None:
        env["KINEMA_NUM_THREADS"] = env_value
    code = (
        "import warnings\n"
        "with warnings.catch_warnings(record=True) as w:\n"
        "    warnings.simplefilter('always')\n"
        "    import kinema\n"
        "print(kinema.num_threads())\n"
        "print(*[str(x.message) for x in w if x.category is RuntimeWarning])\n"
    )
    result = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    threads, warnings = result.stdout.split("\n", 1)
    return threads, warnings


@pytest.mark.parametrize("value", ["0", "-1", "1025", "10**6", "two", "99999999999999999999999"])
def test_bad_KINEMA_NUM_THREADS_warns_naming_it_and_keeps_the_default(value: str):
    threads, warnings = threads_at_import(value)
    assert f"KINEMA_NUM_THREADS={value!r} ignored" in warnings
    assert threads == threads_at_import(None)[0]


def test_good_KINEMA_NUM_THREADS_sizes_the_pool():
    assert threads_at_import("3") == ("3", "\n")
