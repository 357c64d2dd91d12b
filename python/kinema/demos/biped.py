"""Biped demo: the 3-D SIMBICON walker (Yin, Loken & van de Panne 2007, §5) on flat ground,
and a limp ragdoll falling down stairs.

Writes ``biped.gif`` (the 3-D biped walking, seen from the side and from the front, pushed
from its left side (+z) at t = 4 s with 100 N for 0.2 s, and recovering), ``biped.png``
(the centre of mass's forward speed, its sideways position, the foot contacts) and
``stairs.gif`` / ``stairs.png`` (the CMU 07 ragdoll thrown forward at 1.5 m/s from the top
of five box steps of 0.18 m by 0.30 m, friction 0.4, tumbling down them, seen from the
side). Prints the
walking speed, the steps taken and the largest push survived of a sweep (a push at 4 s to
the torso for 0.2 s) by the 3-D walker from the side and by the planar walker from behind
and from the front (the planar walker's own figure is gone; its numbers stay). dt = 1e-3 s.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from kinema import geometry, mocap
from kinema.character import Biped, Ragdoll
from kinema.demos._gif import save_gif_and_last_frame

DT = 1e-3
FRAME = 1.0 / 30.0  # s between recorded frames
SIDE_PUSH = 100.0  # N, the GIF's push from the side (survived at 4 phases, docs/character.md)


def walk(
    seconds: float, push: Any = 0.0, at: float = 4.0, dims: int = 2
) -> tuple[Biped, dict[str, Any]]:
    """Walk ``seconds`` s; ``push``: a force (N: a number along +x, or 3 values) on the torso
    for 0.2 s at ``at`` s. Returns the biped and its record per frame (joint positions, COM,
    contacts)."""
    b = Biped(dims=dims)
    per = round(FRAME / DT)
    log: dict[str, list[Any]] = {"joints": [], "rot": [], "com": [], "feet": [], "fell": [False]}
    for k in range(round(seconds / FRAME)):
        if np.any(push) and k == round(at / FRAME):
            b.push(push, 0.2)
        b.step(DT, per)
        log["joints"].append(b.positions())
        log["rot"].append(b.orientations())
        log["com"].append(b.com)
        log["feet"].append(b.feet_in_contact)
        if b.q[1] < 0.7 or _tilt(b) > 0.8:
            log["fell"] = [True]
            break
    return b, log


def _tilt(b: Biped) -> float:
    """The torso's angle from the vertical (rad)."""
    if b.dims == 2:
        return abs(float(b.q[2]))
    _, x, _, z = b.q[3:7]
    return float(np.arccos(np.clip(1.0 - 2.0 * (x * x + z * z), -1.0, 1.0)))


def largest_push(
    direction: tuple[float, float, float], forces: list[float], seconds: float, dims: int
) -> float:
    """The largest of ``forces`` (N, in increasing order) survived along ``direction``."""
    best = 0.0
    for f in forces:
        if walk(seconds, np.multiply(f, direction), dims=dims)[1]["fell"][0]:
            break
        best = f
    return best


def _rotate(q: np.ndarray, v: Any) -> np.ndarray:
    """``v`` turned by the unit quaternion ``q = (w, x, y, z)``."""
    w, u = q[0], np.asarray(q[1:])
    t = 2.0 * np.cross(u, v)
    return np.asarray(v) + w * t + np.cross(u, t)


def _figure(pose: np.ndarray, rot: np.ndarray, centre: np.ndarray, axes: Any) -> None:
    """The 3-D biped's links as lines (hip, knee, ankle, toe) and its torso, seen from the
    side (x–y) and from the front (z–y)."""
    up = _rotate(rot[0], [0.0, 0.48, 0.0])
    hips = [pose[1], pose[5]]
    for ax, (i, lo, hi) in zip(axes, ((0, -1.0, 1.0), (2, -0.6, 0.6)), strict=True):
        ax.plot([pose[0][i], pose[0][i] + up[i]], [pose[0][1], pose[0][1] + up[1]], "k-", lw=5)
        ax.plot([hips[0][i], hips[1][i]], [hips[0][1], hips[1][1]], "k-", lw=3)
        for leg, colour in (((1, 2, 3), "tab:red"), ((5, 6, 7), "tab:blue")):
            toe = pose[leg[2]] + _rotate(rot[leg[2]], [0.15, -0.05, 0.0])
            pts = np.vstack([pose[leg[0]], pose[leg[1]], pose[leg[2]], toe])
            ax.plot(pts[:, i], pts[:, 1], "-o", color=colour, lw=3, ms=3)
        ax.axhline(0.0, color="0.5")
        ax.set_xlim(centre[i] + lo, centre[i] + hi)
        ax.set_ylim(-0.1, 1.6)
        ax.set_aspect("equal")


