"""Simulated seconds per wall-clock second: the two-quadrotor helix on MuJoCo physics
beside the kinematic models.

Each run is seed 000's helix (``mas-kitts-helix``, 80 s simulated, control every 10 ms)
with one controller, timed end to end (reference, closed loop, logging; no files, no
picture). The physics run steps MuJoCo every 2.5 ms with each quadrotor's cascaded
low-level controller and rotor drag in Python between steps. A third row times the bare
physics (two hovering quadrotors, no formation controller, no low-level controller: the
rotor forces held) to show where the time goes.

``--team`` adds the MuJoCo team plant: N = 2, 4, 10 IRIS quadrotors
(``sim.plants.mujoco_team.team_plant``), their cascades evaluated together on ``(N, ...)``
arrays (``vectorised``) and one per vehicle on Python floats (``per-vehicle``), flying a formation that translates, climbs and turns about the
vertical (a pair, a tetrahedron, ten robots on a sphere), each robot on a robot-space
velocity loop ``u = r_dot_ref + k (r_ref - r)`` (no team controller: this times the
plant). It prints simulated seconds per wall second and the share of the time spent in
``mj_step`` (CPU time around each call, shares of the run's CPU time) against Python
(the cascades, the loop, the log); the CPU time is this process's (the wall time of a
shared machine includes the other programs' turns).

Usage: ``python benchmarks/bench_physics.py [--duration 80] [--repeat 3] [--team]
[--team-duration 10]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np
from _common import best_of, fmt, machine_description, optional_import

from quatform.control.contract import Controller, Step
from quatform.robots import HolonomicRobot, Team
from quatform.scenarios import load_scenario
from quatform.scenarios.pair import run_pair, simulate_physics
from quatform.sim.mujoco_backend import INSTALL_HINT, VECTORISED_FROM
from quatform.sim.simulate import simulate


def team_shape(n: int) -> np.ndarray:
    """Robot positions in the formation frame, (n, 3), m: a pair 2 m apart, a regular
    tetrahedron of edge 2 m, else n points spread on a sphere of radius 2 m (Fibonacci)."""
    if n == 2:
        return np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])
    if n == 4:
        return np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=float) / np.sqrt(2.0)
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    phi = np.pi * (1.0 + 5 ** 0.5) * k
    rho = np.sqrt(1.0 - z * z)
    return 2.0 * np.c_[rho * np.cos(phi), rho * np.sin(phi), z]


def team_motion(shape: np.ndarray, t):
    """The formation's motion: the centroid at ``(0.3 t, 0.1 t, 3 + 0.3 sin(0.5 t))``, the shape
    turning about the vertical at 0.2 rad/s, each robot's yaw the formation's.

    Returns ``(r, r_dot)``, shapes ``(T, 4 n)``: every robot's ``(x, y, z, theta)`` and rates.
    """
    t = np.asarray(t, dtype=float)[:, None]
    w = 0.2
    c, s = np.cos(w * t), np.sin(w * t)
    sx, sy, sz = shape[:, 0], shape[:, 1], shape[:, 2]
    x, y, z = 0.3 * t + c * sx - s * sy, 0.1 * t + s * sx + c * sy, 3.0 + 0.3 * np.sin(0.5 * t) + sz
    xd, yd = 0.3 - w * (s * sx + c * sy), 0.1 + w * (c * sx - s * sy)
    zd = np.broadcast_to(0.15 * np.cos(0.5 * t), x.shape)
    th, thd = np.broadcast_to(w * t, x.shape), np.full(x.shape, w)
    r = np.stack([x, y, z, th], axis=-1).reshape(len(t), -1)
    return r, np.stack([xd, yd, zd, thd], axis=-1).reshape(len(t), -1)


class VelocityLoop(Controller):
    """Robot-space velocity loop ``u = r_dot_ref + k (r_ref - r)`` for every robot at once."""

    name = "robot-space velocity loop"

    def __init__(self, n_u: int, k: float = 1.0):
        self.n_u, self.k = n_u, k

    @property
    def command_names(self):
        return tuple(f"u{i}" for i in range(self.n_u))

    def signal_columns(self):
        return {}

    def update(self, t, measured, reference, state):
        r, rd = reference
        return Step(rd + self.k * (r - measured), state, {})


class _TimedMuJoCo:
    """The ``mujoco`` module with ``mj_step`` (and its halves ``mj_step1``, ``mj_step2``)
    timed: seconds summed in ``seconds``."""

    def __init__(self, mj):
        self._mj, self.seconds = mj, 0.0

    def __getattr__(self, name):
        return getattr(self._mj, name)

    def _timed(self, fn, m, d):
        t0 = time.process_time()  # CPU time: a shared machine's other programs do not count
        fn(m, d)
        self.seconds += time.process_time() - t0

    def mj_step(self, m, d):
        self._timed(self._mj.mj_step, m, d)

    def mj_step1(self, m, d):
        self._timed(self._mj.mj_step1, m, d)

    def mj_step2(self, m, d):
        self._timed(self._mj.mj_step2, m, d)


def team_row(n: int, duration: float, cascades: str = "auto", dt: float = 0.01):
    """One team run: ``(wall s, CPU s of this process, mj_step CPU s, max robot position error
    after 5 s, m)``. The CPU time is what the run costs where the machine is shared (the wall time
    then includes other programs' turns)."""
    from quatform.sim.plants.mujoco_team import team_plant

    shape = team_shape(n)
    times = np.arange(round(duration / dt) + 1) * dt
    r_ref, rd_ref = team_motion(shape, times)
    plant = team_plant(Team((HolonomicRobot(),) * n), r_ref[0], dt=dt, cascades=cascades)
    timed = plant.world.mj = _TimedMuJoCo(plant.world.mj)
    t0, c0 = time.perf_counter(), time.process_time()
    log = simulate(plant, VelocityLoop(4 * n), lambda k: (r_ref[k], rd_ref[k]), times, plant.x0, dt=dt)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    err = (log["state"] - r_ref).reshape(len(times), n, 4)[times >= 5.0, :, 0:3]
    return wall, cpu, timed.seconds, float(np.linalg.norm(err, axis=-1).max())



def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--duration", type=float, default=80.0, help="simulated seconds (default: the full helix)")
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--controller", default="quaternion")
    p.add_argument("--team", action="store_true", help="also time the MuJoCo team plant, N = 2, 4, 10")
    p.add_argument("--team-duration", type=float, default=10.0, help="simulated seconds of each team run")
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
    print("| physics | wall s | simulated s per wall s |")
    print("|---|---|---|")
    for name, wall in rows:
        print(f"| {name} | {fmt(wall)} | {fmt(args.duration / wall)} |")
    if mj is None:
        print(f"\n(mujoco not installed: {INSTALL_HINT} in the quatform checkout)")
    elif args.team:
        print(f"\nMuJoCo team plant: N IRIS quadrotors, cascades on (N, ...) arrays or per vehicle, a robot-space velocity "
              f"loop on a translating, climbing, turning formation; {args.team_duration:g} s simulated, "
              f"control every 10 ms, physics every 2.5 ms, best of {args.repeat}\n")
        print("| N | cascades | wall s | simulated s per wall s | simulated s per CPU s | mj_step share (CPU) | "
              "Python share (CPU) | max position error after 5 s (m) |")
        print("|---|---|---|---|---|---|---|---|")
        for n in (2, 4, 10):
            for mode in ("vectorised", "per-vehicle"):
                wall, cpu, step, err = min((team_row(n, args.team_duration, mode) for _ in range(args.repeat)),
                                           key=lambda r: r[1])
                print(f"| {n} | {mode} | {fmt(wall)} | {fmt(args.team_duration / wall)} | "
                      f"{fmt(args.team_duration / cpu)} | {100 * step / cpu:.0f} % | {100 * (1 - step / cpu):.0f} % "
                      f"| {err:.3f} |")
        print(f"\n(team_plant's default, cascades = 'auto', runs the arrays from VECTORISED_FROM = {VECTORISED_FROM} "
              "quadrotors on)")
    return np.array([w for _, w in rows])


if __name__ == "__main__":
    main()
