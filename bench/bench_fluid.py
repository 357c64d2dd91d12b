"""Fluids: the dam break of Martin & Moyce (1952) as in docs/fluid.md — a column `L × 2L`
(L = 0.146 m) in a tank `4L × 3L`, a slab `0.4 L` thick — at several particle spacings, one
frame of 1/60 s at a time: kinema's DFSPH (the default), PBF and WCSPH against a numpy/scipy
implementation of the same WCSPH (cubic spline of support 2 s, Akinci boundary particles and
volumes, Tait pressure clamped at 0, XSPH viscosity, symplectic Euler, neighbours by
`scipy.spatial.cKDTree.query_pairs`) taking the same number of substeps per frame as kinema's
WCSPH, in one process. Reported: ms per frame, substeps per frame, the mean compression of
the last frame (percent) and, for the reference, its time per substep against kinema's.

With `--splishsplash SECONDS`, also SPlisHSPlasH (`pysplishsplash` 2.19, DFSPH) on the same dam
break side by side with kinema's DFSPH, both on one thread, for SECONDS of simulated time (see
`splishsplash_child`: the same fluid lattice, its wall mesh through kinema's boundary particles,
the same CFL limit, tolerances and XSPH viscosity). SPlisHSPlasH runs in a child process
(`OMP_NUM_THREADS=1`, the system's `libGLdispatch.so.0` preloaded: the wheel's own clashes),
since it can only be run to its scene's end and crashes when its model is read afterwards.

With `--scaling`, kinema's DFSPH alone at its defaults on the same dam break with about 10k
and 100k fluid particles (L / s = 24 and 50; `--million` adds 1M, L / s = 108, which needs
several GB and minutes a frame), ms per frame after the first.

Run: python bench/bench_fluid.py [--spacings 10 20] [--frames 6] [--splishsplash 0.5]
[--scaling [--million]] (spacings as L / s; the fluid has 0.8 (L / s)³ particles: 10 is 800,
20 6,400, 40 51,200.)
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
from scipy.spatial import cKDTree

import kinema
from kinema.fluid import Fluid

L = 0.146
FRAME = 1.0 / 60.0
G = np.array([0.0, -9.81, 0.0])
# The front is compared at the first frame from this time on (s; T = t √(2g/L) ≈ 2.3, before
# the surge reaches the far wall at Z = 4L).
FRONT_AT = 0.2


def dam(spacing: float, solver: str) -> Fluid:
    fluid = Fluid(spacing, solver=solver)
    fluid.add_boundary_box((0.0, 0.0, 0.0), (4 * L, 3 * L, 0.4 * L))
    fluid.add_block((0.0, 0.0, 0.0), (L, 2 * L, 0.4 * L))
    return fluid


def cubic(r: np.ndarray, h: float) -> np.ndarray:
    q = r / h
    s = 8.0 / (np.pi * h**3)
    t = np.clip(1.0 - q, 0.0, None)
    return np.where(q <= 0.5, s * (6.0 * q * q * (q - 1.0) + 1.0), s * 2.0 * t**3)


def cubic_derivative(r: np.ndarray, h: float) -> np.ndarray:
    q = r / h
    s = 48.0 / (np.pi * h**4)
    t = np.clip(1.0 - q, 0.0, None)
    return np.where(q <= 0.5, s * q * (3.0 * q - 2.0), -s * t * t)


class NumpyWcsph:
    """The WCSPH substep of kinema's `solver="wcsph"` (docs/fluid.md) written with numpy."""

    def __init__(self, fluid: Fluid, spacing: float, sound_speed: float = 30.0, nu: float = 0.01):
        self.x = np.array(fluid.positions, dtype=float)
        self.v = np.zeros_like(self.x)
        self.b = np.array(fluid.boundary_particles, dtype=float)
        self.h = 2.0 * spacing
        self.vol = spacing**3
        self.c2 = sound_speed**2 / 7.0
        self.nu = nu
        self.margin = 0.25 * spacing
        self.lo = np.zeros(3) + self.margin
        self.hi = np.array([4 * L, 3 * L, 0.4 * L]) - self.margin
        # Akinci's boundary volumes V_b = 1 / Σ_k W(x_b - x_k) (not timed: the setup).
        tree = cKDTree(self.b)
        pairs = tree.query_pairs(self.h, output_type="ndarray")
        w = cubic(np.linalg.norm(self.b[pairs[:, 0]] - self.b[pairs[:, 1]], axis=1), self.h)
        total = np.full(len(self.b), cubic(np.zeros(1), self.h)[0])
        total += np.bincount(pairs[:, 0], w, len(self.b)) + np.bincount(pairs[:, 1], w, len(self.b))
        self.vb = 1.0 / total

    def substep(self, dt: float) -> float:
        n, h = len(self.x), self.h
        points = np.concatenate([self.x, self.b])
        pairs = cKDTree(points).query_pairs(h, output_type="ndarray")
        pairs = pairs[pairs[:, 0] < n]  # fluid–fluid and fluid–boundary (i < j: i is fluid)
        i, j = pairs[:, 0], pairs[:, 1]
        fluid = j < n
        d = points[i] - points[j]
        r = np.linalg.norm(d, axis=1)
        w = cubic(r, h)
        grad = d * (cubic_derivative(r, h) / np.where(r > 0, r, 1.0))[:, None]
        mass_j = np.where(fluid, self.vol, self.vb[np.minimum(j - n, len(self.vb) - 1)])
        ff_i, ff_j = i[fluid], j[fluid]
        rho = self.vol * cubic(np.zeros(1), h)[0] + np.bincount(i, mass_j * w, n)
        rho += np.bincount(ff_j, self.vol * w[fluid], n)
        # Gravity and XSPH viscosity.
        dv = np.tile(G * dt, (n, 1))
        rel = (self.v[ff_j] - self.v[ff_i]) * w[fluid, None]
        for a in range(3):
            dv[:, a] += self.nu * self.vol * np.bincount(ff_i, rel[:, a] / rho[ff_j], n)
            dv[:, a] -= self.nu * self.vol * np.bincount(ff_j, rel[:, a] / rho[ff_i], n)
        self.v += dv
        # Tait pressure, clamped, and its acceleration.
        k = np.maximum(self.c2 * (rho**7 - 1.0), 0.0) / rho**2
        coef = np.where(fluid, self.vol * (k[i] + k[np.minimum(j, n - 1)]), mass_j * k[i])
        force = grad * coef[:, None]
        for a in range(3):
            self.v[:, a] -= dt * np.bincount(i, force[:, a], n)
            self.v[:, a] += dt * np.bincount(ff_j, force[fluid, a], n)
        # Symplectic Euler and the tank.
        self.x += dt * self.v
        below, above = self.x < self.lo, self.x > self.hi
        self.x = np.clip(self.x, self.lo, self.hi)
        self.v = np.where(below, np.maximum(self.v, 0.0), self.v)
        self.v = np.where(above, np.minimum(self.v, 0.0), self.v)
        return 100.0 * float(np.maximum(rho - 1.0, 0.0).mean())


