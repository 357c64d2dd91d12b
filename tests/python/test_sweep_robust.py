"""kinema.sweep under failure, on real processes: a worker SIGKILLed mid-task is retried (from
its last checkpoint when the task saves them) and nothing is computed twice to completion; a
sweep whose scheduler and client were SIGKILLed half way resumes; every result is bitwise the
serial run's. Each task appends what it does to a log file (any process may write), which the
tests count."""

from __future__ import annotations

import functools
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from kinema import sweep as ks
from kinema.particles import Gravity, ParticleSystem, Springs
from kinema.scene import Scene
from kinema.sweep import engine

FRAMES = 60  # frames per task
EVERY = 10  # frames between checkpoints


@pytest.fixture(scope="module")
def client():
    from dask.distributed import Client, LocalCluster

    cluster = LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
    )
    with Client(cluster) as c:
        yield c
    cluster.close()


def _append(log: str, line: str) -> None:
    with open(log, "a") as f:  # one short line per write: appends do not interleave
        f.write(line + "\n")


def _lines(log: Path, kind: str) -> list[list[int]]:
    if not log.exists():
        return []
    rows = [line.split() for line in log.read_text().splitlines()]
    return [[int(x) for x in r[1:]] for r in rows if r and r[0] == kind]


# A scene per task: a hanging chain of 6 particles on springs, in a scene whose frame rate
# (100 + seed frames per second) tells the tasks apart even after a reload from a checkpoint.
def build_scene(seed: int) -> Scene:
    scene = Scene(dt=1.0 / (100 + seed))
    x = np.zeros((6, 3))
    x[:, 0] = np.arange(6) * 0.1
    chain = ParticleSystem(x, masses=np.r_[np.inf, np.ones(5)])
    chain.add(Springs([[i, i + 1] for i in range(5)], 200.0 + 50.0 * seed, damping=0.05))
    chain.add(Gravity())
    scene.add(chain)
    return scene


def run_scene(scene: Scene, log: str, pause: float, save: bool) -> dict:
    """Advance to frame FRAMES (from wherever the scene is), a checkpoint every EVERY frames
    if ``save``; log the start frame, every frame and the completion, with the process id."""
    tag, pid = round(1.0 / scene.dt) - 100, os.getpid()
    _append(log, f"start {tag} {pid} {scene.frame}")
    while scene.frame < FRAMES:
        scene.step()
        if save:
            ks.checkpoint(scene, every=EVERY)
        _append(log, f"frame {tag} {pid} {scene.frame}")
        time.sleep(pause)
    _append(log, f"done {tag} {pid} {scene.frame}")
    return {"x": scene.systems[0].positions.copy(), "t": scene.time}


def _kill_when(log: Path, tag: int, frame: int, stop: threading.Event) -> threading.Thread:
    """A thread that SIGKILLs the process running task ``tag`` once it logged ``frame``."""

    def watch() -> None:
        while not stop.is_set():
            hits = [r for r in _lines(log, "frame") if r[0] == tag and r[2] >= frame]
            if hits:
                os.kill(hits[0][1], signal.SIGKILL)
                return
            time.sleep(0.01)

    thread = threading.Thread(target=watch, daemon=True)
    thread.start()
    return thread


def _same(a, b) -> None:
    assert list(a["status"]) == list(b["status"]) == ["ok"] * len(a)
    assert np.array_equal(a["t"], b["t"])
    for xa, xb in zip(a["x"], b["x"], strict=True):
        assert xa.shape == (6, 3) and np.array_equal(xa, xb)


@pytest.mark.parametrize("save", [False, True], ids=["no-checkpoints", "checkpoints"])
def test_a_worker_killed_mid_task_is_retried_and_nothing_finishes_twice(client, tmp_path, save):
    log = tmp_path / "log.txt"
    run = functools.partial(run_scene, log=str(log), pause=0.01, save=save)
    design = ks.grid(seed=range(4))
    stop = threading.Event()
    killer = _kill_when(log, tag=1, frame=35, stop=stop)
    table = ks.sweep(
        build_scene, design, run, client=client, checkpoint_dir=tmp_path / "ck", progress=False
    )
    stop.set()
    killer.join()
    starts = _lines(log, "start")
    killed = [r for r in starts if r[0] == 1]
    assert len(killed) == 2 and killed[0][1] != killed[1][1]  # run again, by another process
    # Task 1 ran again from its last checkpoint (frame 30 or later, a multiple of EVERY) with
    # checkpoints, from zero without; every task finished exactly once.
    if save:
        assert killed[1][2] >= 30 and killed[1][2] % EVERY == 0
    else:
        assert killed[1][2] == 0
    assert sorted(r[0] for r in _lines(log, "done")) == [0, 1, 2, 3]
    # The second attempt stepped only from where it started to the end.
    again = [r[2] for r in _lines(log, "frame") if r[0] == 1 and r[1] == killed[1][1]]
    assert again == list(range(killed[1][2] + 1, FRAMES + 1))
    serial = ks.sweep(
        build_scene,
        design,
        functools.partial(run_scene, log=str(tmp_path / "serial.txt"), pause=0.0, save=False),
        client="serial",
        progress=False,
    )
    _same(serial, table)
    assert not list((tmp_path / "ck" / "tasks").glob("*"))  # no task files left behind


