"""kinema.character: articulated bodies from Python (a pendulum against its period, a
limp ragdoll, pushes, servos, pickling, read-only views, errors naming the argument) and
the MuJoCo oracle (3-link chain and a free ragdoll-like tree, when `mujoco` is installed)."""

from __future__ import annotations

import math
import pickle
from pathlib import Path

import numpy as np
import pytest

import kinema
from kinema import character, mocap

DATA = Path(__file__).resolve().parents[1] / "data" / "mocap"


def pendulum(
    length: float = 0.8, mass: float = 2.0, **settings: object
) -> character.ArticulatedBody:
    m = character.Model()
    m.add_body(None, "revolute", mass=mass, inertia=np.eye(3) * 0.01, com=(0, -length, 0))
    return character.ArticulatedBody(m, ground=False, **settings)


def test_pendulum_swings_with_its_small_angle_period():
    p = pendulum(integrator="rk4")
    p.q = [1e-3]
    period = 2 * math.pi * math.sqrt((0.01 + 2.0 * 0.64) / (2.0 * 9.81 * 0.8))
    p.step(period / 1000, 1000)
    assert p.q[0] == pytest.approx(1e-3, rel=1e-4)
    p.step(period / 2000, 1000)
    assert p.q[0] == pytest.approx(-1e-3, rel=1e-4)
    assert p.time == pytest.approx(1.5 * period)


def test_views_are_read_only_and_follow_the_steps():
    p = pendulum()
    q = p.q
    with pytest.raises(ValueError):
        q[0] = 1.0
    p.q = [0.5]
    p.step(0.01, 10)
    assert q[0] == p.q[0] != 0.5
    del p
    assert np.isfinite(q[0])


def test_limp_ragdoll_falls_and_rests():
    sk = mocap.read_asf(DATA / "07-walk.asf")
    r = character.Ragdoll.from_skeleton(sk, density=1000, clearance=0.3)
    assert len(r) == 31 and r.names[0] == "root"
    t0, v0 = r.energy()
    r.step(1 / 480, 480 * 2)
    t1, v1 = r.energy()
    assert t1 + v1 < t0 + v0 - 100.0
    assert np.all(np.isfinite(r.q)) and r.com[1] < 0.3


def test_self_collision_is_a_setting_that_keeps_a_ball_on_a_ball():
    # Two free balls (0.1 m, 1000 kg/m³), one dropped on the other: with self_collision
    # the upper rests on the lower at 3r - 3g/ω² (tests/character_self_collision.rs), off it
    # falls through to the ground.
    m = character.Model()
    mass = 1000 * 4 / 3 * math.pi * 0.1**3
    for y in (0.1, 0.6):
        m.add_body(
            None,
            "free",
            mass=mass,
            inertia=np.eye(3) * 0.4 * mass * 0.01,
            offset=(0, y, 0),
            shape=((0, 0, 0), (0, 0, 0), 0.1),
        )
    heights = []
    for on in (True, False):
        b = character.ArticulatedBody(m, self_collision=on)
        assert b.settings["self_collision"] is on
        b.step(1 / 480, 1440)
        heights.append(0.6 + b.q[8])
    sag = 9.81 / b.settings["contact_frequency"] ** 2
    assert heights[0] == pytest.approx(0.3 - 3 * sag, abs=1e-4)
    assert heights[1] == pytest.approx(0.1 - sag, abs=1e-4)


def test_push_moves_a_free_body_by_its_impulse():
    m = character.Model()
    m.add_body(None, "free", mass=2.0, inertia=np.eye(3) * 0.1, offset=(0, 1, 0))
    b = character.ArticulatedBody(m, ground=False, gravity=(0, 0, 0))
    b.push(0, (10.0, 0, 0), 0.1)
    b.step(0.01, 20)
    # Impulse 1 N s on 2 kg: 0.5 m/s along x (a free joint's rates are [ω; v]).
    assert b.qd[3] == pytest.approx(0.5, rel=1e-12)


