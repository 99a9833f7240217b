"""Closed-loop teleoperation of seed 003: master, slave, a human hand and an environment.

Sim layer (above :mod:`quatform.teleop`). One control cycle every ``dt_s`` (zero-order hold):

* the **master** (the Kraft arm; joint inertias, viscous friction, and the static and
  Coulomb friction that makes each actuated joint need ~15 % of full scale to move, the
  "dead region" of seed 003 §6; joint 6 unactuated) is driven by the controller's torques
  and by a **hand**, a spring-damper pulling the handle toward a commanded pose path;
* the **slave** (the 7-DOF arm with its mass matrix, Coriolis and centrifugal torques and
  joint damping) is driven by the
  controller's torques and by its environment: a **wall** of given stiffness and damping,
  and optionally a **push**, an external spring moving its tool (what moves the slave
  when the master follows it);
* the master's joints are modelled as decoupled constant inertias (a light, counterbalanced
  desk arm), so it has no Coriolis terms;
* both arms are gravity compensated (``tau_grav`` of seed 003 (11)-(12)), so gravity is
  left out of both plants.

Integration: semi-implicit Euler per cycle, friction stick/slip resolved per joint (the
master's inertia is diagonal). Scenarios are TOML files with ``kind = "teleop"``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..algebra import q_from_axis_angle, qmul, qslerp
from ..algebra._kernels import qmul_components
from ..errors import InvalidInputError
from ..teleop import (
    KRAFT_DEADBAND,
    KRAFT_FULL_SCALE,
    KRAFT_MASTER,
    ORIENTATION_ERRORS,
    PANDA_SLAVE,
    Registration,
    TeleopController,
    TeleopMeasurement,
    VirtualWall,
)
from ..teleop.control import StiffnessGains

__all__ = ["HandKey", "Hand", "SlavePush", "ContactWall", "TeleopScenario", "TeleopRun", "simulate_teleop",
           "teleop_metrics", "teleop_timeseries", "teleop_scenario_from_dict"]


def _smooth(s):
    s = min(max(s, 0.0), 1.0)
    return s * s * (3.0 - 2.0 * s)


def _vec(x, n, what):
    a = np.asarray(x, dtype=float)
    if a.shape != (n,) or not np.all(np.isfinite(a)):
        raise InvalidInputError(f"{what} must be {n} finite numbers, got {x!r}")
    return a


@dataclass(frozen=True)
class HandKey:
    """Where the hand holds the master's handle at ``t_s``: master joints ``q`` (whose tool
    pose it is), or ``move`` (m) and ``turn`` (rotation vector, rad) from the home pose,
    both in the master's base axes. Between two joint keys the path is interpolated in
    joint space; otherwise pose by pose (position linearly, orientation by slerp), with a
    smooth start and stop."""

    t_s: float
    q: tuple | None = None
    move: tuple = (0.0, 0.0, 0.0)
    turn: tuple = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Hand:
    """The operator's hand: a spring-damper on the handle (N/m, N s/m, N m/rad, N m s/rad)."""

    keys: tuple = (HandKey(0.0),)
    stiffness: float = 400.0
    damping: float = 20.0
    rot_stiffness: float = 4.0
    rot_damping: float = 0.2

    def key_poses(self, home) -> list:
        """Each key's handle pose ``(p, r)``; ``home`` is the master's home tool pose."""
        return [self._pose(k, home) for k in self.keys]

    def target(self, t, poses):
        """The commanded handle pose ``(p, r)`` at ``t`` (master base frame); ``poses`` from
        :meth:`key_poses`."""
        keys = self.keys
        k = 0
        while k + 1 < len(keys) and t >= keys[k + 1].t_s:
            k += 1
        if k + 1 >= len(keys) or t <= keys[k].t_s:
            return poses[k]
        a, b = keys[k], keys[k + 1]
        s = _smooth((t - a.t_s) / (b.t_s - a.t_s))
        if a.q is not None and b.q is not None:
            qa, qb = np.asarray(a.q, float), np.asarray(b.q, float)
            return KRAFT_MASTER.forward(qa + s * (qb - qa))
        (pa, ra), (pb, rb) = poses[k], poses[k + 1]
        return pa + s * (pb - pa), qslerp(ra, rb, s)

    @staticmethod
    def _pose(key, home):
        if key.q is not None:
            return KRAFT_MASTER.forward(np.asarray(key.q, float))
        p0, r0 = home
        turn = np.asarray(key.turn, float)
        angle = float(np.linalg.norm(turn))
        r = r0 if angle == 0.0 else qmul(q_from_axis_angle(turn / angle, angle), r0)
        return p0 + np.asarray(key.move, float), r


