"""The ``teleop`` scenario kind (seed 003): the scenario, its strict TOML reader, its run and metrics.

Scenarios layer. A teleoperation scenario (``kind = "teleop"``, ``docs/scenarios.md``) is the
Kraft master and the 7-DOF slave from their homes, the operator's hand path, the slave's
environment (a contact wall, a push) and the controller's settings (orientation error,
preload, gains, force reflection, virtual walls). :data:`TELEOP` (registered in
:data:`quatform.scenarios.KINDS`) builds its :class:`~quatform.scenarios.base.Experiment`:
the :class:`~quatform.sim.plants.teleop.TeleopPlant`, the
:class:`~quatform.teleop.TeleopController` (stateless; no reference: each arm's reference is
the other arm), one control cycle per plant step, and what to make of the log:
:func:`teleop_finish` adds the channels the metrics, the CSV and the figures read
(``angle``, ``F_s``, ``F_hand``, ``F_reflected``, ``p_master``, ``wall_depth`` and the joint
tables), :func:`teleop_metrics` computes ``metrics.json``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..algebra import matrix_from_q
from ..checks import check_keys, check_work, flag, number, short, table, text, vector
from ..control.stiffness import StiffnessGains, effective_mass, explicit_stiffness_limit
from ..errors import InvalidInputError
from ..robots.arms import KraftMaster, PandaSlave
from ..sim.log import Channel, Log
from ..sim.plants.teleop import (
    ContactWall,
    Hand,
    HandKey,
    SlavePush,
    TeleopPlant,
    angle_between,
)
from ..teleop import (
    KRAFT_DEADBAND,
    KRAFT_MASTER,
    ORIENTATION_ERRORS,
    PANDA_SLAVE,
    Registration,
    TeleopController,
    VirtualWall,
)
from . import KINDS
from .base import Experiment, Option, ScenarioKind, finish_worlds

__all__ = ["TeleopScenario", "TeleopKind", "TELEOP", "TELEOP_COLUMNS", "CSV_CHANNELS", "teleop_finish",
           "teleop_metrics", "teleop_scenario_from_dict", "check_teleop_work", "check_teleop_stiffness",
           "teleop_stiffness_limits", "chatter", "settled_since"]


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


    def plant(self) -> TeleopPlant:
        """The two arms, the hand and the environment of this scenario."""
        return TeleopPlant(
            KraftMaster(self.master_inertia, self.master_viscous, self.master_deadband), PandaSlave(self.slave_damping),
            self.hand, self.hand.key_poses(KRAFT_MASTER.forward(np.array(self.q_m0, float))),
            PANDA_SLAVE.arm.forward(np.array(self.q_s0, float))[0], self.push, self.wall, self.virtual_walls)

    def x0(self) -> np.ndarray:
        """The plant's initial state: both arms at rest at their homes, the wrist sensor at zero."""
        return np.concatenate([np.array(self.q_m0, float), np.zeros(6), np.array(self.q_s0, float), np.zeros(7),
                               np.zeros(6)])


def _at(log, sc, t_s):
    return int(min(max(round(t_s / sc.dt_s), 0), len(log.t) - 1))


def chatter(tau) -> float:
    """``sqrt(mean_k |tau[k+1] - tau[k]|^2)``, N m per cycle (0 for a single sample)."""
    d = np.diff(np.asarray(tau, float), axis=0)
    return float(np.sqrt(np.mean(np.sum(d * d, axis=1)))) if len(d) else 0.0


def settled_since(sc, t_end) -> float:
    """When the commanded motion (hand and push keys) last stopped before ``t_end`` (0: never
    moved; ``t_end``: still moving then)."""
    since = 0.0
    hand = [(a.t_s, b.t_s, a.q != b.q or a.move != b.move or a.turn != b.turn)
            for a, b in zip(sc.hand.keys, sc.hand.keys[1:])]
    push = [] if sc.push is None else [(a[0], b[0], tuple(a[1]) != tuple(b[1]))
                                       for a, b in zip(sc.push.keys, sc.push.keys[1:])]
    for a, b, moves in hand + push:
        if not moves or a >= t_end:
            continue
        since = max(since, min(b, t_end))
    return since


