"""Crowd demo: ORCA's circle crossing (van den Berg et al. 2011, RVO2's example), a
social-force bottleneck evacuation through a door (Helbing, Farkas & Vicsek 2000) and ORCA
agents drawn as a CMU walk cycle (kinema.walkcycle) as GIFs, and a flock of boids steering
round spheres to a goal (Reynolds 1999) as a picture; with the numbers: collisions, mean
time to goal, flow through the door."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from kinema import mocap
from kinema.crowd import RVO2_CIRCLE, Crowd, crossings, door_goals, flow_rate
from kinema.flock import Flock
from kinema.geometry import Sphere
from kinema.walkcycle import WalkCycle


def _gif(frames: list[np.ndarray], radius: float, walls: list[Any], title: str, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation, PillowWriter

    everything = np.concatenate(frames)
    lo, hi = everything.min(axis=0) - 1, everything.max(axis=0) + 1
    fig, ax = plt.subplots(figsize=(5.0, 5.0))
    size = (72 * 5.0 * 2 * radius / float((hi - lo).max())) ** 2

    def draw(k: int) -> None:
        ax.cla()
        for wall in walls:
            w = np.asarray(wall, dtype=np.float64)
            closed = np.concatenate([w, w[:1]]) if len(w) > 2 else w
            ax.plot(closed[:, 0], closed[:, 1], "k-", lw=2)
        p = frames[k]
        ax.scatter(p[:, 0], p[:, 1], s=size, c=np.arange(len(p)), cmap="hsv")
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal")
        ax.set_title(f"{title}, frame {k}")

    FuncAnimation(fig, draw, frames=range(len(frames))).save(path, writer=PillowWriter(fps=15))
    plt.close(fig)


def _circle(out_dir: Path, quick: bool) -> dict[str, object]:
    n, r = (24, 30.0) if quick else (64, 60.0)
    c = Crowd(**RVO2_CIRCLE)
    a = np.arange(n) * 2 * np.pi / n
    start = r * np.stack([np.cos(a), np.sin(a)], axis=1)
    # Starts moved by up to 0.5 m: an exactly symmetric ring deadlocks (docs/crowd.md).
    start += np.random.default_rng(0).uniform(-0.5, 0.5, start.shape)
    c.add_agents(start, -start)
    frames = []
    for _ in range(100 if quick else 250):
        c.step(0.25, 4)
        frames.append(c.positions.copy())
    _gif(
        frames[::2], RVO2_CIRCLE["radius"], [], "ORCA circle crossing", out_dir / "crowd_circle.gif"
    )
    m = c.metrics()
    return {
        "circle: agents arrived": f"{m['arrived']} of {n}",
        "circle: mean time to goal (s)": round(m["mean_time_to_goal"], 1),
        "circle: overlapping pair-steps": m["agent_collisions"],
    }


def _bottleneck(out_dir: Path, quick: bool) -> dict[str, object]:
    n, door = (40, 1.2) if quick else (100, 1.2)
    c = Crowd("social_force", radius=0.25, neighbour_distance=2.0, max_substep=0.01)
    half = door / 2
    walls = [
        [[0, -6], [0, -half]],
        [[0, half], [0, 6]],
        [[-10, -6], [0, -6]],
        [[-10, 6], [0, 6]],
        [[-10, -6], [-10, 6]],
    ]
    for w in walls:
        c.add_obstacle(w)
    rng = np.random.default_rng(0)
    side = int(np.ceil(np.sqrt(n)))
    grid = np.array(
        [[-1.0 - 0.7 * (k // side), -0.7 * (side - 1) / 2 + 0.7 * (k % side)] for k in range(n)]
    )
    c.add_agents(grid + rng.uniform(-0.05, 0.05, grid.shape), np.tile([6.0, 0.0], (n, 1)))
    # Every step: to the nearest point of the door (e⁰ points to the exit, Helbing et al.),
    # then to (6, 0) once through.
    door_line = [[0.0, half], [0.0, -half]]
    frames, times = [], []
    for _ in range(300 if quick else 600):
        goals = door_goals(c.positions, door_line, 0.25)
        goals[c.positions[:, 0] > 0.0] = [6.0, 0.0]
        c.set_goals(goals)
        c.step(0.1)
        frames.append(c.positions.copy())
        times.append(c.time)
    found = crossings(np.array(frames), np.array(times), door_line)
    _gif(
        frames[::4], 0.25, walls, f"social forces, {door} m door", out_dir / "crowd_bottleneck.gif"
    )
    m = c.metrics()
    return {
        "bottleneck: agents out": f"{found.size} of {n}",
        "bottleneck: flow (1/s)": round(flow_rate(found), 2),
        "bottleneck: wall penetrations": m["obstacle_collisions"],
    }


def _walkers(out_dir: Path, quick: bool) -> dict[str, object]:
    """ORCA agents crossing a circle, drawn as the CMU 07_05 walk cycle played by the
    distance each has walked (kinema.walkcycle), preferred speed the clip's own."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation, PillowWriter

    skeleton = mocap.read_asf(mocap.SAMPLE_DIR / "07-walk.asf")
    cycle = WalkCycle(skeleton, mocap.read_amc(mocap.SAMPLE_DIR / "07_05-walk.amc", skeleton))
    n = 6 if quick else 12
    c = Crowd("orca", radius=0.3, preferred_speed=cycle.speed, perturbation=0.05)
    a = np.arange(n) * 2 * np.pi / n
    start = 5.0 * np.stack([np.cos(a), np.sin(a)], axis=1)
    c.add_agents(start, -start)
    poses = []  # (frames, agents, joints, 3)
    for _ in range(140 if quick else 200):
        c.step(0.1)
        poses.append(cycle.pose(c.positions, c.velocities, c.metrics()["path_lengths"]))
    bones = [(j, int(p)) for j, p in enumerate(skeleton.parents) if p >= 0]
    fig = plt.figure(figsize=(5.0, 4.0))
    ax = fig.add_subplot(projection="3d")

    def draw(k: int) -> None:
        ax.cla()
        for joints in poses[k]:
            for j, p in bones:
                # World (x, y up, z) drawn as (x, z, y) so that up is up in the picture.
                ax.plot(*joints[[j, p]][:, [0, 2, 1]].T, "k-", lw=0.8)
        ax.set_xlim(-6, 6)
        ax.set_ylim(-6, 6)
        ax.set_zlim(0, 2)
        ax.set_box_aspect((12, 12, 2), zoom=2.2)
        ax.view_init(elev=30, azim=-60)
        ax.set_axis_off()
        ax.set_title(f"ORCA crossing, CMU 07_05 walk cycle, t = {0.1 * (k + 1):.1f} s")

    FuncAnimation(fig, draw, frames=range(0, len(poses), 4)).save(
        out_dir / "crowd_walkers.gif", writer=PillowWriter(fps=5)
    )
    plt.close(fig)
    m = c.metrics()
    return {
        "walkers: agents arrived": f"{m['arrived']} of {n}",
        "walkers: walk cycle speed (m/s)": round(cycle.speed, 3),
    }


