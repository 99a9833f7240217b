"""Time of one quaternion-team control step for N = 10, 100, 1000 robots.

One ``TeamController(QuaternionTeam(N), Table 1 gains, Team of N holonomic 4-DOF robots)``
step, ``ctrl.step(t, r, Reference(c, c_dot))`` on one formation: the input checks, the
forward map with the reference as hint (centroid, Horn's attitude fit, shape, robot
quaternions), the laws of the four law groups (centroid, attitude, shape, orientation:
seed 000 §3.2 and eq. (20)), the inverse map's directional derivative
(``QuaternionTeam.robot_rate``) and the team's saturation. Columns:

* **step**: the whole step, microseconds, and per robot (ns);
* **maps**: ``forward(r, near_c=c)`` plus ``robot_rate(c_meas, c_dot)``, this description's
  part, microseconds and per robot;
* **saturate**: ``team.saturate(u)`` alone (the team's per-robot Python loop, being
  vectorised in the robots layer on another branch), so ``step - saturate`` is what the
  formation and the laws cost;
* the ratio of the per-robot cost at the largest N to that at the smallest (target <= 1.5), and the marginal cost per added robot (the slope between two N).

The reference: N robots on a ring of radius ``0.5 N / pi`` m (about 1 m apart) at 1 m
altitude, the formation pitched 0.4 rad and yawed 0.3 rad, every robot yawed 0.2 rad,
with rates 0.1 in every chart variable (``QuaternionTeam.from_chart``); the measured robots
are the reference's displaced by ``0.01 N(0, 1)`` (``numpy.random.default_rng(0)``). Times
are the best of several repeats of a timed loop (:mod:`timeit` style) in CPU time of this
process (``time.process_time``, as ``bench_control.py --before``: less disturbed by the other
processes of a shared machine; ``--wall`` for ``time.perf_counter``).

Run it from the repository root::

    PYTHONPATH=src python benchmarks/bench_team.py              # N = 10, 100, 1000 (~15 s)
    PYTHONPATH=src python benchmarks/bench_team.py --n 10 1000 --repeat 3
"""

from __future__ import annotations

import argparse
import time
import timeit

import numpy as np
from quatform.control import TABLE1, Reference
from quatform.control.team import TeamController
from quatform.formations.quaternion_team import QuaternionTeam
from quatform.robots import HolonomicRobot, Team

from _common import fmt, machine_description

#: The targets: at most 1 ms a step at N = 1000, a per-robot cost ratio of at most 1.5.
TARGET_STEP_US_AT_1000 = 1000.0
TARGET_PER_ROBOT_RATIO = 1.5


def make_inputs(N: int, seed: int = 0):
    """``(controller, r, reference, c_meas, c_dot)`` of the ring of ``N`` robots (module docstring)."""
    F = QuaternionTeam(N)
    team = Team((HolonomicRobot(),) * N)
    ctrl = TeamController(F, TABLE1["quaternion"], team, name="quaternion")
    ch = F.chart
    e = np.zeros(ch.size)
    yaw, pitch = 0.3, 0.4
    e[0:3] = (0.1, 0.2, 1.0)
    e[3:7] = np.array([np.cos(yaw / 2) * np.cos(pitch / 2), -np.sin(yaw / 2) * np.sin(pitch / 2),
                       np.cos(yaw / 2) * np.sin(pitch / 2), np.sin(yaw / 2) * np.cos(pitch / 2)])
    a = 2.0 * np.pi * np.arange(N) / N
    e[ch.shape_index] = (0.5 * N / np.pi) * np.stack([np.cos(a), np.sin(a), np.zeros(N)], -1)
    e[ch.yaw_index] = 0.2
    c, c_dot = F.from_chart(e, 0.1 * np.ones(ch.size))
    rng = np.random.default_rng(seed)
    r = F.inverse(c) + 0.01 * rng.normal(size=F.n_r)
    return ctrl, r, Reference(c, c_dot), F.forward(r, near_c=c), c_dot


def best_time(fn, repeat: int, min_run: float, timer=time.process_time) -> float:
    """Best-of-``repeat`` seconds per call of ``fn`` (``_common.best_time`` with a choice of timer)."""
    t = timeit.Timer(fn, timer=timer)
    number = 1
    while t.timeit(number) < min_run:
        number *= 2
    return min(t.repeat(repeat=repeat, number=number)) / number


