"""The showcase (``kinema demo`` with no name): one :class:`kinema.Scene` with cloth draping
over a moving sphere, a particle fountain, a rigid stack hit by a ball and a motion-captured
walk, stepped on one clock and written as ``showcase.gif`` and ``showcase.png``."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from kinema import anim, cloth, mocap, particles, plot, rigid
from kinema.scene import AnimatedSphere, Character, Scene

DATA = Path(__file__).resolve().parent.parent / "data"


def build(quick: bool) -> Scene:
    """The showcase scene: 30 frames per second, 2 steps per frame."""
    scene = Scene(dt=1 / 30, substeps=2)

    n = 12 if quick else 24
    sheet = cloth.Cloth.grid(n, n, 1.0, 1.0, stretch=2000.0, bend=1e-4, damping=0.02)
    sheet.set_state(sheet.positions + np.array([0.0, 0.9, 0.0]))
    sheet.add_collider(cloth.Plane())
    scene.add(sheet, tol=1e-3)
    path = anim.Track([0.0, 1.5, 3.0], [[0.0, 0.35, 0.0], [0.0, 0.35, 0.25], [0.0, 0.35, 0.0]])
    scene.add(AnimatedSphere(0.3, path))

    fountain = particles.ParticleSystem(np.zeros((0, 3)), capacity=400 if quick else 1500)
    for item in [
        particles.Gravity(),
        particles.Drag(quadratic=0.02),
        particles.Plane(restitution=0.3, friction=0.2),
        particles.Emitter(
            rate=150 if quick else 500,
            position=(-1.5, 0.05, -1.2),
            velocity=(0.0, 3.5, 0.0),
            velocity_spread=0.6,
            lifespan=1.5,
            mass=0.01,
            seed=1,
        ),
    ]:
        fountain.add(item)
    scene.add(fountain)

    world = rigid.World()
    world.add_ground(friction=0.6)
    for k in range(5):
        world.add_body(
            rigid.Box([0.1, 0.1, 0.1]), mass=1.0, position=(-1.5, 0.1 + 0.2 * k, 0.8), friction=0.6
        )
    world.add_body(
        rigid.Sphere(0.1), mass=2.0, position=(-0.6, 0.5, 0.8), velocity=(-3.0, 0.0, 0.0)
    )
    scene.add(world)

    skel = mocap.read_asf(DATA / "07-walk.asf")
    walk = mocap.read_amc(DATA / "07_05-walk.amc", skel)
    scene.add(Character(skel, walk, radius=0.06, offset=(0.9, 0.06, 0.0)))
    return scene


def run(out_dir: Path, quick: bool) -> dict[str, object]:
    """Run and render the showcase; return what happened."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scene = build(quick)
    frames = 15 if quick else 90
    sheet, fountain, world = scene.systems[0], scene.systems[1], scene.systems[2]
    scene.record("0.kinetic_energy")
    start = time.perf_counter()
    gif = out_dir / "showcase.gif"
    plot.render(scene, gif, frames, every=5 if quick else 3)
    seconds = time.perf_counter() - start
    ax = plot.scene(scene)
    png = out_dir / "showcase.png"
    ax.figure.savefig(png, dpi=100)
    plt.close(ax.figure)
    ball = np.linalg.norm(sheet.positions - scene.systems[3].position(scene.time), axis=1)
    return {
        "pictures": f"{gif}, {png}",
        "systems": ", ".join(type(s).__name__ for s in scene.systems),
        "frames, simulated time": f"{scene.frame}, {scene.time:.2f} s",
        "wall time incl. drawing": f"{seconds:.1f} s",
        "cloth vertices, closest approach to the moving sphere (m)": f"{len(sheet)}, {ball.min() - 0.3:.2e}",
        "particles alive": int(fountain.alive.sum()),
        "top box height (m)": f"{world.positions[4, 1]:.3f}",
        "cloth kinetic energy at the end (J)": f"{scene.records['0.kinetic_energy'][-1]:.3g}",
    }
