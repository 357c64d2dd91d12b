"""Rods and hair: kinema's discrete elastic rods beside PyElastica (Cosserat rods, explicit
position Verlet) on PyElastica's own cantilever benchmark, and the time per step of 10,000
hair strands on a moving head.

**Cantilever** (PyElastica's documented Timoshenko beam example,
``examples/TimoshenkoBeamCase/timoshenko.py``; Gazzola et al. 2018, sec. 3.4.3): a rod of
length 3 m, radius 0.25 m, density 5000 kg/m³, E = 1e6 Pa along +z, its first node and
element clamped, a tip force of 15 N along -x ramped up linearly over half of 5000 s, damped
by PyElastica's ``AnalyticalLinearDamper`` (constant 0.1 / 7 / ρ / A) and integrated by
``PositionVerlet``. kinema's discrete elastic rods are Kirchhoff rods (no shear), so the
comparison uses the example's *unshearable* rod (its ``ADD_UNSHEARABLE_ROD`` option, shear
modulus E / 0.3) and its analytic solution, the Euler–Bernoulli tip deflection
``F L³ / (3 E I)``; the example's time step ``0.07 dl`` is unstable for that rod (measured:
the rod blows up), so PyElastica runs at ``0.01 dl``, the step of its earlier versions of the
example. kinema runs the same rod (same n elements from the same clamp) by its static solve
(``solve_static``: Newton to equilibrium, what a user wanting the deflection calls) and by
implicit Euler over the same ramp at 0.5 s steps. Both are timed in CPU time
(``process_time``) in this process, one thread each (PyElastica is single-threaded numba; a
single rod in kinema runs on one thread). Errors are of the tip's deflection along x.

**Hair**: 10,000 strands of 32 segments (15 cm, r = 50 µm, E = 1 GPa, ρ = 1300 kg/m³: the
library's hair defaults), straight, groomed on the upper cap (80°) of a 10 cm head that turns
and nods (±0.7 rad yaw, ±0.3 rad pitch), stepped at dt = 1/60 s by ``Hair.step`` with the
defaults a new user gets (no repulsion, tolerance 1e-10); time per step (wall and CPU) on 1
and on 2 threads, each in a subprocess with ``KINEMA_NUM_THREADS``.

Run: python bench/bench_rods.py [--quick] [--elements 20 50] [--final-time 5000]
[--strands 10000] [--steps 10] [--skip-pyelastica] [--skip-hair]
(--quick: 10 elements over 50 s, 500 strands, 3 steps: a smoke run, not the figures.)
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

from kinema.rods import Rod

LENGTH, RADIUS, DENSITY, E = 3.0, 0.25, 5000.0, 1e6
SHEAR = E / 0.3  # the example's unshearable rod (Poisson ratio -0.7)
FORCE = 15.0
INERTIA = np.pi * RADIUS**4 / 4
ANALYTIC = FORCE * LENGTH**3 / (3 * E * INERTIA)  # Euler–Bernoulli tip deflection (m)


def pyelastica_tip(n: int, final_time: float) -> tuple[float, float, int]:
    """PyElastica's Timoshenko example with the unshearable rod of ``n`` elements: the tip's
    deflection (m), the CPU time (s) and the number of steps."""
    import elastica as ea

    class Sim(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.Damping):
        pass

    sim = Sim()
    area = np.pi * RADIUS**2
    rod = ea.CosseratRod.straight_rod(
        n, np.zeros(3), np.array([0.0, 0.0, 1.0]), np.array([0.0, 1.0, 0.0]), LENGTH, RADIUS,
        DENSITY, youngs_modulus=E, shear_modulus=SHEAR,
    )  # fmt: skip
    sim.append(rod)
    dt = 0.01 * LENGTH / n
    sim.dampen(rod).using(
        ea.AnalyticalLinearDamper, damping_constant=0.1 / 7 / DENSITY / area, time_step=dt
    )
    sim.constrain(rod).using(
        ea.OneEndFixedBC, constrained_position_idx=(0,), constrained_director_idx=(0,)
    )
    end = np.array([-FORCE, 0.0, 0.0])
    sim.add_forcing_to(rod).using(ea.EndpointForces, 0.0 * end, end, ramp_up_time=final_time / 2)
    sim.finalize()
    steps = int(final_time / dt)
    start = time.process_time()
    ea.integrate(ea.PositionVerlet(), sim, final_time, steps, progress_bar=False)
    return -float(rod.position_collection[0, -1]), time.process_time() - start, steps


def kinema_rod(n: int) -> Rod:
    """The same rod in kinema: ``n`` edges along +z from the origin, its first edge clamped."""
    rod = Rod.straight(
        n + 1, LENGTH, direction=(0, 0, 1), radius=RADIUS, youngs_modulus=E,
        shear_modulus=SHEAR, density=DENSITY, gravity=(0, 0, 0),
    )  # fmt: skip
    rod.clamp(0)
    return rod


def kinema_static(n: int) -> tuple[float, float]:
    """kinema's static solve under the full tip force: deflection (m), CPU time (s; best of 5)."""
    best, tip = np.inf, 0.0
    for _ in range(5):
        rod = kinema_rod(n)
        rod.set_force(-1, (-FORCE, 0.0, 0.0))
        start = time.process_time()
        rod.solve_static()
        best = min(best, time.process_time() - start)
        tip = -float(rod.positions[-1, 0])
    return tip, best


