"""Rigid bodies: kinema against MuJoCo and PyBullet in one process, speed beside accuracy.

1. Free bodies: N boxes (0.2 x 0.4 x 0.6 m, 1 kg) tumbling under gravity with random angular
   velocities, no contacts, dt = 1/240 s. Accuracy: the drift of the total spin angular
   momentum about the bodies' centres (conserved exactly by the physics) and of the rotational
   kinetic energy, relative, after the run.
2. Boxes on a plane: N boxes (0.2 m cubes, 1 kg) dropped in a loose grid from up to ~1 m onto
   the ground (friction 0.5), 2 s at dt = 1/240 s. Accuracy: the deepest penetration into the
   ground and the largest speed left at the end (they should be at rest).

Each engine uses its defaults except: no damping (PyBullet's default 0.04 set to 0), the same
time step, Y up. MuJoCo steps in C (``mj_step`` with ``nstep``), kinema in Rust (one ``step``
call), PyBullet one ``stepSimulation`` per step (its only way). Peers that are not installed
are skipped.

Run: python bench/bench_rigid.py [--quick]

A/B of the box drops alone (kinema and MuJoCo alternated, best and median of R runs each, and a
hash of kinema's end state, which must not change when a change is meant to be bitwise):
python bench/bench_rigid.py --drops 100 400 1000 --repeat R
"""

from __future__ import annotations

import argparse
import hashlib
import time

import numpy as np

from kinema.rigid import Box, World
from kinema.rotation import Rotation

DT = 1.0 / 240.0
HALF = np.array([0.1, 0.2, 0.3])  # free bodies' half extents (m)
CUBE = 0.1  # contact boxes' half extent (m)


