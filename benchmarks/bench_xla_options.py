"""quatform's XLA options on the CPU against XLA's defaults: compiled team rollouts and the environments' step.

:func:`quatform.sim.jax_devices.compiler_options` turns XLA's YNNPACK fusions off where the
CPU backend's XLA has them (jaxlib 0.10.2 uses them by default; docs/performance.md, "XLA's
YNNPACK fusions"). This script times the same work twice, each in its own process (XLA's
options are read when a program compiles, and a process compiles each program once):

* ``options``: quatform's defaults (the options passed where XLA knows them);
* ``xla``: ``QUATFORM_XLA_OPTIONS=off``, XLA's own defaults.

The work, each best of ``--repeat`` after a warm-up (compilation left out):

* ``rollout``: :func:`quatform.sim.jax_rollout.rollout_metrics` of each ``--scenarios`` entry
  (``NAME:CONTROLLER``, the team kind) with ``formation_metrics=False``, ``--worlds`` worlds
  from starts 1 cm apart, the scenario cut to ``--ticks`` control ticks: robot-steps/s;
* ``envs``: ``jax.jit(lax.scan(jax.vmap(core.step)))`` of the functional core
  (:func:`quatform.envs.functional`, the scenario's controller, residual mode, a zero residual,
  barrier on), ``ceil(--bodies / N)`` worlds, 20 steps a call, the observation and the reward
  kept: agent-steps/s.

It prints both rates and ``options / xla`` (above 1: quatform's options are faster).

Usage: ``python benchmarks/bench_xla_options.py [--scenarios team-tetrahedron-helix:quaternion,...]
[--worlds 512] [--ticks 1000] [--bodies 1024] [--repeat 3]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
from _common import best_of, machine_description, optional_import

HERE = Path(__file__).resolve().parent


def rollout_rate(jax, scenario: str, worlds: int, ticks: int, repeat: int) -> float:
    """Robot-steps/s of ``rollout_metrics`` (module docstring)."""
    from quatform.scenarios import kind_of, load_scenario
    from quatform.sim.jax_rollout import rollout_metrics

    name, _, controller = scenario.partition(":")
    sc = load_scenario(name)
    sc = dataclasses.replace(sc, duration_s=(ticks - 1) * sc.dt_s, metrics_from_s=0.0)
    ex = kind_of(sc).experiment(sc, controller=controller or "quaternion")
    x0 = np.asarray(ex.x0) + 0.01 * np.random.default_rng(0).normal(size=(worlds,) + np.shape(ex.x0))
    rollout_metrics(ex, x0, None, formation_metrics=False)  # compiles
    t = best_of(lambda: rollout_metrics(ex, x0, None, formation_metrics=False), repeat)
    return worlds * ex.times.size * ex.plant.team.layout.n / t


def envs_rate(jax, scenario: str, bodies: int, repeat: int) -> float:
    """Agent-steps/s of the functional core's scan on one device (module docstring):
    :func:`bench_envs_crazyflow.quatform_rates`' scan form."""
    from bench_envs_crazyflow import quatform_rates

    return quatform_rates(jax, scenario, bodies, 20, repeat, ["scan"], True, "agents", jax.devices()[:1])["scan"]


def child(args) -> None:
    """One side's rates, as JSON on stdout's last line."""
    from quatform.sim.loop import require_jax

    jax = require_jax()
    from quatform.sim import jax_devices

    out = {"options": jax_devices.compiler_options(jax), "rollout": {}, "envs": {}}
    for scenario in args.scenarios.split(","):
        out["rollout"][scenario] = rollout_rate(jax, scenario, args.worlds, args.ticks, args.repeat)
        out["envs"][scenario] = envs_rate(jax, scenario, args.bodies, args.repeat)
    print(json.dumps(out))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenarios", default="team-tetrahedron-helix:quaternion,team-tetrahedron-helix:robot-space",
                    help="team scenarios, each NAME:CONTROLLER (default the tetrahedron with the quaternion and "
                         "robot-space controllers)")
    ap.add_argument("--worlds", type=int, default=512, help="worlds of a rollout (default 512)")
    ap.add_argument("--ticks", type=int, default=1000, help="control ticks of a rollout (default 1000)")
    ap.add_argument("--bodies", type=int, default=1024, help="robots of the environments' batch (default 1024)")
    ap.add_argument("--repeat", type=int, default=3, help="best of this many timings (default 3)")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        return child(args)
    if optional_import("jax") is None:
        raise SystemExit('bench_xla_options: needs JAX (pip install -e ".[jax]")')
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"quatform's XLA options against XLA's defaults, each side in its own process; best of {args.repeat}; "
          f"load average at start {load:.2f}")
    for line in machine_description({"jax": True}):
        print(line)
    sides = {}
    for side, env in (("options", {}), ("xla", {"QUATFORM_XLA_OPTIONS": "off"})):
        cmd = [sys.executable, str(Path(__file__).resolve()), "--child", *sys.argv[1:]]
        done = subprocess.run(cmd, env={**os.environ, **env}, capture_output=True, text=True, check=False)
        if done.returncode != 0:
            raise SystemExit(f"bench_xla_options: the {side} side failed: {done.stderr.strip().splitlines()[-1:]}")
        sides[side] = json.loads(done.stdout.strip().splitlines()[-1])
    print(f"options passed: {sides['options']['options'] or 'none (this XLA does not know them)'}")
    print(f"{'work':<8}{'scenario:controller':<42}{'options':>12}{'xla':>12}{'options/xla':>13}")
    for work, unit in (("rollout", "robot-steps/s"), ("envs", "agent-steps/s")):
        for scenario, rate in sides["options"][work].items():
            other = sides["xla"][work][scenario]
            print(f"{work:<8}{scenario:<42}{rate:>12.4g}{other:>12.4g}{rate / other:>13.2f}")
    print(f"(rates: rollout {args.worlds} worlds x {args.ticks} ticks, robot-steps/s; envs {args.bodies} robots, "
          "agent-steps/s)")
    if hasattr(os, "getloadavg"):
        print(f"load average at end {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
