"""Social forces through a bottleneck (Helbing, Farkas & Vicsek 2000's model and
parameters: m 80 kg, τ 0.5 s, A 2000 N, B 0.08 m, k 1.2·10⁵ kg/s², κ 2.4·10⁵ kg/(m s);
substeps of 5 ms in steps of 0.05 s; neighbour distance 2 m; max speed twice the desired
speed, which bounds only the fastest pushes), at full size:

1. the flow through a door against its width: `--agents` (150) agents of radius 0.25 m
   at 1.34 m/s on a grid of 10 rows 0.7 m apart in front of a wall 0.2 m thick,
   for doors of 0.8–2.4 m, the steady flow (crossings of the door's far side, the first and
   last 10 dropped), as published and with the time gap 0.065 s that gives Weidmann's
   fundamental diagram (docs/crowd.md), against the Jülich experiments (Liddle et al. 2011, as tabulated in
   JuPedSim's `Utest/testflow.py`; Seyfried et al. 2009: about 1.9 /(m s)); the table, and
   the plot `docs/images/crowd_bottleneck_flow.png`;
2. ORCA through the same doors (kinema's ORCA defaults, max speed 2 m/s), with its default
   planning margin 0.1 and without (0), and RVO2 (`pyrvo`, when installed) on the same
   set-up, the steady flow averaged over seeds 0–2 (those with more than 20 crossings;
   `--orca` agents, 150; 0 skips it);
3. "faster is slower" (Helbing et al. 2000, Fig. 1c): `--panic` (200) agents of radius
   0.3 m (Helbing's radii are 0.25–0.35 m) on a grid of 20 rows 0.75 m apart leave through a
   1 m door at desired speeds 0.6–5 m/s; the time for the first 90 %
   and for all of them to leave.

Every agent walks to the nearest point of the door's far side narrowed by its radius at each
jamb (Helbing et al.: e⁰ points to the exit), then straight on (`kinema.crowd.door_goals`;
the same set-up as `tests/crowd_bottleneck.rs`, which runs it at reduced size).

Run: python bench/bench_bottleneck.py [--quick] [--agents 150] [--orca 150] [--panic 200] [--no-plot]
(--quick: 40 agents in each, no plot: a smoke run, not the figures.)
"""

from __future__ import annotations

import argparse
import importlib.util
import time
from pathlib import Path

import numpy as np

from kinema.crowd import Crowd, crossings, door_goals, flow_rate

# Jülich bottleneck experiments (Liddle, Seyfried, Steffen, Klingsch, Rupprecht, Winkens &
# Boltes 2011, arXiv:1105.1532): width (m) and flow 150 / (t_last - t_first) (1/s).
LIDDLE_2011 = np.array(
    [
        [0.9, 1.710],
        [1.0, 2.025],
        [1.1, 2.194],
        [1.2, 2.532],
        [1.4, 2.911],
        [1.6, 3.115],
        [1.8, 3.906],
        [2.0, 3.910],
        [2.2, 4.524],
        [2.5, 5.547],
    ]
)
DT = 0.05


