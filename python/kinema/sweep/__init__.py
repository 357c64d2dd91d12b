"""Parameter sweeps and ensembles: many independent runs, on one machine or a Dask cluster.

A sweep is ``build(**p)`` (make a scene or any system from one parameter set ``p``) followed
by ``run(system)`` (advance it and return a dict of numbers or arrays), for every ``p`` of a
design: :func:`grid` (every combination), :func:`latin_hypercube` (a space-filling random
design, McKay, Beckman & Conover 1979) or any list of dicts. :func:`sweep` runs the design on
Dask distributed (a ``LocalCluster`` of one single-threaded worker process per core by default,
or any cluster a caller connects a ``Client`` to) or in a plain loop (``client="serial"``), and
returns a pandas table with one row per parameter set (:func:`to_xarray` makes it a Dataset
with the parameters as coordinates). With a ``checkpoint_dir`` every finished batch is written
there at once and a later sweep skips what is there, and a long task that calls
:func:`checkpoint` restarts from its last checkpoint when its worker is lost. :func:`trade`
measures error against cost per method and time step and draws the work–precision diagram.
See docs/sweep.md.

Modules: :mod:`~kinema.sweep.design` (designs, task keys), :mod:`~kinema.sweep.engine` (the
sweep on Dask or in a loop), :mod:`~kinema.sweep.store` (the checkpoint directory),
:mod:`~kinema.sweep.trade` (accuracy sweeps), :mod:`~kinema.sweep.tables` (xarray output),
:mod:`~kinema.sweep.config` (``kinema sweep CONFIG.toml``).
"""

from kinema.sweep.design import grid, latin_hypercube
from kinema.sweep.engine import QUIET_WORKERS, local_client, sweep
from kinema.sweep.store import checkpoint
from kinema.sweep.tables import to_xarray
from kinema.sweep.trade import trade

__all__ = [
    "QUIET_WORKERS",
    "checkpoint",
    "grid",
    "latin_hypercube",
    "local_client",
    "sweep",
    "to_xarray",
    "trade",
]