def spin_state(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions, orientations (w x y z) and world angular velocities of the free bodies."""
    rng = np.random.default_rng(0)
    x = rng.uniform(-20, 20, (n, 3))
    q = Rotation.random(n, rng=1).as_quat()
    w = rng.normal(scale=3.0, size=(n, 3))
    return x, q, w


def drop_state(n: int) -> np.ndarray:
    """Centres of the dropped boxes: a grid of columns 0.3 m apart, up to 4 layers high."""
    side = int(np.ceil(np.sqrt(n / 4)))
    rng = np.random.default_rng(2)
    pts = [
        (0.3 * (i % side), 0.15 + 0.25 * layer + 0.02 * rng.random(), 0.3 * (i // side))
        for layer in range(4)
        for i in range(side * side)
    ]
    return np.array(pts[:n])


def spin_invariants(q: np.ndarray, w: np.ndarray, inertia: np.ndarray) -> tuple[np.ndarray, float]:
    """Total spin angular momentum (world) and rotational kinetic energy."""
    r = Rotation.from_quat(q).as_matrix()
    i_world = r @ inertia @ np.transpose(r, (0, 2, 1))
    ang = np.einsum("nij,nj->ni", i_world, w)
    return ang.sum(axis=0), 0.5 * float(np.einsum("ni,ni->", w, ang))


def box_inertia(half: np.ndarray, mass: float = 1.0) -> np.ndarray:
    a, b, c = (2 * half) ** 2
    return np.diag([b + c, a + c, a + b]) * mass / 12.0


def drift(start: tuple[np.ndarray, float], end: tuple[np.ndarray, float]) -> tuple[float, float]:
    dl = np.linalg.norm(end[0] - start[0]) / np.linalg.norm(start[0])
    return float(dl), abs(end[1] - start[1]) / start[1]


# ----------------------------------------------------------------------------- kinema
def kinema_free(n: int, steps: int) -> tuple[float, tuple[float, float]]:
    x, q, w = spin_state(n)
    world = World(collisions=False)
    for i in range(n):
        world.add_body(
            Box(HALF),
            mass=1.0,
            position=x[i],
            orientation=Rotation.from_quat(q[i]),
            angular_velocity=w[i],
        )
    inertia = box_inertia(HALF)
    before = spin_invariants(world.orientations, world.angular_velocities, inertia)
    start = time.perf_counter()
    world.step(DT, steps)
    seconds = time.perf_counter() - start
    return seconds, drift(
        before, spin_invariants(world.orientations, world.angular_velocities, inertia)
    )


def kinema_drop(n: int, steps: int) -> tuple[float, float, float, str]:
    """Seconds, deepest penetration, largest end speed and a hash of the end state."""
    world = World()
    world.add_ground(friction=0.5)
    for p in drop_state(n):
        world.add_body(Box([CUBE] * 3), mass=1.0, position=p, friction=0.5)
    start = time.perf_counter()
    world.step(DT, steps)
    seconds = time.perf_counter() - start
    lowest = _lowest_corner(world.positions, world.orientations)
    speed = float(np.linalg.norm(world.velocities, axis=1).max())
    digest = hashlib.sha256()
    for a in (world.positions, world.velocities, world.orientations, world.angular_velocities):
        digest.update(np.ascontiguousarray(a).tobytes())
    return seconds, max(0.0, -lowest), speed, digest.hexdigest()[:16]


def _lowest_corner(x: np.ndarray, q: np.ndarray) -> float:
    corners = np.array([[a, b, c] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)]) * CUBE
    r = Rotation.from_quat(q).as_matrix()
    return float((np.einsum("nij,kj->nki", r, corners)[..., 1] + x[:, None, 1]).min())


# ----------------------------------------------------------------------------- MuJoCo
def mujoco_model(bodies: str, ground: bool) -> object:
    import mujoco

    plane = '<geom type="plane" size="50 50 0.1" zaxis="0 1 0" friction="0.5"/>' if ground else ""
    xml = f"""<mujoco><option timestep="{DT}" gravity="0 -9.81 0"/>
    <worldbody>{plane}{bodies}</worldbody></mujoco>"""
    return mujoco.MjModel.from_xml_string(xml)


def mujoco_free(n: int, steps: int) -> tuple[float, tuple[float, float]] | None:
    try:
        import mujoco
    except ImportError:
        return None
    x, q, w = spin_state(n)
    sx, sy, sz = HALF
    bodies = "".join(
        f'<body pos="{p[0]} {p[1]} {p[2]}" quat="{o[0]} {o[1]} {o[2]} {o[3]}"><freejoint/>'
        f'<geom type="box" size="{sx} {sy} {sz}" mass="1" contype="0" conaffinity="0"/></body>'
        for p, o in zip(x, q, strict=True)
    )
    model = mujoco_model(bodies, ground=False)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    qv = data.qvel.reshape(n, 6)
    # A free joint's angular velocity is in the body frame.
    qv[:, 3:] = Rotation.from_quat(q).apply(w, inverse=True)
    inertia = box_inertia(HALF)

    def invariants() -> tuple[np.ndarray, float]:
        quat = data.qpos.reshape(n, 7)[:, 3:]
        omega = Rotation.from_quat(quat).apply(data.qvel.reshape(n, 6)[:, 3:])
        return spin_invariants(quat, omega, inertia)

    before = invariants()
    start = time.perf_counter()
    mujoco.mj_step(model, data, nstep=steps)
    seconds = time.perf_counter() - start
    return seconds, drift(before, invariants())


def mujoco_drop(n: int, steps: int) -> tuple[float, float, float] | None:
    try:
        import mujoco
    except ImportError:
        return None
    bodies = "".join(
        f'<body pos="{p[0]} {p[1]} {p[2]}"><freejoint/>'
        f'<geom type="box" size="{CUBE} {CUBE} {CUBE}" mass="1" friction="0.5"/></body>'
        for p in drop_state(n)
    )
    model = mujoco_model(bodies, ground=True)
    data = mujoco.MjData(model)
    start = time.perf_counter()
    mujoco.mj_step(model, data, nstep=steps)
    seconds = time.perf_counter() - start
    qpos = data.qpos.reshape(n, 7)
    lowest = _lowest_corner(qpos[:, :3], qpos[:, 3:])
    speed = float(np.linalg.norm(data.qvel.reshape(n, 6)[:, :3], axis=1).max())
    return seconds, max(0.0, -lowest), speed


# ----------------------------------------------------------------------------- PyBullet
def _bullet() -> tuple[object, int] | None:
    try:
        import pybullet as p
    except ImportError:
        return None
    client = p.connect(p.DIRECT)
    p.setGravity(0, -9.81, 0, physicsClientId=client)
    p.setTimeStep(DT, physicsClientId=client)
    return p, client


def _xyzw(q: np.ndarray) -> list[float]:
    return [float(q[1]), float(q[2]), float(q[3]), float(q[0])]


def bullet_free(n: int, steps: int) -> tuple[float, tuple[float, float]] | None:
    got = _bullet()
    if got is None:
        return None
    p, c = got
    x, q, w = spin_state(n)
    shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=HALF.tolist(), physicsClientId=c)
    ids = []
    for i in range(n):
        b = p.createMultiBody(1.0, shape, -1, x[i].tolist(), _xyzw(q[i]), physicsClientId=c)
        p.setCollisionFilterGroupMask(b, -1, 0, 0, physicsClientId=c)
        p.changeDynamics(b, -1, linearDamping=0.0, angularDamping=0.0, physicsClientId=c)
        p.resetBaseVelocity(b, [0, 0, 0], w[i].tolist(), physicsClientId=c)
        ids.append(b)
    inertia = box_inertia(HALF)

    def invariants() -> tuple[np.ndarray, float]:
        quat = np.array([p.getBasePositionAndOrientation(b, physicsClientId=c)[1] for b in ids])
        omega = np.array([p.getBaseVelocity(b, physicsClientId=c)[1] for b in ids])
        return spin_invariants(quat[:, [3, 0, 1, 2]], omega, inertia)

    before = invariants()
    start = time.perf_counter()
    for _ in range(steps):
        p.stepSimulation(physicsClientId=c)
    seconds = time.perf_counter() - start
    out = drift(before, invariants())
    p.disconnect(c)
    return seconds, out


def bullet_drop(n: int, steps: int) -> tuple[float, float, float] | None:
    got = _bullet()
    if got is None:
        return None
    p, c = got
    plane = p.createCollisionShape(p.GEOM_PLANE, planeNormal=[0, 1, 0], physicsClientId=c)
    ground = p.createMultiBody(0, plane, physicsClientId=c)
    p.changeDynamics(ground, -1, lateralFriction=0.5, physicsClientId=c)
    shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=[CUBE] * 3, physicsClientId=c)
    ids = []
    for pos in drop_state(n):
        b = p.createMultiBody(1.0, shape, -1, pos.tolist(), physicsClientId=c)
        p.changeDynamics(
            b, -1, lateralFriction=0.5, linearDamping=0.0, angularDamping=0.0, physicsClientId=c
        )
        ids.append(b)
    start = time.perf_counter()
    for _ in range(steps):
        p.stepSimulation(physicsClientId=c)
    seconds = time.perf_counter() - start
    pose = [p.getBasePositionAndOrientation(b, physicsClientId=c) for b in ids]
    x = np.array([a for a, _ in pose])
    q = np.array([o for _, o in pose])[:, [3, 0, 1, 2]]
    v = np.array([p.getBaseVelocity(b, physicsClientId=c)[0] for b in ids])
    p.disconnect(c)
    return seconds, max(0.0, -_lowest_corner(x, q)), float(np.linalg.norm(v, axis=1).max())


def drops_ab(sizes: list[int], steps: int, repeat: int) -> None:
    """The box drops alone, kinema and MuJoCo alternated `repeat` times: steps/s best and
    median, penetration, end speed and the hash of kinema's end state."""
    print(f"box drops, {steps} steps of 1/240 s, {repeat} alternated runs each\n")
    print("| boxes | engine | steps/s best | steps/s median | penetration (m) | end speed (m/s) |")
    print("|---:|---|---:|---:|---:|---:|")
    for n in sizes:
        runs: dict[str, list[tuple]] = {"kinema": [], "MuJoCo": []}
        for _ in range(repeat):
            runs["kinema"].append(kinema_drop(n, steps))
            peer = mujoco_drop(n, steps)
            if peer is not None:
                runs["MuJoCo"].append(peer)
        for name, r in runs.items():
            if r:
                rates = [steps / x[0] for x in r]
                best, median = max(rates), float(np.median(rates))
                print(
                    f"| {n} | {name} | {best:.0f} | {median:.0f} | {r[0][1]:.1e} | {r[0][2]:.1e} |"
                )
        hashes = {x[3] for x in runs["kinema"]}
        print(f"| {n} | kinema end-state hash | {', '.join(sorted(hashes))} | | | |")


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true", help="small sizes, short runs")
    parser.add_argument("--drops", type=int, nargs="+", help="only these box drops, A/B form")
    parser.add_argument("--repeat", type=int, default=5, help="runs of each drop with --drops")
    parser.add_argument("--steps", type=int, default=480, help="steps of each drop with --drops")
    args = parser.parse_args()
    if args.drops:
        drops_ab(args.drops, args.steps, args.repeat)
        return
    n_free, free_steps = (200, 240) if args.quick else (1000, 2400)
    drops, drop_steps = ([100], 240) if args.quick else ([100, 400, 1000], 480)

    print(f"### {n_free} free bodies, {free_steps} steps of 1/240 s (no contacts)\n")
    print("| engine | steps/s | kinema / engine | spin momentum drift | rotational energy drift |")
    print("|---|---:|---:|---:|---:|")
    rows = [
        ("kinema", kinema_free(n_free, free_steps)),
        ("MuJoCo", mujoco_free(n_free, free_steps)),
        ("PyBullet", bullet_free(n_free, free_steps)),
    ]
    ours = free_steps / rows[0][1][0]  # type: ignore[index]
    for name, r in rows:
        if r is None:
            print(f"| {name} | not installed | | | |")
            continue
        rate = free_steps / r[0]
        print(f"| {name} | {rate:.0f} | {ours / rate:.2f}x | {r[1][0]:.1e} | {r[1][1]:.1e} |")

    for n in drops:
        print(f"\n### {n} boxes dropped on a plane, {drop_steps} steps of 1/240 s\n")
        print(
            "| engine | steps/s | kinema / engine | deepest penetration (m) | largest speed at the end (m/s) |"
        )
        print("|---|---:|---:|---:|---:|")
        drop_rows = [
            ("kinema", kinema_drop(n, drop_steps)),
            ("MuJoCo", mujoco_drop(n, drop_steps)),
            ("PyBullet", bullet_drop(n, drop_steps)),
        ]
        ours = drop_steps / drop_rows[0][1][0]  # type: ignore[index]
        for name, d in drop_rows:
            if d is None:
                print(f"| {name} | not installed | | | |")
                continue
            rate = drop_steps / d[0]
            print(f"| {name} | {rate:.0f} | {ours / rate:.2f}x | {d[1]:.1e} | {d[2]:.1e} |")


if __name__ == "__main__":
    main()
