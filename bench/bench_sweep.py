"""kinema.sweep on Dask: overhead per task and the 2-worker speed-up, against plain processes.

All in one process, one after the other, on a machine that may be busy (ratios matter):

1. overhead: tasks that do nothing, on a 2-worker cluster of ``kinema.sweep.local_client``
   (what ``sweep`` starts by default: one thread each): wall time per task, batching included;
   and ``--chains`` tasks of under a millisecond (a spring chain), whose 2-worker time is
   compared with the serial time, with the workers' time outside the tasks against the time
   inside them, both as wall time (2 x wall - the tasks' own seconds) and as CPU time (the
   worker processes' CPU time, every thread, less the CPU time of the thread that ran the
   tasks while in them; a busy machine does not inflate it); and the same CPU time outside the
   tasks in two plain processes running a plain ``for`` loop over half the tasks each at the
   same time (their loop thread's CPU time less the tasks'): such a loop pays for calling
   ``build``, freeing each system and the clock reads too, so the difference is the sweep's own
   cost per task, of which the part on the workers' event-loop threads is printed apart;
2. speed-up: ``--tasks`` cloth tasks (a 16x16 Baraff-Witkin cloth, 160 implicit steps, a
   stiffness x dt grid) run (a) in a plain loop in this process, (b) on a two-process
   ``multiprocessing.Pool`` started beforehand (one task at a time from its shared queue), (c)
   by ``sweep`` on the 2-worker cluster.
   Every run uses one kinema thread per process. Reported: (a)/(b), (a)/(c) and their ratio,
   and the CPU seconds of each plain process beside its wall time (a process that got a whole
   core has the two equal).

Run: python bench/bench_sweep.py [--quick]
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import time

import numpy as np


def cloth_build(stretch: float, dt: float):
    from kinema.cloth import Cloth

    cloth = Cloth.grid(16, 16, 1.0, 1.0, stretch=stretch, shear=stretch / 10, damping=5e-3)
    cloth.pin([0, 15])
    return cloth, dt


def cloth_run(system) -> dict[str, float]:
    cloth, dt = system
    cloth.step(dt, 160)  # about 0.3 s of work, as the 40 steps were before the Cholesky default
    return {"lowest": float(cloth.positions[:, 1].min())}


def chain_build(stiffness: float, seed: int = 0):
    """A spring chain of 8 particles, and this thread's CPU clock at the start of the task
    (the thread's, not the process's: a Dask worker's event loop runs beside the task), taken
    first, so that the task's own import counts as the task's."""
    cpu = time.thread_time()
    from kinema.particles import Gravity, ParticleSystem, Springs

    n = 8
    x = np.zeros((n, 3))
    x[:, 0] = np.arange(n) * 0.1
    masses = np.full(n, 1.0)
    masses[0] = np.inf
    ps = ParticleSystem(x, masses=masses)
    ps.add(Springs([[i, i + 1] for i in range(n - 1)], stiffness, damping=0.1))
    ps.add(Gravity())
    return ps, cpu


def chain_run(system) -> dict[str, float]:
    ps, cpu = system
    ps.step(1e-3, steps=1000)
    return {"tip_y": float(ps.positions[-1, 1]), "cpu": time.thread_time() - cpu}


def nothing_build(i: int) -> int:
    return i


def nothing_run(i: int) -> dict[str, int]:
    return {"i": i}


def _plain_loop(design: list[dict]) -> float:
    """CPU seconds of this thread outside the tasks while running ``chain_run(chain_build(**p))``
    for every ``p``: the tiny tasks without any sweep around them."""
    inside = 0.0
    cpu = time.thread_time()
    for p in design:
        inside += chain_run(chain_build(**p))["cpu"]
    return time.thread_time() - cpu - inside


def plain_loops(design: list[dict]) -> float:
    """CPU seconds outside the tasks of two plain processes running :func:`_plain_loop` over
    half of ``design`` each, at the same time (as the sweep's two workers run)."""
    ctx = mp.get_context("spawn")
    with ctx.Pool(2, initializer=_one_thread) as pool:
        pool.map(time.sleep, [1.0, 1.0], chunksize=1)  # both started and imported kinema
        return sum(pool.map(_plain_loop, [design[0::2], design[1::2]], chunksize=1))


def _cpu_clocks() -> tuple[float, float]:
    """A worker's CPU seconds: its whole process, and the thread this runs on (``client.run``
    runs it on the worker's event loop)."""
    return time.process_time(), time.thread_time()


def _one_thread() -> None:
    import kinema

    kinema.set_num_threads(1)


def _plain_task(p: dict) -> tuple[int, float]:
    """One cloth task in a pool process: its process id and CPU seconds."""
    cpu = time.process_time()
    cloth_run(cloth_build(**p))
    return os.getpid(), time.process_time() - cpu


def two_processes(design: list[dict]) -> tuple[float, list[float]]:
    """Wall time of ``design`` on a plain two-process ``multiprocessing.Pool`` (one task at a
    time from a shared queue, as Dask balances), and each process's CPU seconds in the tasks."""
    ctx = mp.get_context("spawn")
    with ctx.Pool(2, initializer=_one_thread) as pool:
        pool.map(time.sleep, [1.0, 1.0], chunksize=1)  # both started and imported kinema
        t0 = time.perf_counter()
        done = pool.map(_plain_task, design, chunksize=1)
        wall = time.perf_counter() - t0
    cpu: dict[int, float] = {}
    for pid, seconds in done:
        cpu[pid] = cpu.get(pid, 0.0) + seconds
    return wall, sorted(cpu.values())


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--chains", type=int, help="spring-chain tasks (default 10000, 500 quick)")
    args = parser.parse_args()
    import kinema
    from kinema.sweep import grid, local_client, sweep

    kinema.set_num_threads(1)
    n_cloth = 8 if args.quick else 64
    tiny = 200 if args.quick else 2000
    design = grid(
        stretch=np.geomspace(1e3, 1e4, n_cloth // 4), dt=[1 / 240, 1 / 120, 1 / 90, 1 / 60]
    )
    client = local_client(2)
    sweep(nothing_build, grid(i=range(4)), nothing_run, client=client, progress=False)  # warm

    t0 = time.perf_counter()
    sweep(nothing_build, grid(i=range(tiny)), nothing_run, client=client, progress=False)
    empty = time.perf_counter() - t0
    print(f"{tiny} empty tasks on 2 workers: {empty / tiny * 1e6:.0f} µs per task (wall)")

    n_chains = args.chains or (500 if args.quick else 10_000)
    chains = grid(stiffness=np.linspace(100.0, 1000.0, n_chains))
    t0 = time.perf_counter()
    sweep(chain_build, chains, chain_run, client="serial", progress=False)
    serial = time.perf_counter() - t0
    before = client.run(_cpu_clocks)
    t0 = time.perf_counter()
    batched = sweep(chain_build, chains, chain_run, client=client, progress=False)
    dask = time.perf_counter() - t0
    after = client.run(_cpu_clocks)
    worker_cpu = sum(after[w][0] - before[w][0] for w in after)
    loop_cpu = sum(after[w][1] - before[w][1] for w in after)  # the event loops' threads
    busy = batched["seconds"].sum()  # worker wall time inside build + run
    busy_cpu = batched["cpu"].sum()  # the same, CPU time
    plain_outside = plain_loops(chains)
    print(
        f"{len(chains)} tasks of {serial / len(chains) * 1e3:.2f} ms: serial {serial:.2f} s, "
        f"2 workers {dask:.2f} s, speed-up {serial / dask:.2f}; worker time outside the "
        f"tasks (batched): wall {(2 * dask - busy) / busy * 100:.1f} % of the time in them "
        f"({(2 * dask - busy) / len(chains) * 1e6:.0f} µs per task), CPU "
        f"{(worker_cpu - busy_cpu) / busy_cpu * 100:.1f} % "
        f"({(worker_cpu - busy_cpu) / len(chains) * 1e6:.0f} µs per task); in plain loops "
        f"{plain_outside / busy_cpu * 100:.1f} % ({plain_outside / len(chains) * 1e6:.0f} µs); "
        f"the sweep's own cost {(worker_cpu - busy_cpu - plain_outside) / busy_cpu * 100:.1f} % "
        f"({(worker_cpu - busy_cpu - plain_outside) / len(chains) * 1e6:.0f} µs per task), of "
        f"which the workers' event loops {loop_cpu / busy_cpu * 100:.1f} % "
        f"({loop_cpu / len(chains) * 1e6:.0f} µs per task)"
    )

    t0 = time.perf_counter()
    table = sweep(cloth_build, design, cloth_run, client="serial", progress=False)
    serial = time.perf_counter() - t0
    plain, plain_cpu = two_processes(design)
    t0 = time.perf_counter()
    on_dask = sweep(cloth_build, design, cloth_run, client=client, progress=False)
    dask = time.perf_counter() - t0
    busy = on_dask["seconds"].sum()
    assert np.array_equal(table["lowest"], on_dask["lowest"], equal_nan=True)
    print(
        f"{len(design)} cloth tasks of {serial / len(design):.2f} s: serial {serial:.1f} s, "
        f"two plain processes {plain:.1f} s (x{serial / plain:.2f}; CPU in the tasks "
        f"{' and '.join(f'{c:.1f} s' for c in plain_cpu)}), "
        f"sweep on 2 workers {dask:.1f} s (x{serial / dask:.2f}): "
        f"{plain / dask * 100:.0f} % of the plain processes' speed-up; worker time outside "
        f"the tasks {(2 * dask - busy) / busy * 100:.1f} %"
    )
    print(f"load average (1, 5, 15 min) after the run: {os.getloadavg()}")
    client.close()


if __name__ == "__main__":
    main()
