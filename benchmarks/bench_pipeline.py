"""The seed 000 spiral on the one pipeline: one world in process, and a batch of worlds per tick.

Two measurements:

single
    ``mas-kitts-spiral`` (60 s simulated, control every 10 ms, 6001 ticks) with each
    controller, timed end to end in process (:func:`quatform.scenarios.pair.run_pair`:
    reference, closed loop, log, derived channels; no files): simulated seconds per wall
    second. With ``--old REV`` the same runs of the old path (``quatform.sim.simulate(sc,
    controller)`` of git revision ``REV``, e.g. the commit before the pipeline) are timed
    in a subprocess on an export of that revision's ``src/`` (``git archive``), so both
    numbers come from the same machine and load.
batched
    ``--worlds`` B (default 1000) worlds of the spiral, each starting from its own random
    initial offset (seeded), shortened to ``--batch-duration`` s (default 5 s, 501 ticks:
    a 60 s batch of 1000 worlds logs ~3 GB), run by one :func:`quatform.sim.simulate` with
    ``x0`` of shape ``(B, 8)``: one Python iteration per tick for all worlds. Against it,
    ``--separate`` (default 20) of the same worlds run one by one, the time of B separate
    runs extrapolated linearly. Reported: the loop alone (``simulate``) and the loop plus the
    derived channels (``Experiment.finish``: recovered Euclidean variables, singularity
    measure), per world, and the per-world throughput ratio batched / separate.

Usage: ``python benchmarks/bench_pipeline.py [--repeat 3] [--worlds 1000] [--old REV]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
from _common import best_of, fmt, machine_description

from quatform.control import CONTROLLERS
from quatform.formations import EuclideanPair
from quatform.scenarios import load_scenario
from quatform.scenarios.pair import run_pair
from quatform.scenarios.team import TEAM
from quatform.sim import simulate

#: Spread of the random initial offsets of the batched worlds (Euclidean variables: m for
#: x_c, y_c, z_c, d_c; rad for the angles), about the scenario's own offset.
OFFSET_SCALE = np.array([0.2, 0.2, 0.2, 0.3, 0.3, 0.1, 0.3, 0.3])

_OLD = """
import json, sys, time
from quatform.sim import load_scenario  # the old revision's API
from quatform.sim import simulate
sc, best = load_scenario("mas-kitts-spiral"), {}
for c in sys.argv[2:]:
    best[c] = float("inf")
    for _ in range(int(sys.argv[1])):
        t0 = time.perf_counter(); simulate(sc, c); best[c] = min(best[c], time.perf_counter() - t0)
print(json.dumps(best))
"""



def old_times(rev: str, repeat: int) -> dict:
    """Best wall time of the old path's spiral run per controller, at git revision ``rev``."""
    root = subprocess.run(["git", "rev-parse", "--show-toplevel"], capture_output=True, text=True, check=True,
                          cwd=os.path.dirname(os.path.abspath(__file__))).stdout.strip()
    with tempfile.TemporaryDirectory() as tmp:
        tar = subprocess.run(["git", "archive", rev, "src"], capture_output=True, check=True, cwd=root).stdout
        subprocess.run(["tar", "-x", "-C", tmp], input=tar, check=True)
        out = subprocess.run([sys.executable, "-c", _OLD, str(repeat), *CONTROLLERS], capture_output=True, text=True,
                             check=True, env={**os.environ, "PYTHONPATH": os.path.join(tmp, "src")}).stdout
    return json.loads(out)


def single(repeat: int, old: str | None):
    sc = load_scenario("mas-kitts-spiral")
    before = old_times(old, repeat) if old else {}
    span = float(sc.times[-1])
    print(f"\nsingle: {sc.name}, {span:g} s simulated ({sc.times.size} ticks), best of {repeat}")
    print("| controller | wall s | simulated s per wall s |" + (f" old ({old}) wall s | old sim s per wall s |"
                                                               if old else ""))
    print("|---|---|---|" + ("---|---|" if old else ""))
    for c in CONTROLLERS:
        w = best_of(lambda: run_pair(sc, c), repeat)
        row = f"| {c} | {fmt(w)} | {fmt(span / w)} |"
        if old:
            row += f" {fmt(before[c])} | {fmt(span / before[c])} |"
        print(row)


def batched(worlds: int, duration: float, separate: int, controllers):
    sc = dataclasses.replace(load_scenario("mas-kitts-spiral"), duration_s=duration, metrics_from_s=0.0)
    e0, _ = sc.path(np.zeros(1))
    rng = np.random.default_rng(2026)
    r0 = EuclideanPair().inverse(e0[0] + sc.initial_offset + rng.normal(scale=OFFSET_SCALE, size=(worlds, 8)))
    print(f"\nbatched: {worlds} worlds of {sc.name} shortened to {duration:g} s ({sc.times.size} ticks); "
          f"{separate} separate runs extrapolated to {worlds}")
    print("| controller | batched loop s | separate loop s (x B) | loop ratio | batched + finish s | "
          "separate + finish s (x B) | ratio |")
    print("|---|---|---|---|---|---|---|")
    for c in controllers:
        def run(x0):
            exp = TEAM.experiment(sc, controller=c, r0=x0)
            t0 = time.perf_counter()
            log = simulate(exp.plant, exp.controller, exp.reference, exp.times, exp.x0, dt=exp.dt, meta=exp.meta)
            t1 = time.perf_counter()
            exp.finish(log)
            return t1 - t0, time.perf_counter() - t0

        loop_b, all_b = run(r0)
        one = np.array([run(r0[i]) for i in range(separate)])
        loop_s, all_s = one.mean(axis=0) * worlds
        print(f"| {c} | {fmt(loop_b)} | {fmt(loop_s)} | {fmt(loop_s / loop_b)} | {fmt(all_b)} | {fmt(all_s)} | "
              f"{fmt(all_s / all_b)} |")


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeat", type=int, default=3, help="best of this many single runs (default 3)")
    p.add_argument("--old", metavar="REV", help="also time the old path at this git revision")
    p.add_argument("--worlds", type=int, default=1000, help="batched worlds (default 1000)")
    p.add_argument("--batch-duration", type=float, default=5.0, help="simulated s of the batch (default 5)")
    p.add_argument("--separate", type=int, default=20, help="separate runs timed (default 20)")
    p.add_argument("--controller", action="append", choices=list(CONTROLLERS),
                   help="batched controllers (default: all; repeat the flag for several)")
    p.add_argument("--skip-single", action="store_true", help="only the batched measurement")
    args = p.parse_args(argv)
    for line in machine_description({}):
        print(line)
    if not args.skip_single:
        single(args.repeat, args.old)
    batched(args.worlds, args.batch_duration, args.separate, args.controller or list(CONTROLLERS))


if __name__ == "__main__":
    main()
