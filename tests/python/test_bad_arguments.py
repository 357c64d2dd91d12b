"""Every public entry point called with bad values: negative, huge (10**12, 2**64, 10**30),
NaN, inf, wrong types and impossible sizes.

Each case must raise ValueError, MemoryError or TypeError whose message names the argument;
never OverflowError, an abort or a hang. Cases that allocated by the size they were given
before it was checked (and so aborted the process: "memory allocation failed") or looped once
per requested item run in a fresh process with a timeout, so an abort or a hang fails the
test instead of killing pytest.
"""

from __future__ import annotations

import re
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import kinema
from kinema import anim, ode, rigid

PRELUDE = """
import numpy as np
import kinema
from kinema import Rotation, anim, cloth, constraints, ik, mocap, ode, particles, rigid
"""

# (id, code raising the error, name the message must contain). The code sees the fixtures
# below as `ps`, `cl`, `world`, `cs`, `skeleton`, `motion`, `arm`.
CASES: list[tuple[str, str, str]] = [
    # threads
    ("threads negative", "kinema.set_num_threads(-1)", "n"),
    ("threads zero", "kinema.set_num_threads(0)", "n"),
    ("threads 10**6", "kinema.set_num_threads(10**6)", "n"),
    ("threads 2**70", "kinema.set_num_threads(2**70)", "n"),
    ("threads float", "kinema.set_num_threads(1.5)", "n"),
    ("threads str", "kinema.set_num_threads('4')", "n"),
    # particles
    ("capacity negative", "particles.ParticleSystem(np.zeros((1, 3)), capacity=-1)", "capacity"),
    ("capacity 10**12", "particles.ParticleSystem(np.zeros((1, 3)), capacity=10**12)", "capacity"),
    (
        "capacity beyond memory",
        "particles.ParticleSystem(np.zeros((1, 3)), capacity=10**9)",
        "capacity",
    ),
    ("capacity 2**62", "particles.ParticleSystem(np.zeros((1, 3)), capacity=2**62)", "capacity"),
    ("capacity 2**64", "particles.ParticleSystem(np.zeros((1, 3)), capacity=2**64)", "capacity"),
    ("capacity 10**30", "particles.ParticleSystem(np.zeros((1, 3)), capacity=10**30)", "capacity"),
    ("capacity float", "particles.ParticleSystem(np.zeros((1, 3)), capacity=2.5)", "capacity"),
    (
        "capacity nan",
        "particles.ParticleSystem(np.zeros((1, 3)), capacity=float('nan'))",
        "capacity",
    ),
    (
        "capacity inf",
        "particles.ParticleSystem(np.zeros((1, 3)), capacity=float('inf'))",
        "capacity",
    ),
    ("positions nan", "particles.ParticleSystem([[np.nan, 0, 0]])", "positions"),
    ("positions shape", "particles.ParticleSystem(np.zeros((2, 2)))", "positions"),
    ("particle steps negative", "ps.step(0.01, -1)", "steps"),
    ("particle steps 2**64", "ps.step(0.01, 2**64)", "steps"),
    ("drag wind inf", "ps.add(particles.Drag(wind=(np.inf, 0, 0)))", "wind"),
    ("drag linear negative", "ps.add(particles.Drag(linear=-1.0))", "linear"),
    ("drag quadratic nan", "ps.add(particles.Drag(quadratic=np.nan))", "quadratic"),
    ("turbulence seed negative", "ps.add(particles.Turbulence(1.0, 1.0, seed=-1))", "seed"),
    ("turbulence seed 2**64", "ps.add(particles.Turbulence(1.0, 1.0, seed=2**64))", "seed"),
    ("emitter rate inf", "ps.add(particles.Emitter(rate=np.inf))", "rate"),
    ("emitter rate negative", "ps.add(particles.Emitter(rate=-1.0))", "rate"),
    ("emitter mass zero", "ps.add(particles.Emitter(rate=1.0, mass=0.0))", "mass"),
    (
        "emitter spread nan",
        "ps.add(particles.Emitter(rate=1.0, position_spread=np.nan))",
        "position_spread",
    ),
    ("emitter seed negative", "ps.add(particles.Emitter(rate=1.0, seed=-1))", "seed"),
    ("particle collider index", "ps.set_collider(-1, particles.Plane())", "index"),
    # cloth
    ("grid 10**6 x 10**6", "cloth.Cloth.grid(10**6, 10**6)", "nx, ny"),
    # Sizes the allocator grants (overcommit) but the memory cannot hold: refused up front
    # instead of the process being killed when the pages are touched.
    ("grid beyond memory", "cloth.Cloth.grid(10**5, 4 * 10**4)", "nx, ny"),
    ("grid negative", "cloth.Cloth.grid(-1, 3)", "nx"),
    ("grid huge", "cloth.Cloth.grid(3, 2**70)", "ny"),
    ("grid float", "cloth.Cloth.grid(2.5, 3)", "nx"),
    # Real-number arguments given a string or None name the argument (not float()'s words).
    ("cloth dt string", "cl.step('fast')", "dt"),
    ("world dt None", "world.step(None)", "dt"),
    ("constraints dt string", "cs.step('0.01')", "dt"),
    (
        "ode rtol None",
        "ode.solve(lambda t, y: -y, [1.0], (0, 1), method='dopri5', rtol=None)",
        "rtol",
    ),
    ("friction string", "world.add_ground(friction='high')", "friction"),
    ("cloth steps negative", "cl.step(0.01, -1)", "steps"),
    ("cloth max_iterations zero", "cl.step(0.01, max_iterations=0)", "max_iterations"),
    ("cloth max_iterations negative", "cl.step(0.01, max_iterations=-1)", "max_iterations"),
    ("cloth max_iterations 10**9", "cl.step(0.01, max_iterations=10**9)", "max_iterations"),
    ("cloth pin negative", "cl.pin([-1])", "indices"),
    ("cloth pin huge", "cl.pin([2**64])", "indices"),
    ("cloth collider index", "cl.set_collider(-1, cloth.Plane())", "index"),
    # rigid
    ("contact_iterations 10**9", "world.contact_iterations = 10**9", "contact_iterations"),
    ("contact_iterations negative", "world.contact_iterations = -1", "contact_iterations"),
    ("contact_iterations float", "world.contact_iterations = 2.5", "contact_iterations"),
    ("joint_iterations 10**9", "world.joint_iterations = 10**9", "joint_iterations"),
    ("xpbd_substeps zero", "world.xpbd_substeps = 0", "xpbd_substeps"),
    ("xpbd_substeps 2**64", "world.xpbd_substeps = 2**64", "xpbd_substeps"),
    ("rigid steps negative", "world.step(0.01, -1)", "steps"),
    ("rigid apply_force body", "world.apply_force(2**64, [0, 1, 0], [0, 0, 0])", "body"),
    # constraints
    ("distance i negative", "cs.add(constraints.Distance(-1, 1))", "i, j"),
    ("distance j huge", "cs.add(constraints.Distance(0, 2**64))", "i, j"),
    ("constrained steps negative", "cs.step(0.01, -1)", "steps"),
    ("curve_parameter k", "cs.curve_parameter(-1)", "k"),
    # ode
    ("ode dt 1e-12", "ode.solve(lambda t, y: -y, [1.0], (0, 1), dt=1e-12)", "dt"),
    ("ode dt 1e-320", "ode.solve(lambda t, y: -y, [1.0], (0, 1), dt=1e-320)", "dt"),
    ("ode dt nan", "ode.solve(lambda t, y: -y, [1.0], (0, 1), dt=np.nan)", "dt"),
    (
        "ode max_steps negative",
        "ode.solve(lambda t, y: -y, [1.0], (0, 1), dt=0.1, max_steps=-1)",
        "max_steps",
    ),
    (
        "dopri5 max_steps 2**64",
        "ode.solve(lambda t, y: -y, [1.0], (0, 1), method='dopri5', max_steps=2.0)",
        "max_steps",
    ),
    (
        "ode dense jacobian 10**5",
        "ode.solve(lambda t, y: -y, np.zeros(10**5), (0, 1), dt=0.5, method='implicit_euler')",
        "y0",
    ),
    ("ode t_span inf", "ode.solve(lambda t, y: -y, [1.0], (0, np.inf), dt=0.1)", "t_span"),
    # anim
    ("subdivide 60", "anim.subdivide(np.eye(3), iterations=60)", "iterations"),
    ("subdivide 200", "anim.subdivide(np.eye(3), iterations=200)", "iterations"),
    ("subdivide negative", "anim.subdivide(np.eye(3), iterations=-1)", "iterations"),
    ("subdivide float", "anim.subdivide(np.eye(3), iterations=1.5)", "iterations"),
    ("track times nan", "anim.Track([0.0, np.nan], [0.0, 1.0])", "times"),
    # mocap
    ("resample 1e9", "motion.resample(1e9)", "to_rate"),
    ("resample 1e300", "motion.resample(1e300)", "to_rate"),
    ("pose negative", "motion.pose(-1)", "i"),
    ("pose huge", "motion.pose(2**64)", "i"),
    ("pose float", "motion.pose(1.5)", "i"),
    ("slice negative", "motion.slice(-1, 2)", "start"),
    ("stitch transition negative", "mocap.stitch(skeleton, motion, motion, -1)", "transition"),
    ("warp key negative", "mocap.warp(skeleton, motion, {-1: motion.pose(0)})", "keys"),
    # ik
    (
        "ik max_iters negative",
        "ik.solve(arm, np.zeros(arm.stride), {'link2': [0.3, 0.3, 0]}, max_iters=-1)",
        "max_iters",
    ),
    (
        "ik max_iters 10**9",
        "ik.solve(arm, np.zeros(arm.stride), {'link2': [0.3, 0.3, 0]}, max_iters=10**9)",
        "max_iters",
    ),
    # rotations
    ("identity negative", "Rotation.identity(-1)", "n"),
    ("identity 10**12", "Rotation.identity(10**12)", "n"),
    ("random 10**12", "Rotation.random(10**12)", "n"),
]

