"""Scenes: one clock, coupling, recording, bit-exact checkpoints, thread-count independence,
Ctrl-C, damaged files, pickling of the main objects."""

from __future__ import annotations

import os
import pickle
import signal
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import numpy as np
import pytest

import kinema
import kinema.ode
from kinema import anim, cloth, constraints, mocap, particles, rigid
from kinema.scene import AnimatedSphere, Character, CheckpointError, Scene, StabilityWarning

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
    mid = walker.joints(10.5 / motion.frame_rate)
    np.testing.assert_allclose(mid, 0.5 * (fk[10] + fk[11]) * 0.0254 / 0.45, atol=1e-12)
    assert len(walker._shapes(0.0)) == sum(p >= 0 for p in skel.parents)
    scene = Scene(dt=1 / 30)
    c = scene.add(cloth.Cloth.grid(6, 6, 0.4, 0.4))
    c.set_state(c.positions + j[0] + np.array([0.0, 0.3, 0.0]))
    scene.add(walker)
    scene.run(frames=3, progress=False)
    assert np.isfinite(c.positions).all()


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

    rt = anim.RotationTrack([0, 1, 2], kinema.Rotation.random(3, seed=2), interpolation="spline")
    rt2 = pickle.loads(pickle.dumps(rt))
    assert np.array_equal(rt(0.7).as_quat(), rt2(0.7).as_quat())
    skel = mocap.read_asf(DATA / "07-walk.asf")
    motion = mocap.read_amc(DATA / "07_05-walk.amc", skel)
    s2, m2 = pickle.loads(pickle.dumps((skel, motion)))
    assert np.array_equal(s2.forward_kinematics(m2)[0], skel.forward_kinematics(motion)[0])
    assert m2.frame_rate == motion.frame_rate
    tf = kinema.Transform(kinema.Rotation.random(2, seed=1), [[1, 2, 3], [4, 5, 6]])
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