@dataclass(frozen=True)
class SlavePush:
    """An external spring-damper pulling the slave's tool toward ``home + move(t)`` (slave
    base axes): ``keys`` are ``(t_s, (dx, dy, dz))`` pairs, interpolated smoothly."""

    keys: tuple
    stiffness: float = 2000.0
    damping: float = 60.0

    def target(self, t, home):
        keys = self.keys
        k = 0
        while k + 1 < len(keys) and t >= keys[k + 1][0]:
            k += 1
        if k + 1 >= len(keys) or t <= keys[k][0]:
            return home + np.asarray(keys[min(k, len(keys) - 1)][1], float)
        (ta, ma), (tb, mb) = keys[k], keys[k + 1]
        s = _smooth((t - ta) / (tb - ta))
        return home + np.asarray(ma, float) + s * (np.asarray(mb, float) - np.asarray(ma, float))


@dataclass(frozen=True)
class ContactWall:
    """A frictionless wall in the slave's workspace: free side ``normal . (p - point) >= 0``.

    Inside, the wall pushes the tool point out with ``stiffness depth + damping (inward
    speed)`` along ``normal`` (N/m, N s/m).
    """

    point: tuple
    normal: tuple
    stiffness: float = 5000.0
    damping: float = 50.0

    def force_on_slave(self, p, v):
        n = np.asarray(self.normal, float)
        n = n / np.linalg.norm(n)
        depth = -float(n @ (p - np.asarray(self.point, float)))
        if depth <= 0.0:
            return np.zeros(3), 0.0
        inward = max(-float(n @ v), 0.0)
        return (self.stiffness * depth + self.damping * inward) * n, depth


@dataclass(frozen=True)
class TeleopScenario:
    """A teleoperation run (``kind = "teleop"`` in TOML; see ``docs/scenarios.md``)."""

    name: str
    duration_s: float = 4.0
    dt_s: float = 0.001
    title: str = ""
    source: str = ""
    q_m0: tuple = (0.0, 0.3, -0.4, 0.2, 0.3, 0.0)
    q_s0: tuple = (0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8)
    master_inertia: tuple = (0.02, 0.02, 0.015, 0.004, 0.004, 0.002)
    master_viscous: float = 0.05
    master_deadband: tuple = KRAFT_DEADBAND
    slave_damping: float = 2.0
    hand: Hand = Hand()
    push: SlavePush | None = None
    wall: ContactWall | None = None
    virtual_walls: tuple = ()
    orientation_error: str = "euler-parameters"
    preload: bool = False
    gains_master: StiffnessGains = StiffnessGains()
    gains_slave: StiffnessGains = StiffnessGains()
    reflection: float = -0.5
    k_for: float | None = None
    holds: tuple = ()

    @property
    def steps(self) -> int:
        return int(round(self.duration_s / self.dt_s)) + 1

    def controller(self, orientation_error: str | None = None, preload: bool | None = None) -> TeleopController:
        """The scenario's controller, optionally with another orientation error or preload."""
        oe = self.orientation_error if orientation_error is None else orientation_error
        pl = self.preload if preload is None else preload
        reg = Registration.from_homes(KRAFT_MASTER, PANDA_SLAVE.arm, self.q_m0, self.q_s0)
        return TeleopController(
            registration=reg, q_rest=np.asarray(self.q_s0), gains_master=self.gains_master,
            gains_slave=self.gains_slave, orientation_error=oe, reflection=self.reflection, k_for=self.k_for,
            preload_nm=TeleopController.default_preload() if pl else None, walls=self.virtual_walls)


