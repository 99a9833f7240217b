"""Throughput of the batched ugv-uav kind (seed 001 §5) against separate runs of its worlds.

One closed loop of ``marciano-circle`` (the Pioneer and the Bebop, the UGV-UAV controller of
Fig. 18, the motion capture at 100 Hz with 5 mm / 10 mrad noise, 30 ms control ticks of six
5 ms plant steps), ``--duration`` s simulated, through ``Experiment.run(backend=...)``:

* separate runs: one world per run (``x0`` of shape ``(11,)``), the way a sweep ran this kind
  before it batched;
* a batch of B worlds (``x0`` ``(B, 11)``, one ``MotionCapture`` whose schedule draws world
  ``b`` from the streams of ``seed + b``): what one chunk of a ``ugv-uav`` sweep runs.

For each backend (``numpy``; ``jax`` when installed: ``jax.jit(lax.scan)`` of the same tick,
compiled once per batch shape before the timing) it prints worlds x control ticks per second
of the loop alone (the ``finish`` of the log left out) and, for the batch, the same with
every world's finish and metrics (``finish_worlds``: world by world on the host, as a sweep
reduces a chunk), and the ratio to the separate runs of the same backend and to NumPy's.

Usage: ``python benchmarks/bench_ugv_uav_batch.py [--duration 10] [--sizes 1,16,64,256]
[--backends numpy,jax] [--repeat 2]``.
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np
from _common import best_of, machine_description, optional_import

from quatform.scenarios import load_scenario
from quatform.scenarios.ugv_uav import ugv_uav_experiment


def _experiment(duration: float):
    sc = dataclasses.replace(load_scenario("marciano-circle"), duration_s=duration, transient_s=min(20.0, duration / 2),
                             mocap_noise_m=0.005, mocap_noise_rad=0.01)
    return ugv_uav_experiment(sc, "quaternion")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=10.0, help="simulated seconds per run (default 10)")
    ap.add_argument("--sizes", default="1,16,64,256", help="batch sizes B (default 1,16,64,256)")
    ap.add_argument("--backends", default="numpy,jax", help="compute backends (default numpy,jax)")
    ap.add_argument("--repeat", type=int, default=2, help="best of this many timings (default 2)")
    args = ap.parse_args()
    sizes = [int(b) for b in args.sizes.split(",")]
    have_jax = optional_import("jax") is not None
    backends = [b for b in args.backends.split(",") if b != "jax" or have_jax]
    exp = _experiment(args.duration)
    raw = dataclasses.replace(exp, finish=lambda log: log)
    T = len(exp.times)
    print(f"ugv-uav batch: marciano-circle, {args.duration:g} s = {T} control ticks x {exp.substeps} plant steps, "
          "quaternion description, noisy motion capture")
    for line in machine_description({"jax": have_jax}):
        print(line)
    print(f"{'backend':<8}{'B':>6}{'loop (worlds*ticks/s)':>24}{'x separate':>12}{'x numpy sep.':>14}"
          f"{'+finish, metrics':>18}{'x separate':>12}")
    numpy_separate = None
    for backend in backends:
        raw.run(backend=backend)  # a warm-up (JAX: the one-world compilation)
        separate = T / best_of(lambda: raw.run(backend=backend), args.repeat)
        separate_full = T / best_of(lambda: exp.metrics(exp.run(backend=backend)), args.repeat)
        if backend == "numpy":
            numpy_separate = separate
        print(f"{backend:<8}{'sep.':>6}{separate:>24.4g}{1.0:>12.3g}"
              f"{separate / numpy_separate if numpy_separate else float('nan'):>14.3g}{separate_full:>18.4g}"
              f"{1.0:>12.3g}")
        for B in sizes:
            x0 = np.repeat(np.asarray(exp.x0)[None], B, axis=0)
            batch = dataclasses.replace(raw, x0=x0)
            batch.run(backend=backend)  # JAX: compiled for this batch shape before the timing
            loop = B * T / best_of(lambda: batch.run(backend=backend), 1 if B >= 64 else args.repeat)
            full_exp = dataclasses.replace(exp, x0=x0)

            def full():
                log = full_exp.run(backend=backend)
                return [exp.metrics(log.world(b)) for b in range(B)]

            whole = B * T / best_of(full, 1)
            print(f"{backend:<8}{B:>6}{loop:>24.4g}{loop / separate:>12.3g}"
                  f"{loop / numpy_separate if numpy_separate else float('nan'):>14.3g}{whole:>18.4g}"
                  f"{whole / separate_full:>12.3g}")


if __name__ == "__main__":
    main()
