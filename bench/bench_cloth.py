"""Cloth: milliseconds per implicit step of kinema's Baraff–Witkin cloth on n x n grids at
dt = 1/60 s (each solver and integrator, with CG iterations), side by side in one process with
a straightforward numpy/scipy.sparse implementation of the same method, and the largest stable
step of explicit integration of the same cloth.

The reference implements the same triangle model (stretch, shear, dihedral bending; Gauss–Newton
force Jacobians), the same linear system `(M - h ∂f/∂v - h² ∂f/∂x) Δv = h (f + h ∂f/∂x v)`
assembled with scipy.sparse and solved by scipy's conjugate gradient on the free degrees of
freedom (the pinned ones eliminated), preconditioned by pyamg's smoothed aggregation multigrid
with the rigid motions as near-null space (the method of kinema's default solver; the tol-1e-3 table
uses Jacobi) or by Jacobi, to the same relative tolerance. Position Based Dynamics (pypbd, Bender et al.) runs the same grid with its
default solver iterations when it is installed: a different method (constraint projection, no
linear solve), what a user wanting speed over accuracy would pick instead; so does Newton's
Vertex Block Descent (Chen et al. 2024) on the hanging square, on Warp's CPU backend (this
machine has no GPU), when newton is installed.

The first tables run the defaults a new user gets on the cotton-like square hung from two
corners and on a drape over a sphere onto the ground, wall and CPU time (process_time).

Run: python bench/bench_cloth.py [--quick] [--defaults-only] [--sizes 32 64 128 256] [--steps 10]
[--newton-max 64]
(--quick: 16² and 32² grids, 3 steps, the solver trade on 24² for 10 steps, the explicit limit
on an 8² cloth.)
"""

from __future__ import annotations

import argparse
import os
import time

# One thread for the reference too: a multi-threaded BLAS on shared cores made scipy's CG
# 5-10x slower at 64² (each vector dot product waking idle threads), not faster.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

import kinema  # noqa: E402
import kinema.cloth  # noqa: E402
from kinema.cloth import Cloth, Plane, Sphere  # noqa: E402

try:
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla
except ImportError:
    sp = None
try:
    import pyamg
except ImportError:
    pyamg = None

MATERIAL = dict(kinema.cloth.MATERIAL)
"""The speed tables' material: the library's default."""
DT = 1.0 / 60.0
TOL = 1e-3
"""The speed tables' PCG tolerance (with step subdivision off); the defaults are tol 1e-6 and
max_strain_change 0.01 (subdivision on), measured in `defaults_tables`."""


def kinema_cloth(n: int) -> Cloth:
    cloth = Cloth.grid(n, n, 1.0, 1.0, **MATERIAL)
    cloth.pin([0, n - 1])
    return cloth


def time_kinema(n: int, steps: int, integrator: str, solver: str) -> tuple[float, float]:
    cloth = kinema_cloth(n)
    opts = {
        "integrator": integrator,
        "solver": solver,
        "tol": TOL,
        "max_strain_change": float("inf"),
    }
    cloth.step(DT, 10, **opts)
    iterations = 0
    start = time.perf_counter()
    for _ in range(steps):
        cloth.step(DT, **opts)
        iterations += cloth.stats["iterations"]
    return (time.perf_counter() - start) / steps, iterations / steps