STAIRS = (5, 0.18, 0.30)  # steps, rise (m), run (m), going down along +x
STAIRS_FRICTION = 0.4  # the steps' Coulomb μ (with 1 the ragdoll stops lying across them)
DATA = Path(__file__).resolve().parent.parent / "data"


def staircase(n: int, rise: float, run: float) -> list[geometry.Box]:
    """``n`` box steps going down along +x from a landing: step ``k`` spans ``x`` from ``k
    run`` to ``(k + 1) run`` (the landing from ``x = −1``) and ``y`` from the floor to
    ``(n − k) rise``, each of friction :data:`STAIRS_FRICTION`."""
    boxes = []
    for k in range(n):
        x0, x1, top = (-1.0 if k == 0 else k * run), (k + 1) * run, (n - k) * rise
        centre, half = ((x0 + x1) / 2, top / 2, 0.0), ((x1 - x0) / 2, top / 2, 1.5)
        boxes.append(geometry.Box(centre, half, friction=STAIRS_FRICTION))
    return boxes


def tumble(seconds: float) -> tuple[Ragdoll, list[np.ndarray], list[float]]:
    """The limp CMU 07 ragdoll (self-collision on) thrown forward at 1.5 m/s from the top
    of :data:`STAIRS`, ``seconds`` s at 1/480 s. Returns it, its capsules' world axis ends
    ``(bodies, 2, 3)`` per frame and its energy (J, kinetic + gravitational) at the start
    and after each frame."""
    n, rise, run = STAIRS
    r = Ragdoll.from_skeleton(mocap.read_asf(DATA / "07-walk.asf"), clearance=0.05)
    r.configure(self_collision=True)
    for box in staircase(n, rise, run):
        r.add_collider(box)
    q, qd = r.q.copy(), r.qd.copy()
    q[0] -= 0.3
    q[1] += n * rise
    qd[3] = 1.5
    r.q, r.qd = q, qd
    capsules = r.capsules()
    frames, energy = [], [sum(r.energy())]
    for _ in range(round(seconds / FRAME)):
        r.step(1.0 / 480.0, 16)
        x, rot = r.positions(), r.orientations()
        ends = [
            [x[i] + _rotate(rot[i], c[0]), x[i] + _rotate(rot[i], c[1])]
            for i, c in enumerate(capsules)
            if c is not None
        ]
        frames.append(np.array(ends))
        energy.append(sum(r.energy()))
    return r, frames, energy


def _stairs_gif(out_dir: Path, frames: list[np.ndarray], every: int) -> tuple[Path, Path]:
    """The side view (x–y) of the tumble: the steps and the ragdoll's capsules as lines."""
    import matplotlib.pyplot as plt

    n, rise, run = STAIRS
    fig, ax = plt.subplots(figsize=(6, 4))

    def draw(k: int) -> None:
        ax.clear()
        xs, ys = [-1.0], [n * rise]
        for j in range(n):
            xs += [(j + 1) * run, (j + 1) * run]
            ys += [(n - j) * rise, (n - j - 1) * rise]
        xs, ys = [*xs, 3.5], [*ys, 0.0]
        ax.fill_between(xs, ys, color="0.8")
        ax.plot(xs, ys, color="0.4")
        for a, b in frames[k]:
            ax.plot([a[0], b[0]], [a[1], b[1]], "-", color="tab:red", lw=3, solid_capstyle="round")
        ax.set_xlim(-1.0, 3.5)
        ax.set_ylim(-0.05, 2.3)
        ax.set_aspect("equal")
        ax.set_title(f"limp CMU ragdoll down 5 box steps, t = {(k + 1) * FRAME:.2f} s", fontsize=9)

    return save_gif_and_last_frame(fig, draw, range(0, len(frames), every), out_dir / "stairs", 15)