@dataclass(frozen=True)
class TeleopRun:
    """Logged signals of a teleoperation run (``T`` control cycles).

    ``p_m``/``r_m``: the master's tool pose registered in the slave's workspace; ``p_s``/
    ``r_s``: the slave's; ``p_master``: the master's tool in its own base frame; ``e``: the
    controller's task error; ``angle``: the true angle between the two orientations;
    ``tau_m``/``tau_s``: the torques sent; ``F_s``: the slave's wrist force (what it
    exerts on its environment) as the controller read it in that cycle (sensed at the end
    of the previous one); ``F_hand``: the hand's force on the master (master axes);
    ``F_reflected``: the master actuators' commanded force at the handle (master axes);
    ``wall_depth``: the master's depth into each virtual wall over that wall's thickness
    (``(T, n_walls)``; <= 0 outside, > 1 through it);
    ``raw_finite``: False where the controller produced a non-finite torque.
    """

    scenario: TeleopScenario
    controller: TeleopController
    t: np.ndarray
    q_m: np.ndarray
    q_s: np.ndarray
    p_m: np.ndarray
    r_m: np.ndarray
    p_s: np.ndarray
    r_s: np.ndarray
    p_master: np.ndarray
    e: np.ndarray
    angle: np.ndarray
    tau_m: np.ndarray
    tau_s: np.ndarray
    F_s: np.ndarray
    F_hand: np.ndarray
    F_reflected: np.ndarray
    wall_depth: np.ndarray
    raw_finite: np.ndarray
    saturated: np.ndarray


def _qconj_f(q):
    return (q[0], -q[1], -q[2], -q[3])


def _angle_between(q1, q2) -> float:
    """Rotation angle of ``q1* q2`` (rad, in ``[0, pi]``), precise for small angles."""
    d = qmul_components(*_qconj_f(q1), *q2)
    return 2.0 * math.atan2(math.sqrt(d[1] * d[1] + d[2] * d[2] + d[3] * d[3]), abs(d[0]))


def _friction_step(qd, inertia, tau, static, dt):
    """Per-joint velocity update with static and Coulomb friction of size ``static``.

    A joint at rest stays at rest while ``|tau| <= static``; a moving joint feels
    ``-static sign(qd)``, and friction alone never reverses its velocity within a step.
    """
    qd_new = qd + dt * tau / inertia
    if not np.any(static > 0):
        return qd_new
    out = qd_new.copy()
    for j in range(len(qd)):
        f = static[j]
        if f <= 0:
            continue
        if qd[j] == 0.0 and abs(tau[j]) <= f:
            out[j] = 0.0
            continue
        direction = math.copysign(1.0, qd[j]) if qd[j] != 0.0 else math.copysign(1.0, tau[j])
        v = qd[j] + dt * (tau[j] - f * direction) / inertia[j]
        if v * direction < 0:  # friction stops the joint within this step
            v = 0.0
        out[j] = v
    return out


