"""Choosing an integrator: stability limits, orders and a stiff spring.

Run: python examples/ode_stability.py
"""

import numpy as np

from kinema import ode

# The largest stable step for a spring of stiffness k = 100 N/m on 1 kg (eigenvalues ±10i).
eig = [10j, -10j]
for method in ["explicit_euler", "rk4", "symplectic_euler", "velocity_verlet", "implicit_euler"]:
    print(f"{method:17s} max stable dt = {ode.max_stable_dt(method, eig):.4f} s")

# The error of each method on a damped spring, at two steps: the ratio shows the order.
rows = ode.work_precision("damped_spring", ["explicit_euler", "heun", "rk4"], [0.01, 0.005])
for a, b in zip(rows[::2], rows[1::2], strict=True):
    print(
        f"{a.method:15s} error {a.error:.2e} -> {b.error:.2e}, order {np.log2(a.error / b.error):.2f}"
    )

# A stiff spring (k = 1e6) at a frame step: implicit Euler stays bounded, RK4 would explode.
t, y = ode.solve(
    lambda t, y: [y[1], -1e6 * y[0]], [1.0, 0.0], (0, 1), dt=1 / 60, method="implicit_euler"
)
print(f"implicit Euler, k = 1e6, dt = 1/60: |x| after 1 s = {abs(y[-1, 0]):.2e}")