def evacuate(
    width: float,
    n: int,
    radius: float,
    speed: float,
    rows: int,
    spacing: float,
    seconds: float,
    seed: int = 0,
    time_gap: float = 0.0,
    orca_margin: float | None = None,
) -> np.ndarray:
    """Crossing times (s) of the door's far side by ``n`` agents started on a grid of
    ``rows`` rows ``spacing`` m apart in front of a door of ``width`` m, each moved by up to
    0.1 m (uniform, ``seed``: a symmetric start jams symmetrically); ``time_gap`` (s) is
    the social forces' Seyfried time gap (0: Helbing et al. 2000 as published); with
    ``orca_margin`` ORCA at its defaults with that planning margin instead."""
    if orca_margin is None:
        c = Crowd(
            "social_force",
            radius=radius,
            max_speed=2.0 * speed,
            preferred_speed=speed,
            neighbour_distance=2.0,
            time_gap=time_gap,
        )
    else:
        c = Crowd("orca", radius=radius, preferred_speed=speed, planning_margin=orca_margin)
    half = width / 2
    for lo, hi in [(half, 20.0), (-20.0, -half)]:
        c.add_obstacle([[0.0, lo], [0.2, lo], [0.2, hi], [0.0, hi]])
    i = np.arange(n)
    start = np.stack(
        [-0.5 - radius - spacing * (i // rows), spacing * ((i % rows) - (rows - 1) / 2)], axis=1
    )
    start += np.random.default_rng(seed).uniform(-0.1, 0.1, start.shape)
    c.add_agents(start, start)
    frames = [start]
    far_side = [[0.2, half], [0.2, -half]]
    while len(frames) * DT < seconds:
        c.set_goals(door_goals(c.positions, far_side, radius))
        c.step(DT)
        frames.append(c.positions.copy())
        if np.all(frames[-1][:, 0] > 0.2):
            break
    t = np.arange(len(frames)) * DT
    return crossings(np.array(frames), t, far_side)


def evacuate_rvo2(width: float, n: int, seconds: float, seed: int) -> np.ndarray:
    """``evacuate``'s ORCA set-up (kinema's defaults, radius 0.25 m, 1.34 m/s) in RVO2
    (``pyrvo``): the same walls, starts and goals, the preferred velocity towards the goal at
    1.34 m/s (or landing on it), no separation and no planning margin (RVO2 has neither)."""
    import pyrvo

    sim = pyrvo.RVOSimulator(DT, 5.0, 10, 5.0, 2.0, 0.25, 2.0)
    half = width / 2
    for lo, hi in [(half, 20.0), (-20.0, -half)]:
        sim.add_obstacle([(0.0, lo), (0.2, lo), (0.2, hi), (0.0, hi)])
    sim.process_obstacles()
    i = np.arange(n)
    start = np.stack([-0.75 - 0.7 * (i // 10), 0.7 * ((i % 10) - 4.5)], axis=1)
    start += np.random.default_rng(seed).uniform(-0.1, 0.1, start.shape)
    for p in start:
        sim.add_agent((float(p[0]), float(p[1])))
    frames = [start]
    far_side = [[0.2, half], [0.2, -half]]
    while len(frames) * DT < seconds:
        d = door_goals(frames[-1], far_side, 0.25) - frames[-1]
        length = np.linalg.norm(d, axis=1, keepdims=True)
        pref = np.where(length > 1.34 * DT, d * (1.34 / np.maximum(length, 1e-12)), d / DT)
        for k in range(n):
            sim.set_agent_pref_velocity(k, (float(pref[k, 0]), float(pref[k, 1])))
        sim.do_step()
        q = [sim.get_agent_position(k) for k in range(n)]
        frames.append(np.array([[a.x, a.y] for a in q]))
        if np.all(frames[-1][:, 0] > 0.2):
            break
    t = np.arange(len(frames)) * DT
    return crossings(np.array(frames), t, far_side)


def steady(times: np.ndarray, drop: int = 10) -> float:
    return flow_rate(times[drop : len(times) - drop]) if len(times) > 2 * drop + 1 else np.nan


def flows(n: int, plot: bool) -> None:
    widths = [0.8, 1.0, 1.2, 1.6, 2.0, 2.4]
    print(f"flow through a door: {n} agents, radius 0.25 m, 1.34 m/s, 120 s at most")
    print(
        "| width (m) | out | steady flow (1/s) | per width (1/(m s)) | with time gap 0.065 s: flow"
        " | per width | Liddle 2011 (1/s) | CPU s |"
    )
    print("|---|---|---|---|---|---|---|---|")
    rows = []
    for w in widths:
        t0 = time.process_time()
        c = evacuate(w, n, 0.25, 1.34, 10, 0.7, 120.0)
        g = evacuate(w, n, 0.25, 1.34, 10, 0.7, 120.0, time_gap=0.065)
        j, jg = steady(c), steady(g)
        exp = np.interp(w, LIDDLE_2011[:, 0], LIDDLE_2011[:, 1], left=np.nan)
        rows.append((w, j, jg))
        cpu = time.process_time() - t0
        print(
            f"| {w:.1f} | {c.size}, {g.size} | {j:.2f} | {j / w:.2f} | {jg:.2f} | {jg / w:.2f} "
            f"| {exp:.2f} | {cpu:.1f} |",
            flush=True,
        )
    if plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        r = np.array(rows)
        fig, ax = plt.subplots(figsize=(5.5, 4.0))
        ax.plot(r[:, 0], r[:, 1], "o-", label="social forces (Helbing et al. 2000)")
        ax.plot(r[:, 0], r[:, 2], "s-", label="the same, time gap 0.065 s")
        ax.plot(LIDDLE_2011[:, 0], LIDDLE_2011[:, 1], "kD", label="Liddle et al. 2011 (Jülich)")
        w = np.linspace(0.7, 2.5, 2)
        ax.plot(w, 1.9 * w, "k--", lw=1, label="1.9 w (Seyfried et al. 2009)")
        ax.set_xlabel("door width w (m)")
        ax.set_ylabel("steady flow J (1/s)")
        ax.set_title(f"bottleneck flow against width, {n} agents")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        out = Path(__file__).resolve().parent.parent / "docs" / "images"
        fig.tight_layout()
        fig.savefig(out / "crowd_bottleneck_flow.png", dpi=100)
        plt.close(fig)


def orca_flows(n: int) -> None:
    have_rvo2 = importlib.util.find_spec("pyrvo") is not None
    print(f"ORCA through a door: {n} agents, radius 0.25 m, 1.34 m/s, 120 s at most, seeds 0-2")
    print(
        "| width (m) | out, margin 0 | flow (1/s) | out, margin 0.1 | flow (1/s) "
        "| out, RVO2 | flow (1/s) | Liddle 2011 |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for w in [0.8, 1.0, 1.2, 1.6, 2.0, 2.4]:
        cells = []
        for m in [0.0, 0.1, None]:
            if m is None and not have_rvo2:
                cells += ["pyrvo not installed", "-"]
                continue
            runs = [
                evacuate(w, n, 0.25, 1.34, 10, 0.7, 120.0, seed, orca_margin=m)
                if m is not None
                else evacuate_rvo2(w, n, 120.0, seed)
                for seed in range(3)
            ]
            out = "/".join(str(t.size) for t in runs)
            cells += [out, f"{np.nanmean([steady(t) for t in runs]):.2f}"]
        exp = np.interp(w, LIDDLE_2011[:, 0], LIDDLE_2011[:, 1], left=np.nan)
        print(f"| {w:.1f} | {' | '.join(cells)} | {exp:.2f} |", flush=True)


def panic(n: int) -> None:
    print(f"faster is slower: {n} agents, radius 0.3 m, 1 m door, 300 s at most")
    print("| desired speed (m/s) | out | 90 % out (s) | all out (s) | CPU s |")
    print("|---|---|---|---|---|")
    for v0 in [0.6, 1.0, 1.5, 2.0, 3.0, 4.0, 5.0]:
        t0 = time.process_time()
        c = evacuate(1.0, n, 0.3, v0, 20, 0.75, 300.0)
        k = int(np.ceil(0.9 * n)) - 1
        t90 = c[k] if c.size > k else np.nan
        t_all = c[n - 1] if c.size >= n else np.nan
        cpu = time.process_time() - t0
        print(f"| {v0:.1f} | {c.size} | {t90:.1f} | {t_all:.1f} | {cpu:.1f} |", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--agents", type=int, default=150)
    ap.add_argument("--orca", type=int, default=150)
    ap.add_argument("--panic", type=int, default=200)
    ap.add_argument("--no-plot", action="store_true")
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args()
    if a.quick:
        a.agents, a.orca, a.panic, a.no_plot = 40, 40, 40, True
    flows(a.agents, not a.no_plot)
    if a.orca:
        orca_flows(a.orca)
    panic(a.panic)


if __name__ == "__main__":
    main()
