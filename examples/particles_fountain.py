"""A particle fountain: an emitter, gravity, drag, a vortex and a ground plane.

Run: python examples/particles_fountain.py
"""

import numpy as np

from kinema.particles import Drag, Emitter, Gravity, ParticleSystem, Plane, Vortex

ps = ParticleSystem(np.zeros((0, 3)), capacity=2000)
ps.add(Emitter(rate=500, velocity=[0, 6, 0], velocity_spread=1.0, lifespan=2.0, mass=0.01, seed=1))
ps.add(Gravity())
ps.add(Drag(quadratic=1e-4))
ps.add(Vortex(center=[0, 0, 0], strength=2.0))
ps.add(Plane(restitution=0.4, friction=0.3))

positions = ps.positions  # a live, read-only view: no copy per step
for frame in range(60):
    ps.step(1 / 240, steps=4)
    if frame % 20 == 19:
        alive = ps.alive
        print(
            f"t = {ps.time:.2f} s: {alive.sum()} particles, highest at {positions[alive, 1].max():.2f} m"
        )
assert np.all(positions[ps.alive, 1] >= 0.0)