def test_a_lost_batch_run_again_reads_back_its_finished_tasks(tmp_path):
    """A batch dies in its third task (a BaseException escapes, as a killed process would stop
    it); run again, it reads the two finished tasks back and restarts the third from its last
    checkpoint."""
    log = tmp_path / "log.txt"
    tasks = [(ks_key(p), p) for p in ks.grid(seed=range(3))]

    def dying(scene: Scene) -> dict:
        if round(1.0 / scene.dt) == 102 and scene.frame == 0:
            scene.step(25)
            ks.checkpoint(scene, every=EVERY)  # frame 25: not a multiple of 10, not saved
            scene.step(5)
            assert ks.checkpoint(scene, every=EVERY)  # frame 30: saved
            raise SystemExit("the process dies")
        return run_scene(scene, str(log), 0.0, True)

    where = str(tmp_path / "ck")
    with pytest.raises(SystemExit):
        engine._run_batch(build_scene, dying, tasks, False, where)
    assert [r[0] for r in _lines(log, "done")] == [0, 1]
    rows = engine._run_batch(build_scene, dying, tasks, False, where)
    assert [r[0] for r in _lines(log, "done")] == [0, 1, 2]  # 0 and 1 were not run again
    assert [r[2] for r in _lines(log, "start") if r[0] == 2] == [30]
    assert [r["status"] for r in rows] == ["ok"] * 3
    direct = run_scene(build_scene(2), str(tmp_path / "direct.txt"), 0.0, False)
    assert np.array_equal(np.reshape(rows[2]["x"], (6, 3)), direct["x"])
    assert rows[2]["t"] == direct["t"]


def ks_key(p: dict) -> str:
    from kinema.sweep.design import key

    return key(p)


def test_checkpoint_outside_a_sweep_does_nothing_and_checks_its_arguments():
    scene = build_scene(0)
    assert ks.checkpoint(scene) is False
    with pytest.raises(ValueError, match=r"^scene:"):
        ks.checkpoint(object())
    with pytest.raises(ValueError, match=r"^every:"):
        ks.checkpoint(scene, every=0)


# The scheduler-kill test: a sweep on its own LocalCluster (the default client=None) in a
# subprocess, SIGKILLed with its whole process group (client, scheduler, nannies, workers) while
# both workers are inside a task that waits for a file to disappear.
CHILD = """
import sys
sys.path.insert(0, {tests!r})
from test_sweep_robust import build_chain, run_chain
from kinema.sweep import grid, sweep

if __name__ == "__main__":
    design = grid(seed=range(12), log=[{log!r}], gate=[{gate!r}])
    sweep(build_chain, design, run_chain, checkpoint_dir={ck!r}, progress=False)
"""


def build_chain(seed: int, log: str, gate: str) -> dict:
    system = build_scene(seed)
    return {"scene": system, "seed": seed, "log": log, "gate": gate}


def run_chain(system: dict) -> dict:
    seed, log = system["seed"], system["log"]
    _append(log, f"start {seed} {os.getpid()}")
    while seed >= 6 and os.path.exists(system["gate"]):  # tasks 6.. wait for the gate to open
        time.sleep(0.01)
    out = run_scene(system["scene"], str(Path(log).with_suffix(".frames")), 0.0, False)
    _append(log, f"done {seed} {os.getpid()}")
    return out


def test_a_sweep_resumed_after_its_scheduler_was_killed_gives_the_serial_bits(client, tmp_path):
    log, gate, ck = tmp_path / "log.txt", tmp_path / "gate", tmp_path / "ck"
    gate.write_text("closed")
    code = CHILD.format(tests=str(Path(__file__).parent), log=str(log), gate=str(gate), ck=str(ck))
    child = subprocess.Popen(
        [sys.executable, "-c", code],
        start_new_session=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
    )
    try:
        deadline = time.monotonic() + 120
        # Both workers wait at the gate: every task they ran before has finished.
        while len({r[0] for r in _lines(log, "start") if r[0] >= 6}) < 2:
            assert child.poll() is None, child.communicate()[0].decode()
            assert time.monotonic() < deadline
            time.sleep(0.05)
    finally:
        os.killpg(child.pid, signal.SIGKILL)
        child.wait()
    first = sorted(r[0] for r in _lines(log, "done"))
    assert first == list(range(6))  # the tasks before the gate, nothing of the waiting ones
    gate.unlink()

    design = ks.grid(seed=range(12), log=[str(log)], gate=[str(gate)])
    resumed = ks.sweep(
        build_chain, design, run_chain, client=client, checkpoint_dir=ck, progress=False
    )
    # Each task finished exactly once over the two runs: the first six were not run again
    # (read from the part files, or from the task files of a batch the client never stored).
    assert sorted(r[0] for r in _lines(log, "done")) == list(range(12))
    serial = ks.sweep(
        build_chain,
        ks.grid(seed=range(12), log=[str(tmp_path / "serial.txt")], gate=[str(gate)]),
        run_chain,
        client="serial",
        progress=False,
    )
    _same(serial, resumed)