#METRICS
def teleop_metrics(log: Log) -> dict:
    """The numbers of a run (``metrics.json``) from its finished log (:func:`teleop_finish`);
    entries that do not apply are None.

    * ``final_position_error_m``, ``final_orientation_error_rad``: slave vs registered
      master at the end; ``peak_position_error_m``: over the run;
      ``peak_orientation_error_rad``: with ``holds``, the largest orientation error while the
      commanded motion rests (the ``hold_peak_orientation_error_rad`` windows), so the
      tracking lag that every law shows while the hand moves does not dominate it (seed 003's
      point is the RPY law's failure at the lock, not the lag); without holds, over the run;
      ``peak_orientation_error_whole_run_rad``: over the run, lag included;
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
      ``virtual_wall_crossed``: deeper than a wall's thickness; ``virtual_wall_force_n``: the
      wall's spring force ``resist_force_n / thickness_m * depth`` at that deepest point (at
      rest, the push it holds); ``slave_zone_penetration_m``: the slave's deepest point in the
      zone the wall maps to in its workspace (through the registration; slave metres). A
      virtual wall is a spring of finite stiffness: the master, and the slave that follows
      it, enter the zone by ``push / stiffness``, and a push above about ``resist_force_n``
      takes them through its thickness (``docs/derivations.md``, "Teleoperation (seed 003): walls, gains and limits");
    * ``final_hand_force_n``: the hand's force on the master at the end;
    * ``slave_torque_chatter_nm``, ``master_torque_chatter_nm``: the root mean square of the
      torque's change from one cycle to the next, ``sqrt(mean_k |tau[k+1] - tau[k]|^2)``
      (Euclidean norm over the joints, N m per cycle): a smooth command changes by little per
      cycle, a chattering one by up to twice its limit;
    * ``hold_position_error_m``, ``hold_orientation_error_rad``: with ``holds``, the errors at
      the end of each hold; ``hold_peak_position_error_m``, ``hold_peak_orientation_error_rad``:
      their peaks over each hold, from the moment the commanded motion (hand and push keys)
      stopped to the hold's end, so the tracking lag of the motion before it does not count;
    * ``nonfinite_torques``: cycles whose raw torque was not finite (replaced by zero).
    """
    sc, ctrl = log.meta["scenario"], log.meta["teleop_controller"]
    n_m = ctrl.master.n
    p_m, p_s, angle = log["p_m"], log["p_s"], log["angle"][:, 0]
    tau_m, tau_s = log["command"][:, :n_m], log["command"][:, n_m:]
    F_s, F_hand, F_reflected = log["F_s"], log["F_hand"], log["F_reflected"]
    pos_err = np.linalg.norm(p_s - p_m, axis=1)
    m = {
        "scenario": sc.name,
        "orientation_error": ctrl.orientation_error,
        "preload": ctrl.preload_nm is not None,
        "duration_s": float(sc.duration_s),
        "dt_s": float(sc.dt_s),
        "final_position_error_m": float(pos_err[-1]),
        "peak_position_error_m": float(pos_err.max()),
        "final_orientation_error_rad": float(angle[-1]),
        "peak_orientation_error_rad": float(angle.max()),
        "peak_orientation_error_whole_run_rad": float(angle.max()),
        "peak_slave_torque_nm": float(np.abs(tau_s).max()),
        "saturated_fraction": float((log["saturated"][:, 0] > 0.5).mean()),
        "nonfinite_torques": int((log["raw_finite"][:, 0] < 0.5).sum()),
        "final_hand_force_n": float(np.linalg.norm(F_hand[-1])),
        "contact_force_error_pct": None,
        "reflected_force_ratio": None,
        "hand_force_ratio": None,
        "contact_force_n": None,
        "reversal_hysteresis_m": None,
        "limit_cycle_amplitude_m": None,
        "wall_penetration_m": None,
        "virtual_wall_crossed": None,
        "virtual_wall_force_n": None,
        "slave_zone_penetration_m": None,
        "slave_torque_chatter_nm": chatter(tau_s),
        "master_torque_chatter_nm": chatter(tau_m),
        "hold_position_error_m": None,
        "hold_orientation_error_rad": None,
        "hold_peak_position_error_m": None,
        "hold_peak_orientation_error_rad": None,
    }
    if sc.holds:
        ends = [_at(log, sc, t) for t in sc.holds]
        starts = [_at(log, sc, settled_since(sc, t)) for t in sc.holds]
        m.update(hold_position_error_m=[float(pos_err[k]) for k in ends],
                 hold_orientation_error_rad=[float(angle[k]) for k in ends],
                 hold_peak_position_error_m=[float(pos_err[a:b + 1].max()) for a, b in zip(starts, ends)],
                 hold_peak_orientation_error_rad=[float(angle[a:b + 1].max()) for a, b in zip(starts, ends)])
        m["peak_orientation_error_rad"] = max(m["hold_peak_orientation_error_rad"])
    kp = sc.gains_slave.kp[0:3]
    if sc.wall is not None and sc.holds:
        errs, refl, felt, force = [], [], [], []
        for t_end in sc.holds:
            k = _at(log, sc, t_end)
            F = F_s[k]
            if np.linalg.norm(F) < 1e-6:
                continue
            F13 = kp * (p_m[k] - p_s[k])  # seed 003 eq. (13), tau_red contributes nothing
            errs.append(100.0 * np.linalg.norm(F - F13) / max(np.linalg.norm(F13), 1e-12))
            refl.append(np.linalg.norm(F_reflected[k]) / np.linalg.norm(F))
            felt.append(np.linalg.norm(F_hand[k]) / np.linalg.norm(F))
            force.append(float(np.linalg.norm(F)))
        if errs:
            m.update(contact_force_error_pct=float(max(errs)), reflected_force_ratio=[float(x) for x in refl],
                     hand_force_ratio=[float(x) for x in felt], contact_force_n=force)
    if sc.push is not None and sc.holds:
        p_s0 = p_s[0]
        targets = [sc.push.target(t_end, p_s0) for t_end in sc.holds]
        steps = np.diff(np.vstack([sc.push.target(0.0, p_s0)] + targets), axis=0)
        moved = np.linalg.norm(steps, axis=1) > 1e-9
        if moved.any():
            u = steps[moved][0] / np.linalg.norm(steps[moved][0])  # the first push's direction
            err = [float(u @ (p_m[_at(log, sc, t)] - p_s[_at(log, sc, t)])) for t in sc.holds]
            after_pos = [e for e, st, mv in zip(err, steps, moved) if mv and st @ u > 0]
            after_neg = [e for e, st, mv in zip(err, steps, moved) if mv and st @ u < 0]
            if after_pos and after_neg:
                m["reversal_hysteresis_m"] = float(np.mean(after_neg) - np.mean(after_pos))
        # over the last second, if it lies in the final hold (after every commanded motion)
        still_from = max(max(k[0] for k in sc.push.keys), max(k.t_s for k in sc.hand.keys))
        last = log.t >= max(log.t[-1] - 1.0, still_from)
        if still_from < log.t[-1] - 0.5:
            m["limit_cycle_amplitude_m"] = float(np.ptp(p_m[last], axis=0).max())
    if sc.virtual_walls:
        thick = np.array([w.thickness_m for w in sc.virtual_walls])
        depth = log["wall_depth"].max(axis=0) * thick  # each wall's deepest point, m
        deepest = int(np.argmax(depth))
        reg = ctrl.registration
        R = matrix_from_q(reg.base)
        zone = []
        for w in sc.virtual_walls:  # the wall's plane carried into the slave's workspace
            n = np.asarray(w.normal, float) / np.linalg.norm(w.normal)
            p_master = (R.T @ (p_s - reg.p_slave0).T).T / reg.scale + reg.p_master0
            zone.append(reg.scale * float((p_master @ n - w.offset).max()))
        m.update(wall_penetration_m=float(max(depth.max(), 0.0)), virtual_wall_crossed=bool(np.any(depth > thick)),
                 virtual_wall_force_n=float(sc.virtual_walls[deepest].stiffness * max(depth[deepest], 0.0)),
                 slave_zone_penetration_m=float(max(max(zone), 0.0)))
    return m