def simulate_teleop(scenario: TeleopScenario, orientation_error: str | None = None, preload: bool | None = None,
                    progress=None) -> TeleopRun:
    """Run ``scenario`` (optionally with another orientation error or preload setting)."""
    sc = scenario
    ctrl = sc.controller(orientation_error, preload)
    M, S = KRAFT_MASTER, PANDA_SLAVE
    q_m, qd_m = np.array(sc.q_m0, float), np.zeros(6)
    q_s, qd_s = np.array(sc.q_s0, float), np.zeros(7)
    hand_poses = sc.hand.key_poses(M.forward(q_m))
    p_s0 = S.arm.forward(q_s)[0]
    I_m = np.array(sc.master_inertia, float)
    static = np.asarray(sc.master_deadband, float) * np.asarray(KRAFT_FULL_SCALE)
    n = sc.steps
    names = ("q_m", "q_s", "p_m", "r_m", "p_s", "r_s", "p_master", "e", "angle", "tau_m", "tau_s", "F_s",
             "F_hand", "F_reflected", "wall_depth", "raw_finite", "saturated")
    log = {k: [] for k in names}
    F_s = np.zeros(6)
    every = max(n // 10, 1)
    for k in range(n):
        t = k * sc.dt_s
        cmd = ctrl.compute(t, TeleopMeasurement(q_m, qd_m, q_s, qd_s, F_s))
        # the plant (perfect measurement: the controller's kinematics are the plant's)
        J_mf, J_sf = cmd.J_mf, cmd.J_sf
        p_master, r_master = M.forward(q_m)
        v_m = J_mf @ qd_m
        p_h, r_h = sc.hand.target(t, hand_poses)
        d = qmul_components(*r_h, *_qconj_f(r_master))  # the hand's orientation error
        d = d if d[0] >= 0 else tuple(-x for x in d)
        h = sc.hand
        wrench = np.r_[h.stiffness * (p_h - p_master) - h.damping * v_m[0:3],
                       h.rot_stiffness * 2.0 * np.array(d[1:]) - h.rot_damping * v_m[3:6]]
        tau_m_net = cmd.tau_m + J_mf.T @ wrench - sc.master_viscous * qd_m
        # the force at the handle the actuators' torques make (the Kraft's 6x6 J_mf^T [F; m] = tau)
        F_refl = np.linalg.lstsq(J_mf.T, cmd.tau_m, rcond=None)[0][0:3]
        # the slave, touching its environment
        p_s = cmd.p_s
        v_s = J_sf[0:3] @ qd_s
        F_env = np.zeros(3)
        if sc.wall is not None:
            F_env = F_env + sc.wall.force_on_slave(p_s, v_s)[0]
        if sc.push is not None:
            F_env = F_env + sc.push.stiffness * (sc.push.target(t, p_s0) - p_s) - sc.push.damping * v_s
        tau_s_net = cmd.tau_s + J_sf[0:3].T @ F_env - sc.slave_damping * qd_s
        wall_depth = [w.depth(p_master) / w.thickness_m for w in sc.virtual_walls]
        for key, val in (("q_m", q_m), ("q_s", q_s), ("p_m", cmd.p_m), ("r_m", cmd.r_m), ("p_s", cmd.p_s),
                         ("r_s", cmd.r_s), ("p_master", p_master), ("e", cmd.e),
                         ("angle", _angle_between(cmd.r_m, cmd.r_s)),
                         ("tau_m", cmd.tau_m), ("tau_s", cmd.tau_s),
                         ("F_s", F_s[0:3]), ("F_hand", wrench[0:3]), ("F_reflected", F_refl),
                         ("wall_depth", wall_depth), ("raw_finite", cmd.raw_finite), ("saturated", cmd.saturated)):
            log[key].append(val)
        # semi-implicit Euler, torques held over the cycle
        qd_m = _friction_step(qd_m, I_m, tau_m_net, static, sc.dt_s)
        coriolis = S.coriolis(q_s, qd_s, cmd.M_s)
        qd_s = qd_s + sc.dt_s * np.linalg.solve(cmd.M_s, tau_s_net - coriolis)
        q_m = q_m + sc.dt_s * qd_m
        q_s = q_s + sc.dt_s * qd_s
        F_s = np.r_[-F_env, 0.0, 0.0, 0.0]  # the wrist sensor: what the slave exerts on its environment
        if progress is not None and k % every == 0:
            progress(k / n)
    a = {k: np.array(v) for k, v in log.items()}
    t = np.arange(n) * sc.dt_s
    return TeleopRun(sc, ctrl, t, *(a[k] for k in names))


# ---------------------------------------------------------------------------------------
# metrics


def _at(run, t_s):
    return int(min(max(round(t_s / run.scenario.dt_s), 0), len(run.t) - 1))


def teleop_metrics(run: TeleopRun) -> dict:
    """The numbers of a run (``metrics.json``); entries that do not apply are None.

    * ``final_position_error_m``, ``final_orientation_error_rad``: slave vs registered
      master at the end; ``peak_*``: over the run;
    * ``contact_force_error_pct``: at the end of each hold (``holds``) in contact, the slave's
      contact force against eq. (13)'s ``K_ps (x_m - x_s)`` (the largest difference, %);
      ``reflected_force_ratio``: the master actuators' force at the handle over the contact
      force (``K_pm / K_ps - v`` by (11) and (13)); ``hand_force_ratio``: what the hand
      feels, the master's friction included;
    * ``reversal_hysteresis_m``: with a push, the master-slave position error along the
      first push direction at the end of the holds that follow a negative move, minus the
      same after a positive move (the master stops short of the slave on each side: the
      width of its hysteresis); ``limit_cycle_amplitude_m``: the master's largest
      peak-to-peak motion over the last second, when that second lies after every
      commanded motion;
    * ``wall_penetration_m``: the master's deepest point in a virtual wall (0 if never in);
      ``virtual_wall_crossed``: deeper than a wall's thickness;
    * ``final_hand_force_n``: the hand's force on the master at the end;
    * ``nonfinite_torques``: cycles whose raw torque was not finite (replaced by zero).
    """
    sc = run.scenario
    pos_err = np.linalg.norm(run.p_s - run.p_m, axis=1)
    m = {
        "scenario": sc.name,
        "orientation_error": run.controller.orientation_error,
        "preload": run.controller.preload_nm is not None,
        "duration_s": float(sc.duration_s),
        "dt_s": float(sc.dt_s),
        "final_position_error_m": float(pos_err[-1]),
        "peak_position_error_m": float(pos_err.max()),
        "final_orientation_error_rad": float(run.angle[-1]),
        "peak_orientation_error_rad": float(run.angle.max()),
        "peak_slave_torque_nm": float(np.abs(run.tau_s).max()),
        "saturated_fraction": float(run.saturated.mean()),
        "nonfinite_torques": int((~run.raw_finite).sum()),
        "final_hand_force_n": float(np.linalg.norm(run.F_hand[-1])),
        "contact_force_error_pct": None,
        "reflected_force_ratio": None,
        "hand_force_ratio": None,
        "contact_force_n": None,
        "reversal_hysteresis_m": None,
        "limit_cycle_amplitude_m": None,
        "wall_penetration_m": None,
        "virtual_wall_crossed": None,
    }
    kp = sc.gains_slave.kp[0:3]
    if sc.wall is not None and sc.holds:
        errs, refl, felt, force = [], [], [], []
        for t_end in sc.holds:
            k = _at(run, t_end)
            F = run.F_s[k]
            if np.linalg.norm(F) < 1e-6:
                continue
            F13 = kp * (run.p_m[k] - run.p_s[k])  # seed 003 eq. (13), tau_red contributes nothing
            errs.append(100.0 * np.linalg.norm(F - F13) / max(np.linalg.norm(F13), 1e-12))
            refl.append(np.linalg.norm(run.F_reflected[k]) / np.linalg.norm(F))
            felt.append(np.linalg.norm(run.F_hand[k]) / np.linalg.norm(F))
            force.append(float(np.linalg.norm(F)))
        if errs:
            m.update(contact_force_error_pct=float(max(errs)), reflected_force_ratio=[float(x) for x in refl],
                     hand_force_ratio=[float(x) for x in felt], contact_force_n=force)
    if sc.push is not None and sc.holds:
        p_s0 = run.p_s[0]
        targets = [sc.push.target(t_end, p_s0) for t_end in sc.holds]
        steps = np.diff(np.vstack([sc.push.target(0.0, p_s0)] + targets), axis=0)
        moved = np.linalg.norm(steps, axis=1) > 1e-9
        if moved.any():
            u = steps[moved][0] / np.linalg.norm(steps[moved][0])  # the first push's direction
            err = [float(u @ (run.p_m[_at(run, t)] - run.p_s[_at(run, t)])) for t in sc.holds]
            after_pos = [e for e, st, mv in zip(err, steps, moved) if mv and st @ u > 0]
            after_neg = [e for e, st, mv in zip(err, steps, moved) if mv and st @ u < 0]
            if after_pos and after_neg:
                m["reversal_hysteresis_m"] = float(np.mean(after_neg) - np.mean(after_pos))
        # over the last second, if it lies in the final hold (after every commanded motion)
        still_from = max(max(k[0] for k in sc.push.keys), max(k.t_s for k in sc.hand.keys))
        last = run.t >= max(run.t[-1] - 1.0, still_from)
        if still_from < run.t[-1] - 0.5:
            m["limit_cycle_amplitude_m"] = float(np.ptp(run.p_m[last], axis=0).max())
    if sc.virtual_walls:
        thick = np.array([w.thickness_m for w in sc.virtual_walls])
        depth = run.wall_depth.max(axis=0) * thick  # each wall's deepest point, m
        m.update(wall_penetration_m=float(max(depth.max(), 0.0)), virtual_wall_crossed=bool(np.any(depth > thick)))
    return m


def teleop_timeseries(run: TeleopRun):
    """Column names and a ``(T, k)`` array for ``timeseries.csv``."""
    cols = {"t": run.t[:, None]}
    for name, arr, labels in (("p_m", run.p_m, "xyz"), ("p_s", run.p_s, "xyz"), ("e", run.e, "123456"),
                              ("F_s", run.F_s, "xyz"), ("F_hand", run.F_hand, "xyz")):
        for i, lab in enumerate(labels):
            cols[f"{name}_{lab}"] = arr[:, i:i + 1]
    cols["angle"] = run.angle[:, None]
    for i in range(run.q_m.shape[1]):
        cols[f"q_m{i + 1}"] = run.q_m[:, i:i + 1]
        cols[f"tau_m{i + 1}"] = run.tau_m[:, i:i + 1]
    for i in range(run.q_s.shape[1]):
        cols[f"q_s{i + 1}"] = run.q_s[:, i:i + 1]
        cols[f"tau_s{i + 1}"] = run.tau_s[:, i:i + 1]
    cols["raw_finite"] = run.raw_finite[:, None].astype(float)
    return list(cols), np.hstack(list(cols.values()))


# ---------------------------------------------------------------------------------------
# TOML


def _floats(d, key, n, where, default=None):
    if key not in d:
        if default is None:
            raise InvalidInputError(f"{where}: missing key {key!r}")
        return tuple(default)
    return tuple(_vec(d[key], n, f"{where}: {key}"))


def _number(d, key, where, default, positive=False):
    v = d.get(key, default)
    try:
        v = float(v)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{where}: {key} = {d[key]!r} is not a number") from None
    if not np.isfinite(v) or (positive and v <= 0) or v < 0:
        raise InvalidInputError(f"{where}: {key} must be finite and {'> 0' if positive else '>= 0'}, got {v!r}")
    return v


def _gains(d, where, base=StiffnessGains()):
    if not d:
        return base
    unknown = set(d) - {f.name for f in dataclasses.fields(StiffnessGains)}
    if unknown:
        raise InvalidInputError(f"{where}: unknown gain(s) {', '.join(sorted(unknown))}; use kp_pos, kp_rot, kv_pos, "
                                "kv_rot")
    return dataclasses.replace(base, **{k: _number(d, k, where, 0.0) for k in d})


def _times(keys, where):
    ts = [k[0] for k in keys]
    if any(b <= a for a, b in zip(ts, ts[1:])) or (ts and ts[0] < 0):
        raise InvalidInputError(f"{where}: key times must start at >= 0 and increase, got {ts}")


_KEYS = {
    "": {"kind", "name", "title", "source", "duration_s", "dt_s", "holds_s", "master", "slave", "hand", "push",
         "wall", "virtual_walls", "controller"},
    "master": {"q0", "inertia", "viscous", "deadband"},
    "slave": {"q0", "damping"},
    "hand": {"keys", "stiffness", "damping", "rot_stiffness", "rot_damping"},
    "push": {"keys", "stiffness", "damping"},
    "wall": {"point", "normal", "stiffness", "damping"},
    "controller": {"orientation_error", "preload", "reflection", "k_for", "gains_master", "gains_slave"},
}


def _check_keys(data: dict, where: str):
    for section, allowed in _KEYS.items():
        table = data if section == "" else data.get(section, {})
        if not isinstance(table, dict):
            raise InvalidInputError(f"{where}: [{section}] must be a table")
        unknown = set(table) - allowed
        if unknown:
            place = "top level" if section == "" else f"[{section}]"
            raise InvalidInputError(f"{where}: unknown key(s) {', '.join(sorted(unknown))} at {place}; "
                                    f"allowed: {', '.join(sorted(allowed))} (see docs/scenarios.md)")


def teleop_scenario_from_dict(data: dict, where: str = "scenario") -> TeleopScenario:
    """Build a :class:`TeleopScenario` from parsed TOML; every mistake is an InvalidInputError."""
    _check_keys(data, where)
    try:
        return _teleop_scenario_from_dict(data, where)
    except (TypeError, ValueError, KeyError) as exc:
        if isinstance(exc, InvalidInputError):
            raise
        raise InvalidInputError(f"{where}: {exc} (see docs/scenarios.md for the keys and their types)") from None


def _teleop_scenario_from_dict(data: dict, where: str) -> TeleopScenario:
    d = TeleopScenario(name=str(data.get("name", Path(where).stem)))
    master, slave, hand_d = data.get("master", {}), data.get("slave", {}), data.get("hand", {})
    ctrl = data.get("controller", {})
    hand_keys = []
    for i, k in enumerate(hand_d.get("keys", [{"t_s": 0.0}])):
        wk = f"{where} [[hand.keys]] #{i + 1}"
        if "q" in k and ("move" in k or "turn" in k):
            raise InvalidInputError(f"{wk}: give either q (master joints) or move/turn, not both")
        hand_keys.append(HandKey(
            t_s=_number(k, "t_s", wk, 0.0),
            q=_floats(k, "q", 6, wk) if "q" in k else None,
            move=_floats(k, "move", 3, wk, (0, 0, 0)), turn=_floats(k, "turn", 3, wk, (0, 0, 0))))
    _times([(k.t_s,) for k in hand_keys], f"{where} [hand]")
    hand = Hand(tuple(hand_keys), *(_number(hand_d, key, f"{where} [hand]", getattr(d.hand, key))
                                    for key in ("stiffness", "damping", "rot_stiffness", "rot_damping")))
    push = None
    if "push" in data:
        pd = data["push"]
        keys = tuple((_number(k, "t_s", f"{where} [push]", 0.0), _floats(k, "move", 3, f"{where} [push]"))
                     for k in pd.get("keys", []))
        if not keys:
            raise InvalidInputError(f"{where}: [push] needs keys = [{{t_s = ..., move = [dx, dy, dz]}}, ...]")
        _times(keys, f"{where} [push]")
        push = SlavePush(keys, _number(pd, "stiffness", f"{where} [push]", 2000.0),
                         _number(pd, "damping", f"{where} [push]", 60.0))
    wall = None
    if "wall" in data:
        wd = data["wall"]
        ww = f"{where} [wall]"
        wall = ContactWall(_floats(wd, "point", 3, ww), _floats(wd, "normal", 3, ww),
                           _number(wd, "stiffness", ww, 5000.0, positive=True), _number(wd, "damping", ww, 50.0))
        if np.linalg.norm(wall.normal) < 1e-9:
            raise InvalidInputError(f"{ww}: normal must be nonzero")
    vwalls = []
    for i, v in enumerate(data.get("virtual_walls", [])):
        wv = f"{where} [[virtual_walls]] #{i + 1}"
        offset = v.get("offset", 0.0)
        if isinstance(offset, bool) or not isinstance(offset, (int, float)) or not np.isfinite(offset):
            raise InvalidInputError(f"{wv}: offset must be a finite number (m), got {offset!r}")
        vwalls.append(VirtualWall(_floats(v, "normal", 3, wv), float(offset),
                                  _number(v, "resist_force_n", wv, 8.0, positive=True),
                                  _number(v, "thickness_m", wv, 0.02, positive=True), _number(v, "damping", wv, 20.0)))
    oe = ctrl.get("orientation_error", "euler-parameters")
    if oe not in ORIENTATION_ERRORS:
        raise InvalidInputError(f"{where} [controller]: orientation_error = {oe!r}; use one of "
                                f"{', '.join(ORIENTATION_ERRORS)}")
    pl = ctrl.get("preload", False)
    if not isinstance(pl, bool):
        raise InvalidInputError(f"{where} [controller]: preload must be true or false, got {pl!r}")
    reflection = float(ctrl.get("reflection", -0.5))
    if not reflection < 0:
        raise InvalidInputError(f"{where} [controller]: reflection (v of eq. (11)) must be negative, "
                                f"got {reflection!r}")
    k_for = ctrl.get("k_for")
    if k_for is not None:
        k_for = _number(ctrl, "k_for", f"{where} [controller]", 0.0)
    duration = _number(data, "duration_s", where, None, positive=True) if "duration_s" in data else None
    if duration is None:
        raise InvalidInputError(f"{where}: missing key 'duration_s'")
    dt = _number(data, "dt_s", where, 0.001, positive=True)
    if dt > duration:
        raise InvalidInputError(f"{where}: dt_s = {dt} exceeds duration_s = {duration}")
    holds = tuple(float(x) for x in data.get("holds_s", []))
    if not all(np.isfinite(h) and 0.0 <= h <= duration for h in holds):
        raise InvalidInputError(f"{where}: holds_s must be times within [0, duration_s = {duration}], "
                                f"got {list(holds)}")
    sc = TeleopScenario(
        name=d.name, duration_s=duration, dt_s=dt, title=str(data.get("title", "")),
        source=str(data.get("source", "")),
        q_m0=_floats(master, "q0", 6, f"{where} [master]", d.q_m0),
        q_s0=_floats(slave, "q0", 7, f"{where} [slave]", d.q_s0),
        master_inertia=_floats(master, "inertia", 6, f"{where} [master]", d.master_inertia),
        master_viscous=_number(master, "viscous", f"{where} [master]", d.master_viscous),
        master_deadband=_floats(master, "deadband", 6, f"{where} [master]", d.master_deadband),
        slave_damping=_number(slave, "damping", f"{where} [slave]", d.slave_damping),
        hand=hand, push=push, wall=wall, virtual_walls=tuple(vwalls), orientation_error=oe, preload=pl,
        gains_master=_gains(ctrl.get("gains_master", {}), f"{where} [controller.gains_master]"),
        gains_slave=_gains(ctrl.get("gains_slave", {}), f"{where} [controller.gains_slave]"),
        reflection=reflection, k_for=k_for, holds=holds,
    )
    if any(i <= 0 for i in sc.master_inertia):
        raise InvalidInputError(f"{where} [master]: inertia must be > 0 for every joint, got {sc.master_inertia}")
    if any(b < 0 for b in sc.master_deadband):
        raise InvalidInputError(f"{where} [master]: deadband fractions must be >= 0, got {sc.master_deadband}")
    sc.controller()  # the registration and limits must make a controller
    return sc