def kinema_frames(fluid: Fluid, frames: int) -> tuple[float, float, float, float]:
    """(ms per frame, CPU ms per frame (all threads), substeps per frame, mean compression
    of the last frame in percent)."""
    fluid.step(FRAME)  # the first frame sizes the buffers
    start, cpu = time.perf_counter(), time.process_time()
    substeps = 0
    for _ in range(frames):
        fluid.step(FRAME)
        substeps += int(fluid.stats["substeps"])
    seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
    return (
        1e3 * seconds / frames,
        1e3 * cpu / frames,
        substeps / frames,
        float(fluid.stats["density_error"]),
    )


def compression(densities: np.ndarray, rest: float = 1000.0) -> float:
    """Mean compression `max(ρ/ρ₀ - 1, 0)` over the particles (percent)."""
    return 100.0 * float(np.maximum(densities / rest - 1.0, 0.0).mean())


def kinema_seconds(per_l: int, seconds: float) -> dict[str, float]:
    """kinema's DFSPH on the dam break for `seconds`, one frame of 1/60 s at a time: CPU and
    wall seconds per simulated second (the first frame not timed), substeps and iterations
    per substep, the mean compression of the fresh densities at the frames' ends (percent)
    and the front `Z/L` (the farthest particle plus half a spacing) at `FRONT_AT`, with its
    `T`."""
    fluid = dam(L / per_l, "dfsph")
    fluid.step(FRAME)
    frames = max(1, round(seconds / FRAME) - 1)
    wall, cpu, spent, errors, front = 0.0, 0.0, np.zeros(3), [], {}
    for _ in range(frames):
        start, cpu0 = time.perf_counter(), time.process_time()
        fluid.step(FRAME)
        wall += time.perf_counter() - start
        cpu += time.process_time() - cpu0
        stats = fluid.stats
        spent += [stats["substeps"], stats["density_iterations"], stats["divergence_iterations"]]
        errors.append(compression(fluid.densities))
        if "front" not in front and fluid.time >= FRONT_AT - 1e-9:
            front["front"] = (float(fluid.positions[:, 0].max()) + 0.5 * L / per_l) / L
            front["T"] = fluid.time * np.sqrt(-2.0 * G[1] / L)
    simulated = frames * FRAME
    return {
        "particles": len(fluid),
        "boundary": len(fluid.boundary_particles),
        "cpu_per_s": cpu / simulated,
        "wall_per_s": wall / simulated,
        "dt": simulated / spent[0],
        "iterations": spent[1] / spent[0],
        "iterations_v": spent[2] / spent[0],
        "compression": float(np.mean(errors)),
        **front,
    }


