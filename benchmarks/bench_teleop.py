"""One master-plus-slave control step of seed 003's teleoperator.

The step is ``TeleopController.step``: forward kinematics and force-reflecting Jacobians
of the Kraft master (6 joints) and the 7-DOF slave, the slave's mass matrix and the
kinetic-energy-weighted null-space projection, the Euler-parameter task error and its
rate, both stiffness torques (14a)/(14b) with force reflection and the redundancy torque,
the preload function and saturation, with the measurement validated. The 1990
implementation ran at about 60 Hz on a 68020; the target here is 5 kHz (200 us).

Beside it, the same cycle through the controller contract (``update``: the stacked
measurement in, the torques and the named signals a log keeps out), one closed-loop cycle of
``teleop-free-motion`` through :func:`quatform.sim.simulate` (controller, plant, log; 0.5 s
simulated), and the slave's kinematics and mass matrix alone, quatform's against the peer that
could have supplied them: roboticstoolbox-python's Panda (DH model; ``fkine``, ``jacob0``,
``inertia``, its C back end), when installed (``pip install roboticstoolbox-python``).

Usage: ``python benchmarks/bench_teleop.py [--repeat 7]``.
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np
from _common import best_time, fmt, machine_description, optional_import

from quatform.scenarios.teleop import TELEOP
from quatform.scenarios import load_scenario
from quatform.teleop import (
    KRAFT_MASTER,
    PANDA,
    PANDA_SLAVE,
    Registration,
    TeleopController,
    TeleopMeasurement,
)

Q_M0 = np.array([0.0, 0.3, -0.4, 0.2, 0.3, 0.0])
Q_S0 = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--min-run", type=float, default=0.2)
    args = ap.parse_args(argv)
    rtb = optional_import("roboticstoolbox")
    for line in machine_description({"quatform": True, "roboticstoolbox-python": rtb is not None}, width=22):
        print(line)
    rng = np.random.default_rng(0)
    meas = TeleopMeasurement(Q_M0 + rng.uniform(-0.3, 0.3, 6), rng.uniform(-0.5, 0.5, 6),
                             Q_S0 + rng.uniform(-0.3, 0.3, 7), rng.uniform(-0.5, 0.5, 7), rng.normal(size=6))
    reg = Registration.from_homes(KRAFT_MASTER, PANDA, Q_M0, Q_S0)
    print()
    for label, ctrl in (
        ("Euler parameters, preload", TeleopController(reg, Q_S0, preload_nm=TeleopController.default_preload())),
        ("roll-pitch-yaw baseline", TeleopController(reg, Q_S0, orientation_error="rpy")),
    ):
        t = best_time(lambda c=ctrl: c.step(0.0, meas), args.repeat, args.min_run)
        rate = 1.0 / t
        print(f"one master + slave control step, {label:26s}: {fmt(t * 1e6)} us  ->  {fmt(rate / 1e3)} kHz "
              f"(1990: ~60 Hz; target >= 5 kHz: {'met' if rate >= 5e3 else 'NOT met'})")
    ctrl = TeleopController(reg, Q_S0, preload_nm=TeleopController.default_preload())
    vec = np.concatenate([meas.q_m, meas.qd_m, meas.q_s, meas.qd_s, meas.F_s])
    t = best_time(lambda: ctrl.update(0.0, vec, None, None), args.repeat, args.min_run)
    print(f"the same through the contract, update(t, stacked, None, None) -> Step: {fmt(t * 1e6)} us")
    exp = TELEOP.experiment(dataclasses.replace(load_scenario("teleop-free-motion"), duration_s=0.5))
    n = len(exp.times)
    t = best_time(exp.run, max(1, args.repeat // 3), args.min_run)
    print(f"closed loop through simulate (teleop-free-motion, {n} cycles + finish): {fmt(t / n * 1e6)} us per cycle")
    print("\nslave (7 DOF) alone, one configuration:      quatform    roboticstoolbox")
    arm, q = PANDA_SLAVE, meas.q_s
    rows = [("frames + tool pose", lambda: arm.arm.forward(q, arm.arm.frames(q)), "fkine"),
            ("geometric Jacobian", lambda: arm.arm.jacobian(q), "jacob0"),
            ("mass matrix", lambda: arm.mass_matrix(q), "inertia")]
    robot = rtb.models.DH.Panda() if rtb is not None else None
    for label, fn, peer in rows:
        ours = best_time(fn, args.repeat, args.min_run)
        theirs = "-" if robot is None else fmt(best_time(lambda p=peer: getattr(robot, p)(q), args.repeat,
                                                         args.min_run) * 1e6) + " us"
        print(f"  {label:40s} {fmt(ours * 1e6):>7s} us  {theirs:>12s}")


if __name__ == "__main__":
    main()