def test_stable_pd_holds_a_stiff_servo_at_a_sixtieth():
    p = pendulum()
    p.set_servo(0, kp=5000.0, kd=500.0)
    p.targets = [0.7]
    p.step(1 / 60, 240)
    # At rest the servo holds gravity's torque: kp (0.7 - q) = m g L sin q (2 kg, 0.8 m).
    offset = 2.0 * 9.81 * 0.8 * np.sin(p.q[0]) / 5000.0
    assert p.q[0] == pytest.approx(0.7 - offset, abs=1e-5)
    p.configure(servo_mode="explicit")
    p.targets = [0.2]  # from rest at the old target (a fixed point), towards a new one
    with pytest.raises(kinema.SimulationError):
        p.step(1 / 60, 240)
    # At rest the servo holds gravity's torque: kp (0.7 - q) = m g L sin q (2 kg, 0.8 m).
    offset = 2.0 * 9.81 * 0.8 * np.sin(p.q[0]) / 5000.0
    assert p.q[0] == pytest.approx(0.7 - offset, abs=1e-5)


def test_pickle_resumes_bit_for_bit():
    sk = mocap.read_asf(DATA / "07-walk.asf")
    r = character.Ragdoll.from_skeleton(sk, clearance=0.2)
    r.step(1 / 480, 50)
    back = pickle.loads(pickle.dumps(r))
    r.step(1 / 480, 50)
    back.step(1 / 480, 50)
    assert np.array_equal(r.q, back.q) and np.array_equal(r.qd, back.qd)


def test_bad_arguments_name_the_argument_without_quoting_it():
    m = character.Model()
    with pytest.raises(ValueError, match="joint") as e:
        m.add_body(None, "hingeSECRET", mass=1.0, inertia=np.eye(3))
    assert "SECRET" not in str(e.value)
    with pytest.raises(ValueError, match="mass"):
        m.add_body(None, "ball", mass=-1.0, inertia=np.eye(3))
    with pytest.raises(ValueError, match="inertia"):
        m.add_body(None, "ball", mass=1.0, inertia=-np.eye(3))
    with pytest.raises(ValueError, match="parent"):
        m.add_body(3, "ball", mass=1.0, inertia=np.eye(3))
    with pytest.raises(ValueError, match="model"):
        character.ArticulatedBody(m)
    p = pendulum()
    with pytest.raises(ValueError, match="dt"):
        p.step(float("nan"))
    with pytest.raises(ValueError, match="q"):
        p.q = [float("inf")]
    with pytest.raises(ValueError, match="body"):
        p.push(5, (1, 0, 0), 0.1)
    with pytest.raises(ValueError, match="duration"):
        p.push(0, (1, 0, 0), -1.0)
    with pytest.raises(ValueError, match="servo"):
        p.set_servo(0, kp=-1.0)
    with pytest.raises(ValueError, match="integrator"):
        p.configure(integrator="eulerSECRET")
    with pytest.raises(TypeError, match="skeleton"):
        character.Ragdoll.from_skeleton("nope")


# --- MuJoCo as an oracle -------------------------------------------------------------------

CHAIN = [  # (parent, offset, mass, com, diagonal inertia) of a 3-link planar chain
    (None, (0.0, 0.0, 0.0), 1.0, (0.25, 0.0, 0.0), (0.02, 0.001, 0.02)),
    (0, (0.5, 0.0, 0.0), 1.5, (0.2, 0.05, 0.0), (0.03, 0.002, 0.03)),
    (1, (0.4, 0.0, 0.0), 0.7, (0.15, 0.0, 0.02), (0.01, 0.003, 0.012)),
]  # principal moments obey the triangle inequality A + B >= C, which MuJoCo checks


