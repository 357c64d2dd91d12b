"""Scenes: one clock, coupling, recording, bit-exact checkpoints, thread-count independence,
Ctrl-C, damaged files, pickling of the main objects."""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import pickle
import signal
import struct
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import numpy as np
import pytest

import kinema
import kinema.ode
from kinema import anim, character, cloth, constraints, mocap, particles, rigid
from kinema._checkpoint import _HEADER, _MAGIC
from kinema.scene import (
    FORMAT_VERSION,
    AnimatedSphere,
    Character,
    CheckpointError,
    Scene,
    StabilityWarning,
)

DATA = Path(kinema.__file__).parent / "data"


def mixed_scene(n_cloth: int = 10, n_particles: int = 60) -> Scene:
    """Cloth over an animated sphere and a rigid ball, a particle fountain with neighbour
    forces, rigid boxes on the ground: every kind of state a checkpoint must carry."""
    scene = Scene(dt=1 / 30, substeps=2)
    c = cloth.Cloth.grid(n_cloth, n_cloth, 1.0, 1.0)
    c.set_state(c.positions + np.array([0.0, 0.8, 0.0]))
    scene.add(c, integrator="bdf2", solver="cholesky")
    rng = np.random.default_rng(1)
    ps = particles.ParticleSystem(
        rng.uniform(-0.3, 0.3, (n_particles, 3)) + np.array([0, 1.5, 0]), capacity=n_particles + 40
    )
    for item in [
        particles.Gravity(),
        particles.Drag(quadratic=0.05),
        particles.NeighborRepulsion(0.05, 20.0),
        particles.Plane(restitution=0.4, friction=0.2),
        particles.Emitter(
            rate=200,
            position=(0, 0.1, 0),
            velocity=(0, 3, 0),
            velocity_spread=0.5,
            lifespan=0.2,
            mass=0.1,
            seed=3,
        ),
    ]:
        ps.add(item)
    scene.add(ps, method="velocity_verlet")
    world = rigid.World()
    world.add_ground()
    world.add_body(rigid.Sphere(0.15), mass=1.0, position=(0.3, 0.15, 0.0))
    for k in range(3):
        world.add_body(
            rigid.Box([0.1, 0.1, 0.1]), mass=1.0, position=(-0.4, 0.1 + 0.2 * k, 0.01 * k)
        )
    scene.add(world)
    path = anim.Track([0.0, 1.0, 2.0], [[0.0, 0.4, 0.0], [0.2, 0.5, 0.1], [0.0, 0.4, 0.0]])
    scene.add(AnimatedSphere(0.2, path))
    return scene


def fingerprint(scene: Scene) -> list[np.ndarray]:
    out = []
    for s in scene.systems:
        if isinstance(s, (cloth.Cloth, particles.ParticleSystem)):
            out += [s.positions.copy(), s.velocities.copy()]
        elif isinstance(s, rigid.World):
            out += [s.positions, s.orientations, s.velocities, s.angular_velocities]
    return out


def same(a: list[np.ndarray], b: list[np.ndarray]) -> bool:
    return len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))


def test_a_run_resumed_from_a_checkpoint_is_bit_identical(tmp_path: Path):
    straight = mixed_scene()
    straight.run(frames=20, progress=False)

    first = mixed_scene()
    first.run(frames=8, progress=False)
    first.save(tmp_path / "run.kin")
    resumed = Scene.load(tmp_path / "run.kin")
    assert resumed.time == first.time and resumed.frame == 8
    resumed.run(frames=12, progress=False)
    assert same(fingerprint(straight), fingerprint(resumed))
    # The state moved and the coupling acted: the cloth is not where free fall would put it.
    assert straight.systems[0].positions[:, 1].min() < 0.7


def test_pickled_scene_continues_bit_identically():
    a = mixed_scene()
    a.run(frames=5, progress=False)
    b = pickle.loads(pickle.dumps(a))
    a.run(frames=5, progress=False)
    b.run(frames=5, progress=False)
    assert same(fingerprint(a), fingerprint(b))


def test_one_thread_and_all_threads_give_identical_scenes():
    before = kinema.num_threads()
    try:
        results = []
        for n in (1, max(2, os.cpu_count() or 2)):
            kinema.set_num_threads(n)
            assert kinema.num_threads() == n
            scene = mixed_scene(n_cloth=24, n_particles=3000)
            scene.run(frames=6, progress=False)
            results.append(fingerprint(scene))
        assert same(results[0], results[1])
    finally:
        kinema.set_num_threads(before)


