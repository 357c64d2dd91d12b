"""The work–precision diagram of kinema's fixed-step integrators on a spring chain.

A chain of 100 particles of 100 g on undamped springs (40 N/m) swinging under gravity from a
pinned end is stepped for 2 s by each method at five time steps; kinema.sweep.trade compares every run's
final positions with a reference run (RK4 at dt = 1e-4 s), measures its wall time (the fastest
of five runs) and draws
the diagram into sweep_work_precision.png: error against time, one line per method. The
observed order of each method (slope of log error against log dt) is printed beside the order
it should have (kinema.ode.METHODS).

Run: python examples/sweep_work_precision.py
"""

import os

import numpy as np

from kinema.ode import METHODS
from kinema.particles import Gravity, ParticleSystem, Springs
from kinema.sweep import trade

N, T = 100, 2.0  # particles, seconds simulated


def build(method: str, dt: float) -> tuple[ParticleSystem, str, float]:
    x = np.zeros((N, 3))
    x[:, 0] = np.arange(N) * 0.01  # horizontal at rest length: it swings down
    chain = ParticleSystem(x, masses=np.r_[np.inf, np.full(N - 1, 0.1)])
    chain.add(Springs([[i, i + 1] for i in range(N - 1)], 40.0))
    chain.add(Gravity())
    return chain, method, dt


def run(system: tuple[ParticleSystem, str, float]) -> dict[str, np.ndarray]:
    chain, method, dt = system
    chain.step(dt, steps=round(T / dt), method=method)
    return {"positions": chain.positions.copy()}


if __name__ == "__main__":
    quick = bool(os.environ.get("KINEMA_QUICK"))
    methods = ["symplectic_euler", "velocity_verlet", "rk4"]
    dts = [0.02, 0.01, 0.005] if quick else [0.02, 0.01, 0.005, 0.0025, 0.00125]
    table = trade(
        build,
        run,
        reference={"method": "rk4", "dt": 1e-4},
        dts=dts,
        methods=methods,
        repeat=1 if quick else 5,  # the fastest of 5 runs: a busy machine only adds time
        plot="sweep_work_precision.png",
    )
    print(table[["method", "dt", "deviation", "seconds"]].to_string(index=False))
    for method in methods:
        rows = table[table["method"] == method]
        order = np.polyfit(np.log(rows["dt"]), np.log(rows["deviation"]), 1)[0]
        print(f"{method}: observed order {order:.2f} (expected {METHODS[method]})")
        assert abs(order - METHODS[method]) < 0.3 * METHODS[method]
    print("wrote sweep_work_precision.png")
