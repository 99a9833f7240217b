"""Decentralised formations at scale: the 1 000-robot swarm against real time, and batches of the ring.

Two measurements of ``quatform.scenarios.network`` runs (``NetworkedController`` in the one
loop), the simulation alone (the log's finish, metrics and files left out):

* ``net-swarm-1000``: 1 000 holonomic robots on a radio graph (7 614 candidate edges), 50 ms
  delay and 10 % loss, each robot's separation filter on; NumPy, one world: the wall time of
  the ``--duration`` s simulated (the links' schedule drawn up front included), the real-time
  factor (simulated s per wall s) and the time of one tick;
* ``net-consensus-ring``: 12 free bodies on a directed ring, the dual-quaternion pose
  consensus; separate runs (one world per run, ``x0`` ``(84,)``) against a batch of B worlds
  (``x0`` ``(B, 84)``, each world drawing its links from its own seed), on NumPy and on JAX
  (``jax.jit(lax.scan)`` of the same tick, compiled for each shape before the timing): worlds
  x ticks per second and the ratio of the batch to the separate runs of the same backend and
  to NumPy's separate runs.

Usage: ``python benchmarks/bench_network.py [--duration 20] [--ring-duration 10]
[--sizes 16,256] [--backends numpy,jax] [--repeat 2]``.
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np
from _common import best_of, machine_description, optional_import

from quatform.scenarios import KINDS, load_scenario


def _raw(name: str, duration: float):
    sc = dataclasses.replace(load_scenario(name), duration_s=duration)
    return dataclasses.replace(KINDS["network"].experiment(sc), finish=lambda log: log)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=20.0, help="simulated seconds of the swarm (default 20)")
    ap.add_argument("--ring-duration", type=float, default=10.0, help="simulated seconds of the ring (default 10)")
    ap.add_argument("--sizes", default="16,256", help="batch sizes B of the ring (default 16,256)")
    ap.add_argument("--backends", default="numpy,jax", help="compute backends of the ring (default numpy,jax)")
    ap.add_argument("--repeat", type=int, default=2, help="best of this many timings (default 2)")
    args = ap.parse_args()
    have_jax = optional_import("jax") is not None
    for line in machine_description({"jax": have_jax}):
        print(line)

    swarm = _raw("net-swarm-1000", args.duration)
    T = len(swarm.times)
    wall = best_of(lambda: swarm.run(), args.repeat)
    print(f"net-swarm-1000: {args.duration:g} s simulated = {T} ticks of {swarm.dt:g} s, 1000 robots, "
          f"{len(swarm.controller.links.edges)} candidate edges, separation filter on")
    print(f"  wall {wall:.3g} s, {args.duration / wall:.3g}x real time, {1e3 * wall / T:.3g} ms a tick (schedule "
          f"included)")

    ring = _raw("net-consensus-ring", args.ring_duration)
    T = len(ring.times)
    sizes = [int(b) for b in args.sizes.split(",")]
    backends = [b for b in args.backends.split(",") if b != "jax" or have_jax]
    print(f"net-consensus-ring: {args.ring_duration:g} s = {T} ticks, 12 free bodies, dq-consensus")
    print(f"{'backend':<8}{'B':>6}{'worlds*ticks/s':>18}{'x separate':>12}{'x numpy sep.':>14}")
    numpy_separate = None
    for backend in backends:
        ring.run(backend=backend)  # a warm-up (JAX: the one-world compilation)
        separate = T / best_of(lambda: ring.run(backend=backend), args.repeat)
        if backend == "numpy":
            numpy_separate = separate
        print(f"{backend:<8}{'sep.':>6}{separate:>18.4g}{1.0:>12.3g}"
              f"{separate / numpy_separate if numpy_separate else float('nan'):>14.3g}")
        for B in sizes:
            batch = dataclasses.replace(ring, x0=np.repeat(np.asarray(ring.x0)[None], B, axis=0))
            batch.run(backend=backend)  # JAX: compiled for this batch shape before the timing
            rate = B * T / best_of(lambda: batch.run(backend=backend), 1 if B >= 64 else args.repeat)
            print(f"{backend:<8}{B:>6}{rate:>18.4g}{rate / separate:>12.3g}"
                  f"{rate / numpy_separate if numpy_separate else float('nan'):>14.3g}")


if __name__ == "__main__":
    main()
