"""Closed-loop batched rollouts: robot-steps/s on NumPy and JAX, crazyflow beside.

Three measurements, printed as ratios in one run:

1. **rollouts**: seed 000's pair (``mas-kitts-helix``, its gains, kinematic holonomic robots)
   under each of the four controllers, ``--worlds`` worlds from random offset starts (perfect
   measurement), ``--ticks`` control ticks: the controller, the team's saturation and the
   plant every tick. Robot-steps = worlds x robots (2) x ticks. NumPy:
   :func:`quatform.sim.simulate` (the reference, one Python iteration per tick, every channel
   logged); JAX: :func:`quatform.sim.jax_rollout.rollout_metrics` (the loop's compiled tick, as
   the ``jax`` backend, the errors from the robots reduced as it runs, ``formation_metrics=False``:
   the description's singularity measure and chart left out; compile time excluded: the best of
   ``--repeat`` runs after one warm-up; the batch in chunks split over JAX's devices, one
   CPU device per core: :mod:`quatform.sim.jax_devices`).
2. **crazyflow**: its batched ``Sim.step`` (``n_worlds`` worlds of one drone, default
   first-principles dynamics, attitude control, 500 Hz), run as a subprocess with the
   interpreter ``--crazyflow-python`` (default ``/work/venv-crazyflow/bin/python``; "not
   installed" otherwise): drone-steps/s beside ours.
3. **Monte Carlo** (``--mc-trials``, default 10^4): the helix, 60 s of flight each at the
   scenario's 100 Hz, the quaternion controller, each trial from its own start offset (2 cm,
   0.02 rad) with TickMeasurement noise (2 mm on positions, 2 mrad on yaws), 20 ms latency
   and 1 % dropped frames, all drawn up front from ``numpy.random.default_rng(seed)``; end to
   end, s: building the batch (the draws), the rollout (including compilation) and every
   trial's metrics (:data:`quatform.sim.jax_rollout.ROLLOUT_METRICS`).

Run it from the repository root (``pip install -e ".[jax]"``)::

    python benchmarks/bench_rollout.py                      # ~2 min on 2 cores
    python benchmarks/bench_rollout.py --worlds 1000 --ticks 100 --mc-trials 100   # quick
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import fmt, machine_description, optional_import

from quatform.scenarios import load_scenario
from quatform.scenarios.team import TEAM
from quatform.sim import simulate
from quatform.sim.trial_measurement import TickMeasurement

CONTROLLERS = ("cluster-space", "robot-space", "quaternion", "dual-quaternion")
CRAZYFLOW_PYTHON = "/work/venv-crazyflow/bin/python"
#: The peer's timing, run in its own interpreter (its own JAX); prints drone-steps/s.
CRAZYFLOW_SNIPPET = """
import sys, time
import jax
from crazyflow.sim import Sim
worlds, steps = int(sys.argv[1]), int(sys.argv[2])
sim = Sim(n_worlds=worlds, n_drones=1)
sim.step(steps)  # compile
jax.block_until_ready(sim.data)
best = float("inf")
for _ in range(3):
    t0 = time.perf_counter()
    sim.step(steps)
    jax.block_until_ready(sim.data)
    best = min(best, time.perf_counter() - t0)
print(worlds * steps / best)
"""


def experiment(controller: str, ticks: int):
    sc = load_scenario("mas-kitts-helix")
    sc = dataclasses.replace(sc, duration_s=(ticks - 1) * sc.dt_s, metrics_from_s=0.0)
    return TEAM.experiment(sc, controller=controller)


def starts(ex, worlds: int, seed: int = 0, spread: float = 0.02):
    return ex.x0 + np.random.default_rng(seed).normal(0.0, spread, (worlds, 8))


def numpy_rate(controller: str, worlds: int, ticks: int) -> float:
    """Robot-steps/s of :func:`quatform.sim.simulate` (one run: seconds long)."""
    ex = experiment(controller, ticks)
    x0 = starts(ex, worlds)
    t0 = time.perf_counter()
    simulate(ex.plant, ex.controller, ex.reference, ex.times, x0, dt=ex.dt)
    return worlds * 2 * ticks / (time.perf_counter() - t0)


def jax_rate(controller: str, worlds: int, ticks: int, repeat: int) -> float:
    """Robot-steps/s of the compiled JAX rollout (best of ``repeat`` after a warm-up)."""
    from quatform.sim.jax_rollout import rollout_metrics

    ex = experiment(controller, ticks)
    x0 = starts(ex, worlds)
    rollout_metrics(ex, x0, formation_metrics=False)  # compile
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        rollout_metrics(ex, x0, formation_metrics=False)
        best = min(best, time.perf_counter() - t0)
    return worlds * 2 * ticks / best


def crazyflow_rate(python: str, worlds: int, steps: int):
    """Drone-steps/s of crazyflow's batched step, or the reason it was not timed."""
    if not os.path.exists(python):
        return "not installed"
    try:
        out = subprocess.run([python, "-c", CRAZYFLOW_SNIPPET, str(worlds), str(steps)], check=False,
                             capture_output=True, text=True, timeout=300)
    except subprocess.TimeoutExpired:
        return "timed out"
    if out.returncode:
        tail = (out.stderr.strip().splitlines() or ["failed"])[-1]
        return "not installed" if "No module named 'crazyflow'" in out.stderr else f"failed: {tail}"
    return float(out.stdout.strip().splitlines()[-1])