def _flock(out_dir: Path, quick: bool) -> dict[str, object]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = 60 if quick else 200
    rng = np.random.default_rng(1)
    f = Flock(rng.uniform(-3, 3, (n, 2)), rng.uniform(-1, 1, (n, 2)), max_force=3.0)
    balls = [Sphere([12.0, 1.0, 0.0], 2.0), Sphere([22.0, -2.0, 0.0], 2.5)]
    for b in balls:
        f.add_behaviour("avoid", shape=b, horizon=1.5, clearance=0.5, weight=3.0)
    f.add_behaviour("arrive", target=[35.0, 0.0], slow_radius=5.0, weight=0.5)
    trail, inside = [], 0
    for _ in range(400):
        f.step(0.05)
        trail.append(f.positions.copy())
        for b in balls:
            inside += int(np.sum(np.linalg.norm(f.positions - b.center[:2], axis=1) < b.radius))
    fig, ax = plt.subplots(figsize=(8.0, 3.5))
    path = np.array(trail)
    for k in range(0, n, max(1, n // 30)):
        ax.plot(path[:, k, 0], path[:, k, 1], lw=0.5)
    for b in balls:
        ax.add_patch(plt.Circle(b.center[:2], b.radius, color="0.6"))
    ax.set_aspect("equal")
    ax.set_title("boids: flocking + avoid two spheres + arrive at x = 35 m")
    png = out_dir / "flock.png"
    fig.savefig(png, dpi=100)
    plt.close(fig)
    return {
        "flock: polarisation at the end": round(f.polarisation(), 3),
        "flock: boid-steps inside a sphere": inside,
    }


def run(out_dir: Path, quick: bool) -> dict[str, object]:
    """Run the four scenes, write ``crowd_circle.gif``, ``crowd_bottleneck.gif``,
    ``crowd_walkers.gif`` and ``flock.png``, and return their numbers."""
    return {
        **_circle(out_dir, quick),
        **_bottleneck(out_dir, quick),
        **_walkers(out_dir, quick),
        **_flock(out_dir, quick),
    }
