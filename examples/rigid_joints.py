"""A chain of five hinged links released horizontal, once per joint formulation, and a door
on a hinge with limits driven by a motor.

Run: python examples/rigid_joints.py
"""

import math

from kinema.rigid import METHODS, Box, Hinge, World


def chain(method: str) -> World:
    world = World(collisions=False)
    for i in range(5):
        world.add_body(Box([0.2, 0.02, 0.02]), mass=0.5, position=[0.2 + 0.4 * i, 0, 0])
        # Link i hangs from link i - 1 (the first from the world) about z.
        world.add_joint(Hinge(i, i - 1 if i else None, [0.4 * i, 0, 0], [0, 0, 1]), method)
    return world


for method in METHODS:
    world = chain(method)
    e0 = world.kinetic_energy() + world.potential_energy()
    world.step(1e-3, 3000)
    drift = world.joint_violations[:, 0].max()
    de = world.kinetic_energy() + world.potential_energy() - e0
    print(f"{method:>8}: joint drift {drift:.1e} m, energy change {de:+.2f} J after 3 s")

# A door (1 m wide, 20 kg) hinged about +y to a fixed post, opened by a motor at 1 rad/s with at
# most 5 N m (it accelerates at 5 / I = 0.75 rad/s²) until its limit at 90 degrees stops it.
# The hinge angle is the door's (b) relative to the post (a).
world = World()
post = world.add_body(Box([0.05, 1.0, 0.05]), mass=1.0, position=[-0.05, 1.0, 0], fixed=True)
door = world.add_body(Box([0.5, 1.0, 0.02]), mass=20.0, position=[0.5, 1.0, 0])
world.add_joint(
    Hinge(
        post, door, [0, 1, 0], [0, 1, 0], limits=(0.0, math.pi / 2), motor_speed=1.0, max_torque=5.0
    )
)
for _ in range(4):
    world.step(1e-3, 1000)
    angle, rate = world.joint_coordinates[0]
    print(f"door angle {angle:.3f} rad, opening at {rate:.3f} rad/s")
