"""One master-plus-slave control step of seed 003's teleoperator (issue 6).

The step: forward kinematics and force-reflecting Jacobians of the Kraft master (6 joints)
and the 7-DOF slave, the slave's mass matrix and kinetic-energy-weighted inverse, the
Euler-parameter task error and its rate, both stiffness torques (14a)/(14b) with force
reflection and the null-space redundancy torque, and the preload function. The 1990
implementation ran at about 60 Hz on a 68020; the target here is 5 kHz (200 us).

Usage: ``python benchmarks/bench_teleop.py [--repeat 7]``.
"""

from __future__ import annotations

import argparse

import numpy as np
from _common import best_time, fmt, machine_description

from quatform.teleop import KRAFT_MASTER, PANDA, PANDA_SLAVE, task_jacobian
from quatform.teleop.control import (
    StiffnessGains,
    master_torque,
    preload,
    redundancy_torque,
    slave_torque,
    task_error,
)

GAINS = StiffnessGains()
PRELOAD = np.array([0.1, 0.1, 0.1, 0.05, 0.05, 0.0])


def control_step(q_m, qd_m, q_s, qd_s, F_s, q_rest):
    F_m, F_ss = KRAFT_MASTER.frames(q_m), PANDA.frames(q_s)  # each arm's frames, once
    p_m, r_m = KRAFT_MASTER.forward(q_m, F_m)
    p_s, r_s = PANDA.forward(q_s, F_ss)
    J_mf, J_sf = KRAFT_MASTER.jacobian(q_m, F_m), PANDA.jacobian(q_s, F_ss)
    e = task_error(p_m, r_m, p_s, r_s)
    e_dot = task_jacobian(J_sf, r_m, r_s) @ qd_s - task_jacobian(J_mf, r_m, r_s) @ qd_m
    tau_m = master_torque(J_mf, r_m, r_s, e, e_dot, GAINS, F_s, -0.5)
    J_bar = PANDA_SLAVE.generalized_inverse(q_s, J_sf, F_ss)
    tau_s = slave_torque(J_sf, r_m, r_s, e, e_dot, GAINS, redundancy_torque(J_sf, J_bar, q_s, qd_s, q_rest))
    return preload(tau_m, PRELOAD), tau_s


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--min-run", type=float, default=0.2)
    args = ap.parse_args(argv)
    for line in machine_description({"quatform": True}, width=10):
        print(line)
    rng = np.random.default_rng(0)
    q_m, qd_m = rng.uniform(-1, 1, 6), rng.uniform(-0.5, 0.5, 6)
    q_s, qd_s = rng.uniform(-1, 1, 7), rng.uniform(-0.5, 0.5, 7)
    F_s, q_rest = rng.normal(size=6), np.zeros(7)
    t = best_time(lambda: control_step(q_m, qd_m, q_s, qd_s, F_s, q_rest), args.repeat, args.min_run)
    rate = 1.0 / t
    print(f"\none master + slave control step: {fmt(t * 1e6)} us  ->  {fmt(rate / 1e3)} kHz "
          f"(1990: ~60 Hz; target >= 5 kHz: {'met' if rate >= 5e3 else 'NOT met'})")


if __name__ == "__main__":
    main()