#: Channels of ``timeseries.csv``, in order (the recorded columns: ``t``, the registered master's and
#: the slave's tool positions, the task error, the wrist force, the hand's force, the angle
#: between the tools, each arm's joint angle and torque side by side, ``raw_finite``).
CSV_CHANNELS = ("p_m", "p_s", "e", "F_s", "F_hand", "angle", "master_joints", "slave_joints", "raw_finite")


def teleop_finish(log: Log) -> Log:
    """``log`` with the channels the metrics, the CSV and the figures read.

    ``angle`` (rad): the true angle between the two tools' orientations (``r_m``, ``r_s``);
    ``F_s`` (N): the wrist force the controller read in that cycle (the measured ``F_s``
    columns, sensed at the end of the previous cycle); ``p_master``, ``F_hand``,
    ``F_reflected``, ``wall_depth``: the environment's side of each tick
    (:meth:`~quatform.sim.plants.teleop.TeleopPlant.forces`, recomputed from the logged states
    and commands); ``master_joints``, ``slave_joints``: each joint's angle and torque side by
    side (``q_m1, tau_m1, q_m2, ...``) for the CSV. A batch of worlds is finished world by
    world (:func:`~quatform.scenarios.base.finish_worlds`).
    """
    if log.batch_shape:
        return finish_worlds(log, teleop_finish)
    sc, ctrl = log.meta["scenario"], log.meta["teleop_controller"]
    plant = log.meta["plant"]
    x, u, measured = log["state"], log["command"], log["measured"]
    n_m, n_s = ctrl.master.n, ctrl.slave.arm.n
    f = plant.forces(log.t, x, u)
    i_F = log.columns("measured").index("F_s_x")
    q_m, q_s = x[:, :n_m], x[:, 2 * n_m:2 * n_m + n_s]
    tau_m, tau_s = u[:, :n_m], u[:, n_m:]
    joints = [(f"{a}{i + 1}", f"{b}{i + 1}") for a, b, n in (("q_m", "tau_m", n_m), ("q_s", "tau_s", n_s))
              for i in range(n)]
    return log.with_channels(
        Channel("angle", ("angle",), angle_between(log["r_m"], log["r_s"])[:, None]),
        Channel("F_s", ("F_s_x", "F_s_y", "F_s_z"), measured[:, i_F:i_F + 3]),
        Channel("p_master", ("p_master_x", "p_master_y", "p_master_z"), f["p_master"]),
        Channel("F_hand", ("F_hand_x", "F_hand_y", "F_hand_z"), f["F_hand"]),
        Channel("F_reflected", ("F_reflected_x", "F_reflected_y", "F_reflected_z"), f["F_reflected"]),
        Channel("wall_depth", tuple(f"wall{k + 1}_depth" for k in range(len(sc.virtual_walls))), f["wall_depth"]),
        Channel("master_joints", sum(joints[:n_m], ()), np.stack([q_m, tau_m], axis=-1).reshape(len(log.t), -1)),
        Channel("slave_joints", sum(joints[n_m:], ()), np.stack([q_s, tau_s], axis=-1).reshape(len(log.t), -1)))