def splishsplash_child(per_l: int, seconds: float, folder: str) -> None:
    """Run SPlisHSPlasH's DFSPH on the dam break (in this process: called in a child) and print
    a JSON line like `kinema_seconds`'s. The set-up matches kinema's: particle radius `s/2`; the
    fluid block's lattice is kinema's (SPlisHSPlasH fills a block from one diameter inside its
    corner, so the block is given half a spacing larger); the tank is a box mesh (normals in,
    `mapInvert`) whose faces lie on kinema's boundary-particle layer (its Akinci particles are
    sampled on the mesh, kinema's a distance behind the tank's faces), sampled regularly;
    DFSPH with the divergence solve, mean density error 0.05 %, divergence 0.1 %, at most 100
    iterations each; XSPH 0.01; the CFL step `cflFactor 0.4 diameter / v_max` with
    `cflFactor = 1` (kinema's `0.4 s / v_max`), at most 0.005 s, at least 1e-6 s. Timed from
    the end of its first step to the end (CPU time of this process, minus the callback's)."""
    import pysplishsplash as sph  # only in the child: it needs the preload

    s = L / per_l
    behind = -float(np.array(dam(s, "dfsph").boundary_particles)[:, 0].min())
    lower = np.full(3, -behind)
    upper = np.array([4 * L, 3 * L, 0.4 * L]) + behind
    corners = [(x, y, z) for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)]
    quads = [(1, 3, 4, 2), (5, 6, 8, 7), (1, 2, 6, 5), (3, 7, 8, 4), (1, 5, 7, 3), (2, 4, 8, 6)]
    with open(f"{folder}/box.obj", "w") as out:
        out.writelines(f"v {x} {y} {z}\n" for x, y, z in corners)
        for a, b, c, d in quads:
            out.write(f"f {a} {b} {c}\nf {a} {c} {d}\n")
    scene = {
        "Configuration": {
            "particleRadius": s / 2,
            "simulationMethod": 4,
            "gravitation": list(G),
            "cflMethod": 1,
            "cflFactor": 1.0,
            "cflMaxTimeStepSize": 0.005,
            "cflMinTimeStepSize": 1e-6,
            "maxIterations": 100,
            "maxError": 0.05,
            "maxIterationsV": 100,
            "maxErrorV": 0.1,
            "enableDivergenceSolver": True,
            "boundaryHandlingMethod": 0,
            "stopAt": seconds,
            "enableVTKExport": False,
            "enablePartioExport": False,
        },
        "Materials": [{"id": "Fluid", "density0": 1000, "viscosityMethod": 0, "xsph": 0.01}],
        "RigidBodies": [
            {
                "geometryFile": f"{folder}/box.obj",
                "translation": list((lower + upper) / 2),
                "scale": list(upper - lower),
                "isDynamic": False,
                "isWall": True,
                "mapInvert": True,
                "samplingMode": 1,
            }
        ],
        "FluidBlocks": [
            {
                "denseMode": 0,
                "start": [-s / 2] * 3,
                "end": [L + s / 2, 2 * L + s / 2, 0.4 * L + s / 2],
                "translation": [0, 0, 0],
                "scale": [1, 1, 1],
            }
        ],
    }
    with open(f"{folder}/dam.json", "w") as out:
        json.dump(scene, out)
    base = sph.Exec.SimulatorBase()
    base.init(useGui=False, outputDir=f"{folder}/out", sceneFile=f"{folder}/dam.json")
    record = {"steps": 0, "start": 0.0, "t0": 0.0, "cpu": 0.0, "aside": 0.0, "errors": []}
    frame = {"next": FRAME}

    def after_step() -> None:
        entered = time.process_time()
        sim, now = sph.Simulation.getCurrent(), sph.TimeManager.getCurrent().getTime()
        if record["steps"] == 0:
            record["start"], record["t0"] = entered, now
        record["steps"] += 1
        if now >= frame["next"]:
            frame["next"] += FRAME
            fm = sim.getFluidModel(0)
            n = fm.numActiveParticles()
            rho = np.array([fm.getDensity(i) for i in range(n)])
            record["errors"].append(compression(rho))
            if "front" not in record and now >= FRONT_AT - 1e-9:
                x = float(max(fm.getPosition(i)[0] for i in range(n)))
                record["front"], record["T"] = (x + s / 2) / L, now * np.sqrt(-2.0 * G[1] / L)
            record["particles"] = n
            record["boundary"] = sim.getBoundaryModel(0).numberOfParticles()
        record["cpu"], record["t1"] = time.process_time(), now
        record["aside"] += record["cpu"] - entered

    base.setTimeStepCB(after_step)
    base.run()
    simulated = record["t1"] - record["t0"]
    print(
        "RESULT "
        + json.dumps(
            {
                "particles": record["particles"],
                "boundary": record["boundary"],
                "cpu_per_s": (record["cpu"] - record["start"] - record["aside"]) / simulated,
                "dt": simulated / (record["steps"] - 1),
                "compression": float(np.mean(record["errors"])),
                "front": record["front"],
                "T": float(record["T"]),
            }
        ),
        flush=True,
    )
    os._exit(0)  # SPlisHSPlasH crashes in its clean-up