def test_damaged_foreign_and_other_version_checkpoints_are_refused(tmp_path: Path):
    scene = mixed_scene(n_cloth=4, n_particles=5)
    path = tmp_path / "good.kin"
    scene.save(path)
    data = path.read_bytes()

    def refused(blob: bytes, match: str) -> None:
        bad = tmp_path / "bad.kin"
        bad.write_bytes(blob)
        with pytest.raises(CheckpointError, match=match):
            Scene.load(bad)

    refused(data[: len(data) // 2], "truncated")
    flipped = bytearray(data)
    flipped[len(data) - 100] ^= 0x40
    refused(bytes(flipped), "checksum")
    other = bytearray(data)
    other[16] = 99  # the version field follows the 16-byte magic
    refused(bytes(other), "version 99")
    refused(b"\x89PNG\r\n\x1a\n" + bytes(200), "not a kinema scene")
    refused(b"", "not a kinema scene")
    assert isinstance(Scene.load(path), Scene)


def _with_header(payload: bytes, version: int = FORMAT_VERSION) -> bytes:
    """A checkpoint container around ``payload`` with a correct length and checksum."""
    return _HEADER.pack(_MAGIC, version, len(payload), hashlib.sha256(payload).digest()) + payload


class _RunsCode:
    """A pickle payload that runs a shell command when unpickled (what an attacker writes)."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (os.system, (f"touch {self.marker}",))


def test_a_checkpoint_whose_payload_would_run_code_is_refused_and_runs_nothing(tmp_path: Path):
    marker = tmp_path / "ran"
    evil = pickle.dumps(_RunsCode(marker))
    pickle.loads(evil)  # the payload does run code when unpickled...
    assert marker.exists()
    marker.unlink()
    path = tmp_path / "evil.kin"
    # ...but Scene.load never unpickles: not as the old format (version 1, a valid checksum),
    path.write_bytes(_with_header(evil, version=1))
    with pytest.raises(CheckpointError, match="version 1"):
        Scene.load(path)
    # not as the current version,
    path.write_bytes(_with_header(evil))
    with pytest.raises(CheckpointError, match="invalid checkpoint"):
        Scene.load(path)
    # and a manifest can only name kinema's own data classes, never a function.
    for root in (
        {"$object": ["system", 0, {}]},
        {"$native": ["system", 0, 0, []]},
        {"$object": ["posix.system", 0, {}]},
        {"$native": ["Particles", 0, 0, [{"$object": ["_RunsCode", 1, {}]}]]},
    ):
        manifest = json.dumps({"blobs": [0], "root": root}).encode()
        path.write_bytes(_with_header(struct.pack("<Q", len(manifest)) + manifest))
        with pytest.raises(CheckpointError, match=r"unknown class|invalid checkpoint"):
            Scene.load(path)
    assert not marker.exists()


def test_the_checkpoint_is_json_and_snapshots_without_pickle(tmp_path: Path):
    scene = mixed_scene(n_cloth=4, n_particles=5)
    scene.save(tmp_path / "a.kin")
    data = (tmp_path / "a.kin").read_bytes()
    payload = data[_HEADER.size :]
    (n,) = struct.unpack_from("<Q", payload)
    manifest = json.loads(payload[8 : 8 + n])
    assert manifest["root"]["$object"][0] == "Scene"
    assert b"kinema:Cloth:" in payload and b"kinema:World:" in payload
    assert b"\x80\x05" not in payload[: 8 + n]  # no pickle protocol marker in the manifest


def _mutants(data: bytes, count: int, seed: int) -> list[bytes]:
    """Damaged copies of a checkpoint, each with a correct header (length and checksum), so
    that everything past the checksum is exercised: truncations, bit flips, byte runs set to
    random values, and bit flips inside the manifest's JSON numbers."""
    rng = np.random.default_rng(seed)
    payload = data[_HEADER.size :]
    out = []
    for k in range(count):
        p = bytearray(payload)
        kind = k % 4
        if kind == 0:
            p = p[: int(rng.integers(0, len(p)))]
        elif kind == 1:
            for _ in range(int(rng.integers(1, 4))):
                i = int(rng.integers(0, len(p)))
                p[i] ^= 1 << int(rng.integers(0, 8))
        elif kind == 2:
            i = int(rng.integers(0, len(p)))
            run = rng.integers(0, 256, int(rng.integers(1, 16)), dtype=np.uint8).tobytes()
            p[i : i + len(run)] = run
        else:  # digits of the manifest changed: wrong sizes, ids, indices, shapes
            (n,) = struct.unpack_from("<Q", p)
            digits = [i for i in range(8, 8 + n) if chr(p[i]).isdigit()]
            for i in rng.choice(digits, size=int(rng.integers(1, 3))):
                p[int(i)] = ord(str(int(rng.integers(0, 10))))
        out.append(_with_header(bytes(p)))
    return out


def test_damaged_checkpoints_past_the_checksum_give_only_checkpoint_error(tmp_path: Path):
    scene = mixed_scene(n_cloth=4, n_particles=6)
    ps = scene.systems[1]
    ps.add(particles.Springs([[0, 1], [2, 3]], stiffness=50.0))
    cs = constraints.ConstrainedSystem(particles.ParticleSystem([[0, 1, 0], [1, 1, 0]]), ks=1)
    cs.add(constraints.Distance(0, 1))
    scene.add(cs)
    world = scene.systems[2]
    world.add_joint(rigid.Ball(1, 2, (-0.4, 0.2, 0.0)))
    scene.run(frames=3, progress=False)
    scene.save(tmp_path / "good.kin")
    data = (tmp_path / "good.kin").read_bytes()
    path = tmp_path / "bad.kin"
    outcomes = {"refused": 0, "loaded": 0}
    for blob in _mutants(data, 400, seed=19):
        path.write_bytes(blob)
        try:
            loaded = Scene.load(path)
        except BaseException as e:  # a panic is a BaseException: catch it too
            assert isinstance(e, CheckpointError), f"{type(e).__name__}: {e}"
            outcomes["refused"] += 1
            continue
        outcomes["loaded"] += 1
        try:  # what loads must step without a panic (an error for bad values is fine)
            loaded.step(2)
        except BaseException as e:
            assert isinstance(e, Exception) and type(e).__name__ != "PanicException", repr(e)
    assert outcomes["refused"] > 200 and outcomes["loaded"] > 0, outcomes


def test_damaged_bytes_given_to_from_snapshot_raise_value_error_not_a_panic():
    from kinema import _kinema

    c = cloth.Cloth.grid(4, 4)
    c.step(0.01)
    _, (data, *_) = c._core.__reduce__()
    rng = np.random.default_rng(5)
    loaded = 0
    for _ in range(200):
        bad = bytearray(data)
        for i in rng.integers(16, len(bad), size=2):
            bad[int(i)] ^= 1 << int(rng.integers(0, 8))
        try:
            core = _kinema.ClothCore._from_snapshot(bytes(bad))
        except BaseException as e:  # a panic is a BaseException: catch it too
            assert isinstance(e, ValueError), repr(e)
            continue
        loaded += 1
        try:
            cloth.Cloth(None, None, _core=core).step(0.01)
        except BaseException as e:
            assert isinstance(e, Exception) and type(e).__name__ != "PanicException", repr(e)
    assert 0 < loaded < 200
    # A constrained system's snapshot is checked against the particles it is given.
    ps = particles.ParticleSystem([[0, 1, 0], [1, 1, 0], [2, 1, 0]])
    cs = constraints.ConstrainedSystem(ps)
    cs.add(constraints.Distance(1, 2))
    _, (data, _) = cs._sys.__reduce__()
    small = particles.ParticleSystem([[0, 1, 0], [1, 1, 0]])
    with pytest.raises(ValueError, match="particle"):
        _kinema.Constrained._from_snapshot(data, small._sys)


def test_objects_that_are_not_data_are_named_at_save(tmp_path: Path):
    scene = Scene()
    ps = particles.ParticleSystem([[0.0, 1.0, 0.0]])
    ps.add(particles.Field(lambda t, x, v: np.zeros_like(x)))
    scene.add(ps)
    with pytest.raises(CheckpointError, match=r"scene\.systems\[0\].*Field"):
        scene.save(tmp_path / "x.kin")
    scene = Scene()
    scene.add(rigid.World())
    scene.add(AnimatedSphere(0.1, lambda t: (0.0, t, 0.0)))
    with pytest.raises(CheckpointError, match=r"scene\.systems\[1:\]\[0\].*AnimatedSphere"):
        scene.save(tmp_path / "x.kin")
    scene = Scene()
    custom = constraints.ConstrainedSystem(particles.ParticleSystem([[0, 1, 0]]))
    custom.add(constraints.Custom([0], lambda x: x[0, 1] - 1, lambda x: [0, 1, 0]))
    scene.add(custom)
    with pytest.raises(CheckpointError, match=r"scene\.systems\[0\]._sys.*saved"):
        scene.save(tmp_path / "x.kin")
    assert not (tmp_path / "x.kin").exists()


def test_records_are_kept_and_function_recorders_are_registered_again(tmp_path: Path):
    scene = Scene()
    ps = particles.ParticleSystem([[0.0, 1.0, 0.0]])
    ps.add(particles.Gravity())
    scene.add(ps)
    scene.record("0.kinetic_energy")
    scene.record("height", lambda: ps.positions[0, 1])
    scene.step(3)
    scene.save(tmp_path / "r.kin")
    loaded = Scene.load(tmp_path / "r.kin")
    assert np.array_equal(loaded.records["height"], scene.records["height"])
    loaded.step(1)
    assert len(loaded.records["0.kinetic_energy"]) == 4 and len(loaded.records["height"]) == 3
    p = loaded.systems[0]
    loaded.record("height", lambda: p.positions[0, 1])
    loaded.step(1)
    assert len(loaded.records["height"]) == 4


def test_an_interrupted_write_leaves_the_previous_checkpoint_readable(tmp_path: Path, monkeypatch):
    scene = mixed_scene(n_cloth=4, n_particles=5)
    path = tmp_path / "ckpt.kin"
    scene.save(path)
    scene.run(frames=3, progress=False)

    def crash(fd: int) -> None:  # the machine "dies" after the bytes, before the rename
        raise OSError("power cut")

    monkeypatch.setattr(os, "fsync", crash)
    with pytest.raises(OSError, match="power cut"):
        scene.save(path)
    monkeypatch.undo()
    assert Scene.load(path).frame == 0  # the old checkpoint, intact
    assert [p.name for p in tmp_path.iterdir()] == ["ckpt.kin"]  # no temporary left behind


def test_ctrl_c_stops_at_the_last_completed_step(tmp_path: Path):
    script = textwrap.dedent(
        f"""
        import sys
        sys.path.insert(0, {str(Path(__file__).parent)!r})
        from test_scene import mixed_scene
        scene = mixed_scene()
        scene.run(frames=2, progress=False)
        print("running", flush=True)
        done = scene.run(frames=100000, progress=False)
        c, p = scene.systems[0], scene.systems[1]
        print(done, scene.interrupted, scene.time, c.time, p.time, flush=True)
        scene.save({str(tmp_path / "after.kin")!r})
        """
    )
    child = subprocess.Popen(
        [sys.executable, "-c", script], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    assert child.stdout is not None
    assert child.stdout.readline().strip() == "running"
    import time

    time.sleep(1.0)
    child.send_signal(signal.SIGINT)
    out, err = child.communicate(timeout=120)
    assert child.returncode == 0, err
    done, interrupted, t, t_cloth, t_particles = out.split()
    assert interrupted == "True" and 0 < int(done) < 100000
    # Every system stopped at the same completed step.
    assert float(t) == pytest.approx(float(t_cloth), rel=1e-11)
    assert float(t) == pytest.approx(float(t_particles), rel=1e-11)
    assert Scene.load(tmp_path / "after.kin").time == pytest.approx(float(t), abs=1e-12)


def test_cloth_drapes_on_an_animated_sphere_without_going_through():
    scene = Scene(dt=1 / 60, substeps=2)
    c = scene.add(cloth.Cloth.grid(12, 12, 1.0, 1.0))
    c.set_state(c.positions + np.array([0.0, 0.5, 0.0]))
    center = anim.Track([0.0, 2.0], [[0.0, 0.0, 0.0], [0.3, 0.0, 0.0]], "linear")
    ball = scene.add(AnimatedSphere(0.3, center))
    scene.run(duration=1.0, progress=False)
    d = np.linalg.norm(c.positions - ball.position(scene.time), axis=1)
    assert d.min() > 0.3 - 0.02
    assert c.positions[:, 1].max() > 0.25  # resting on top, not fallen past


def test_particles_bounce_off_a_rigid_ball():
    scene = Scene(dt=1 / 120)
    world = rigid.World(gravity=(0, 0, 0))
    world.add_body(rigid.Sphere(0.5), position=(0, 0, 0), fixed=True)
    scene.add(world)
    ps = scene.add(particles.ParticleSystem([[0.0, 1.0, 0.0]], [[0.0, -2.0, 0.0]]))
    scene.run(duration=1.0, progress=False)
    assert ps.positions[0, 1] >= 0.5 - 1e-6 and ps.velocities[0, 1] > 0


def test_character_capsules_follow_the_motion():
    skel = mocap.read_asf(DATA / "07-walk.asf")
    motion = mocap.read_amc(DATA / "07_05-walk.amc", skel)
    walker = Character(skel, motion, radius=0.05, scale=0.0254 / 0.45)
    fk, _ = skel.forward_kinematics(motion)
    j = walker.joints(10 / motion.frame_rate)
    np.testing.assert_allclose(j, fk[10] * 0.0254 / 0.45, atol=1e-12)
    # Half way between frames the root is half way and every bone is as long as in the
    # frames, along the bisector of its two directions (a linear blend of the joints shortened
    # the right toes by 5.4 %, which the biped's collider check refused).
    mid = walker.joints(10.5 / motion.frame_rate)
    np.testing.assert_allclose(mid[0], 0.5 * (fk[10, 0] + fk[11, 0]) * 0.0254 / 0.45, atol=1e-12)
    a, b = walker._bones.T
    d0, d1, d = ((x[b] - x[a]) for x in (fk[10] * 0.0254 / 0.45, fk[11] * 0.0254 / 0.45, mid))
    lengths = np.linalg.norm(d0, axis=1)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), lengths, rtol=1e-12, atol=1e-15)
    bisector = d0 / lengths[:, None] + d1 / lengths[:, None]
    np.testing.assert_allclose(np.cross(d, bisector), 0.0, atol=1e-12)
    assert (np.sum(d * bisector, axis=1) >= 0).all()
    # A quarter of the way, the bone has turned a quarter of the angle.
    quarter = walker.joints(10.25 / motion.frame_rate)
    dq = quarter[b] - quarter[a]
    turned, whole = (
        np.arctan2(np.linalg.norm(np.cross(d0, x), axis=1), np.sum(d0 * x, axis=1))
        for x in (dq, d1)
    )
    np.testing.assert_allclose(turned, whole / 4, atol=1e-9)
    assert len(walker._shapes(0.0)) == sum(p >= 0 for p in skel.parents)
    scene = Scene(dt=1 / 30)
    c = scene.add(cloth.Cloth.grid(6, 6, 0.4, 0.4))
    c.set_state(c.positions + j[0] + np.array([0.0, 0.3, 0.0]))
    scene.add(walker)
    scene.run(frames=3, progress=False)
    assert np.isfinite(c.positions).all()


def test_a_biped_takes_a_characters_bones_frame_after_frame(tmp_path: Path):
    # The scene hands the character's bones to the biped as colliders every step; the
    # biped refuses a collider whose size changed, so the bones must keep their lengths
    # between frames (the second step raised "shape: must be of the collider's kind and
    # size" when joints were blended linearly). The character walks 3 m to the side, out of
    # reach: the biped walks bit for bit as without it. Saved and loaded, the scene goes on
    # bit for bit.
    skel = mocap.read_asf(DATA / "07-walk.asf")
    walker = Character(skel, mocap.read_amc(DATA / "07_05-walk.amc", skel), offset=(0, 0, 3))
    scenes = [Scene(dt=1 / 120, substeps=4) for _ in range(2)]
    bipeds = [s.add(character.Biped()) for s in scenes]
    scenes[0].add(walker)
    for s in scenes:
        s.step(12)
    assert len(scenes[0]._entries[0].colliders) == len(walker._bones)
    assert np.array_equal(bipeds[0].q, bipeds[1].q) and np.array_equal(bipeds[0].qd, bipeds[1].qd)
    assert bipeds[0].time == pytest.approx(0.1)
    scenes[0].save(tmp_path / "walkers.kin")
    loaded = Scene.load(tmp_path / "walkers.kin")
    scenes[0].step(6)
    loaded.step(6)
    assert np.array_equal(bipeds[0].q, loaded.systems[0].q)
    t = 0.123
    assert np.array_equal(walker.joints(t), loaded.systems[1].joints(t))


def test_recording_and_diagnostics():
    scene = mixed_scene(n_cloth=4, n_particles=5)
    scene.record("0.kinetic_energy")
    scene.record("corner", lambda: scene.systems[0].positions[0])
    scene.run(frames=4, progress=False)
    rec = scene.records
    assert rec["corner"].shape == (4, 3) and rec["0.kinetic_energy"].shape == (4,)
    assert rec["0.kinetic_energy"][-1] > rec["0.kinetic_energy"][0] > 0  # falling cloth speeds up
    with pytest.raises(ValueError, match="name"):
        scene.record("no.such.quantity")


def test_stability_warning_for_an_explicit_step_beyond_the_limit():
    def stiff_pair() -> particles.ParticleSystem:
        ps = particles.ParticleSystem([[0, 0, 0], [1, 0, 0]])
        ps.add(particles.Springs([[0, 1]], stiffness=1e4))
        return ps

    scene = Scene(dt=1 / 30)
    scene.add(stiff_pair(), method="symplectic_euler")
    with pytest.warns(StabilityWarning, match="substeps"):
        scene.run(frames=1, progress=False)
    calm = Scene(dt=1 / 30, substeps=20)
    calm.add(stiff_pair(), method="symplectic_euler")
    implicit = Scene(dt=1 / 30)
    implicit.add(stiff_pair(), method="implicit_euler")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        calm.run(frames=1, progress=False)
        implicit.run(frames=1, progress=False)


def test_empty_scene_counts_time_and_bad_input_is_named():
    scene = Scene(dt=0.01, substeps=3)
    assert scene.run(frames=10, progress=False) == 10
    assert scene.frame == 10 and scene.time == pytest.approx(0.1)
    with pytest.raises(ValueError, match="dt"):
        Scene(dt=-1)
    with pytest.raises(ValueError, match="substeps"):
        Scene(substeps=0)
    with pytest.raises(ValueError, match="item"):
        scene.add("cloth")
    with pytest.raises(ValueError, match="duration"):
        scene.run(1.0, frames=3)
    with pytest.raises(ValueError, match="radius"):
        AnimatedSphere(-1.0, lambda t: (0, 0, 0))
    ps = particles.ParticleSystem([[0, 0, 0]])
    cs = constraints.ConstrainedSystem(ps)
    scene.add(cs)
    with pytest.raises(ValueError, match="constrained"):
        scene.add(ps)


def test_main_objects_pickle(tmp_path: Path):
    ps = particles.ParticleSystem([[0, 1, 0], [1, 1, 0]])
    ps.add(particles.Gravity())
    cs = constraints.ConstrainedSystem(ps, ks=10, kd=1)
    cs.add(constraints.Distance(0, 1))
    cs.step(0.01, 3)
    cs2 = pickle.loads(pickle.dumps(cs))
    cs.step(0.01, 5)
    cs2.step(0.01, 5)
    assert np.array_equal(cs._particles.positions, cs2._particles.positions)

    custom = constraints.ConstrainedSystem(particles.ParticleSystem([[0, 1, 0]]))
    custom.add(constraints.Custom([0], lambda x: x[0, 1] - 1, lambda x: [0, 1, 0]))
    with pytest.raises(
        (ValueError, pickle.PicklingError, AttributeError), match=r"saved|pickle|lambda"
    ):
        pickle.dumps(custom)

    rt = anim.RotationTrack([0, 1, 2], kinema.Rotation.random(3, rng=2), interpolation="spline")
    rt2 = pickle.loads(pickle.dumps(rt))
    assert np.array_equal(rt(0.7).as_quat(), rt2(0.7).as_quat())
    skel = mocap.read_asf(DATA / "07-walk.asf")
    motion = mocap.read_amc(DATA / "07_05-walk.amc", skel)
    s2, m2 = pickle.loads(pickle.dumps((skel, motion)))
    assert np.array_equal(s2.forward_kinematics(m2)[0], skel.forward_kinematics(motion)[0])
    assert m2.frame_rate == motion.frame_rate
    tf = kinema.Transform(kinema.Rotation.random(2, rng=1), [[1, 2, 3], [4, 5, 6]])
    assert np.array_equal(pickle.loads(pickle.dumps(tf)).as_matrix(), tf.as_matrix())


def test_obj_sequence_and_pictures(tmp_path: Path):
    from matplotlib.animation import FFMpegWriter

    from kinema import plot

    scene = mixed_scene(n_cloth=5, n_particles=10)
    paths: list[Path] = []
    scene.run(
        frames=3, progress=False, on_frame=lambda s: paths.append(s.export_obj(tmp_path / "obj"))
    )
    assert [p.name for p in paths] == ["frame_00001.obj", "frame_00002.obj", "frame_00003.obj"]
    lines = paths[-1].read_text().splitlines()
    objects = [line.split()[1] for line in lines if line.startswith("o ")]
    assert objects == ["cloth0", "body2_0", "body2_1", "body2_2", "body2_3", "sphere3"]
    vertices = np.array(
        [[float(v) for v in line.split()[1:]] for line in lines if line.startswith("v ")]
    )
    faces = np.array(
        [[int(v) for v in line.split()[1:]] for line in lines if line.startswith("f ")]
    )
    assert faces.min() == 1 and faces.max() == len(vertices)
    # The cloth's vertices come first, exactly as the cloth has them (to the 9 digits written).
    np.testing.assert_allclose(vertices[:25], scene.systems[0].positions, rtol=1e-8, atol=1e-9)

    ax = plot.scene(scene)
    ax.figure.savefig(tmp_path / "frame.png")
    assert (tmp_path / "frame.png").stat().st_size > 1000
    assert plot.render(scene, tmp_path / "run.gif", frames=4, every=2) == 3
    assert (tmp_path / "run.gif").stat().st_size > 1000 and scene.frame == 7
    with pytest.raises(ValueError, match="path"):
        plot.render(scene, tmp_path / "run.avi", frames=1)
    if FFMpegWriter.isAvailable():
        plot.render(scene, tmp_path / "run.mp4", frames=2)
        assert (tmp_path / "run.mp4").stat().st_size > 1000
    else:
        with pytest.raises(RuntimeError, match="ffmpeg"):
            plot.render(scene, tmp_path / "run.mp4", frames=1)


def test_stability_warning_for_explicit_cloth():
    def sheet() -> cloth.Cloth:
        c = cloth.Cloth.grid(6, 6, 0.5, 0.5, stretch=1e4)
        c.pin([0, 5])
        return c

    omega, c = sheet().fastest_mode()
    assert omega > 0 and c > 0
    limit = kinema.ode.max_stable_dt_oscillator("symplectic_euler", omega, c)
    coarse = Scene(dt=1 / 60)
    coarse.add(sheet(), integrator="symplectic_euler")
    with pytest.warns(StabilityWarning, match="cloth's fastest vibration"):
        coarse._check_stability()
    fine = Scene(dt=1 / 60, substeps=int(np.ceil(1 / 60 / (0.9 * limit))))
    fine.add(sheet(), integrator="symplectic_euler")
    implicit = Scene(dt=1 / 60)
    implicit.add(sheet())
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fine._check_stability()
        implicit._check_stability()
    fine.run(frames=2, progress=False)  # and the predicted substeps are indeed stable


def test_rigid_boxes_are_colliders_for_cloth_and_particles():
    scene = Scene(dt=1 / 60, substeps=2)
    world = rigid.World(gravity=(0, 0, 0))
    turned = kinema.Rotation.from_rotvec([0.0, 0.5, 0.0])
    world.add_body(rigid.Box([0.3, 0.1, 0.3]), position=(0, 0.1, 0), orientation=turned, fixed=True)
    scene.add(world)
    c = scene.add(cloth.Cloth.grid(10, 10, 0.4, 0.4))
    c.set_state(c.positions + np.array([0.0, 0.4, 0.0]))
    ps = scene.add(particles.ParticleSystem([[0.1, 0.6, 0.05]]))
    ps.add(particles.Gravity())
    scene.run(duration=1.0, progress=False)
    # Both rest on the box's top face (y = 0.2), neither fell through.
    assert c.positions[:, 1].min() > 0.2 - 0.01
    assert ps.positions[0, 1] == pytest.approx(0.2, abs=1e-6)


def _cores(scene: Scene) -> list[bytes]:
    """Snapshot bytes of the scene's rigid worlds (a cloth's carry the timings of its last
    step, so cloths are compared through ``fingerprint``; a particle system's carry its step
    workspaces, which a scene's undo does not copy, so they are compared by stepping)."""
    return [s._world.__reduce__()[1][0] for s in scene.systems if isinstance(s, rigid.World)]


def _steps_alike(restored: particles.ParticleSystem, copy: bytes, method: str) -> bool:
    """Whether ``restored`` and the pickled ``copy`` step to the same bits (3 steps)."""
    other = pickle.loads(copy)
    for system in (restored, other):
        system.step(1 / 600, 3, method=method)
    return same([restored.positions, restored.velocities], [other.positions, other.velocities])


def test_a_frame_where_the_last_system_diverges_leaves_the_scene_as_before():
    # Cloth, particles, a rigid world and an animated sphere (coupled), then a spring pair
    # stepped explicitly far beyond its stability limit: it diverges after a few frames, in a
    # frame whose first substep every other system has completed.
    scene = mixed_scene(n_cloth=6, n_particles=20)
    pair = particles.ParticleSystem([[0.0, 3.0, 0.0], [1.0, 3.0, 0.0]])
    pair.add(particles.Springs([[0, 1]], stiffness=1e12, rest=[0.5]))
    scene.add(pair, method="explicit_euler")
    pair_views = (pair.positions, pair.velocities)
    for _ in range(100):
        before, cores = fingerprint(scene), _cores(scene)
        copies = [pickle.dumps(s) for s in scene.systems if isinstance(s, particles.ParticleSystem)]
        frame, time = scene.frame, scene.time
        colliders = [len(e.colliders) for e in scene._entries]
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", StabilityWarning)
                scene.step()
        except kinema.SimulationError:
            break
    else:
        pytest.fail("the spring pair never diverged")
    assert frame > 0 and scene.frame == frame
    assert scene.time == time
    assert same(fingerprint(scene), before)
    assert _cores(scene) == cores
    assert [len(e.colliders) for e in scene._entries] == colliders
    # Views taken before the failure still show the (restored) state.
    assert np.array_equal(pair_views[0], pair.positions)
    assert np.isfinite(pair.positions).all()
    # The restored particle systems step as copies taken before the frame (the culprit is
    # about to diverge whatever steps it).
    restored = [s for s in scene.systems if isinstance(s, particles.ParticleSystem)]
    assert restored[-1] is pair
    for system, copy in zip(restored[:-1], copies[:-1], strict=True):
        assert _steps_alike(system, copy, "implicit_euler")
    # The scene goes on once the culprit is calmed and stepped stably.
    pair.set_state([[0.0, 3.0, 0.0], [0.5, 3.0, 0.0]], np.zeros((2, 3)))
    scene._entries[-1].options["method"] = "implicit_euler"
    scene.step(2)
    assert scene.frame == frame + 2


def test_moving_colliders_meet_cloth_and_particles_where_the_analytic_pose_is():
    # A sphere rising at a known speed carries a cloth and a particle resting on its top: at
    # every frame they are at the top of the sphere's pose at that time (the cloth at its
    # collision thickness above it), not at the pose one step later (u h = 8 mm here).
    u, r, thickness = 0.5, 0.2, 1e-3
    scene = Scene(dt=1 / 60)
    c = scene.add(cloth.Cloth.grid(9, 9, 0.4, 0.4, thickness=thickness))
    ps = scene.add(particles.ParticleSystem([[0.0, 0.0, 0.0]]))
    ps.add(particles.Gravity())
    ball = scene.add(AnimatedSphere(r, lambda t: (0.0, u * t - 0.25, 0.0)))
    middle = 4 + 9 * 4  # the vertex above the sphere's centre
    scene.run(duration=0.5, progress=False)
    for _ in range(10):
        scene.step()
        top = ball.position(scene.time)[1] + r
        assert c.positions[middle, 1] == pytest.approx(top + thickness, abs=2e-4)
        p = ps.positions[0] - ball.position(scene.time)
        assert np.linalg.norm(p) == pytest.approx(r, abs=1e-9)


@pytest.mark.parametrize(("mu", "slides"), [(0.0, True), (1.0, False)])
def test_rigid_colliders_use_the_bodys_own_friction(mu: float, slides: bool):
    # A particle on the top face of a fixed box tilted by 35° (tan 35° = 0.70): frictionless,
    # it slides down the face as a = g sin 35° says; with μ = 1 it stays put.
    tilt = np.radians(35.0)
    scene = Scene(dt=1 / 240)
    world = rigid.World(gravity=(0, 0, 0))
    turned = kinema.Rotation.from_rotvec([0.0, 0.0, tilt])
    world.add_body(rigid.Box([1.0, 0.1, 0.5]), orientation=turned, fixed=True, friction=mu)
    assert world.bodies[0].friction == mu
    scene.add(world)
    up = turned.apply([0.0, 0.1, 0.0])
    start = up + 1e-9 * up
    ps = scene.add(particles.ParticleSystem([start]))
    ps.add(particles.Gravity())
    scene.run(duration=0.5, progress=False)
    moved = np.linalg.norm(ps.positions[0] - start)
    if slides:
        assert moved == pytest.approx(0.5 * 9.81 * np.sin(tilt) * 0.25, rel=0.05)
    else:
        assert moved < 1e-6


def _ragdoll_bits(r: character.ArticulatedBody) -> tuple[bytes, bytes, bytes, float]:
    """The bits of a ragdoll's coordinates, rates and targets, and its time."""
    return (r.q.tobytes(), r.qd.tobytes(), np.asarray(r.targets).tobytes(), r.time)


def _absurd_servos(r: character.ArticulatedBody) -> None:
    """Explicit PD servos far beyond their stability limit on every hinge and ball joint,
    aimed at the current pose: the ragdoll diverges at its second step (of 1/480 s)."""
    r.configure(servo_mode="explicit")
    for b in range(1, len(r)):
        with contextlib.suppress(ValueError):  # a fixed joint has no servo
            r.set_servo(b, kp=1e9, kd=1e9)
    r.targets = r.q


def test_a_ragdolls_failed_frame_leaves_it_as_before():
    # The ragdoll as the culprit (its own step diverges, in the second or a later substep of
    # a frame) and as a bystander (rolled back by the scene when a spring pair stepped after
    # it diverges): each time its coordinates, rates, targets and time are bitwise as before
    # the frame, and views taken before stay valid.
    sk = mocap.read_asf(DATA / "07-walk.asf")
    scene = Scene(dt=1 / 120, substeps=4)
    culprit = scene.add(character.Ragdoll.from_skeleton(sk, clearance=0.3))
    scene.step(3)
    _absurd_servos(culprit)
    views, before, time = (culprit.q, culprit.qd), _ragdoll_bits(culprit), scene.time
    with pytest.raises(kinema.SimulationError):
        scene.step()
    assert _ragdoll_bits(culprit) == before and scene.time == time
    assert np.array_equal(views[0], culprit.q) and np.array_equal(views[1], culprit.qd)

    scene = Scene(dt=1 / 120, substeps=2)
    bystander = scene.add(character.Ragdoll.from_skeleton(sk, clearance=0.3))
    pair = particles.ParticleSystem([[0.0, 3.0, 0.0], [1.0, 3.0, 0.0]])
    pair.add(particles.Springs([[0, 1]], stiffness=1e12, rest=[0.5]))
    scene.add(pair, method="explicit_euler")
    for _ in range(100):
        before, time = _ragdoll_bits(bystander), scene.time
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", StabilityWarning)
                scene.step()
        except kinema.SimulationError:
            break
    else:
        pytest.fail("the spring pair never diverged")
    assert time > 0 and scene.time == time
    assert _ragdoll_bits(bystander) == before


def _fixed_box(centre: tuple[float, float, float], half: list[float], mu: float) -> rigid.World:
    """A rigid world holding one fixed box (a scene's collider)."""
    world = rigid.World()
    world.add_body(rigid.Box(half), position=centre, fixed=True, friction=mu)
    return world


def test_articulated_bodies_rest_on_a_scenes_box():
    # A ball (r = 0.1 m, no ground of its own) dropped on a rigid world's fixed box (top at
    # y = 0.2) rests on its top sunk by the contact spring's g / ω_c² (as on its own
    # colliders, docs/character.md): its centre at 0.2 + r - g/ω_c² to 1e-4. The limp CMU 07
    # ragdoll dropped 0.3 m onto a box whose top is 0.5 m up (its own ground below) comes to
    # rest on it: after 3 s its lowest capsule point within 2 cm of the top (not through it,
    # not on its ground) and its kinetic energy under 1 J. Without the scene's colliders
    # (receivers not including articulated bodies) both fall through.
    scene = Scene(dt=1 / 120, substeps=4)
    scene.add(_fixed_box((0.0, 0.1, 0.0), [1.0, 0.1, 1.0], 0.5))
    m = character.Model()
    radius = 0.1
    mass = 1000.0 * 4.0 / 3.0 * np.pi * radius**3
    m.add_body(
        None,
        "free",
        mass=mass,
        inertia=np.eye(3) * 0.4 * mass * radius**2,
        offset=(0.0, 0.6, 0.0),
        shape=((0, 0, 0), (0, 0, 0), radius),
    )
    ball = scene.add(character.ArticulatedBody(m, ground=False))
    scene.step(240)
    rest = 0.2 + radius - 9.81 / ball.settings["contact_frequency"] ** 2
    height = ball.positions()[0, 1]
    assert height == pytest.approx(rest, abs=1e-4)
    assert len(ball.colliders()) == 1

    scene = Scene(dt=1 / 120, substeps=4)
    top = 0.5
    scene.add(_fixed_box((0.0, top / 2, 0.0), [1.5, top / 2, 1.5], 0.5))
    sk = mocap.read_asf(DATA / "07-walk.asf")
    r = scene.add(character.Ragdoll.from_skeleton(sk, clearance=top + 0.3))
    scene.step(360)
    lowest = min(
        (p + kinema.Rotation.from_quat(o).apply(end))[1] - c[2]
        for p, o, c in zip(r.positions(), r.orientations(), r.capsules(), strict=True)
        if c is not None
        for end in c[:2]
    )
    kinetic, _ = r.energy()
    print(f"ball at {height:.6f} m (rest {rest:.6f}); ragdoll lowest {lowest:.4f} m, ", end="")
    print(f"{kinetic:.3g} J")
    assert top - 0.02 < lowest < top + 0.02
    assert kinetic < 1.0


def test_a_failed_first_frame_takes_back_the_colliders_a_ragdoll_was_given():
    # The ragdoll diverges in the first frame, after the scene gave it its collider: the
    # collider goes with the undone frame (none left, the scene's record empty), so the next
    # frames give it exactly one again. A checkpoint of the scene resumes bit for bit.
    sk = mocap.read_asf(DATA / "07-walk.asf")
    scene = Scene(dt=1 / 120, substeps=4)
    scene.add(_fixed_box((0.0, 0.25, 0.0), [1.5, 0.25, 1.5], 0.5))
    r = scene.add(character.Ragdoll.from_skeleton(sk, clearance=0.8))
    _absurd_servos(r)
    before = _ragdoll_bits(r)
    with pytest.raises(kinema.SimulationError):
        scene.step()
    assert r.colliders() == [] and scene._entries[1].colliders == []
    assert _ragdoll_bits(r) == before
    r.configure(servo_mode="stable")
    for b in range(1, len(r)):
        with contextlib.suppress(ValueError):
            r.set_servo(b, kp=None)
    scene.step(3)
    assert len(r.colliders()) == 1
    copy = pickle.loads(pickle.dumps(scene))
    scene.step(30)
    copy.step(30)
    assert np.array_equal(r.q, copy.systems[1].q)