#: Columns of the comparison table: (metrics key, header, format).
TELEOP_COLUMNS = (
    ("orientation_error", "orientation error", "{}"),
    ("preload", "preload", "{}"),
    ("final_position_error_m", "final pos (m)", "{:.2e}"),
    ("peak_position_error_m", "peak pos (m)", "{:.2e}"),
    ("final_orientation_error_rad", "final orient (rad)", "{:.2e}"),
    ("peak_orientation_error_rad", "peak orient (rad)", "{:.3f}"),
    ("peak_slave_torque_nm", "peak slave tau (N m)", "{:.2f}"),
    ("slave_torque_chatter_nm", "slave tau chatter (N m)", "{:.3g}"),
    ("contact_force_error_pct", "eq.13 err (%)", "{:.2f}"),
    ("reversal_hysteresis_m", "hysteresis (m)", "{:.4f}"),
    ("wall_penetration_m", "wall depth (m)", "{:.4f}"),
    ("slave_zone_penetration_m", "slave zone depth (m)", "{:.4f}"),
    ("nonfinite_torques", "NaN torques", "{}"),
)

#: ``--preload`` values.
PRELOAD_CHOICES = {"on": True, "off": False}


def _preload(value, where="preload"):
    if value is None or isinstance(value, bool):
        return value
    if isinstance(value, str) and value in PRELOAD_CHOICES:
        return PRELOAD_CHOICES[value]
    raise InvalidInputError(f"{where} = {short(value)} must be on or off (or True / False)")


