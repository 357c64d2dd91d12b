"""Articulated bodies: a 30-body limp ragdoll in reduced coordinates (``kinema.character``,
Featherstone's ABA) against the same bodies on maximal-coordinate ball joints
(``kinema.rigid``) and against MuJoCo (``mujoco``), in one process.

The ragdoll: a free root (a capsule 0.3 m long, 10 kg) with five chains hanging from it on
ball joints — two legs and two arms of 7 capsules each (0.12 m, 0.6 kg) and a spine of 1
(0.2 m, 3 kg): 30 bodies, 29 ball joints, 93 degrees of freedom. Capsule inertias are
kinema.rigid's (read back from its bodies) and given to the other two. No contact, no
damping, gravity 9.81 m/s². It starts straight, tumbling as one rigid body (root angular
velocity (1, 3, −0.5) rad/s, every body's velocity consistent with it), so the limp chains
flail and every joint moves. Each engine at the defaults a new user gets, dt = 1 ms:
kinema.character symplectic Euler (its default) and RK4; kinema.rigid Lagrange-multiplier
joints (its default method, "splitting" rotation integrator); MuJoCo's default Euler with
its constraint solver idle (no contact, no equality).

Measured over 2 s: cost per step (best of three runs of 2,000 steps, each engine stepped in
one call; MuJoCo by a Python loop of ``mj_step``, whose call overhead is included), the
largest change of kinetic plus potential energy (J; about 80 J of kinetic energy at the
start), the largest joint-anchor separation (m; zero by construction in reduced
coordinates), and the largest body-position difference from kinema.character RK4 at
dt = 0.1 ms (m).

Run: python bench/bench_character.py [--write] (--write replaces the table in
bench/RESULTS.md).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from kinema import character
from kinema.rigid import Ball, Capsule, World

DT, T = 1e-3, 2.0
SPIN = np.array([1.0, 3.0, -0.5])
RESULTS = Path(__file__).with_name("RESULTS.md")
BEGIN, END = "<!-- character:begin -->", "<!-- character:end -->"


def layout() -> list[tuple[int | None, np.ndarray, float, float, float, float]]:
    """``(parent, joint position (world, m), radius, length, mass, sign)`` per body, parents
    first; a capsule hangs below its joint (``sign`` −1) or stands above it (+1)."""
    bodies: list[tuple[int | None, np.ndarray, float, float, float, float]] = [
        (None, np.array([0.0, 1.0, 0.0]), 0.12, 0.3, 10.0, 0.0)
    ]
    chains = [((0.1, 0.85, 0.0), 7, -1.0), ((-0.1, 0.85, 0.0), 7, -1.0)]
    chains += [((0.25, 1.1, 0.0), 7, -1.0), ((-0.25, 1.1, 0.0), 7, -1.0)]
    for start, links, sign in chains:
        parent, at = 0, np.array(start)
        for _ in range(links):
            bodies.append((parent, at.copy(), 0.03, 0.12, 0.6, sign))
            parent, at = len(bodies) - 1, at + sign * np.array([0.0, 0.12, 0.0])
    bodies.append((0, np.array([0.0, 1.15, 0.0]), 0.06, 0.2, 3.0, 1.0))
    return bodies


def centre(body: tuple) -> np.ndarray:
    _, at, _, length, _, sign = body
    return at + sign * np.array([0.0, length / 2, 0.0])


def rigid_world() -> tuple[World, list[tuple[np.ndarray, np.ndarray]]]:
    """The ragdoll in kinema.rigid, and each body's (centre of mass offset, inertia)."""
    w = World(collisions=False)
    root = centre(layout()[0])
    for b in layout():
        c = centre(b)
        w.add_body(
            Capsule(b[2], b[3]),
            mass=b[4],
            position=c,
            velocity=np.cross(SPIN, c - root),
            angular_velocity=SPIN,
        )
    for i, b in enumerate(layout()):
        if b[0] is not None:
            w.add_joint(Ball(i, b[0], b[1]))
    props = [(body.center_of_mass, body.inertia) for body in w.bodies]
    return w, props


def reduced(props: list, integrator: str) -> character.ArticulatedBody:
    m = character.Model()
    bodies = layout()
    for i, b in enumerate(bodies):
        com = centre(b) - b[1] + props[i][0] if b[0] is not None else props[i][0]
        offset = b[1] - bodies[b[0]][1] if b[0] is not None else centre(b)
        if b[0] == 0:  # the root's frame is at its centre
            offset = b[1] - centre(bodies[0])
        m.add_body(
            b[0],
            "free" if b[0] is None else "ball",
            mass=b[4],
            inertia=props[i][1],
            offset=offset,
            com=com,
        )
    body = character.ArticulatedBody(m, ground=False, integrator=integrator)
    qd = np.zeros(body.nv)
    qd[:3] = SPIN  # body axes = world axes at the start
    body.qd = qd
    return body


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``v`` turned by the unit quaternion ``q`` = (w, x, y, z)."""
    w, u = q[0], q[1:]
    return v + 2.0 * np.cross(u, np.cross(u, v) + w * v)


def centres(body: character.ArticulatedBody) -> np.ndarray:
    """World centres of mass of a reduced-coordinate ragdoll's bodies (n, 3)."""
    local = [centre(b) - b[1] if b[0] is not None else np.zeros(3) for b in layout()]
    return np.array(
        [
            p + rotate(q, c)
            for p, q, c in zip(body.positions(), body.orientations(), local, strict=True)
        ]
    )


