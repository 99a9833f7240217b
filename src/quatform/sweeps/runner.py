"""Running a sweep: its chunks planned and estimated up front, sent to an executor, stored, reported.

Sweeps layer. :func:`plan_chunks` cuts every cell's trials into chunks (a cell's batch, or
slices of ``chunk_trials``; fixed by the spec, not by the executor, so the batches and hence
the numbers are the same everywhere); :func:`estimate` builds one experiment per distinct
run shape and refuses, before anything runs, a sweep whose batches cannot fit in memory
(batch x T x channels x 8 B) or whose trials cannot finish in the time budget;
:func:`run_sweep` runs the chunks not yet stored, shows progress on stderr (trials done,
trials/s, time left) and writes the tables and figures: from the rows in memory
(``results = "csv"``), or from the Parquet shards a batch at a time (``"parquet"``, ``"both"``).
"""

from __future__ import annotations

import math
import sys
import time
from concurrent.futures import FIRST_COMPLETED, wait
from dataclasses import dataclass
from pathlib import Path

from ..checks import memory_budget_bytes, time_budget_s
from ..errors import ResourceLimitError
from ..sim.output import write_failures
from .executors import check_scheduler, executor, parallel_workers
from .results import (CSV_MAX_TRIALS, ChunkStore, metric_values, ordered_rows, results_mode, shard_metric_values,
                      stored_results, summarize, summarize_shards, typed_rows, write_table)
from .trials import SWEEP_KINDS, Chunk, cell_experiment, cell_scenario, row_metrics, run_chunk

__all__ = ["plan_chunks", "estimate", "Estimate", "run_sweep", "SECONDS_PER_TICK", "SECONDS_PER_ROBOT_STEP",
           "BYTES_PER_VALUE", "MEMORY_FACTOR"]

#: Wall time of one batched control tick apart from its worlds' arithmetic, s: the Python
#: loop of :func:`quatform.sim.simulate` and the controller's call overhead, measured 0.5-1.3 ms
#: per tick (seed 000 helix, any controller, 1 to 32 worlds) on this project's 2-core machine.
SECONDS_PER_TICK = 1.5e-3
#: Wall time per robot-step inside a batch, s: measured 0.4-2.6e-5 (the helix at 32 worlds:
#: 4e4-8e4 robot-steps/s; 100-robot teams: 1e5-2.6e5) plus the per-trial metrics; 5e-5 covers
#: the slowest description's singularity measure of a 36-robot team.
SECONDS_PER_ROBOT_STEP = 5e-5
#: One logged value, bytes (float64).
BYTES_PER_VALUE = 8
#: Peak memory over the logged arrays: the per-tick lists and their stacked copy, the noise.
MEMORY_FACTOR = 2.5


def plan_chunks(spec, backend: str = "numpy") -> list[Chunk]:
    """Every chunk of the sweep, cell by cell."""
    size = spec.chunk_trials or spec.trials
    return [Chunk(spec, cell, start, min(start + size, spec.trials), backend)
            for cell in range(len(spec.cells())) for start in range(0, spec.trials, size)]


@dataclass(frozen=True)
class Estimate:
    """The up-front cost of a sweep."""

    trials: int
    robot_steps: float
    seconds: float
    chunk_bytes: float


def estimate(spec, workers: int = 1) -> Estimate:
    """The sweep's trials, robot-steps, wall time (``workers`` chunks at once) and largest chunk's memory;
    refuses (one line with the numbers and the key to change) what cannot fit."""
    shapes: dict = {}
    cells = spec.cells()
    size = spec.chunk_trials or spec.trials
    checked = set()
    for _, choice, values in cells:
        variant = SWEEP_KINDS[spec.data["kind"]].variant(choice, values)
        if variant not in checked:  # every scenario variant built once: a bad one is refused before any run
            checked.add(variant)
            cell_scenario(spec, values, choice)
        key = (choice, values.get("team_size"))
        if key not in shapes:
            exp = cell_experiment(spec, values, choice)
            ctrl = exp.controller
            n_y = len(exp.plant.output_columns)
            width = (len(exp.plant.state_columns) + 2 * n_y + len(ctrl.command_names)
                     + sum(len(c) for c in ctrl.signal_columns().values()))
            shapes[key] = (len(exp.times), exp.substeps, SWEEP_KINDS[spec.data["kind"]].robots(exp), width)
    steps = 0.0
    seconds = 0.0
    chunk_bytes = 0.0
    n_chunks = math.ceil(spec.trials / size)
    for _, choice, values in cells:
        T, sub, n, width = shapes[(choice, values.get("team_size"))]
        steps += spec.trials * T * sub * n
        seconds += n_chunks * T * SECONDS_PER_TICK + spec.trials * T * sub * n * SECONDS_PER_ROBOT_STEP
        chunk_bytes = max(chunk_bytes, size * T * width * BYTES_PER_VALUE * MEMORY_FACTOR)
    where = spec.where
    cap = memory_budget_bytes()
    if chunk_bytes > cap:
        raise ResourceLimitError(
            f"{where}: one batch of {size} trials needs about {chunk_bytes / 1e9:.3g} GB (batch x T x channels x 8 B "
            f"x {MEMORY_FACTOR}), more than the {cap / 1e9:.3g} GB allowed (QUATFORM_MAX_MEMORY_BYTES); lower "
            "chunk_trials (or trials), or shorten duration_s")
    wall = seconds / max(1, min(workers, len(cells) * n_chunks))  # no more chunks at once than there are
    budget = time_budget_s()
    if wall > budget:
        raise ResourceLimitError(
            f"{where}: {len(cells)} cells x {spec.trials} trials = {len(cells) * spec.trials:,} trials, "
            f"{steps:.3g} robot-steps, need about {wall / 3600:.3g} h on {workers} worker(s) (at "
            f"{SECONDS_PER_TICK * 1e3:g} ms a tick + {SECONDS_PER_ROBOT_STEP * 1e6:g} us a robot-step), more than the "
            f"{budget / 3600:.3g} h limit (QUATFORM_MAX_WORK_S); lower trials, coarsen [vary] or shorten duration_s")
    return Estimate(len(cells) * spec.trials, steps, wall, chunk_bytes)


