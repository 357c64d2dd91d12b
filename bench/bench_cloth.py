"""Cloth: milliseconds per implicit step of kinema's Baraff–Witkin cloth on n x n grids at
dt = 1/60 s (each solver and integrator, with CG iterations), side by side in one process with
a straightforward numpy/scipy.sparse implementation of the same method, and the largest stable
step of explicit integration of the same cloth.

The reference implements the same triangle model (stretch, shear, dihedral bending; Gauss–Newton
force Jacobians), the same linear system `(M - h ∂f/∂v - h² ∂f/∂x) Δv = h (f + h ∂f/∂x v)`
assembled with scipy.sparse and solved by scipy's conjugate gradient with a Jacobi
preconditioner on the free degrees of freedom (the pinned ones eliminated), to the same
relative tolerance. Position Based Dynamics (pypbd, Bender et al.) runs the same grid with its
default solver iterations when it is installed: a different method (constraint projection, no
linear solve), what a user wanting speed over accuracy would pick instead.

Run: python bench/bench_cloth.py [--quick] [--sizes 32 64 128 256] [--steps 10]
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
from kinema.cloth import Cloth  # noqa: E402

try:
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla
except ImportError:
    sp = None

MATERIAL = dict(kinema.cloth.MATERIAL)
"""The speed tables' material: the library's default."""
COTTON = {"density": 1.0, "stretch": 1e4, "shear": 1e3, "bend": 1e-3, "damping": 0.1}
"""A cotton-like cloth (areal density 1 kg/m², as in issue #21), for the at-the-defaults table."""
DT = 1.0 / 60.0
TOL = 1e-3
"""The speed tables' PCG tolerance (with step subdivision off); the defaults are tol 1e-6 and
max_strain_change 0.01 (subdivision on), measured in `at_defaults`."""


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

    def step(self, dt: float) -> int:
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
        precond = sp.diags(1.0 / af.diagonal())
        dv = np.zeros(3 * nv)
        iterations = 0

        def count(_: np.ndarray) -> None:
            nonlocal iterations
            iterations += 1

        dv[free], _ = spla.cg(af, b[free], rtol=TOL, M=precond, callback=count)
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


def at_defaults(n: int, material: dict[str, float], steps: int) -> tuple[float, float, float]:
    """ms per step, CG iterations per step and the largest edge stretch (length / rest length)
    of an n x n cloth pinned at two corners, stepped with ``step(dt)`` and no other option: the
    step settings a new user gets (PCG, tol 1e-6, max_strain_change 0.01)."""
    cloth = Cloth.grid(n, n, 1.0, 1.0, **material)
    cloth.pin([0, n - 1])
    cloth.step(DT, 10)
    iterations = 0
    start = time.perf_counter()
    for _ in range(steps):
        cloth.step(DT)
        iterations += cloth.stats["iterations"]
    elapsed = (time.perf_counter() - start) / steps
    x = cloth.positions
    edges = np.concatenate([cloth.triangles[:, [a, b]] for a, b in ((0, 1), (1, 2), (2, 0))])
    rest = kinema_cloth(n).positions
    stretch = np.linalg.norm(x[edges[:, 0]] - x[edges[:, 1]], axis=1) / np.linalg.norm(
        rest[edges[:, 0]] - rest[edges[:, 1]], axis=1
    )
    return elapsed, iterations / steps, float(stretch.max())


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
        "--numpy-max", type=int, default=64, help="largest grid for the numpy reference"
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
    print(
        f"At the defaults a new user gets (`step(dt)`: PCG, tol 1e-6, max_strain_change 0.01),"
        f" dt = 1/60 s, pinned at two corners, {base_steps} steps after 10 (1/3 as many from 128²):"
    )
    print("| grid | material | ms/step | CG its/step | largest edge stretch |")
    print("|---|---|---:|---:|---:|")
    for n in sizes:
        steps = max(2, base_steps if n <= 64 else base_steps // 3)
        for name, material in (
            ("default (0.1 kg/m², stretch 1e3)", MATERIAL),
            ("cotton-like (1 kg/m², stretch 1e4)", COTTON),
        ):
            elapsed, its, stretch = at_defaults(n, material, steps)
            print(f"| {n}² | {name} | {1e3 * elapsed:.1f} | {its:.0f} | {stretch:.3f} |")
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
