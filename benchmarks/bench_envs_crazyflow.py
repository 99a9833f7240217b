"""Throughput of the environments' functional JAX form beside crazyflow's batched ``Sim.step``.

One process, one table: for each batch size ``B`` (the number of simulated bodies),

* crazyflow 0.4.0 (``Sim(n_worlds=B, n_drones=1)``, its default control and dynamics,
  float32 as it ships): ``sim.step(n)`` after ``sim.reset()`` and a warm-up, best of
  ``--repeat`` timings of ``n`` steps, ``jax.block_until_ready(sim.data)``; one drone-step is
  one drone's physics step (500 Hz, the controllers at their own rates inside it);
* quatform's functional core (:func:`quatform.envs.functional`, float64) on each
  ``--scenarios`` entry with the scenario's own controller (its barrier included unless
  ``--barrier off``) in residual mode, a zero residual (the base controller's commands, every
  step still through the action's path), ``ceil(B / N)`` worlds of ``N`` robots (``--match
  worlds``: ``B`` worlds); one agent-step is one robot's control tick (the plant's substeps,
  the observation, the reward and the episode's end included), the worlds (rounded up to a
  multiple of the devices) on ``--devices`` JAX CPU devices (default 1, as crazyflow's ``Sim``
  runs; more: ``jax.shard_map``, each device stepping its own slice, which with the barrier's
  batched solves larger than 4 x 4 can stall: docs/performance.md, "Sharded scans"). Two
  forms, both timed:

  - ``scan``: ``jax.jit`` of ``lax.scan`` over ``n`` steps of
    ``jax.vmap(core.step, in_axes=(0, 0, 0, None))`` (one dispatch per ``n`` steps);
  - ``loop``: a Python loop of ``n`` calls of ``jax.jit(jax.vmap(core.step, ...))`` (one
    dispatch per step, what a training loop stepping a policy on the host pays).

Each prints steps/s and the ratio to crazyflow's drone-steps/s at the same ``B`` (above 1:
quatform steps more agents per second). Compilation is left out of every timing (each form
is called once before it is timed).

crazyflow needs ``jax != 0.10.2`` (the project's environment pins it), so it is not in the
``bench`` extra: it lives in its own virtual environment, e.g.::

    python -m venv /work/cfvenv && /work/cfvenv/bin/pip install crazyflow==0.4.0 "jax==0.10.1" -e .
    PYTHONPATH=src /work/cfvenv/bin/python benchmarks/bench_envs_crazyflow.py

Without crazyflow the script says so in one line and prints quatform's numbers alone.

Usage: ``python benchmarks/bench_envs_crazyflow.py [--sizes 64,1024,4096]
[--scenarios team-tetrahedron-helix,team-grid-100] [--steps 20] [--repeat 5]
[--forms scan,loop] [--barrier on|off] [--devices N] [--match agents|worlds]``.
"""

from __future__ import annotations

import argparse
import math
import os
import warnings

import numpy as np
from _common import best_of, machine_description, optional_import

from quatform.envs import compiler_options, functional, key


