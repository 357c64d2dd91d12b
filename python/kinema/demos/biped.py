"""Biped demo: the planar SIMBICON walker (Yin, Loken & van de Panne 2007) on flat ground.

Writes ``biped.gif`` (the stick figure walking, pushed from behind at t = 4 s with 350 N for
0.2 s, and recovering) and ``biped.png`` (the centre of mass's speed and height, the foot
contacts). Prints the walking speed, the steps taken and the largest push survived of a
sweep (a push at 4 s to the torso for 0.2 s, from behind and from the front). dt = 1e-3 s.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from kinema.character import Biped

DT = 1e-3
FRAME = 1.0 / 30.0  # s between recorded frames


def walk(seconds: float, push: float = 0.0, at: float = 4.0) -> tuple[Biped, dict[str, Any]]:
    """Walk ``seconds`` s; ``push``: a force (N, +x forward) on the torso for 0.2 s at ``at``
    s. Returns the biped and its record per frame (joint positions, COM, contacts)."""
    b = Biped()
    per = round(FRAME / DT)
    log: dict[str, list[Any]] = {"joints": [], "com": [], "feet": [], "fell": [False]}
    for k in range(round(seconds / FRAME)):
        if push and k == round(at / FRAME):
            b.push(push, 0.2)
        b.step(DT, per)
        log["joints"].append(b.positions())
        log["com"].append(b.com)
        log["feet"].append(b.feet_in_contact)
        if b.q[1] < 0.7 or abs(b.q[2]) > 0.8:
            log["fell"] = [True]
            break
    return b, log


def largest_push(sign: float, forces: list[float], seconds: float) -> float:
    """The largest of ``forces`` (N, in increasing order) survived in direction ``sign``."""
    best = 0.0
    for f in forces:
        if walk(seconds, sign * f)[1]["fell"][0]:
            break
        best = f
    return best


def _figure(pose: np.ndarray, x0: float, ax: Any) -> None:
    hip = pose[0]
    ax.plot([hip[0], hip[0]], [hip[1], hip[1] + 0.48], "k-", lw=5)
    for leg, colour in ((pose[1:4], "tab:red"), (pose[4:7], "tab:blue")):
        pts = np.vstack([hip, leg[1], leg[2]])
        ax.plot(pts[:, 0], pts[:, 1], "-o", color=colour, lw=3, ms=3)
        ax.plot([leg[2][0] - 0.05, leg[2][0] + 0.15], [leg[2][1] - 0.07] * 2, color=colour)
    ax.axhline(0.0, color="0.5")
    ax.set_xlim(x0 - 1.0, x0 + 1.0)
    ax.set_ylim(-0.1, 1.6)
    ax.set_aspect("equal")


def run(out_dir: Path, quick: bool) -> dict[str, object]:
    """Walk, render ``biped.gif`` and ``biped.png``, sweep pushes, return the numbers."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation, PillowWriter

    seconds = 5.0 if quick else 10.0
    b, log = walk(seconds, push=350.0)
    com = np.array(log["com"])
    t = FRAME * np.arange(1, len(com) + 1)
    half = len(t) // 2
    speed = (com[-1, 0] - com[half, 0]) / (t[-1] - t[half])

    fig, ax = plt.subplots(figsize=(6, 4))
    every = 2 if quick else 1
    poses = log["joints"][::every]

    def frame(k: int) -> None:
        ax.clear()
        _figure(poses[k], poses[k][0][0], ax)
        now = (k * every + 1) * FRAME
        pushed = " (pushed)" if 4.0 <= now < 4.2 else ""
        ax.set_title(f"SIMBICON, t = {now:.2f} s{pushed}")

    gif = out_dir / "biped.gif"
    FuncAnimation(fig, frame, frames=len(poses)).save(gif, writer=PillowWriter(fps=15))
    plt.close(fig)

    fig, axes = plt.subplots(1, 2, figsize=(11, 3.5))
    v = np.gradient(com[:, 0], t)
    axes[0].plot(t, v, label="COM speed (m/s)")
    axes[0].plot(t, com[:, 1], label="COM height (m)")
    axes[0].axvspan(4.0, 4.2, color="0.85", label="350 N push")
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

    forces = [350.0] if quick else [100.0 * k for k in range(2, 11)]
    sweep_seconds = 5.0 if quick else 7.0
    return {
        "seconds": seconds,
        "fell": log["fell"][0],
        "speed_m_per_s": round(float(speed), 3),
        "steps": b.steps,
        "largest_push_from_behind_N": largest_push(1.0, forces, sweep_seconds),
        "largest_push_from_the_front_N": largest_push(-1.0, forces, sweep_seconds),
        "files": [str(gif), str(png)],
    }