def run(out_dir: Path, quick: bool) -> dict[str, object]:
    """Walk, render ``biped.gif`` and ``biped.png``, sweep pushes, return the numbers."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation, PillowWriter

    seconds = 5.0 if quick else 10.0
    side = (0.0, 0.0, SIDE_PUSH)
    b, log = walk(seconds, push=side, dims=3)
    com = np.array(log["com"])
    t = FRAME * np.arange(1, len(com) + 1)
    half = len(t) // 2
    speed = (com[-1, 0] - com[half, 0]) / (t[-1] - t[half])

    fig, axes = plt.subplots(1, 2, figsize=(8, 4), gridspec_kw={"width_ratios": [2, 1.2]})
    every = 2 if quick else 1
    poses = log["joints"][::every]
    rots = log["rot"][::every]

    def frame(k: int) -> None:
        for ax in axes:
            ax.clear()
        _figure(poses[k], rots[k], poses[k][0], axes)
        now = (k * every + 1) * FRAME
        pushed = f" (pushed {SIDE_PUSH:.0f} N from the side)" if 4.0 <= now < 4.2 else ""
        axes[0].set_title(f"3-D SIMBICON, t = {now:.2f} s{pushed}", fontsize=9)
        axes[1].set_title("front view", fontsize=9)

    gif = out_dir / "biped.gif"
    FuncAnimation(fig, frame, frames=len(poses)).save(gif, writer=PillowWriter(fps=15))
    plt.close(fig)

    fig, axes = plt.subplots(1, 2, figsize=(11, 3.5))
    v = np.gradient(com[:, 0], t)
    axes[0].plot(t, v, label="COM speed (m/s)")
    axes[0].plot(t, com[:, 2], label="COM sideways, +z (m)")
    axes[0].axvspan(4.0, 4.2, color="0.85", label=f"{SIDE_PUSH:.0f} N push (+z)")
    axes[0].set_xlabel("time (s)")
    axes[0].legend(fontsize=8)
    feet = np.array(log["feet"], dtype=float)
    axes[1].plot(t, feet[:, 0] + 0.05, label="right foot down")
    axes[1].plot(t, feet[:, 1] - 0.05, label="left foot down")
    axes[1].set_xlabel("time (s)")
    axes[1].legend(fontsize=8)
    fig.tight_layout()
    png = out_dir / "biped.png"
    fig.savefig(png, dpi=100)
    plt.close(fig)

    ragdoll, tumbled, energy = tumble(4.0 if quick else 6.0)
    stairs = _stairs_gif(out_dir, tumbled, 2 if quick else 1)

    forces = [350.0] if quick else [100.0 * k for k in range(2, 11)]
    sides = [100.0] if quick else [50.0 * k for k in range(1, 7)]
    sweep_seconds = 5.0 if quick else 7.0
    return {
        "seconds": seconds,
        "fell": log["fell"][0],
        "speed_m_per_s": round(float(speed), 3),
        "steps": b.steps,
        "3d_largest_push_from_the_left_N": largest_push((0, 0, 1), sides, sweep_seconds, 3),
        "3d_largest_push_from_the_right_N": largest_push((0, 0, -1), sides, sweep_seconds, 3),
        "planar_largest_push_from_behind_N": largest_push((1, 0, 0), forces, sweep_seconds, 2),
        "planar_largest_push_from_the_front_N": largest_push((-1, 0, 0), forces, sweep_seconds, 2),
        "stairs_energy_J": [round(energy[0], 1), round(max(energy), 1), round(energy[-1], 1)],
        "stairs_rest_com_m": [round(float(v), 3) for v in ragdoll.com],
        "files": [str(gif), str(png), *map(str, stairs)],
    }