def crazyflow_rate(jax, Sim, B: int, steps: int, repeat: int) -> float:
    """crazyflow's drone-steps/s of ``Sim(n_worlds=B, n_drones=1).step(steps)``."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Sim(n_worlds=B, n_drones=1)
    sim.reset()
    sim.step(steps)  # compiles step for this n
    jax.block_until_ready(sim.data)

    def run():
        sim.step(steps)
        jax.block_until_ready(sim.data)

    return B * steps / best_of(run, repeat)


def quatform_rates(jax, scenario: str, B: int, steps: int, repeat: int, forms, barrier: bool, match: str,
                   devices=None) -> dict:
    """Agent-steps/s of the functional core's forms (module docstring), with the worlds' count,
    on ``devices`` (default all of JAX's)."""
    jnp = jax.numpy
    with jax.enable_x64(True):
        name, _, controller = scenario.partition(":")
        core = functional(name, controller or None, action="residual",
                          **({} if barrier else {"min_separation": 0.0}))
        N = core.layout.n
        worlds = B if match == "worlds" else max(1, math.ceil(B / N))
        devices = jax.devices() if devices is None else list(devices)
        worlds = -(-worlds // len(devices)) * len(devices)  # an equal slice per device
        params = jax.tree_util.tree_map(jnp.asarray, core.default_params)
        keys = np.stack([key(s * worlds + w) for s in range(steps) for w in range(worlds)]).reshape(steps, worlds, 2)
        options = compiler_options(jax)
        _, state0 = jax.jit(jax.vmap(core.reset, in_axes=(0, None)), compiler_options=options)(keys[0], params)

        def vstep(k, state):  # a zero residual on the worlds of k (all, or one device's)
            return jax.vmap(core.step, in_axes=(0, 0, 0, None))(k, state, jnp.zeros((k.shape[0], core.n_u)), params)

        def scanned(state, keys):
            def body(state, k):
                obs, state, reward, *_ = vstep(k, state)
                return state, (obs, reward)  # what a learner reads: the observation kept

            return jax.lax.scan(body, state, keys)

        scan_fn, step_fn = scanned, vstep
        if len(devices) > 1:  # each device steps its own slice of the worlds (no collective)
            from jax.sharding import Mesh, NamedSharding
            from jax.sharding import PartitionSpec as P

            mesh = Mesh(np.array(devices), ("worlds",))
            state0 = jax.device_put(state0, NamedSharding(mesh, P("worlds")))
            keys = jax.device_put(keys, NamedSharding(mesh, P(None, "worlds")))
            scan_fn = jax.shard_map(scanned, mesh=mesh, in_specs=(P("worlds"), P(None, "worlds")),
                                    out_specs=(P("worlds"), P(None, "worlds")), check_vma=False)
            step_fn = jax.shard_map(vstep, mesh=mesh, in_specs=(P("worlds"), P("worlds")), out_specs=P("worlds"),
                                    check_vma=False)
        out = {"N": N, "worlds": worlds}
        if "scan" in forms:
            scan = jax.jit(scan_fn, compiler_options=options)
            jax.block_until_ready(scan(state0, keys))
            out["scan"] = worlds * N * steps / best_of(lambda: jax.block_until_ready(scan(state0, keys)), repeat)
        if "loop" in forms:
            step = jax.jit(step_fn, compiler_options=options)
            jax.block_until_ready(step(keys[0], state0))

            def loop():
                state = state0
                for s in range(steps):
                    state = step(keys[s], state)[1]
                jax.block_until_ready(state)

            out["loop"] = worlds * N * steps / best_of(loop, repeat)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="64,1024,4096", help="bodies per batch B (default 64,1024,4096)")
    ap.add_argument("--scenarios", default="team-tetrahedron-helix,team-grid-100",
                    help="team or network scenarios, each NAME or NAME:CONTROLLER (the team kind's controller, "
                         "default quaternion; a network scenario's law) (default team-tetrahedron-helix,team-grid-100)")
    ap.add_argument("--steps", type=int, default=20, help="steps per timing (default 20)")
    ap.add_argument("--repeat", type=int, default=5, help="best of this many timings (default 5)")
    ap.add_argument("--forms", default="scan,loop", help="quatform's forms: scan, loop (default both)")
    ap.add_argument("--barrier", choices=("on", "off"), default="on",
                    help="the team scenarios' separation barrier in the controller (default on, as the scenario)")
    ap.add_argument("--devices", type=int, default=1,
                    help="JAX CPU devices quatform's worlds are sharded over (default 1, as crazyflow's Sim runs; "
                         "more can stall with the barrier's solves: docs/performance.md, 'Sharded scans')")
    ap.add_argument("--match", choices=("agents", "worlds"), default="agents",
                    help="quatform's batch: ceil(B/N) worlds of N robots (agents) or B worlds (default agents)")
    args = ap.parse_args()
    jax = optional_import("jax")
    if jax is None:
        raise SystemExit('bench_envs_crazyflow: needs JAX (pip install -e ".[jax]")')
    jax.config.update("jax_num_cpu_devices", max(1, args.devices))  # before JAX starts its backends
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            from crazyflow.sim import Sim
    except ImportError:
        Sim = None
        print("crazyflow is not installed: quatform's numbers alone (see this script's docstring for its venv)")
    sizes = [int(b) for b in args.sizes.split(",")]
    scenarios = args.scenarios.split(",")
    forms = [f for f in args.forms.split(",") if f in ("scan", "loop")]
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"envs vs crazyflow: {args.steps} steps per timing, best of {args.repeat}; quatform float64, zero "
          f"residual on the scenario's controller (barrier {args.barrier}), its worlds on {len(jax.devices())} CPU "
          f"device(s), crazyflow on one; load average at start {load:.2f}")
    for line in machine_description({"jax": True, "crazyflow": Sim is not None}):
        print(line)
    print(f"{'B':>6} {'crazyflow drone-steps/s':>24} {'scenario':<40}{'N':>4}{'worlds':>7}"
          + "".join(f"{f + ' agent-steps/s':>20}{'ratio':>7}" for f in forms))
    for B in sizes:
        cf = crazyflow_rate(jax, Sim, B, args.steps, args.repeat) if Sim is not None else float("nan")
        for i, scenario in enumerate(scenarios):
            q = quatform_rates(jax, scenario, B, args.steps, args.repeat, forms, args.barrier == "on", args.match)
            cells = "".join(f"{q[f]:>20.4g}{q[f] / cf:>7.3f}" for f in forms)
            head = f"{B:>6} {cf:>24.4g}" if i == 0 else f"{'':>6} {'':>24}"
            print(f"{head} {scenario:<40}{q['N']:>4}{q['worlds']:>7}{cells}", flush=True)
    if hasattr(os, "getloadavg"):
        print(f"load average at end {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
