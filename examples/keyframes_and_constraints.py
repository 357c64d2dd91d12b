"""Keyframe a bouncing ball, then hang a rope of rods from a pin.

Run: python examples/keyframes_and_constraints.py
"""

import numpy as np

from kinema.anim import Track
from kinema.constraints import ConstrainedSystem, Distance
from kinema.particles import Gravity, ParticleSystem

height = Track(
    [0.0, 0.5, 1.0, 1.4], [2.0, 0.0, 1.0, 0.0], interpolation="kochanek_bartels", tension=0.5
)
print(
    "ball height at 0.25 s:",
    round(height(0.25), 4),
    "velocity:",
    round(height.derivative()(0.25), 4),
)

n = 30
x = np.column_stack([np.arange(n) * 0.1, np.zeros(n), np.zeros(n)])
masses = np.full(n, 0.05)
masses[0] = np.inf  # pinned
rope = ParticleSystem(x, masses=masses)
rope.add(Gravity())
rods = ConstrainedSystem(rope)
for i in range(n - 1):
    rods.add(Distance(i, i + 1))
rods.step(1 / 60, 60, method="projection")
print("rope end after 1 s:", np.round(rope.positions[-1], 3), "violation:", rods.violation())