def _mujoco_xml(bodies: list[tuple], joints: list[str]) -> str:
    def body(i: int) -> str:
        _, offset, mass, com, inertia = bodies[i]
        joint = {
            "revolute": '<joint type="hinge" axis="0 0 1"/>',
            "ball": '<joint type="ball"/>',
            "free": "<freejoint/>",
        }[joints[i]]
        kids = "".join(body(k) for k, b in enumerate(bodies) if b[0] == i)
        return (
            f'<body pos="{" ".join(map(str, offset))}">{joint}'
            f'<inertial pos="{" ".join(map(str, com))}" mass="{mass}" '
            f'diaginertia="{" ".join(map(str, inertia))}"/>{kids}</body>'
        )

    roots = "".join(body(i) for i, b in enumerate(bodies) if b[0] is None)
    return (
        '<mujoco><option gravity="0 -9.81 0" timestep="0.001" integrator="RK4">'
        '<flag contact="disable"/></option>'
        f"<worldbody>{roots}</worldbody></mujoco>"
    )


def _kinema_body(bodies: list[tuple], joints: list[str]) -> character.ArticulatedBody:
    m = character.Model()
    for (parent, offset, mass, com, inertia), joint in zip(bodies, joints, strict=True):
        m.add_body(parent, joint, mass=mass, inertia=np.diag(inertia), offset=offset, com=com)
    return character.ArticulatedBody(m, ground=False, integrator="rk4")


@pytest.mark.parametrize("shape", ["chain", "tree"])
def test_trajectories_agree_with_mujoco(shape: str):
    import mujoco  # the oracle, in the test extra

    if shape == "chain":
        bodies, joints = CHAIN, ["revolute"] * 3
        q0 = np.array([0.3, 0.4, -0.2])
        qd0 = np.array([0.5, -1.0, 2.0])
        mj_q, mj_qd = q0, qd0
    else:
        # A limp ragdoll-like tree: a free root with two ball-jointed limbs of two links.
        bodies = [
            (None, (0.0, 1.0, 0.0), 3.0, (0.0, 0.05, 0.0), (0.05, 0.04, 0.03)),
            (0, (0.1, 0.0, 0.0), 1.0, (0.0, -0.2, 0.0), (0.01, 0.002, 0.01)),
            (1, (0.0, -0.4, 0.0), 0.8, (0.0, -0.2, 0.01), (0.008, 0.002, 0.009)),
            (0, (-0.1, 0.0, 0.0), 1.0, (0.0, -0.2, 0.0), (0.01, 0.002, 0.01)),
            (3, (0.0, -0.4, 0.0), 0.8, (0.02, -0.2, 0.0), (0.008, 0.002, 0.009)),
        ]
        joints = ["free", "ball", "ball", "ball", "ball"]
        rng = np.random.default_rng(7)
        quats = [q / np.linalg.norm(q) for q in rng.normal(size=(5, 4)) * 0.3 + [1, 0, 0, 0]]
        q0 = np.concatenate([np.zeros(3), *quats])  # kinema: position from the offset
        w_root, v_root = rng.normal(size=3), rng.normal(size=3)
        balls = rng.normal(size=12)
        qd0 = np.concatenate([w_root, v_root, balls])  # kinema: free [ω; v]
        mj_q, mj_qd = q0.copy(), np.concatenate([v_root, w_root, balls])  # MuJoCo: [v; ω]
        mj_q[:3] = bodies[0][1]  # MuJoCo: the body's world position
    ours = _kinema_body(bodies, joints)
    ours.q, ours.qd = q0, qd0
    model = mujoco.MjModel.from_xml_string(_mujoco_xml(bodies, joints))
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = mj_q, mj_qd
    worst = 0.0
    for _ in range(100):
        ours.step(0.001, 10)
        for _ in range(10):
            mujoco.mj_step(model, data)
        # mj_step leaves xpos from its last RK4 stage, not from the final qpos: recompute.
        mujoco.mj_kinematics(model, data)
        worst = max(worst, float(np.abs(ours.positions() - data.xpos[1:]).max()))
    assert worst < 1e-6, f"largest body position difference over 1 s: {worst} m"
