"""Sweeps layer: Monte Carlo sweeps of a scenario over controllers, noise, latency, gains, starts, team sizes.

Top layer, beside :mod:`quatform.runs` (it uses scenarios, sim and report). A sweep spec
(plain TOML, ``docs/sweeps.md``) names a scenario, the choices to compare and the parameters
to vary; its trials run in batches through the scenario kind's own experiment (B worlds per
tick, each trial's random numbers from its own seed), on any executor, resumably.

* :mod:`.spec` - the strict reader (:func:`load_sweep`) and the parameters (:data:`PARAMETERS`,
  a registry: :func:`sweep_parameter` adds one, with how it changes a cell);
* :mod:`.trials` - a cell's batch and its rows (:func:`run_chunk`), the kinds a sweep can batch
  (the pair and team kinds there; :mod:`.ugv_uav` and :mod:`.teleop` add theirs);
* :mod:`.executors` - in process, local processes, Dask (local, ``tcp://``, SLURM);
* :mod:`.runner` - planning, the up-front estimate, progress, :func:`run_sweep`;
* :mod:`.results`, :mod:`.figures` - the chunk store, the tables, the summary and the figures;
* :mod:`.shards` - the trials as Parquet shards, one per chunk (pyarrow, ``pip install -e ".[dask]"``);
* :mod:`.cli` - ``quatform sweep`` and ``quatform sweeps``.
"""

from . import network, teleop, ugv_uav  # noqa: F401  (their sweep adapters and parameters register themselves)
from .runner import estimate, plan_chunks, run_sweep
from .spec import PARAMETERS, SweepSpec, builtin_sweeps, load_sweep, sweep_parameter

__all__ = ["PARAMETERS", "sweep_parameter", "SweepSpec", "builtin_sweeps", "load_sweep", "run_sweep", "estimate", "plan_chunks"]