class NumpyCloth:
    """The same method written with numpy and scipy.sparse, as a user would."""

    def __init__(self, n: int) -> None:
        cloth = kinema_cloth(n)
        self.x = cloth.positions.copy()
        self.v = np.zeros_like(self.x)
        self.m = cloth.masses.copy()
        self.tri = cloth.triangles
        uv = self.x[:, [0, 2]]
        d1 = uv[self.tri[:, 1]] - uv[self.tri[:, 0]]
        d2 = uv[self.tri[:, 2]] - uv[self.tri[:, 0]]
        det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
        self.area = 0.5 * np.abs(det)
        wu = np.column_stack([d2[:, 1], -d1[:, 1]]) / det[:, None]
        wv = np.column_stack([-d2[:, 0], d1[:, 0]]) / det[:, None]
        self.du = np.column_stack([-wu.sum(1), wu])
        self.dv = np.column_stack([-wv.sum(1), wv])
        edges: dict[tuple[int, int], int] = {}
        hinges = []
        for t in self.tri:
            for k in range(3):
                a, b, c = int(t[k]), int(t[(k + 1) % 3]), int(t[(k + 2) % 3])
                key = (min(a, b), max(a, b))
                if key in edges:
                    hinges.append([a, b, edges[key], c])
                else:
                    edges[key] = c
        self.hinges = np.array(hinges)
        h = self.hinges
        e2 = np.sum((self.x[h[:, 1]] - self.x[h[:, 0]]) ** 2, axis=1)
        a1 = 0.5 * np.linalg.norm(
            np.cross(self.x[h[:, 1]] - self.x[h[:, 0]], self.x[h[:, 2]] - self.x[h[:, 0]]), axis=1
        )
        a2 = 0.5 * np.linalg.norm(
            np.cross(self.x[h[:, 1]] - self.x[h[:, 0]], self.x[h[:, 3]] - self.x[h[:, 0]]), axis=1
        )
        self.kb = MATERIAL["bend"] * 3 * e2 / (a1 + a2)
        self.free = np.ones(3 * len(self.x), bool)
        for i in (0, n - 1):
            self.free[3 * i : 3 * i + 3] = False

    def conditions(self):  # yields (vertex indices, C, gradient (E, N, 3), k)
        x, a = self.x, self.area
        p = x[self.tri]
        wu = np.einsum("en,enk->ek", self.du, p)
        wv = np.einsum("en,enk->ek", self.dv, p)
        for w, d in ((wu, self.du), (wv, self.dv)):
            length = np.linalg.norm(w, axis=1)
            grad = (a / length)[:, None, None] * d[:, :, None] * w[:, None, :]
            yield self.tri, a * (length - 1.0), grad, MATERIAL["stretch"] / a
        c = a * np.sum(wu * wv, axis=1)
        grad = a[:, None, None] * (
            self.du[:, :, None] * wv[:, None, :] + self.dv[:, :, None] * wu[:, None, :]
        )
        yield self.tri, c, grad, MATERIAL["shear"] / a
        h = self.hinges
        xa, xb, xp, xq = (x[h[:, k]] for k in range(4))
        e = xb - xa
        el = np.linalg.norm(e, axis=1)
        n1 = np.cross(xp - xa, xp - xb)
        n2 = np.cross(xq - xb, xq - xa)
        u1 = n1 / np.sum(n1 * n1, axis=1)[:, None]
        u2 = n2 / np.sum(n2 * n2, axis=1)[:, None]
        dot = lambda p_, q_: np.sum(p_ * q_, axis=1)[:, None]  # noqa: E731
        ga = dot(xp - xb, e) / el[:, None] * u1 + dot(xq - xb, e) / el[:, None] * u2
        gb = -dot(xp - xa, e) / el[:, None] * u1 - dot(xq - xa, e) / el[:, None] * u2
        grad = np.stack([ga, gb, el[:, None] * u1, el[:, None] * u2], axis=1)
        m1 = n1 / np.linalg.norm(n1, axis=1)[:, None]
        m2 = n2 / np.linalg.norm(n2, axis=1)[:, None]
        theta = -np.arctan2(np.sum(np.cross(m1, m2) * e, axis=1) / el, np.sum(m1 * m2, axis=1))
        yield h, theta, grad, self.kb

    def step(self, dt: float, tol: float = TOL, multigrid: bool = False) -> int:
        nv = len(self.x)
        f = np.zeros((nv, 3))
        f[:, 1] = -9.81 * self.m
        rows, cols, vals = [], [], []
        damping = MATERIAL["damping"]
        for verts, c, grad, k in self.conditions():
            cdot = np.einsum("enk,enk->e", grad, self.v[verts])
            np.add.at(f, verts, -((k * c + damping * k * cdot)[:, None, None] * grad))
            nn = verts.shape[1]
            # Blocks (α k_d + β k) g_m g_nᵀ of -(h D + h² K), Gauss–Newton.
            weight = dt * damping * k + dt * dt * k
            block = (
                weight[:, None, None, None, None]
                * grad[:, :, None, :, None]
                * grad[:, None, :, None, :]
            )
            r = 3 * verts[:, :, None, None, None] + np.arange(3)[None, None, None, :, None]
            s = 3 * verts[:, None, :, None, None] + np.arange(3)[None, None, None, None, :]
            shape = (len(c), nn, nn, 3, 3)
            rows.append(np.broadcast_to(r, shape).ravel())
            cols.append(np.broadcast_to(s, shape).ravel())
            vals.append(block.ravel())
        m3 = np.repeat(self.m, 3)
        a = sp.coo_matrix(
            (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
            shape=(3 * nv, 3 * nv),
        ).tocsr()
        # K v via the Gauss-Newton blocks: K = -(A - M - h D)/h² ≈ -(blocks)/h² for the stiffness part.
        kv = -(a @ self.v.ravel()) / (dt * dt) * (1.0 / (1.0 + damping / dt))
        a = a + sp.diags(m3)
        b = dt * (f.ravel() + dt * kv)
        free = self.free
        af = a[free][:, free]
        if multigrid:
            # Smoothed aggregation on the free degrees of freedom, with the rigid motions
            # (three translations, three rotations) as near-null space, as kinema's multigrid.
            xf = self.x - self.x.mean(0)
            modes = np.zeros((len(self.x), 3, 6))
            modes[:, :, :3] = np.eye(3)
            modes[:, :, 3:] = np.cross(np.eye(3)[None, :, :], xf[:, None, :]).transpose(0, 2, 1)
            near_null = modes.reshape(3 * len(self.x), 6)[free]
            precond = pyamg.smoothed_aggregation_solver(af, B=near_null).aspreconditioner()
        else:
            precond = sp.diags(1.0 / af.diagonal())
        dv = np.zeros(3 * nv)
        iterations = 0

        def count(_: np.ndarray) -> None:
            nonlocal iterations
            iterations += 1

        dv[free], _ = spla.cg(af, b[free], rtol=tol, M=precond, callback=count, maxiter=20000)
        self.v += dv.reshape(-1, 3)
        self.x += dt * self.v
        return iterations


def time_numpy(n: int, steps: int) -> tuple[float, float]:
    cloth = NumpyCloth(n)
    for _ in range(3):
        cloth.step(DT)
    iterations = 0
    start = time.perf_counter()
    for _ in range(steps):
        iterations += cloth.step(DT)
    return (time.perf_counter() - start) / steps, iterations / steps


def time_pbd(n: int, steps: int) -> float | None:
    """pypbd: an n x n cloth (distance constraints, dihedral bending) pinned at two corners."""
    try:
        import pypbd as pbd
    except ImportError:
        return None
    sim = pbd.Simulation.getCurrent()
    sim.initDefault()
    model = sim.getModel()
    model.cleanup()
    tm = model.addRegularTriangleModel(n, n, scale=np.array([1.0, 1.0]))
    model.addClothConstraints(tm, 1, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, False, False)
    model.addBendingConstraints(tm, 2, 0.01)
    particles = model.getParticles()
    particles.setMass(0, 0.0)
    particles.setMass(n - 1, 0.0)
    pbd.TimeManager.getCurrent().setTimeStepSize(DT)
    stepper = sim.getTimeStep()
    for _ in range(3):
        stepper.step(model)
    start = time.perf_counter()
    for _ in range(steps):
        stepper.step(model)
    return (time.perf_counter() - start) / steps


def newton_hanging(n: int, substeps: int = 10, iterations: int = 10):
    """Newton's VBD (Chen et al. 2024, "Vertex Block Descent") on the hanging square, on this
    machine's CPU (Warp's CPU backend; Newton is built for GPUs): 1 m, n x n vertices, two
    corners pinned, 1 kg/m² spread evenly, gravity along -z (Newton's up axis). Its membrane is
    neo-Hookean with Lamé moduli (μ, λ) per unit rest area; the small-strain match of the
    Baraff–Witkin stretch and shear stiffnesses (`ψ = k_s/2 ε²` along a warp or weft, `k_sh/2 γ²`
    in shear) is μ = k_sh, λ = k_s - 2 k_sh; damping 0.1 s of each stiffness; the dihedral
    bending stiffness as kinema's `bend`. Substeps and iterations as Newton's cloth examples
    (10 x 10 a frame of 1/60 s). Returns a function stepping one frame, one returning the
    positions (N, 3) and the triangles (T, 3), or None when newton is not installed."""
    try:
        import newton
        import warp as wp
    except ImportError:
        return None
    wp.config.quiet = True
    shear, stretch = MATERIAL["shear"], MATERIAL["stretch"]
    spacing = 1.0 / (n - 1)
    builder = newton.ModelBuilder()
    builder.add_cloth_grid(
        pos=wp.vec3(-0.5, -0.5, 0.0),
        rot=wp.quat_identity(),
        vel=wp.vec3(0.0, 0.0, 0.0),
        dim_x=n - 1,
        dim_y=n - 1,
        cell_x=spacing,
        cell_y=spacing,
        mass=MATERIAL["density"] / n**2,
        tri_ke=shear,
        tri_ka=stretch - 2 * shear,
        tri_kd=MATERIAL["damping"] * shear,
        edge_ke=MATERIAL["bend"],
        edge_kd=MATERIAL["damping"] * MATERIAL["bend"],
        particle_radius=0.2 * spacing,
    )
    for corner in (0, n - 1):
        builder.particle_flags[corner] &= ~newton.ParticleFlags.ACTIVE
        builder.particle_mass[corner] = 0.0
    builder.color(include_bending=True)
    model = builder.finalize(device="cpu")
    solver = newton.solvers.SolverVBD(model=model, iterations=iterations)
    states, control = [model.state(), model.state()], model.control()
    pipeline = newton.CollisionPipeline(model)
    contacts = pipeline.contacts()

    def frame() -> None:
        for _ in range(substeps):
            states[0].clear_forces()
            pipeline.collide(states[0], contacts)
            solver.step(states[0], states[1], control, contacts, DT / substeps)
            states.reverse()

    return frame, lambda: states[0].particle_q.numpy(), model.tri_indices.numpy()


def newton_row(n: int, steps: int) -> str:
    """Wall and CPU ms per frame of 1/60 s and the largest edge stretch after 30 + ``steps``
    frames of `newton_hanging(n)`, as table cells."""
    made = newton_hanging(n)
    if made is None:
        return "not installed | | |"
    frame, positions, triangles = made
    rest = positions().copy()
    for _ in range(30):
        frame()
    wall, cpu, _ = timed(lambda: frame() or 0.0, steps)
    return f"{1e3 * wall:.0f} | {1e3 * cpu:.0f} | {edge_stretch(positions(), rest, triangles):.3f}"


def hanging(n: int) -> Cloth:
    """The default (cotton-like) n x n square of 1 m, flat, pinned at two corners."""
    return kinema_cloth(n)


def drape(n: int) -> Cloth:
    """The default n x n square of 1 m dropped from 0.75 m over a sphere of radius 0.3 m
    resting on the ground."""
    cloth = Cloth.grid(n, n, 1.0, 1.0)
    cloth.set_state(cloth.positions + np.array([0.0, 0.75, 0.0]))
    cloth.add_collider(Sphere((0.0, 0.3, 0.0), 0.3))
    cloth.add_collider(Plane())
    return cloth


def largest_stretch(cloth: Cloth, rest: np.ndarray) -> float:
    """The largest edge length over its rest length."""
    return edge_stretch(cloth.positions, rest, cloth.triangles)


def edge_stretch(x: np.ndarray, rest: np.ndarray, triangles: np.ndarray) -> float:
    """The largest length over rest length of the triangles' edges, positions ``x`` and
    ``rest`` (N, 3) m, ``triangles`` (T, 3)."""
    t = triangles
    edges = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    length = np.linalg.norm(x[edges[:, 0]] - x[edges[:, 1]], axis=1)
    return float((length / np.linalg.norm(rest[edges[:, 0]] - rest[edges[:, 1]], axis=1)).max())


def timed(step, steps: int) -> tuple[float, float, float]:
    """Wall and CPU (process_time) seconds per call of ``step`` and its mean return value."""
    total = 0.0
    wall, cpu = time.perf_counter(), time.process_time()
    for _ in range(steps):
        total += step()
    return (
        (time.perf_counter() - wall) / steps,
        (time.process_time() - cpu) / steps,
        total / steps,
    )


def at_defaults(
    scene, n: int, steps: int, **options: float | str
) -> tuple[float, float, float, float, float]:
    """Wall and CPU ms per step, CG iterations and substeps per step, and the largest edge
    stretch at the end, of ``scene(n)`` stepped by ``step(dt, **options)`` (no options: the
    settings a new user gets) after 30 steps (0.5 s)."""
    cloth = scene(n)
    rest = cloth.positions.copy()
    cloth.step(DT, 30, **options)
    substeps = 0.0

    def one() -> float:
        nonlocal substeps
        cloth.step(DT, **options)
        substeps += cloth.stats["substeps"]
        return cloth.stats["iterations"]

    wall, cpu, its = timed(one, steps)
    return 1e3 * wall, 1e3 * cpu, its, substeps / steps, largest_stretch(cloth, rest)


def numpy_at_tol(n: int, steps: int, multigrid: bool) -> tuple[float, float, float]:
    """Wall and CPU ms per step and CG iterations of the numpy/scipy reference on the hanging
    square at tol 1e-6 (pyamg's smoothed aggregation or Jacobi as preconditioner), after 30
    steps."""
    cloth = NumpyCloth(n)
    for _ in range(30):
        cloth.step(DT, 1e-6, multigrid)
    wall, cpu, its = timed(lambda: cloth.step(DT, 1e-6, multigrid), steps)
    return 1e3 * wall, 1e3 * cpu, its


def defaults_tables(sizes: list[int], steps: int, numpy_max: int, newton_max: int) -> None:
    """The at-the-defaults tables (issue #21)."""
    print(
        "At the defaults a new user gets (default cotton-like material; `step(dt)`: sparse"
        " Cholesky, max_strain_change 0.01, max_strain 0.03), dt = 1/60 s, from 0.5 s on;"
        " kinema on one thread:"
    )
    print(
        "| scene | grid | wall ms/step | CPU ms/step | CG its/step | substeps/step | largest edge stretch |"
    )
    print("|---|---|---:|---:|---:|---:|---:|")
    hung = {}
    for name, scene in (("hanging from two corners", hanging), ("drape over a sphere", drape)):
        for n in sizes:
            w, c, its, sub, st = at_defaults(scene, n, steps if n <= 64 else max(2, steps // 3))
            print(f"| {name} | {n}² | {w:.1f} | {c:.1f} | {its:.0f} | {sub:.2f} | {st:.3f} |")
            if scene is hanging:
                hung[n] = (w, c, st)
    print()
    print(
        "The hanging square against Newton's VBD (10 substeps x 10 iterations a frame, as its"
        " cloth examples; Warp's CPU backend, one thread), ms per frame of 1/60 s from 0.5 s on:"
    )
    print(
        "| grid | kinema wall | kinema CPU | kinema stretch | Newton VBD wall | Newton VBD CPU"
        " | Newton VBD stretch |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|")
    for n in (n for n in sizes if n <= newton_max):
        w, c, st = hung[n]
        print(f"| {n}² | {w:.1f} | {c:.1f} | {st:.3f} | {newton_row(n, steps)} |")
    if sp is None:
        return
    print()
    print(
        "The same method (implicit Euler, one Newton step, tol 1e-6, no subdivision, no strain"
        " limit) on the hanging square, kinema against numpy/scipy.sparse (scipy's CG; pyamg's"
        " smoothed aggregation with the rigid modes, rebuilt every step, or Jacobi), CPU ms per"
        " step (wall in brackets), one thread each, one process:"
    )
    print(
        "| grid | kinema multigrid | its | numpy + pyamg SA | its | ratio | numpy + Jacobi | its | ratio |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    same = {
        "solver": "multigrid",
        "tol": 1e-6,
        "max_strain_change": float("inf"),
        "max_strain": float("inf"),
    }
    for n in sizes:
        k = steps if n <= 64 else max(2, steps // 3)
        w, c, its, _, _ = at_defaults(hanging, n, k, **same)
        cells = f"{c:.1f} ({w:.1f}) | {its:.0f}"
        for multigrid in (True, False):
            if n > numpy_max or (multigrid and pyamg is None):
                cells += " | — | — | —"
                continue
            nw, nc, nits = numpy_at_tol(n, max(2, k // 3), multigrid)
            cells += f" | {nc:.0f} ({nw:.0f}) | {nits:.0f} | {nc / c:.0f}x"
        print(f"| {n}² | {cells} |")


def solver_trade(n: int, steps: int) -> list[tuple[str, float, float]]:
    """Time per step and the distance (m) from the Cholesky solution after ``steps`` steps."""
    runs = [("cholesky", 0.0)] + [("multigrid", tol) for tol in (1e-1, 1e-2, 1e-3, 1e-4, 1e-6)]
    results = []
    reference = None
    for solver, tol in runs:
        cloth = kinema_cloth(n)
        start = time.perf_counter()
        cloth.step(DT, steps, solver=solver, tol=tol or 1e-6, max_strain_change=float("inf"))
        elapsed = (time.perf_counter() - start) / steps
        if reference is None:
            reference = cloth.positions.copy()
        error = float(np.abs(cloth.positions - reference).max())
        results.append(
            (solver if solver == "cholesky" else f"multigrid, tol {tol:g}", elapsed, error)
        )
    return results


def explicit_limit(n: int, stretch: float) -> float:
    """Largest step (halving from 1/30 s) at which symplectic Euler survives 0.1 s."""
    dt = 1.0 / 30.0
    while dt > 1e-8:
        cloth = Cloth.grid(
            n, n, 1.0, 1.0, **{**MATERIAL, "stretch": stretch, "shear": stretch / 10}
        )
        cloth.pin([0, n - 1])
        try:
            cloth.step(dt, max(1, round(0.1 / dt)), integrator="symplectic_euler")
            if np.abs(cloth.positions).max() < 10.0:
                return dt
        except kinema.SimulationError:
            pass
        dt /= 2.0
    return 0.0


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="small grids, few steps")
    parser.add_argument(
        "--sizes", type=int, nargs="+", help="default 32 64 128 (16 32 with --quick)"
    )
    parser.add_argument("--steps", type=int, help="default 10 (3 with --quick)")
    parser.add_argument(
        "--numpy-max", type=int, default=128, help="largest grid for the numpy reference"
    )
    parser.add_argument(
        "--newton-max", type=int, default=64, help="largest grid for Newton's VBD (CPU)"
    )
    parser.add_argument(
        "--defaults-only", action="store_true", help="only the at-the-defaults tables"
    )
    args = parser.parse_args()
    sizes = args.sizes or ([16, 32] if args.quick else [32, 64, 128])
    base_steps = args.steps or (3 if args.quick else 10)
    trade_n, trade_steps, explicit_n = (24, 10, 8) if args.quick else (48, 30, 16)
    kinema.set_num_threads(1)
    if sp is None:
        print("scipy: not installed, no numpy/scipy reference")
    print(
        "Threads: kinema 1 (set_num_threads(1)), numpy/scipy 1 (OPENBLAS_NUM_THREADS=1), pypbd its own."
    )
    print()
    defaults_tables(sizes, base_steps, args.numpy_max, args.newton_max)
    if args.defaults_only:
        return
    print()
    print(
        f"Speed at tol {TOL:g}, subdivision off (max_strain_change=inf), default material, dt = 1/60 s:"
    )
    print(
        "| grid | IE + PCG (ms) | CG its | IE + Cholesky (ms) | BDF2 + PCG (ms) | numpy/scipy (ms) | CG its"
        " | ratio numpy / kinema PCG | PBD, pypbd (ms) |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for n in sizes:
        steps = max(2, base_steps if n <= 64 else base_steps // 3)
        t_pcg, it_pcg = time_kinema(n, steps, "implicit_euler", "multigrid")
        t_chol, _ = time_kinema(n, steps, "implicit_euler", "cholesky")
        t_bdf2, _ = time_kinema(n, steps, "bdf2", "multigrid")
        if sp is not None and n <= args.numpy_max:
            t_np, it_np = time_numpy(n, max(2, steps // 2))
            numpy_cells = f"{1e3 * t_np:.1f} | {it_np:.0f} | {t_np / t_pcg:.1f}x"
        else:
            numpy_cells = "— | — | —"
        t_pbd = time_pbd(n, steps)
        pbd_cell = "not installed" if t_pbd is None else f"{1e3 * t_pbd:.1f}"
        print(
            f"| {n}² | {1e3 * t_pcg:.1f} | {it_pcg:.0f} | {1e3 * t_chol:.1f} | {1e3 * t_bdf2:.1f} | {numpy_cells}"
            f" | {pbd_cell} |"
        )
    print()
    print(
        f"Solver trade on a {trade_n}² cloth, {trade_steps} steps (distance from the Cholesky result):"
    )
    print("| solver | ms/step | max distance (m) |")
    print("|---|---:|---:|")
    for name, elapsed, error in solver_trade(trade_n, trade_steps):
        print(f"| {name} | {1e3 * elapsed:.1f} | {error:.1e} |")
    print()
    if args.quick:
        print(f"Explicit integration on an {explicit_n}² cloth:")
    print(
        "| stretch (N/m) | implicit Euler step (s) | largest stable symplectic Euler step (s) | ratio |"
    )
    print("|---:|---:|---:|---:|")
    for stretch in (1e3, 1e6):
        limit = explicit_limit(explicit_n, stretch)
        print(f"| {stretch:.0e} | {1 / 30:.4f} | {limit:.2e} | {1 / 30 / limit:.0f}x |")


if __name__ == "__main__":
    main()