def kinema_ramp(n: int, final_time: float, dt: float = 0.5) -> tuple[float, float, int]:
    """kinema's implicit Euler over the example's ramp (the force set each step): deflection
    (m), CPU time (s), steps."""
    rod = kinema_rod(n)
    steps = round(final_time / dt)
    start = time.process_time()
    for k in range(1, steps + 1):
        rod.set_force(-1, (-FORCE * min(1.0, k * dt / (final_time / 2)), 0.0, 0.0))
        rod.step(dt)
    return -float(rod.positions[-1, 0]), time.process_time() - start, steps


def cantilever(elements: list[int], final_time: float, pyelastica: bool) -> None:
    print(
        f"## Cantilever: L = {LENGTH} m, r = {RADIUS} m, rho = {DENSITY}, E = {E:g} Pa, "
        f"G = E/0.3, tip force {FORCE} N ramped over {final_time / 2:g} s of {final_time:g} s; "
        f"Euler-Bernoulli tip deflection {ANALYTIC:.6e} m; CPU time, 1 thread each; "
        f"load {os.getloadavg()[0]:.1f}"
    )
    print(
        "| n | PyElastica error | PyElastica CPU s (steps, dt = 0.01 dl) | kinema static error "
        "| kinema static CPU s | ratio | kinema implicit (dt 0.5 s) error | CPU s | ratio |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for n in elements:
        ks, ks_t = kinema_static(n)
        kr, kr_t, kr_steps = kinema_ramp(n, final_time)
        if pyelastica:
            pe, pe_t, pe_steps = pyelastica_tip(n, final_time)
            pe_cells = (f"{pe / ANALYTIC - 1:+.3%}", f"{pe_t:.1f} ({pe_steps})")
            ratios = (f"{pe_t / ks_t:.0f}x", f"{pe_t / kr_t:.0f}x")
        else:
            pe_cells, ratios = ("-", "-"), ("-", "-")
        print(
            f"| {n} | {pe_cells[0]} | {pe_cells[1]} | {ks / ANALYTIC - 1:+.3%} | {ks_t:.2e} "
            f"| {ratios[0]} | {kr / ANALYTIC - 1:+.3%} | {kr_t:.2f} ({kr_steps}) | {ratios[1]} |",
            flush=True,
        )


def hair_run(strands: int, steps: int) -> dict[str, float]:
    """The hair run in this process: seconds per step (wall, CPU) after 3 warm-up steps."""
    import kinema
    from kinema import Rotation
    from kinema.rods import groom, sphere_cap

    points, normals = sphere_cap(strands, radius=0.1, angle=1.4)
    hair = groom(points, normals, length=0.15, segments=32)

    def pose(t: float) -> Rotation:
        yaw, pitch = 0.7 * np.sin(np.pi * t), 0.3 * np.sin(2 * np.pi * t / 1.3)
        return Rotation.from_rotvec([0.0, yaw, 0.0]) * Rotation.from_rotvec([pitch, 0.0, 0.0])

    for k in range(1, 4):
        hair.set_head(pose(k / 60))
        hair.step(1 / 60)
    wall, cpu, iterations = 0.0, 0.0, 0
    for k in range(4, 4 + steps):
        hair.set_head(pose(k / 60))
        w, c = time.perf_counter(), time.process_time()
        hair.step(1 / 60)
        wall += time.perf_counter() - w
        cpu += time.process_time() - c
        iterations += hair.stats["iterations"]
    return {
        "threads": kinema.num_threads(),
        "wall": wall / steps,
        "cpu": cpu / steps,
        "iterations": iterations / (steps * strands),
    }


def hair(strands: int, steps: int) -> None:
    print(
        f"\n## Hair: {strands} strands x 32 segments (15 cm, r = 50 um, E = 1 GPa), moving head, "
        f"dt = 1/60 s, defaults (no repulsion, tolerance 1e-10), {steps} steps after 3"
    )
    print("| threads | s per step (wall) | CPU s per step | Newton iterations per strand step |")
    print("|---:|---:|---:|---:|")
    for threads in (1, 2):
        env = {**os.environ, "KINEMA_NUM_THREADS": str(threads)}
        args = [sys.executable, __file__, "--hair-child", str(strands), str(steps)]
        out = subprocess.run(args, env=env, capture_output=True, text=True, check=True).stdout
        r = json.loads(out.strip().splitlines()[-1])
        print(
            f"| {r['threads']} | {r['wall']:.3f} | {r['cpu']:.3f} | {r['iterations']:.2f} |",
            flush=True,
        )
    print(f"load {os.getloadavg()[0]:.1f} after the runs")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--elements", type=int, nargs="+", default=[20, 50])
    parser.add_argument("--final-time", type=float, default=5000.0)
    parser.add_argument("--strands", type=int, default=10000)
    parser.add_argument("--steps", type=int, default=10)
    parser.add_argument("--skip-pyelastica", action="store_true")
    parser.add_argument("--skip-hair", action="store_true")
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--hair-child", type=int, nargs=2, help=argparse.SUPPRESS)
    a = parser.parse_args()
    if a.quick:
        a.elements, a.final_time, a.strands, a.steps = [10], 50.0, 500, 3
    if a.hair_child:
        print(json.dumps(hair_run(*a.hair_child)))
        return
    try:
        import elastica  # noqa: F401

        have_pyelastica = not a.skip_pyelastica
    except ImportError:
        print("pyelastica is not installed (pip install pyelastica): kinema only")
        have_pyelastica = False
    cantilever(a.elements, a.final_time, have_pyelastica)
    if not a.skip_hair:
        hair(a.strands, a.steps)


if __name__ == "__main__":
    main()