# Cases that aborted the process or hung before they were guarded: run in a subprocess.
RISKY = {
    "capacity 10**12",
    "capacity beyond memory",
    "capacity 2**62",
    "grid 10**6 x 10**6",
    "grid beyond memory",
    "ode dt 1e-12",
    "ode dt 1e-320",
    "ode dense jacobian 10**5",
    "subdivide 60",
    "subdivide 200",
    "resample 1e9",
    "resample 1e300",
    "cloth max_iterations 10**9",
    "contact_iterations 10**9",
    "threads 10**6",
    "identity 10**12",
    "random 10**12",
}

FIXTURES = """
ps = particles.ParticleSystem(np.zeros((2, 3)), capacity=4)
cl = cloth.Cloth.grid(3, 3)
world = rigid.World()
world.add_body(rigid.Sphere(0.5), position=(0, 1, 0))
cs = constraints.ConstrainedSystem(particles.ParticleSystem([[0, 0, 0], [1, 0, 0]]))
skeleton = mocap.read_asf(mocap.SAMPLE_DIR / "07-walk.asf")
motion = mocap.read_amc(mocap.SAMPLE_DIR / "07_05-walk.amc", skeleton)
arm = ik.chain([0.3, 0.25], ["z", "z"])
"""

ALLOWED = (ValueError, MemoryError, TypeError)