def monte_carlo(trials: int, seed: int = 0, trials_per_call: int | None = None) -> dict:
    """The 10^4-trial helix Monte Carlo, end to end (see the module docstring)."""
    from quatform.sim.jax_rollout import rollout_metrics

    t0 = time.perf_counter()
    sc = load_scenario("mas-kitts-helix")
    sc = dataclasses.replace(sc, duration_s=60.0)
    ex = TEAM.experiment(sc, controller="quaternion")
    T = ex.times.size
    rng = np.random.default_rng(seed)
    x0 = ex.x0 + np.concatenate([rng.normal(0.0, 0.02, (trials, 3)), rng.normal(0.0, 0.02, (trials, 1)),
                                 rng.normal(0.0, 0.02, (trials, 3)), rng.normal(0.0, 0.02, (trials, 1))], axis=1)
    noise = rng.standard_normal((T, trials, 8))
    noise *= 0.002  # 2 mm on positions, 2 mrad on yaws (in place: the array is 8 T trials floats)
    meas = TickMeasurement(noise, 2, rng.random((T, trials)) < 0.01)
    t1 = time.perf_counter()
    res = rollout_metrics(ex, x0, meas, trials_per_call=trials_per_call, formation_metrics=False)
    t2 = time.perf_counter()
    return {"trials": trials, "ticks": T, "build_s": t1 - t0, "rollout_and_metrics_s": t2 - t1, "total_s": t2 - t0,
            "lost": int(np.sum(res["reference_lost"])), "failed": int(np.sum(res["failed"])),
            "median_max_position_error_m": float(np.median(res["max_robot_position_error_m"]))}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--worlds", type=int, default=10_000)
    ap.add_argument("--ticks", type=int, default=200)
    ap.add_argument("--numpy-worlds", type=int, default=10_000)
    ap.add_argument("--numpy-ticks", type=int, default=20)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--mc-trials", type=int, default=10_000)
    ap.add_argument("--crazyflow-python", default=CRAZYFLOW_PYTHON)
    ap.add_argument("--json", help="also write the numbers to this file")
    args = ap.parse_args(argv)
    jax = optional_import("jax")
    for line in machine_description({"jax": jax is not None}):
        print(line)
    load = ", ".join(f"{v:.2f}" for v in os.getloadavg())
    print(f"load    : {load} (1, 5, 15 min averages; other processes share the CPUs)")
    out = {"rollouts": {}}
    if jax is not None:
        from quatform.sim import jax_devices
        from quatform.sim.loop import require_jax

        devices = require_jax().devices()
        size = jax_devices.chunk_size(jax, args.worlds)
        print(f"jax     : {len(devices)} {devices[0].platform} device(s) (sim.jax_devices), {size} worlds per "
              "compiled call")
        out["jax_devices"] = [str(d) for d in devices]
    print(f"\nclosed-loop rollouts, M robot-steps/s (NumPy: {args.numpy_worlds} worlds x {args.numpy_ticks} ticks; "
          f"JAX: {args.worlds} worlds x {args.ticks} ticks)")
    print(f"{'controller':<18}{'numpy':>10}{'jax cpu':>10}{'jax/numpy':>11}")
    for c in CONTROLLERS:
        n = numpy_rate(c, args.numpy_worlds, args.numpy_ticks)
        j = jax_rate(c, args.worlds, args.ticks, args.repeat) if jax is not None else float("nan")
        out["rollouts"][c] = {"numpy": n, "jax": j}
        print(f"{c:<18}{fmt(n / 1e6):>10}{fmt(j / 1e6):>10}{fmt(j / n):>11}", flush=True)
    best = max(v["jax"] for v in out["rollouts"].values())
    cf = crazyflow_rate(args.crazyflow_python, args.worlds, args.ticks)
    out["crazyflow_drone_steps_s"] = cf
    print(f"\ncrazyflow Sim.step ({args.worlds} worlds x 1 drone, {args.ticks} steps): "
          + (f"{fmt(cf / 1e6)} M drone-steps/s; fastest quatform rollout / crazyflow = {fmt(best / cf)}"
             if isinstance(cf, float) else cf))
    print(f"target 10 M robot-steps/s: fastest here {fmt(best / 1e6)} M ({fmt(best / 1e7)} of it)")
    if jax is not None and args.mc_trials:
        mc = monte_carlo(args.mc_trials)
        out["monte_carlo"] = mc
        print(f"\nhelix Monte Carlo, quaternion controller: {mc['trials']} trials x {mc['ticks']} ticks: "
              f"{fmt(mc['total_s'])} s end to end (batch {fmt(mc['build_s'])} s, rollout + metrics "
              f"{fmt(mc['rollout_and_metrics_s'])} s; target 60 s); {mc['lost']} lost, {mc['failed']} failed, "
              f"median max robot error {mc['median_max_position_error_m'] * 1e3:.2f} mm")
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