def splishsplash(per_l: int, seconds: float) -> dict[str, float]:
    """`splishsplash_child` in a child process on one thread; its result, with the iterations
    per step that SPlisHSPlasH prints."""
    env = dict(os.environ, OMP_NUM_THREADS="1", OMP_WAIT_POLICY="passive")
    env["LD_PRELOAD"] = "/lib/x86_64-linux-gnu/libGLdispatch.so.0"
    with tempfile.TemporaryDirectory() as folder:
        args = [sys.executable, __file__, "--child", str(per_l), str(seconds), folder]
        out = subprocess.run(args, env=env, capture_output=True, text=True, check=True).stdout
    result = json.loads(out.split("RESULT ", 1)[1])
    for line in out.splitlines():
        if line.startswith("Average number: DFSPH - iterations:"):
            result["iterations"] = float(line.rsplit(":", 1)[1])
        if line.startswith("Average number: DFSPH - iterationsV:"):
            result["iterations_v"] = float(line.rsplit(":", 1)[1])
    return result


def side_by_side(spacings: list[int], seconds: float) -> None:
    """Print kinema's DFSPH against SPlisHSPlasH's, one thread each."""
    kinema.set_num_threads(1)
    print(
        f"DFSPH side by side, {seconds} s simulated, one thread each; load {os.getloadavg()[0]:.1f}"
    )
    print(
        "| L / s | code | fluid / boundary particles | CPU s per simulated s | mean substep (ms) "
        "| iterations (density / divergence) per substep | mean compression % | front Z/L at T |"
    )
    print("|---:|---|---:|---:|---:|---:|---:|---:|")
    for per_l in spacings:
        for name, run in (("kinema", kinema_seconds), ("SPlisHSPlasH", splishsplash)):
            r = run(per_l, seconds)
            print(
                f"| {per_l} | {name} | {r['particles']} / {r['boundary']} | {r['cpu_per_s']:.2f} "
                f"| {1e3 * r['dt']:.3f} | {r['iterations']:.1f} / {r['iterations_v']:.1f} "
                f"| {r['compression']:.3f} | {r['front']:.2f} at {r['T']:.2f} |"
            )


