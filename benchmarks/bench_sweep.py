"""Sweep throughput: one CPU-bound sweep on 1 and 2 workers of each executor.

The sweep: seed 000's helix (``mas-kitts-helix``), its first ``--duration`` s (default 2 s,
200 control ticks at 100 Hz), the four controllers x ``noise_m`` in (0, 10 mm) x
``latency_s`` in (0, 20 ms) = 16 cells of ``--trials`` trials (default 4), each cell one
batch (``quatform.sweeps.run_chunk``): closed loop, measurement noise and latency, per-trial
metrics. Every executor runs the same chunks:

* **in process**: one chunk after another (the reference, and what ``--workers 1`` does);
* **processes 1 / 2**: ``concurrent.futures.ProcessPoolExecutor`` (``--workers N``);
* **Dask 1 / 2**: one ``distributed.LocalCluster`` of 1 and of 2 one-thread worker processes
  (``--scheduler local --workers N``; skipped when distributed is not installed).

Columns: wall seconds for the whole sweep (the executor started and warmed up with one
chunk beforehand, so start-up is not counted), trials/s, and the speed-up of 2 workers over
1 of the same executor (target >= 1.8 for Dask). Every executor's rows are checked
equal to the in-process ones. The machine is shared: the speed-up of 2 workers needs 2
idle cores (``os.getloadavg()`` is printed beside it).

Run it from the repository root::

    PYTHONPATH=src python benchmarks/bench_sweep.py                # about 20 s on an idle machine
    PYTHONPATH=src python benchmarks/bench_sweep.py --trials 8 --duration 5
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import machine_description, optional_import

from quatform.sweeps import plan_chunks
from quatform.sweeps.executors import executor
from quatform.sweeps.spec import sweep_from_dict
from quatform.sweeps.trials import run_chunk


def _spec(trials: int, duration: float):
    data = {"name": "bench", "scenario": "mas-kitts-helix", "trials": trials, "duration_s": duration,
            "settle_s": min(1.0, duration / 2), "vary": {"noise_m": {"values": [0.0, 0.01]},
                                                         "latency_s": {"values": [0.0, 0.02]}}}
    return sweep_from_dict(data, "bench_sweep")


def _run(chunks, ex) -> tuple[float, list]:
    t0 = time.perf_counter()
    if ex is None:
        rows = [run_chunk(c) for c in chunks]
    else:
        rows = list(ex.map(run_chunk, chunks))
    return time.perf_counter() - t0, rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trials", type=int, default=4)
    ap.add_argument("--duration", type=float, default=2.0)
    args = ap.parse_args(argv)
    spec = _spec(args.trials, args.duration)
    chunks = plan_chunks(spec)
    n_trials = len(spec.cells()) * spec.trials
    have_dask = optional_import("distributed") is not None
    for line in machine_description({"distributed": have_dask}):
        print(line)
    print(f"sweep: {len(spec.cells())} cells x {spec.trials} trials of the helix, {args.duration:g} s at 100 Hz; "
          f"load average {os.getloadavg()[0]:.2f}")
    ref_s, ref = _run(chunks, None)
    results = [("in process", 1, ref_s)]
    runs = [("processes", None)] + ([("Dask LocalCluster", "local")] if have_dask else [])
    for label, scheduler in runs:
        for workers in (1, 2):
            with executor(workers, scheduler) as ex:
                if ex is None:  # --workers 1 without a scheduler runs in process: time a 1-process pool
                    from concurrent.futures import ProcessPoolExecutor

                    with ProcessPoolExecutor(1) as pool:
                        pool.submit(run_chunk, chunks[0]).result()
                        s, rows = _run(chunks, pool)
                else:
                    list(ex.map(run_chunk, chunks[:workers]))  # warm up: every worker imports quatform
                    s, rows = _run(chunks, ex)
            if rows != ref:
                print(f"{label} x {workers}: rows differ from the in-process ones", file=sys.stderr)
                return 1
            results.append((label, workers, s))
    print(f"\n{'executor':20s} {'workers':>7s} {'wall s':>8s} {'trials/s':>9s} {'2 vs 1':>7s}")
    one = {}
    for label, workers, s in results:
        one.setdefault(label, s)
        ratio = f"{one[label] / s:7.2f}" if workers == 2 else ""
        print(f"{label:20s} {workers:7d} {s:8.2f} {n_trials / s:9.2f} {ratio}")
    print(f"\nload average after: {os.getloadavg()[0]:.2f}; every executor's rows equal the in-process ones")
    return 0


if __name__ == "__main__":
    sys.exit(main())