class TeleopKind(ScenarioKind):
    """Seed 003's teleoperation scenarios (``kind = "teleop"``)."""

    name = "teleop"
    scenario_type = TeleopScenario
    options = (
        Option("orientation_error", "the controllers' orientation error (default: the scenario's)",
               choices=tuple(ORIENTATION_ERRORS)),
        Option("preload", "the preload function on the master's actuators (default: the scenario's)",
               choices=tuple(PRELOAD_CHOICES)),
    )
    compare_over = "orientation_error"
    table_columns = TELEOP_COLUMNS

    def from_dict(self, data: dict, where: str) -> TeleopScenario:
        return teleop_scenario_from_dict(data, where)

    def experiment(self, scenario: TeleopScenario, orientation_error: str | None = None,
                   preload: bool | str | None = None) -> Experiment:
        """The run of ``scenario`` with another orientation error or preload (None: the scenario's).

        The scenario's size and springs are checked first (:func:`check_teleop_work`,
        :func:`check_teleop_stiffness`), as the reader does, for scenarios built in code.
        """
        sc = scenario
        if not isinstance(sc, TeleopScenario):
            raise InvalidInputError(f"the teleop kind runs a TeleopScenario, got {type(sc).__name__}; "
                                    "load it with quatform.sim.load_scenario")
        if orientation_error is not None and orientation_error not in ORIENTATION_ERRORS:
            raise InvalidInputError(f"orientation_error = {short(orientation_error)} must be one of "
                                    f"{', '.join(ORIENTATION_ERRORS)}")
        preload = _preload(preload)
        check_teleop_work(sc.name, sc.duration_s, sc.dt_s)
        check_teleop_stiffness(sc)
        ctrl = sc.controller(orientation_error, preload)
        plant = sc.plant()
        label = f"{ctrl.orientation_error}, preload {'on' if ctrl.preload_nm is not None else 'off'}"
        return Experiment(
            scenario=sc, label=label, plant=plant, controller=ctrl, reference=lambda k: None,
            times=np.arange(sc.steps) * sc.dt_s, x0=sc.x0(), dt=sc.dt_s, substeps=1, finish=teleop_finish,
            metrics=teleop_metrics, csv_channels=CSV_CHANNELS,
            meta={"scenario": sc, "teleop_controller": ctrl, "plant": plant})


#: The kind's one instance, registered in :data:`quatform.scenarios.KINDS`.
TELEOP = KINDS[TeleopKind.name]

# TOML


_TOP = ("kind", "name", "title", "source", "duration_s", "dt_s", "holds_s", "master", "slave", "hand", "push",
        "wall", "virtual_walls", "controller")
_SECTIONS = {
    "master": ("q0", "inertia", "viscous", "deadband"),
    "slave": ("q0", "damping"),
    "hand": ("keys", "stiffness", "damping", "rot_stiffness", "rot_damping"),
    "push": ("keys", "stiffness", "damping"),
    "wall": ("point", "normal", "stiffness", "damping"),
    "controller": ("orientation_error", "preload", "reflection", "k_for", "gains_master", "gains_slave"),
}
_GAINS = tuple(f.name for f in dataclasses.fields(StiffnessGains))
_WALL_KEYS = ("normal", "offset", "resist_force_n", "thickness_m", "damping")
_HINT = "see docs/scenarios.md"

#: Generous per-cycle cost of a teleop run (measured about 1.4 ms and 3 kB of logs
#: per cycle on one core; ``docs/performance.md``), for :func:`check_teleop_work`.
SECONDS_PER_STEP = 3e-3
BYTES_PER_STEP = 4000.0


def _list_of_tables(data, key, where, place):
    """``data[key]``, a TOML array of tables (``[[key]]`` or ``key = [{...}, ...]``)."""
    value = data.get(key, [])
    if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
        raise InvalidInputError(f"{where}: {place}{key} = {short(value)} must be a list of tables "
                                f"({{t_s = ...}} entries or [[{key}]] blocks; {_HINT})")
    return value


def _key_times(ts, where, place, duration):
    if any(b <= a for a, b in zip(ts, ts[1:])):
        raise InvalidInputError(f"{where}: {place} key times t_s must increase, got {short(list(ts))}")
    if ts and ts[-1] > duration:
        raise InvalidInputError(f"{where}: {place} key time t_s = {ts[-1]:g} is after duration_s = {duration:g}; "
                                "move it inside the run or lengthen it")


def _gains(ctrl, key, where):
    place = f"[controller.{key}]"
    d = table(ctrl, key, where, "[controller]", default={})
    check_keys(d, _GAINS, where, place, _HINT)
    base = StiffnessGains()
    return StiffnessGains(**{g: number(d, g, where, getattr(base, g), place=place, low=0.0) for g in _GAINS})