class _Progress:
    """``sweep NAME: 96/384 trials (25 %), 12.1 trials/s, about 24 s left`` on stderr."""

    def __init__(self, name: str, total: int, done: int, stream=None, quiet: bool = False):
        self.name, self.total, self.done, self.start_done = name, total, done, done
        self.t0 = time.perf_counter()
        self.stream = sys.stderr if stream is None else stream
        self.quiet = quiet
        if done and not quiet:
            print(f"sweep {name}: resuming, {done}/{total} trials already stored", file=self.stream)

    def add(self, n: int) -> None:
        self.done += n
        if self.quiet:
            return
        dt = time.perf_counter() - self.t0
        rate = (self.done - self.start_done) / dt if dt > 0 else float("inf")
        left = (self.total - self.done) / rate if rate > 0 else float("inf")
        print(f"sweep {self.name}: {self.done}/{self.total} trials ({100 * self.done / self.total:.0f} %), "
              f"{rate:.3g} trials/s, about {left:.0f} s left", file=self.stream, flush=True)


def run_sweep(spec, out, *, backend: str = "numpy", workers: int = 1, scheduler: str | None = None,
              plots: bool = True, quiet: bool = False, results: str | None = None) -> list[dict]:
    """Run ``spec`` into the folder ``out`` (resuming the chunks stored there); return the
    summary rows. Writes ``results.csv``/``.json`` and/or the Parquet shards ``trials/`` (``results``:
    ``csv``, ``parquet`` or ``both``; None: the spec's, :func:`~quatform.sweeps.results.results_mode`),
    ``summary.csv``/``.json`` and, with ``plots``, the figures of :mod:`quatform.sweeps.figures`."""
    from ..errors import InvalidInputError, MissingDependencyError
    from ..sim.backends import SIM_BACKENDS, simulator

    if backend == "jax" and backend not in SIM_BACKENDS:
        raise InvalidInputError('--compute jax: the JAX backend is not registered in this install (it needs '
                                'quatform.sim.loop and pip install -e ".[jax]"); use --compute numpy')
    try:
        simulator(backend)  # an unknown or uninstallable backend: one line before anything runs
    except MissingDependencyError:
        raise
    except ImportError as exc:
        raise MissingDependencyError(f"--compute {backend}: {exc}; pip install -e \".[{backend}]\"") from None
    check_scheduler(scheduler)  # Dask missing: one line before the experiments are built
    mode = results_mode(spec, results, out)
    if mode != "csv":
        from .shards import require_pyarrow

        require_pyarrow(f'results = "{mode}"' + ("" if results or spec.results or stored_results(out) else
                                                 f" (the default above {CSV_MAX_TRIALS:,} trials)"))
    est = estimate(spec, parallel_workers(workers, scheduler))
    with write_failures(out):  # a full disk: one line naming --out and the file
        return _run_sweep(spec, out, backend, workers, scheduler, plots, quiet, est, mode)


def _run_sweep(spec, out, backend, workers, scheduler, plots, quiet, est, mode) -> list[dict]:
    """The body of :func:`run_sweep` (its files written into ``out``)."""
    with ChunkStore(out, spec, backend, mode) as store:  # the folder locked till the end
        return _run_chunks(spec, Path(out), store, backend, workers, scheduler, plots, quiet, est, mode)


def _run_chunks(spec, out, store, backend, workers, scheduler, plots, quiet, est, mode) -> list[dict]:
    """Run the chunks ``store`` lacks, then write the tables and figures."""
    with executor(workers, scheduler, spec.slurm) as ex:  # an unreachable scheduler: before any chunk
        stored = 0
        todo = []
        for ch in plan_chunks(spec, backend):
            got = store.load(ch)
            if got is None:
                todo.append(ch)
            else:
                stored += got
        progress = _Progress(spec.name, est.trials, stored, quiet=quiet)
        checked = bool(stored)
        if stored:
            spec.success.check_metrics(row_metrics(spec, store.first_row()), spec.where)

        def finished(ch, got):
            nonlocal checked
            if not checked:
                spec.success.check_metrics(row_metrics(spec, got[0]), spec.where)
                checked = True
            store.save(ch, got)
            progress.add(len(got))

        if ex is None:
            for ch in todo:
                finished(ch, run_chunk(ch))
        else:
            # on Ctrl-C or an error the executor's exit drops what is pending (its workers stopped,
            # the Dask client closed), so the futures are not cancelled here
            pending = {ex.submit(run_chunk, ch): ch for ch in todo}
            while pending:
                done, _ = wait(pending, return_when=FIRST_COMPLETED)
                for fut in done:
                    finished(pending.pop(fut), fut.result())
    if store.shards is None:
        rows = typed_rows(ordered_rows(store.rows))
        summary = summarize(spec, rows)
        write_table(out, "results", rows)
        values = metric_values(spec, rows)
    else:
        from .shards import shard_columns, shard_rows

        paths = store.shards.finish()
        summary = summarize_shards(spec, paths)
        if mode == "both":
            write_table(out, "results", lambda: shard_rows(paths), shard_columns(paths))
        values = shard_metric_values(spec, paths)
    write_table(out, "summary", summary)
    if plots:
        from .figures import sweep_figures

        sweep_figures(spec, values, summary, out / "figures")
    return summary