def fixtures() -> dict[str, object]:
    names: dict[str, object] = {}
    exec(PRELUDE + FIXTURES, names)
    return names


def names(message: str, name: str) -> bool:
    """Whether ``message`` blames ``name`` the kinema way: ``name: ...`` or ``name[k]: ...``."""
    return re.search(rf"(^|\W){re.escape(name)}(\[\d+\])?: ", message) is not None


def check(exc: BaseException, name: str) -> None:
    assert not isinstance(exc, OverflowError), repr(exc)
    assert isinstance(exc, ALLOWED), repr(exc)
    assert names(str(exc), name), f"{name!r} not named in {exc!r}"


@pytest.mark.parametrize(
    ("code", "name"),
    [(c, n) for i, c, n in CASES if i not in RISKY],
    ids=[i for i, _, _ in CASES if i not in RISKY],
)
def test_bad_argument_raises_naming_it(code: str, name: str) -> None:
    names = fixtures()
    with pytest.raises(BaseException) as info:
        exec(code, names)
    check(info.value, name)


RUNNER = """
try:
    {code}
except BaseException as e:
    print(type(e).__name__)
    print(e)
else:
    print("no error")
"""


@pytest.mark.parametrize(
    ("code", "name"),
    [(c, n) for i, c, n in CASES if i in RISKY],
    ids=[i for i, _, _ in CASES if i in RISKY],
)
def test_bad_size_raises_naming_it_in_a_fresh_process(code: str, name: str) -> None:
    script = PRELUDE + FIXTURES + RUNNER.format(code=code)
    result = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0, f"process died ({result.returncode}): {result.stderr[-2000:]}"
    kind, _, message = result.stdout.partition("\n")
    assert kind in {"ValueError", "MemoryError", "TypeError"}, result.stdout
    assert names(message, name), result.stdout