def mujoco_run(props: list) -> tuple[object, object] | None:
    try:
        import mujoco
    except ImportError:
        return None
    bodies = layout()

    def xml(i: int) -> str:
        b = bodies[i]
        pos = (
            centre(b)
            if b[0] is None
            else b[1] - (centre(bodies[0]) if b[0] == 0 else bodies[b[0]][1])
        )
        com = props[i][0] + (0 if b[0] is None else centre(b) - b[1])
        inertia = np.diag(props[i][1])
        joint = "<freejoint/>" if b[0] is None else '<joint type="ball"/>'
        kids = "".join(xml(k) for k, c in enumerate(bodies) if c[0] == i)
        return (
            f'<body pos="{" ".join(map(str, pos))}">{joint}<inertial pos="{" ".join(map(str, com))}" '
            f'mass="{b[4]}" diaginertia="{" ".join(map(str, inertia))}"/>{kids}</body>'
        )

    text = (
        f'<mujoco><option timestep="{DT}" gravity="0 -9.81 0"><flag contact="disable" energy="enable"/></option>'
        f"<worldbody>{xml(0)}</worldbody></mujoco>"
    )
    model = mujoco.MjModel.from_xml_string(text)
    data = mujoco.MjData(model)
    data.qvel[3:6] = SPIN  # MuJoCo's free joint: [v; ω (body axes)]
    mujoco.mj_forward(model, data)
    return model, data


def mj_energy(model: object, data: object) -> float:
    """MuJoCo's kinetic plus potential energy (its ``energy`` flag is enabled)."""
    import mujoco

    mujoco.mj_forward(model, data)
    return float(data.energy.sum())


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--write", action="store_true", help="update bench/RESULTS.md")
    args = parser.parse_args()
    steps = round(T / DT)
    _, props = rigid_world()
    ref = reduced(props, "rk4")
    ref.step(DT / 10, steps * 10)
    reference = centres(ref)
    rows = []

    def timed(make, run) -> float:
        best = float("inf")
        for _ in range(3):
            sim = make()
            start = time.process_time()
            run(sim)
            best = min(best, (time.process_time() - start) / steps)
        return 1e6 * best

    for name, integ in (
        ("kinema.character ABA, symplectic Euler", "symplectic"),
        ("kinema.character ABA, RK4", "rk4"),
    ):
        body = reduced(props, integ)
        e0, worst = sum(body.energy()), 0.0
        for _ in range(steps // 10):
            body.step(DT, 10)
            worst = max(worst, abs(sum(body.energy()) - e0))
        diff = float(np.abs(centres(body) - reference).max())
        cost = timed(lambda integ=integ: reduced(props, integ), lambda b: b.step(DT, steps))
        rows.append((name, cost, worst, 0.0, diff))
    w, _ = rigid_world()
    e0, worst, drift = w.kinetic_energy() + w.potential_energy(), 0.0, 0.0
    for _ in range(steps // 10):
        w.step(DT, 10)
        worst = max(worst, abs(w.kinetic_energy() + w.potential_energy() - e0))
        drift = max(drift, float(w.joint_violations[:, 0].max()))
    diff = float(np.abs(w.positions - reference).max())  # body origins = centres of mass
    cost = timed(lambda: rigid_world()[0], lambda s: s.step(DT, steps))
    rows.append(("kinema.rigid, Lagrange ball joints", cost, worst, drift, diff))
    mj = mujoco_run(props)
    if mj is not None:
        import mujoco

        model, data = mj
        e0, worst = mj_energy(model, data), 0.0
        for _ in range(steps // 10):
            for _ in range(10):
                mujoco.mj_step(model, data)
            worst = max(worst, abs(mj_energy(model, data) - e0))
        mujoco.mj_kinematics(model, data)
        diff = float(np.abs(data.xipos[1:] - reference).max())

        def run_mj(md: tuple) -> None:
            for _ in range(steps):
                mujoco.mj_step(md[0], md[1])

        cost = timed(lambda: mujoco_run(props), run_mj)
        rows.append((f"MuJoCo {mujoco.__version__}, Euler", cost, worst, 0.0, diff))
    base = rows[0][1]
    lines = [
        "| engine (dt = 1 ms, 30 bodies, 2 s) | µs per step (CPU) | vs ABA | max energy change (J) "
        "| max joint separation (m) | max position difference from RK4 at 0.1 ms (m) |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for name, cost, energy, drift, diff in rows:
        lines.append(
            f"| {name} | {cost:.1f} | {cost / base:.2f} | {energy:.2e} | {drift:.1e} | {diff:.1e} |"
        )
    table = "\n".join(lines)
    print(table)
    if args.write:
        text = RESULTS.read_text()
        start, end = text.index(BEGIN) + len(BEGIN), text.index(END)
        RESULTS.write_text(text[:start] + "\n" + table + "\n" + text[end:])


if __name__ == "__main__":
    main()
