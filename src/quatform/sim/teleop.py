"""Closed-loop teleoperation of seed 003: master, slave, a human hand and an environment.

Sim layer (above :mod:`quatform.teleop`). The master (the Kraft arm, counterbalanced, light
joint inertias and viscous friction; joint 6 unactuated) is pulled by a hand modelled as a
spring-damper toward a commanded tool path; its actuators pass the controller's torques
through a deadband (optionally pre-compensated by the preload function). The slave (the
7-DOF arm, its mass matrix, gravity compensated, joint damping) is driven by eq. (14b) and
touches an optional wall of given stiffness. The master's pose is registered in the slave's
workspace by the fixed transform that makes the two home poses coincide. Semi-implicit
Euler at ``dt_s``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..algebra import matrix_from_q, q_angle_between, q_from_axis_angle, qconj, qmul
from ..teleop import KRAFT_MASTER, PANDA, PANDA_SLAVE, task_jacobian
from ..teleop.control import (
    StiffnessGains,
    master_torque,
    redundancy_torque,
    slave_torque,
    task_error,
)

__all__ = ["TeleopSetup", "TeleopRun", "simulate_teleop"]


@dataclass(frozen=True)
class TeleopSetup:
    """Parameters of a teleoperation run (SI units)."""

    duration_s: float = 4.0
    dt_s: float = 0.001
    q_m0: tuple = (0.0, 0.3, -0.4, 0.2, 0.3, 0.0)
    q_s0: tuple = (0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8)
    master_inertia: tuple = (0.02, 0.02, 0.015, 0.004, 0.004, 0.002)
    master_friction: float = 0.05
    slave_damping: float = 2.0
    hand_stiffness: float = 400.0
    hand_damping: float = 20.0
    hand_rot_stiffness: float = 4.0
    hand_rot_damping: float = 0.2
    move: tuple = (0.05, 0.03, -0.04)  # hand displacement of the master tool, m
    turn_axis: tuple = (0.0, 0.0, 1.0)
    turn_rad: float = 0.3
    move_time_s: float = 1.5
    gains: StiffnessGains = StiffnessGains()


@dataclass(frozen=True)
class TeleopRun:
    """Logged signals: ``t``, master and slave joint states, tool poses (slave frame) and the
    true angle between the registered master frame and the slave frame."""

    setup: TeleopSetup
    t: np.ndarray
    q_m: np.ndarray
    q_s: np.ndarray
    p_m: np.ndarray
    p_s: np.ndarray
    angle: np.ndarray
    tau_finite: np.ndarray


def _smooth(s):
    s = np.clip(s, 0.0, 1.0)
    return s * s * (3 - 2 * s)


def simulate_teleop(setup: TeleopSetup = TeleopSetup()) -> TeleopRun:
    """Free motion: the hand moves and turns the master; the slave follows through (14a)/(14b)."""
    st = setup
    q_m, qd_m = np.array(st.q_m0, float), np.zeros(6)
    q_s, qd_s = np.array(st.q_s0, float), np.zeros(7)
    p_m0, r_m0 = KRAFT_MASTER.forward(q_m)
    p_s0, r_s0 = PANDA.forward(q_s)
    r_off = qmul(r_s0, qconj(r_m0))  # master frame -> slave workspace
    R_off = matrix_from_q(r_off)
    Im = np.array(st.master_inertia)
    axis = np.array(st.turn_axis, float)
    n = int(round(st.duration_s / st.dt_s)) + 1
    logs = {k: [] for k in ("t", "q_m", "q_s", "p_m", "p_s", "angle", "ok")}
    for k in range(n):
        t = k * st.dt_s
        F_m, F_s = KRAFT_MASTER.frames(q_m), PANDA.frames(q_s)
        p_m, r_m = KRAFT_MASTER.forward(q_m, F_m)
        p_s, r_s = PANDA.forward(q_s, F_s)
        J_mf = KRAFT_MASTER.jacobian(q_m, F_m)
        J_sf = PANDA.jacobian(q_s, F_s)
        # the master registered in the slave's workspace
        pm_r, rm_r = R_off @ (p_m - p_m0) + p_s0, qmul(r_off, r_m)
        Jm_r = J_mf.copy()
        Jm_r[0:3], Jm_r[3:6] = R_off @ J_mf[0:3], R_off @ J_mf[3:6]
        e = task_error(pm_r, rm_r, p_s, r_s)
        e_dot = task_jacobian(J_sf, rm_r, r_s) @ qd_s - task_jacobian(Jm_r, rm_r, r_s) @ qd_m
        tau_m = master_torque(Jm_r, rm_r, r_s, e, e_dot, st.gains)
        J_bar = PANDA_SLAVE.generalized_inverse(q_s, J_sf, F_s)
        tau_s = slave_torque(J_sf, rm_r, r_s, e, e_dot, st.gains,
                             redundancy_torque(J_sf, J_bar, q_s, qd_s, np.array(st.q_s0)))
        ok = bool(np.all(np.isfinite(tau_m)) and np.all(np.isfinite(tau_s)))
        tau_m = np.where(np.isfinite(tau_m), tau_m, 0.0) * np.array([1, 1, 1, 1, 1, 0.0])  # joint 6 passive
        tau_s = np.where(np.isfinite(tau_s), tau_s, 0.0)
        # the hand: a spring-damper toward the commanded master tool pose
        s = _smooth(t / st.move_time_s)
        p_h = p_m0 + s * np.array(st.move)
        r_h = qmul(q_from_axis_angle(axis, s * st.turn_rad), r_m0)
        v_m = J_mf @ qd_m
        d = qmul(r_h, qconj(r_m))
        d = d if d[0] >= 0 else -d
        wrench = np.r_[st.hand_stiffness * (p_h - p_m) - st.hand_damping * v_m[0:3],
                       st.hand_rot_stiffness * 2.0 * d[1:] - st.hand_rot_damping * v_m[3:6]]
        tau_hand = J_mf.T @ wrench
        # velocity terms implicitly (linearly implicit Euler): the wrist joints' inertias are
        # small, and explicit damping would need dt below 0.7 ms
        Jm_t = task_jacobian(Jm_r, rm_r, r_s)
        Js_t = task_jacobian(J_sf, rm_r, r_s)
        hand_d = np.r_[np.full(3, st.hand_damping), np.full(3, st.hand_rot_damping)]
        D_m = Jm_t.T @ (st.gains.kv[:, None] * Jm_t) + J_mf.T @ (hand_d[:, None] * J_mf) \
            + st.master_friction * np.eye(6)
        qdd_m = np.linalg.solve(np.diag(Im) + st.dt_s * D_m, tau_m + tau_hand - st.master_friction * qd_m)
        M_s = PANDA_SLAVE.mass_matrix(q_s, F_s)
        D_s = Js_t.T @ (st.gains.kv[:, None] * Js_t) + (st.slave_damping + 1.0) * np.eye(7)
        qdd_s = np.linalg.solve(M_s + st.dt_s * D_s, tau_s - st.slave_damping * qd_s)
        for key, val in (("t", t), ("q_m", q_m.copy()), ("q_s", q_s.copy()), ("p_m", pm_r), ("p_s", p_s),
                         ("angle", q_angle_between(rm_r, r_s)), ("ok", ok)):
            logs[key].append(val)
        qd_m = qd_m + st.dt_s * qdd_m
        qd_s = qd_s + st.dt_s * qdd_s
        q_m = q_m + st.dt_s * qd_m
        q_s = q_s + st.dt_s * qd_s
    a = {k: np.array(v) for k, v in logs.items()}
    return TeleopRun(st, a["t"], a["q_m"], a["q_s"], a["p_m"], a["p_s"], a["angle"], a["ok"])