def time_team(N: int, repeat: int, min_run: float, timer=time.process_time) -> dict:
    """Seconds per call of the step, the maps and the saturation for ``N`` robots."""
    ctrl, r, ref, c_meas, c_dot = make_inputs(N)
    F = ctrl.formation
    u = ctrl.step(0.0, r, ref)
    assert np.all(np.isfinite(u))
    return {
        "step": best_time(lambda: ctrl.step(0.0, r, ref), repeat, min_run, timer),
        "maps": best_time(lambda: (F.forward(r, near_c=ref.c), F.robot_rate(c_meas, c_dot, r=r)), repeat, min_run,
                          timer),
        "saturate": best_time(lambda: ctrl.team.saturate(u), repeat, min_run, timer),
    }


def main(argv: list[str] | None = None) -> None:
    """Parse the options, time each N and print the table and the verdicts."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=int, nargs="+", default=[10, 100, 1000], help="team sizes (default 10 100 1000)")
    parser.add_argument("--repeat", type=int, default=5, help="repeats, the best is kept (default 5)")
    parser.add_argument("--min-run", type=float, default=0.2, help="least seconds per repeat (default 0.2)")
    parser.add_argument("--wall", action="store_true", help="wall time (time.perf_counter) instead of CPU time")
    args = parser.parse_args(argv)
    timer = time.perf_counter if args.wall else time.process_time
    if args.repeat < 1 or args.min_run <= 0 or min(args.n) < 2:
        parser.error("--repeat must be >= 1, --min-run > 0 and every --n >= 2")
    sizes = sorted(set(args.n))

    for line in machine_description({"quatform": True}, width=10):
        print(line)
    print(f"timing    : best of {args.repeat} repeats of >= {args.min_run} s each "
          f"({'time.perf_counter' if args.wall else 'time.process_time'})\n")
    cols = (("N", 6), ("step (us)", 12), ("ns/robot", 11), ("maps (us)", 12), ("ns/robot", 11),
            ("saturate (us)", 15), ("step - sat (us)", 17), ("ns/robot", 11))
    print("".join(f"{h:>{w}}" for h, w in cols))
    print("-" * sum(w for _, w in cols))
    res = {}
    for N in sizes:
        t = res[N] = time_team(N, args.repeat, args.min_run, timer)
        own = t["step"] - t["saturate"]
        row = (N, fmt(1e6 * t["step"]), fmt(1e9 * t["step"] / N), fmt(1e6 * t["maps"]), fmt(1e9 * t["maps"] / N),
               fmt(1e6 * t["saturate"]), fmt(1e6 * own), fmt(1e9 * own / N))
        print("".join(f"{v:>{w}}" for v, (_, w) in zip(row, cols)), flush=True)

    lo, hi = sizes[0], sizes[-1]
    print()
    for key, what in (("step", "whole step"), ("maps", "forward + robot_rate")):
        ratio = (res[hi][key] / hi) / (res[lo][key] / lo)
        slope = (res[hi][key] - res[lo][key]) / (hi - lo)
        print(f"{what:22s}: per-robot cost at N = {hi} / at N = {lo} = {ratio:.3f} (target <= "
              f"{TARGET_PER_ROBOT_RATIO}); marginal {1e9 * slope:.0f} ns per added robot, fixed "
              f"{1e6 * (res[lo][key] - slope * lo):.0f} us")
    own = {N: res[N]["step"] - res[N]["saturate"] for N in sizes}
    slope = (own[hi] - own[lo]) / (hi - lo)
    print(f"{'step - saturate':22s}: marginal {1e9 * slope:.0f} ns per added robot, fixed "
          f"{1e6 * (own[lo] - slope * lo):.0f} us")
    if 1000 in res:
        t = res[1000]["step"]
        print(f"\ntarget: one step at N = 1000 <= {TARGET_STEP_US_AT_1000:.0f} us: {fmt(1e6 * t)} us "
              f"({'met' if 1e6 * t <= TARGET_STEP_US_AT_1000 else 'NOT met'}); without the team's saturation "
              f"{fmt(1e6 * own[1000])} us ({'met' if 1e6 * own[1000] <= TARGET_STEP_US_AT_1000 else 'NOT met'})")


if __name__ == "__main__":
    main()
