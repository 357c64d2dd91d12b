"""A box spun about its intermediate axis flips over (the Dzhanibekov effect), while the
world angular momentum stays constant.

Run: python examples/rigid_tumbling.py
"""

import numpy as np

from kinema.rigid import Box, World

world = World(gravity=[0, 0, 0])
world.add_body(Box([1.0, 0.6, 0.2]), mass=2.0, angular_velocity=[1e-3, 5.0, 1e-3])
print("inertia (kg m^2):", np.round(np.diag(world.bodies[0].inertia), 4))
L0 = world.angular_momentum()
for k in range(5):
    world.step(0.002, 500)
    print(f"t = {(k + 1):.0f} s, world angular velocity {np.round(world.angular_velocities[0], 3)}")
print("angular momentum drift:", np.linalg.norm(world.angular_momentum() - L0))
