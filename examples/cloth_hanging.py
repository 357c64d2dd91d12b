"""A cloth pinned at two corners, stepped at the frame rate with the Baraff–Witkin model.

Compares the two solvers of the implicit step (modified PCG and sparse Cholesky) and an
explicit integrator on the same cloth, and prints what each costs.
"""

import time

import numpy as np

import kinema
from kinema.cloth import Cloth


def hang(solver: str) -> tuple[Cloth, float]:
    cloth = Cloth.grid(20, 20, 1.0, 1.0, stretch=5e3, shear=5e2, damping=5e-3, air_damping=0.5)
    cloth.pin([0, 19])
    start = time.perf_counter()
    cloth.step(1 / 60, 120, solver=solver, tol=1e-6)
    return cloth, time.perf_counter() - start


pcg, t_pcg = hang("multigrid")
chol, t_chol = hang("cholesky")
print(
    f"2 s of a 20x20 cloth at dt = 1/60: PCG {t_pcg * 1e3:.0f} ms, Cholesky {t_chol * 1e3:.0f} ms"
)
print(
    f"largest difference between the solvers: {np.abs(pcg.positions - chol.positions).max():.1e} m"
)
print(f"lowest point: {pcg.positions[:, 1].min():.3f} m, energy: {pcg.energy()}")

explicit = Cloth.grid(20, 20, 1.0, 1.0, stretch=5e3, shear=5e2, damping=5e-3, air_damping=0.5)
explicit.pin([0, 19])
try:
    explicit.step(1 / 60, 10, integrator="symplectic_euler")
    print("symplectic Euler at dt = 1/60: survived")
except kinema.SimulationError as error:
    print(f"symplectic Euler at dt = 1/60: {error}")