def test_names_accepts_only_the_blamed_argument() -> None:
    assert names("n: expected an integer >= 0, got -1", "n")
    assert names("indices[3]: expected an integer >= 0, got -1", "indices")
    assert not names("Unable to allocate 29.1 TiB for an array", "n")
    assert not names("steps: expected an integer >= 0", "max_steps")


def test_every_case_id_is_unique_and_risky_ones_exist() -> None:
    ids = [i for i, _, _ in CASES]
    assert len(ids) == len(set(ids))
    assert RISKY <= set(ids)


def test_emitter_at_rate_1e300_fills_the_free_slots_in_a_fresh_process() -> None:
    """A rate of 1e300 /s used to loop once per owed particle (1e298 turns a step)."""
    script = PRELUDE + textwrap.dedent(
        """
        ps = particles.ParticleSystem(np.zeros((1, 3)), capacity=50)
        ps.add(particles.Emitter(rate=1e300, position_spread=1.0))
        ps.step(0.01, 3)
        print(int(ps.alive.sum()), ps.stats["emitted"], ps.stats["dropped"] > 10**18)
        """
    )
    result = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.split() == ["50", "49", "True"]


def test_ode_max_steps_bounds_fixed_steps_exactly() -> None:
    """1/dt steps are allowed up to max_steps and refused, naming dt, above it."""
    t, y = ode.solve(lambda t, y: -y, [1.0], (0, 1), dt=0.01, max_steps=100)
    assert len(t) == 101
    assert abs(y[-1, 0] - np.exp(-1.0)) < 1e-9
    with pytest.raises(ValueError, match=r"dt:.*max_steps=99"):
        ode.solve(lambda t, y: -y, [1.0], (0, 1), dt=0.01, max_steps=99)


def test_iteration_and_thread_bounds_are_inclusive() -> None:
    world = rigid.World()
    world.contact_iterations = 10**6
    assert world.contact_iterations == 10**6
    world.xpbd_substeps = np.int64(7)
    assert world.xpbd_substeps == 7
    before = kinema.num_threads()
    try:
        kinema.set_num_threads(1)
        assert kinema.num_threads() == 1
    finally:
        kinema.set_num_threads(before)


def test_subdivision_just_below_the_memory_bound_still_works() -> None:
    """The size check must not refuse honest work: 3 points, 12 rounds, the exact count."""
    points = np.eye(3)[:, :2]
    out = anim.subdivide(points, "chaikin", 12)
    # Open Chaikin: m points become 2m (both ends kept, two per edge).
    assert out.shape == (3 * 2**12, 2)
    np.testing.assert_array_equal(out[[0, -1]], points[[0, -1]])
