"""Simulated seconds per wall-clock second: the two-quadrotor helix on MuJoCo physics
beside the kinematic backend (issue 7).

Each run is seed 000's helix (``mas-kitts-helix``, 80 s simulated, control every 10 ms)
with one controller, timed end to end (reference, closed loop, logging; no files, no
picture). The physics run steps MuJoCo every 2.5 ms with each quadrotor's cascaded
low-level controller and rotor drag in Python between steps. A third row times the bare
physics (two hovering quadrotors, no formation controller, no low-level controller: the
rotor forces held) to show where the time goes.

Usage: ``python benchmarks/bench_physics.py [--duration 80] [--repeat 3]``.
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np
from _common import best_of, fmt, machine_description, optional_import

from quatform.scenarios.pair import run_pair, simulate_physics
from quatform.scenarios import load_scenario
from quatform.sim.mujoco_backend import INSTALL_HINT



def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--duration", type=float, default=80.0, help="simulated seconds (default: the full helix)")
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--controller", default="quaternion")
    args = p.parse_args(argv)
    mj = optional_import("mujoco")
    for line in machine_description({"mujoco": mj is not None}):
        print(line)
    sc = dataclasses.replace(load_scenario("mas-kitts-helix"), duration_s=args.duration)
    rows = [("kinematic", best_of(lambda: run_pair(sc, args.controller), args.repeat))]
    if mj is not None:
        from quatform.sim.mujoco_backend import PhysicsWorld

        rows.append(("mujoco (cascade + rotor drag in the loop)",
                     best_of(lambda: simulate_physics(sc, args.controller), args.repeat)))

        def bare():
            w = PhysicsWorld(quads=[("a", (0, 0, 2), 0.0), ("b", (1, 0, 2), 0.0)])
            w.data.ctrl[:] = 1.5 * 9.81 / 4
            for _ in range(round(args.duration / w.model.opt.timestep)):
                mj.mj_step(w.model, w.data)

        rows.append(("mujoco bare mj_step (2 quads, forces held)", best_of(bare, args.repeat)))
    print(f"\nscenario: mas-kitts-helix, {args.duration:g} s simulated, controller {args.controller}, "
          f"best of {args.repeat}\n")
    print("| backend | wall s | simulated s per wall s |")
    print("|---|---|---|")
    for name, wall in rows:
        print(f"| {name} | {fmt(wall)} | {fmt(args.duration / wall)} |")
    if mj is None:
        print(f"\n(mujoco not installed: {INSTALL_HINT} in the quatform checkout)")
    return np.array([w for _, w in rows])


if __name__ == "__main__":
    main()