def teleop_scenario_from_dict(data: dict, where: str = "scenario") -> TeleopScenario:
    """Build a :class:`TeleopScenario` from parsed TOML (``docs/scenarios.md``).

    Every mistake is one :class:`~quatform.errors.InvalidInputError` line naming the file,
    the key, the value and the fix (unknown keys name the nearest valid one); the run's
    size is checked up front (:func:`check_teleop_work`) and so are the springs against
    the integrator's stability limit (:func:`check_teleop_stiffness`).
    """
    if not isinstance(data, dict):
        raise InvalidInputError(f"{where}: a teleop scenario must be a TOML table, got {short(data)}")
    check_keys(data, _TOP, where, hint=_HINT)
    sec = {name: table(data, name, where, default={}) for name in _SECTIONS if name not in ("push", "wall")}
    for name, allowed in _SECTIONS.items():
        if name in sec:
            check_keys(sec[name], allowed, where, f"[{name}]", _HINT)
    d = TeleopScenario(name="defaults")
    name = text(data, "name", where, Path(where).stem)
    duration = number(data, "duration_s", where, low=0.0, low_open=True)
    dt = number(data, "dt_s", where, 0.001, low=0.0, low_open=True)
    if dt > duration:
        raise InvalidInputError(f"{where}: dt_s = {dt:g} exceeds duration_s = {duration:g}; choose dt_s <= duration_s")
    check_teleop_work(where, duration, dt)
    holds = data.get("holds_s", [])
    if not isinstance(holds, list):
        raise InvalidInputError(f"{where}: holds_s = {short(holds)} must be a list of times (s)")
    holds = tuple(number({"holds_s": h}, "holds_s", where, low=0.0, high=duration) for h in holds)
    master, slave, hand_d, ctrl = sec["master"], sec["slave"], sec["hand"], sec["controller"]

    hand_keys = []
    for i, k in enumerate(_list_of_tables(hand_d, "keys", where, "[hand] ") or [{"t_s": 0.0}]):
        place = f"[hand] keys #{i + 1}"
        check_keys(k, ("t_s", "q", "move", "turn"), where, place, _HINT)
        if "q" in k and ("move" in k or "turn" in k):
            raise InvalidInputError(f"{where}: {place}: give either q (master joints) or move/turn, not both")
        hand_keys.append(HandKey(
            t_s=number(k, "t_s", where, 0.0, place=place, low=0.0),
            q=vector(k, "q", 6, where, place=place) if "q" in k else None,
            move=vector(k, "move", 3, where, (0.0, 0.0, 0.0), place=place),
            turn=vector(k, "turn", 3, where, (0.0, 0.0, 0.0), place=place)))
    _key_times([k.t_s for k in hand_keys], where, "[hand]", duration)
    hand = Hand(tuple(hand_keys), *(number(hand_d, key, where, getattr(d.hand, key), place="[hand]", low=0.0)
                                    for key in ("stiffness", "damping", "rot_stiffness", "rot_damping")))

    push = None
    if "push" in data:
        pd = table(data, "push", where)
        check_keys(pd, _SECTIONS["push"], where, "[push]", _HINT)
        keys = []
        for i, k in enumerate(_list_of_tables(pd, "keys", where, "[push] ")):
            place = f"[push] keys #{i + 1}"
            check_keys(k, ("t_s", "move"), where, place, _HINT)
            keys.append((number(k, "t_s", where, 0.0, place=place, low=0.0), vector(k, "move", 3, where, place=place)))
        if not keys:
            raise InvalidInputError(f"{where}: [push] needs keys = [{{t_s = ..., move = [dx, dy, dz]}}, ...]")
        _key_times([k[0] for k in keys], where, "[push]", duration)
        push = SlavePush(tuple(keys), number(pd, "stiffness", where, 2000.0, place="[push]", low=0.0),
                         number(pd, "damping", where, 60.0, place="[push]", low=0.0))

    wall = None
    if "wall" in data:
        wd = table(data, "wall", where)
        check_keys(wd, _SECTIONS["wall"], where, "[wall]", _HINT)
        normal = vector(wd, "normal", 3, where, place="[wall]")
        if math.hypot(*normal) < 1e-9:
            raise InvalidInputError(f"{where}: [wall] normal = {list(normal)} must be a nonzero vector (the free side)")
        wall = ContactWall(vector(wd, "point", 3, where, place="[wall]"), normal,
                           number(wd, "stiffness", where, 5000.0, place="[wall]", low=0.0, low_open=True),
                           number(wd, "damping", where, 50.0, place="[wall]", low=0.0))

    vwalls = []
    for i, v in enumerate(_list_of_tables(data, "virtual_walls", where, "")):
        place = f"[[virtual_walls]] #{i + 1}"
        check_keys(v, _WALL_KEYS, where, place, _HINT)
        normal = vector(v, "normal", 3, where, place=place)
        args = (number(v, "offset", where, 0.0, place=place),
                number(v, "resist_force_n", where, 8.0, place=place, low=0.0, low_open=True),
                number(v, "thickness_m", where, 0.02, place=place, low=0.0, low_open=True),
                number(v, "damping", where, 20.0, place=place, low=0.0))
        try:
            vwalls.append(VirtualWall(normal, *args))
        except InvalidInputError as exc:
            raise InvalidInputError(f"{where}: {place}: {exc}") from None

    oe = text(ctrl, "orientation_error", where, "euler-parameters", place="[controller]", choices=ORIENTATION_ERRORS)
    pl = flag(ctrl, "preload", where, False, place="[controller]")
    reflection = number(ctrl, "reflection", where, -0.5, place="[controller]", high=0.0, high_open=True)
    k_for = number(ctrl, "k_for", where, None, place="[controller]", low=0.0)
    sc = TeleopScenario(
        name=name, duration_s=duration, dt_s=dt, title=text(data, "title", where, ""),
        source=text(data, "source", where, ""),
        q_m0=vector(master, "q0", 6, where, d.q_m0, place="[master]"),
        q_s0=vector(slave, "q0", 7, where, d.q_s0, place="[slave]"),
        master_inertia=vector(master, "inertia", 6, where, d.master_inertia, place="[master]"),
        master_viscous=number(master, "viscous", where, d.master_viscous, place="[master]", low=0.0),
        master_deadband=vector(master, "deadband", 6, where, d.master_deadband, place="[master]"),
        slave_damping=number(slave, "damping", where, d.slave_damping, place="[slave]", low=0.0),
        hand=hand, push=push, wall=wall, virtual_walls=tuple(vwalls), orientation_error=oe, preload=pl,
        gains_master=_gains(ctrl, "gains_master", where), gains_slave=_gains(ctrl, "gains_slave", where),
        reflection=reflection, k_for=k_for, holds=holds,
    )
    if any(i <= 0 for i in sc.master_inertia):
        raise InvalidInputError(f"{where}: [master] inertia = {list(sc.master_inertia)} must be > 0 for every "
                                "joint (kg m^2)")
    if any(not 0.0 <= b <= 1.0 for b in sc.master_deadband):
        raise InvalidInputError(f"{where}: [master] deadband = {list(sc.master_deadband)} must be fractions of full "
                                "scale in [0, 1]")
    try:
        sc.controller()  # the registration and limits must make a controller
    except InvalidInputError as exc:
        raise InvalidInputError(f"{where}: {exc}") from None
    check_teleop_stiffness(sc, where)
    return sc