def scaling(frames: int, million: bool) -> None:
    """Print kinema's DFSPH at its defaults on the dam break at 10k, 100k (and 1M) particles."""
    threads = os.environ.get("KINEMA_NUM_THREADS", "all")
    print(
        f"DFSPH scaling, {frames} frames of 1/60 s after the first; threads {threads}; load {os.getloadavg()[0]:.1f}"
    )
    print(
        "| L / s | fluid / boundary particles | ms/frame, CPU ms (substeps) | "
        "µs of CPU per particle and substep | compression % |"
    )
    print("|---:|---:|---:|---:|---:|")
    for per_l in (24, 50, 108) if million else (24, 50):
        fluid = dam(L / per_l, "dfsph")
        ms, cpu, substeps, err = kinema_frames(fluid, frames)
        n, nb = len(fluid), len(fluid.boundary_particles)
        print(
            f"| {per_l} | {n} / {nb} | {ms:.0f}, {cpu:.0f} ({substeps:.0f}) "
            f"| {1e3 * cpu / (n * substeps):.2f} | {err:.3f} |",
            flush=True,
        )


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--spacings", type=int, nargs="+", default=[10, 20])
    parser.add_argument("--frames", type=int, default=6)
    parser.add_argument("--splishsplash", type=float, metavar="SECONDS")
    parser.add_argument("--scaling", action="store_true")
    parser.add_argument("--million", action="store_true")
    parser.add_argument("--child", nargs=3, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        splishsplash_child(int(args.child[0]), float(args.child[1]), args.child[2])
    if args.splishsplash:
        side_by_side(args.spacings, args.splishsplash)
        return
    if args.scaling:
        scaling(args.frames, args.million)
        return
    print(
        f"threads: kinema {os.environ.get('KINEMA_NUM_THREADS', 'all')}, numpy 1; load {os.getloadavg()[0]:.1f}"
    )
    print(
        "| L / s | fluid particles | boundary particles | DFSPH ms/frame, CPU ms (substeps) | PBF "
        "ms/frame (substeps) | WCSPH ms/frame, CPU ms (substeps) | numpy WCSPH ms/frame, CPU ms "
        "| numpy / kinema WCSPH, wall / CPU | compression % (DFSPH / WCSPH / numpy) |"
    )
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---|")
    for per_l in args.spacings:
        s = L / per_l
        results = {}
        for solver in ("dfsph", "pbf", "wcsph"):
            fluid = dam(s, solver)
            results[solver] = kinema_frames(fluid, args.frames)
        ref_fluid = dam(s, "wcsph")
        ref = NumpyWcsph(ref_fluid, s)
        per_frame = max(1, round(results["wcsph"][2]))
        for _ in range(per_frame):  # the first frame, as kinema's
            ref.substep(FRAME / per_frame)
        start, cpu = time.perf_counter(), time.process_time()
        for _ in range(args.frames):
            for _ in range(per_frame):
                err = ref.substep(FRAME / per_frame)
        ms_ref = 1e3 * (time.perf_counter() - start) / args.frames
        cpu_ref = 1e3 * (time.process_time() - cpu) / args.frames
        n = len(ref_fluid)
        nb = len(ref_fluid.boundary_particles)
        d, p, w = results["dfsph"], results["pbf"], results["wcsph"]
        print(
            f"| {per_l} | {n} | {nb} | {d[0]:.1f}, {d[1]:.1f} ({d[2]:.0f}) | {p[0]:.1f} ({p[2]:.0f}) "
            f"| {w[0]:.1f}, {w[1]:.1f} ({w[2]:.0f}) | {ms_ref:.1f}, {cpu_ref:.1f} "
            f"| {ms_ref / w[0]:.1f}x / {cpu_ref / w[1]:.1f}x "
            f"| {d[3]:.3f} / {w[3]:.3f} / {err:.3f} |"
        )


if __name__ == "__main__":
    main()