def check_teleop_work(where: str, duration_s: float, dt_s: float) -> None:
    """Refuse a run whose cycles (``duration_s / dt_s``) cannot fit in memory or the time budget."""
    steps = duration_s / dt_s + 1.0 if dt_s > 0 else math.inf
    check_work(where, "duration_s / dt_s", steps, bytes_per_step=BYTES_PER_STEP, seconds_per_step=SECONDS_PER_STEP,
               fix="shorten duration_s or lengthen dt_s")


def teleop_stiffness_limits(sc: TeleopScenario) -> list[dict]:
    """Each arm's springs against the explicit integration's stability limit, at the homes.

    One entry per arm and motion (``"master translation"``, ``"master rotation"``,
    ``"slave translation"``, ``"slave rotation"``, and the joint dampers): the springs and
    dampers acting on that tool summed as if in one direction (``parts``), the tool's
    effective mass or inertia in its lightest direction at the home configuration
    (:func:`~quatform.control.stiffness.effective_mass`), and the limit
    ``(4 m - 2 c dt) / dt^2`` (:func:`~quatform.control.stiffness.explicit_stiffness_limit`).
    The Euler-parameter controller's rotational springs count ``kp_rot / 4`` N m/rad (its
    small-angle stiffness).
    """
    M, S = KRAFT_MASTER, PANDA_SLAVE
    q_m, q_s = np.asarray(sc.q_m0, float), np.asarray(sc.q_s0, float)
    I_inv = np.diag(1.0 / np.asarray(sc.master_inertia, float))
    J_m, J_s = M.jacobian(q_m), S.arm.jacobian(q_s)
    M_s = S.mass_matrix(q_s)
    Ms_inv = np.linalg.inv(M_s)
    gm, gs, h = sc.gains_master, sc.gains_slave, sc.hand
    springs = {
        "master translation": (effective_mass(J_m[0:3], I_inv), "kg", "N/m", "N s/m", [
            ("[controller.gains_master] kp_pos", gm.kp_pos, gm.kv_pos), ("[hand] stiffness", h.stiffness, h.damping)]
            + [(f"[[virtual_walls]] #{i + 1} resist_force_n / thickness_m", w.stiffness, w.damping)
               for i, w in enumerate(sc.virtual_walls)]),
        "master rotation": (effective_mass(J_m[3:6], I_inv), "kg m^2", "N m/rad", "N m s/rad", [
            ("[controller.gains_master] kp_rot / 4", gm.kp_rot / 4, gm.kv_rot / 4),
            ("[hand] rot_stiffness", h.rot_stiffness, h.rot_damping)]),
        "slave translation": (effective_mass(J_s[0:3], Ms_inv), "kg", "N/m", "N s/m", [
            ("[controller.gains_slave] kp_pos", gs.kp_pos, gs.kv_pos)]
            + ([("[wall] stiffness", sc.wall.stiffness, sc.wall.damping)] if sc.wall is not None else [])
            + ([("[push] stiffness", sc.push.stiffness, sc.push.damping)] if sc.push is not None else [])),
        "slave rotation": (effective_mass(J_s[3:6], Ms_inv), "kg m^2", "N m/rad", "N m s/rad", [
            ("[controller.gains_slave] kp_rot / 4", gs.kp_rot / 4, gs.kv_rot / 4)]),
        # joint dampers alone: c dt < 2 m on the lightest joint (mode) of each arm
        "master joints": (float(np.min(sc.master_inertia)), "kg m^2", "N m/rad", "N m s/rad",
                          [("[master] viscous", 0.0, sc.master_viscous)]),
        "slave joints": (float(np.linalg.eigvalsh(M_s)[0]), "kg m^2", "N m/rad", "N m s/rad",
                         [("[slave] damping", 0.0, sc.slave_damping)]),
    }
    out = []
    for what, (m, mu, ku, cu, parts) in springs.items():
        k, c = sum(p[1] for p in parts), sum(p[2] for p in parts)
        out.append({"what": what, "mass": float(m), "mass_unit": mu, "stiffness": k, "damping": c, "parts": parts,
                    "limit": float(explicit_stiffness_limit(m, c, sc.dt_s)), "units": (ku, cu)})
    return out


def check_teleop_stiffness(sc: TeleopScenario, where: str = "") -> None:
    """Refuse springs or dampers beyond the explicit integration's stability limit.

    Every spring of the scenario (the controllers', the hand's, the push's, the contact wall's
    and the virtual walls') acts through an explicit step of ``dt_s`` (the digital controller's
    zero-order hold and the simulator's semi-implicit Euler step): beyond
    ``k dt^2 + 2 c dt < 4 m`` (:func:`teleop_stiffness_limits`) the run diverges and flings
    the arm (a 1e10 N/m wall threw the slave 1.38 m before this check).
    """
    where = where or sc.name
    for e in teleop_stiffness_limits(sc):
        if e["stiffness"] <= e["limit"] and e["limit"] > 0.0:
            continue
        ku, cu = e["units"]
        big = max(e["parts"], key=lambda p: p[1] if e["stiffness"] > 0 else p[2])
        raise InvalidInputError(
            f"{where}: {big[0]} = {big[1]:.3g} {ku} is beyond the stability limit of the {1 / sc.dt_s:g} Hz explicit "
            f"integration: on the {e['what']} (effective mass {e['mass']:.3g} {e['mass_unit']} at home) springs of "
            f"{e['stiffness']:.3g} {ku} in all with dampers of {e['damping']:.3g} {cu} need k dt^2 + 2 c dt < 4 m, "
            f"i.e. k < {max(e['limit'], 0.0):.3g} {ku}; lower it or dt_s (docs/derivations.md)")
