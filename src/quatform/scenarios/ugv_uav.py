"""The ``ugv-uav`` scenario kind: seed 001 §5's Pioneer + Bebop runs through the one pipeline.

Scenarios layer. A scenario (TOML, ``kind = "ugv-uav"``) gives the cluster path (circle or
lemniscate of the UGV, eqs. (5.1)-(5.7)), the UAV's place relative to the UGV (over it,
eq. (5.3); or in front of it at platform level, then over it), the robots' limits and the
measurement: motion-capture rate, noise and latency, and the Bebop's odometry period
(200 ms), and the world (``profile``: ideal, or the thesis's lab,
:mod:`quatform.scenarios.ugv_uav_profiles`). :class:`UgvUavKind` builds the
:class:`~quatform.scenarios.base.Experiment` that :func:`quatform.sim.simulate` runs: the
plant (:class:`~quatform.sim.plants.ugv_uav.UgvUavPlant`, integrated every ``dt_s``), the motion capture (:class:`~quatform.sim.measurement.MotionCapture`),
the controller of Fig. 18 (every ``control_period_s``, zero-order hold) and the cluster
reference of each tick (NaN where the description cannot express it: the controller then
holds, braking). ``finish`` adds the derived channels (:data:`DERIVED_CHANNELS`) and
``metrics`` reads the finished log (:func:`ugv_uav_metrics`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from .. import checks
from ..algebra import q_angle_between, wrap_angle
from ..control import Reference, UgvUavController
from ..control.ugv_uav import BEBOP_COMMAND, PSI_B, PSI_P, UAV_XY_COMMAND, UAV_XYZ, UGV_XY, V_P
from ..errors import InvalidInputError, NonFiniteError, UnreachableError
from ..formations import FORMATIONS, SPHERICAL_VARIABLES, UGV_UAV_LAYOUT, UGV_UAV_VARIABLES, UgvUavSpherical
from ..robots import Bebop
from ..sim.log import Channel, Log
from ..sim.measurement import MotionCapture
from ..sim.metrics import SINGULAR_THRESHOLD
from ..sim.plants.ugv_uav import PioneerBebopPlant
from . import KINDS
from .base import Experiment, Option, ScenarioKind, finish_worlds, world_meta
from .ugv_uav_profiles import DEFAULT_PROFILE, PROFILES, profile_named

__all__ = ["UgvUavScenario", "UgvUavKind", "UGV_UAV_KIND", "UGV_UAV_FORMATIONS", "UGV_UAV_PHYSICS",
           "UGV_UAV_COLUMNS", "UGV_UAV_CSV_CHANNELS", "DERIVED_CHANNELS", "check_ugv_uav_scenario",
           "ugv_uav_scenario_from_dict", "ugv_uav_metrics", "simulate_ugv_uav", "ugv_uav_experiment",
           "mujoco_experiment"]

#: Named entries, computed once from the controller's measured layout and the descriptions'
#: variables: the UGV's control point (x, y) and the UAV's position among the measured values
#: (index arrays: the gathered copies keep the memory order the metrics' reductions round in,
#: see :func:`_finish`), the UGV's (x, y) in the robot state, the robots on the layout's robot
#: axis, and the chart's beta_c.
_UGV_XY_AT, _UAV_XYZ_AT = (np.arange(s.start, s.stop) for s in (UGV_XY, UAV_XYZ))
_UGV_R_XY = slice(UGV_UAV_LAYOUT.names.index("x_p"), UGV_UAV_LAYOUT.names.index("y_p") + 1)
_UGV, _UAV = range(UGV_UAV_LAYOUT.n)
_BETA_C = [v.name for v in SPHERICAL_VARIABLES].index("beta_c")


def _of_kind(variables, kind: str):
    """The entries of ``variables`` of ``kind`` (consecutive): a slice, or None when none is."""
    idx = [i for i, v in enumerate(variables) if v.kind == kind]
    return slice(idx[0], idx[-1] + 1) if idx else None


#: Errors after the transient beyond these mean the formation lost the reference.
LOST_UGV_M = 0.1
LOST_UAV_M = 0.4

#: The three descriptions of seed 001 by name (the ``formation`` option): the ``ugv-uav-*``
#: entries of the formation registry (configured instances), in its order (spherical,
#: restricted, quaternion).
UGV_UAV_FORMATIONS = {name.removeprefix("ugv-uav-"): F for name, F in FORMATIONS.items()
                      if name.startswith("ugv-uav-")}
#: Where a run's robots live (the ``physics`` option): the robots' models or MuJoCo physics.
UGV_UAV_PHYSICS = ("kinematic", "mujoco")

#: Channels ``finish`` adds to the simulated log (each ``(T, k)``; column names in brackets):
#: ``r_true`` (x_p ... z_b: true robot positions, the UGV at the platform height), ``r_des``
#: (``*_des``: desired), ``r_measured`` (``*_meas``: the positions the controller used, held
#: frames repeated, NaN where none), ``c_des`` (the description's variables + ``_des``;
#: NaN where it cannot express the reference), ``c_continuous`` (the description recovered
#: from ``r_measured``, each sample continued from the previous), ``e`` and ``e_des``
#: (``euclid_*``: the spherical variables recovered through the description, and desired),
#: ``singularity`` (``singularity_measure``; NaN where the description cannot express the
#: robots), ``reachable`` (1 where the description could express the reference), and the
#: time-series views ``ts_*`` that give ``timeseries.csv`` its columns.
DERIVED_CHANNELS = ("r_true", "r_des", "r_measured", "c_des", "c_continuous", "e", "e_des", "singularity",
                    "reachable")
#: Channels of ``timeseries.csv``, in order (with ``t`` first: the recorded columns).
UGV_UAV_CSV_CHANNELS = ("ts_robots", "ts_headings", "ts_cluster", "ts_chart", "ts_command", "singularity", "no_frame")

#: Columns of the comparison table: (metrics key, header, format). The errors count only the
#: samples whose reference the description can express (:func:`ugv_uav_metrics`); the time it
#: cannot (``unreachable_reference_s``) has its own column, and the headers say so.
UGV_UAV_COLUMNS = (
    ("formation", "formation", "{}"),
    ("unreachable_reference_s", "unreachable ref. (s)", "{:.1f}"),
    ("first_singular_time_s", "singular at (s)", "{:.2f}"),
    ("max_ugv_position_error_m", "UGV err, reachable (m)", "{:.3f}"),
    ("max_uav_position_error_m", "UAV err, reachable (m)", "{:.3f}"),
    ("max_uav_yaw_error_rad", "UAV yaw err, reachable (rad)", "{:.3f}"),
    ("max_unexplained_cluster_jump", "state jump", "{:.1e}"),
    ("mocap_dropped_frames", "mocap dropped", "{}"),
    ("mocap_rejected_frames", "mocap rejected", "{}"),
    ("nonfinite_commands", "NaN cmds", "{}"),
)


def _chart_rows(values: dict, shape: tuple) -> np.ndarray:
    """The chart's variables (:data:`SPHERICAL_VARIABLES`) from ``{name: value}`` (arrays of
    ``shape`` or numbers; a variable not named is 0), shape ``(*shape, 6)``."""
    return np.stack([np.broadcast_to(np.asarray(values.get(v.name, 0.0), dtype=float), shape)
                     for v in SPHERICAL_VARIABLES], axis=-1)


@dataclass(frozen=True)
class UgvUavScenario:
    """A seed 001 experiment (see ``docs/scenarios.md``)."""

    name: str
    duration_s: float
    path: str = "circle"  # "circle" (5.1) or "lemniscate" (5.4)
    r_x: float = 1.0
    r_y: float = 1.0
    omega: float = math.pi / 15
    center: tuple = (0.0, 0.0, 0.0)
    d_c: float = 1.5
    uav_front_until_s: float = 0.0  # §5.3: UAV in front at platform level until this time
    title: str = ""
    source: str = ""
    dt_s: float = 0.005
    control_period_s: float = 0.03  # a whole multiple of dt_s
    mocap_rate_hz: float = 100.0
    mocap_noise_m: float = 0.0
    mocap_noise_rad: float = 0.0
    mocap_latency_s: float = 0.0
    odometry_period_s: float = 0.2
    seed: int = 0
    max_fraction: float = 1.0
    transient_s: float = 20.0
    switch_transient_s: float = 15.0  # after the front -> over switch of §5.3
    uav_start: tuple = (0.0, -0.6, -0.3)  # from the UGV's control point in its frame (x ahead, y left); on the floor
    floor_below_platform_m: float = 0.3  # the UGV's landing platform is z0; the floor is below
    mocap_dropout_rate: float = 0.0  # probability that a motion-capture frame is lost (NaN)
    mocap_glitch_rate: float = 0.0  # probability that a frame reads the UAV's marker at the UGV
    mocap_max_hold_s: float = 0.5  # longest the controller holds the last good frame, then stops
    gains: dict = field(default_factory=dict)
    #: The world (:data:`~quatform.scenarios.ugv_uav_profiles.PROFILES`): its keys' values
    #: stand in for the defaults of the keys the file does not set.
    profile: str = DEFAULT_PROFILE
    pioneer_accel_m_s2: float = 0.0  # the Pioneer's largest linear acceleration, m/s^2 (0: none, it follows at once)
    pioneer_accel_rad_s2: float = 0.0  # ... and angular, rad/s^2 (both or neither)

    @property
    def pioneer_accel(self):
        """``(m/s^2, rad/s^2)``: the Pioneer's acceleration limits, or None (it follows its commands at once)."""
        if self.pioneer_accel_m_s2 > 0 and self.pioneer_accel_rad_s2 > 0:
            return (self.pioneer_accel_m_s2, self.pioneer_accel_rad_s2)
        return None

    def e_reference(self, t):
        """Desired spherical variables and rates (``x_c, y_c, z_c, rho_c, alpha_c, beta_c``), (T, 6)."""
        t = np.asarray(t, dtype=float)
        w = self.omega
        cx, cy, cz = self.center
        if self.path == "circle":  # (5.1)-(5.2), (5.6)-(5.7)
            x, y = self.r_x * np.sin(w * t) + cx, self.r_y * np.cos(w * t) + cy
            xd, yd = w * self.r_x * np.cos(w * t), -w * self.r_y * np.sin(w * t)
            xdd, ydd = -w * w * self.r_x * np.sin(w * t), -w * w * self.r_y * np.cos(w * t)
        elif self.path == "lemniscate":  # (5.4)-(5.5)
            x, y = self.r_x * np.sin(w * t) + cx, self.r_y * np.sin(2 * w * t) + cy
            xd, yd = w * self.r_x * np.cos(w * t), 2 * w * self.r_y * np.cos(2 * w * t)
            xdd, ydd = -w * w * self.r_x * np.sin(w * t), -4 * w * w * self.r_y * np.sin(2 * w * t)
        else:
            raise InvalidInputError(f"path must be 'circle' or 'lemniscate', got {self.path!r}")
        front = t < self.uav_front_until_s
        heading = np.unwrap(np.arctan2(yd, xd)) if t.ndim else np.arctan2(yd, xd)
        e = {"x_c": x, "y_c": y, "z_c": cz, "rho_c": self.d_c,
             "alpha_c": np.where(front, heading, 0.0),  # §5.3: alpha_c = atan2(y_dot, x_dot), beta_c = 0
             "beta_c": np.where(front, 0.0, 0.5 * np.pi)}  # over the UGV: beta_c = 90 deg, (5.3)
        ed = {"x_c": xd, "y_c": yd, "alpha_c": np.where(front, (xd * ydd - yd * xdd) / (xd * xd + yd * yd), 0.0)}
        return _chart_rows(e, t.shape), _chart_rows(ed, t.shape)

    def controller(self, formation: str, bebop: Bebop | None = None, **options) -> UgvUavController:
        """The seed 001 controller for ``formation``; ``bebop``: the UAV model it compensates
        (default: Table 2's ``K1..K8`` with this scenario's ``max_fraction``); ``options``
        override the scenario's gains."""
        if formation not in UGV_UAV_FORMATIONS:
            raise InvalidInputError(f"unknown formation {formation!r}; choose {', '.join(UGV_UAV_FORMATIONS)}")
        cz = self.center[2]
        arena = ((-3.0, 3.0), (-2.0, 2.0), (cz - self.floor_below_platform_m, cz - self.floor_below_platform_m + 3.0))
        try:
            bebop = bebop if bebop is not None else Bebop(max_fraction=self.max_fraction)
            return UgvUavController(UGV_UAV_FORMATIONS[formation], bebop=bebop, z_ugv=cz, arena=arena,
                                    **{"max_hold_s": self.mocap_max_hold_s, **self.gains, **options})
        except TypeError as exc:
            raise InvalidInputError(f"scenario {self.name}: [gains]: {exc}") from None


# --------------------------------------------------------------------------- the run


def _reachable(F, e, ed, t):
    """Cluster references and rates where the description can express them (NaN rows
    elsewhere), the mask of those samples, the first time it cannot, and why."""
    try:
        c, cd = F.from_chart(e, ed)
        return c, cd, np.ones(len(t), dtype=bool), None, ""
    except UnreachableError as exc:
        message = str(exc)
    ok = np.ones(len(t), dtype=bool)
    for k in range(len(t)):
        try:
            F.from_chart(e[k])
        except UnreachableError:
            ok[k] = False
    c, cd = np.full((len(t), F.n_c), np.nan), np.full((len(t), F.n_c), np.nan)
    if ok.any():
        c[ok], cd[ok] = F.from_chart(e[ok], ed[ok])
    return c, cd, ok, float(t[np.argmin(ok)]), message


def _initial_state(sc: UgvUavScenario, e0, ed0) -> np.ndarray:
    """The plant's 11 values at t = 0: the UGV on the path heading along it, the UAV on the
    ground at ``uav_start`` in the UGV's frame (x ahead, y to its left: (0, -0.6) is 0.6 m
    to its right), at rest."""
    heading0 = math.atan2(ed0[1], ed0[0])
    ch, sh = math.cos(heading0), math.sin(heading0)
    sx, sy = float(sc.uav_start[0]), float(sc.uav_start[1])
    return np.r_[e0[0], e0[1], heading0, e0[0] + ch * sx - sh * sy, e0[1] + sh * sx + ch * sy,
                 sc.center[2] + sc.uav_start[2], heading0, np.zeros(4)]


def _ticks(sc: UgvUavScenario):
    """Plant steps per control tick and the control ticks, s."""
    steps = max(1, int(round(sc.control_period_s / sc.dt_s)))
    n = int(sc.duration_s / (steps * sc.dt_s)) + 1
    return steps, np.arange(n) * steps * sc.dt_s


def ugv_uav_experiment(sc: UgvUavScenario, formation: str = "quaternion", *, plant=None, bebop: Bebop | None = None,
                       physics: str = "kinematic", **controller_options) -> Experiment:
    """The run of Fig. 18 on scenario ``sc`` with the description ``formation``.

    Parameters
    ----------
    sc : UgvUavScenario
    formation : str
        A key of :data:`UGV_UAV_FORMATIONS`.
    plant : callable ``(x0, floor) -> plant``, optional
        Another plant than the Pioneer and Bebop models (MuJoCo physics) made from the
        models' start ``x0`` (11 values) and the floor height ``floor``, m; the run starts
        from its own ``plant.x0``.
    bebop : Bebop, optional
        The UAV model the controller compensates (default: Table 2's, the scenario's
        ``max_fraction``).
    physics : str
        What moves the robots, as the log's meta and the figures name it.
    **controller_options
        Override the scenario's ``[gains]``.
    """
    check_ugv_uav_scenario(sc)
    for key in ("compensation", "feedforward"):  # switches: a string such as "no" would read as on
        if key in controller_options and not isinstance(controller_options[key], bool | np.bool_):
            raise InvalidInputError(f"{key} must be true or false (or left out: the scenario's), got "
                                    f"{controller_options[key]!r}")
    ctrl = sc.controller(formation, bebop=bebop, **controller_options)
    F = ctrl.formation
    substeps, times = _ticks(sc)
    e_des, ed_des = sc.e_reference(times)
    c_des, cd_des, reachable, unreachable_at, message = _reachable(F, e_des, ed_des, times)
    floor = sc.center[2] - sc.floor_below_platform_m
    x0 = _initial_state(sc, e_des[0], ed_des[0])
    if plant is None:
        plant_ = PioneerBebopPlant(ctrl.pioneer, ctrl.bebop, floor, sc.pioneer_accel)
        x0 = plant_.initial_state(x0)
    else:
        plant_ = plant(x0, floor)
        x0 = plant_.x0
    mocap = MotionCapture(sc.mocap_rate_hz, sc.mocap_noise_m, sc.mocap_noise_rad, sc.mocap_latency_s,
                          sc.odometry_period_s, sc.seed, sc.mocap_dropout_rate, sc.mocap_glitch_rate, sc.center[2])

    def reference(k):
        # NaN where the description cannot express the reference: the controller holds (brakes)
        return Reference(c_des[k], cd_des[k])

    meta = {"scenario": sc, "formation": formation, "physics": physics, "profile": sc.profile,
            "uav_model_k": tuple(ctrl.bebop.k),
            "unreachable_at": unreachable_at, "unreachable_message": message}

    def finish(log: Log) -> Log:
        # a batch: world by world (finish_worlds), each as its run alone, the sample-by-sample
        # continuation of the recovered formation computed for every world at once
        if not log.batch_shape:
            return _finish(log, F, sc, e_des, c_des, reachable)
        c_cont = _continued(F, _measured_robots(log["used"], sc), c_des, reachable)
        return finish_worlds(log, lambda world: _finish(world, F, sc, e_des, c_des, reachable,
                                                        c_cont[(slice(None),) + world.meta["world"]]))

    return Experiment(sc, formation, plant_, ctrl, reference, times, x0, sc.dt_s, substeps, mocap, finish,
                      ugv_uav_metrics, UGV_UAV_CSV_CHANNELS, meta)


def simulate_ugv_uav(sc: UgvUavScenario, formation: str = "quaternion", progress=None, **options) -> Log:
    """The finished log of :func:`ugv_uav_experiment` (same keywords)."""
    return ugv_uav_experiment(sc, formation, **options).run(progress)


def _interleaved(name, pairs, n: int) -> Channel:
    """A time-series view of ``n`` samples: ``(column, data (n,))`` pairs side by side in one channel."""
    data = np.stack([d for _, d in pairs], axis=-1) if pairs else np.zeros((n, 0))
    return Channel(name, tuple(c for c, _ in pairs), data)


def _paired(name, variables, meas, des, prefix="") -> Channel:
    """``v, v_des`` for each variable: the measured and desired columns interleaved."""
    pairs = []
    for i, v in enumerate(variables):
        pairs += [(prefix + v.name, meas[:, i]), (prefix + v.name + "_des", des[:, i])]
    return _interleaved(name, pairs, len(meas))


def _measured_robots(used, sc: UgvUavScenario):
    """The robots' points as the controller used them (``used`` ``(T, *batch, 11)``; the UGV
    at the platform height): ``(T, *batch, 6)``, NaN where it had none."""
    z = np.full(used.shape[:-1], float(sc.center[2]))
    return np.concatenate([used[..., _UGV_XY_AT], z[..., None], used[..., _UAV_XYZ_AT]], axis=-1)


def _continued(F, r_meas, c_des, reachable):
    """The formation recovered from ``r_meas`` (``(T, *batch, 6)``), each sample continued from
    the world's previous one (from the reference ``c_des`` where the previous has none and the
    reference is reachable; NaN where the controller had no measurement or the description
    cannot express it): ``(T, *batch, n_c)``, every world of a sample in one call of
    ``F.forward`` per kind of hint."""
    n = r_meas.shape[0]
    c = np.full(r_meas.shape[:-1] + (F.n_c,), np.nan)
    finite = np.all(np.isfinite(r_meas), axis=-1)
    ok = finite & ~F.outside(np.where(finite[..., None], r_meas, 0.0))
    for k in range(n):
        if not ok[k].any():
            continue
        after = ok[k] & ok[k - 1] if k else np.zeros_like(ok[k])  # continued from the previous sample
        fresh = ok[k] & ~after
        if after.any():
            c[k][after] = F.forward(r_meas[k][after], near_c=c[k - 1][after])
        if fresh.any():
            c[k][fresh] = F.forward(r_meas[k][fresh], near_c=c_des[k] if reachable[k] else None)
    return c


def _finish(log: Log, F, sc: UgvUavScenario, e_des, c_des, reachable, c_cont=None) -> Log:
    """The simulated ``log`` with :data:`DERIVED_CHANNELS`, the time-series views and the
    meta ``stopped_at`` / ``stop_reason`` (from the controller's final state); ``c_cont``: the
    continued formation (:func:`_continued`) when computed already."""
    n = len(log.t)
    x = log["state"]
    z = np.full(n, float(sc.center[2]))
    # the robots' points (the UGV at the platform height), built column by column as here:
    # the memory order of these arrays sets the summation order of the metrics' dot products,
    # and their arccos near 1 (orientation error, the turned angle of _cluster_jumps) turns a
    # 1-ulp change of a dot product into ~1e-8 rad, beyond the 1e-9 regression tolerance
    # (docs/derivations.md, "UGV-UAV runs (seed 001)")
    r_true = np.c_[x[:, UGV_XY], z, x[:, UAV_XYZ]]
    e_des, c_des, reachable = e_des[:n], c_des[:n], reachable[:n]
    r_des = UgvUavSpherical().inverse(e_des) if n else np.zeros((0, 6))
    cluster = log["cluster"]
    try:
        e_rec = F.to_chart(cluster, near_e=e_des, r=r_true) if n else np.zeros((0, 6))
    except NonFiniteError:  # samples before the controller's first good frame: NaN there
        e_rec = np.full((n, 6), np.nan)
        have = np.all(np.isfinite(cluster), axis=1)
        if have.any():
            e_rec[have] = F.to_chart(cluster[have], near_e=e_des[have], r=r_true[have])
    # the singularity measure where the description exists (NaN where it cannot express the robots)
    sing = np.full(n, np.nan)
    inside = ~F.outside(r_true)
    for rows, hint in ((inside & reachable, c_des), (inside & ~reachable, None)):
        if rows.any():
            sing[rows] = F.singularity_measure(r_true[rows], near_c=None if hint is None else hint[rows])
    # the formation as recovered from the measurements used, each sample continued from the
    # last (NaN where the controller had none or the description cannot express them)
    used = log["used"]
    r_meas = np.c_[used[:, _UGV_XY_AT], z, used[:, _UAV_XYZ_AT]]
    if c_cont is None:
        c_cont = np.full((n, F.n_c), np.nan)
        ok = np.all(np.isfinite(r_meas), axis=1) & ~F.outside(np.where(np.isfinite(r_meas), r_meas, 0.0))
        for k in range(n):
            if ok[k]:
                hint = c_cont[k - 1] if k and ok[k - 1] else (c_des[k] if reachable[k] else None)
                c_cont[k] = F.forward(r_meas[k], near_c=hint)
    stopped = np.flatnonzero(log["stopped"][:, 0] > 0.5)
    rvars, cvars = UGV_UAV_VARIABLES, F.variables
    chans = [
        Channel("r_true", [v.name for v in rvars], r_true),
        Channel("r_des", [v.name + "_des" for v in rvars], r_des),
        Channel("r_measured", [v.name + "_meas" for v in rvars], r_meas),
        Channel("c_des", [v.name + "_des" for v in cvars], c_des),
        Channel("c_continuous", [v.name + "_continuous" for v in cvars], c_cont),
        Channel("e", ["euclid_" + v.name for v in SPHERICAL_VARIABLES], e_rec),
        Channel("e_des", ["euclid_" + v.name + "_des" for v in SPHERICAL_VARIABLES], e_des),
        Channel("singularity", ["singularity_measure"], sing[:, None]),
        Channel("reachable", ["reachable"], reachable[:, None].astype(float)),
        # the views of timeseries.csv (its columns since seed 001 runs were first written)
        _paired("ts_robots", rvars, r_true, r_des),
        _interleaved("ts_headings", [("psi_p", x[:, PSI_P]), ("psi_b", x[:, PSI_B]), ("psi_b_des", x[:, PSI_P])], n),
        # the spherical description's variables are the chart's: written once, as euclid_*
        _paired("ts_cluster", () if isinstance(F, UgvUavSpherical) else cvars, cluster, c_des),
        _paired("ts_chart", SPHERICAL_VARIABLES, e_rec, e_des, prefix="euclid_"),
        Channel("ts_command", ["u_" + c for c in log.columns("command")], log["command"]),
    ]
    # why it stopped: the controller's final state (UgvUavState) says (a batch's: this world's)
    reason = ""
    if stopped.size:
        reason = log.meta["controller_state"].stop_reason
        world = log.meta.get("world")
        if world is not None and isinstance(reason, np.ndarray):
            reason = str(reason[world])
    return log.with_channels(*chans, stopped_at=float(log.t[stopped[0]]) if stopped.size else None,
                             stop_reason=reason)


# --------------------------------------------------------------------------- metrics


def ugv_uav_metrics(log: Log) -> dict:
    """metrics.json of a finished UGV-UAV log (errors from the true robot poses, after the transient)."""
    sc, formation = log.meta["scenario"], log.meta["formation"]
    t = log.t
    n = len(t)
    # each channel in the memory order one world's run has it (r_measured: Fortran, built by
    # np.c_ of its columns; the rest C): a world of a batch (Log.world) is a strided view,
    # whose reductions (einsum, norm) may round differently, and the arccos of a dot product
    # near 1 turns one ulp into ~1e-8 rad (see _finish)
    log = log.with_channels(*(Channel(c.name, c.columns, (np.asfortranarray if c.name == "r_measured" else
                                                          np.ascontiguousarray)(c.data))
                              for c in log.channels.values()))
    x = log["state"]
    r_true, r_des = log["r_true"], log["r_des"]
    reachable = log["reachable"][:, 0] > 0.5
    p_true, p_des = UGV_UAV_LAYOUT.positions(r_true), UGV_UAV_LAYOUT.positions(r_des)  # (T, 2, 3): UGV, UAV
    ugv_err = np.linalg.norm(r_true[:, _UGV_R_XY] - r_des[:, _UGV_R_XY], axis=1)
    uav_err = np.linalg.norm(p_true[:, _UAV] - p_des[:, _UAV], axis=1)
    d_true, d_des = p_true[:, _UAV] - p_true[:, _UGV], p_des[:, _UAV] - p_des[:, _UGV]
    sep = np.linalg.norm(d_true, axis=1)
    cosang = np.einsum("ij,ij->i", d_true, d_des) / np.maximum(sep * np.linalg.norm(d_des, axis=1), 1e-300)
    orient = np.arccos(np.clip(cosang, -1, 1))
    yaw_err = np.abs(wrap_angle(x[:, PSI_P] - x[:, PSI_B]))
    # errors count after the take-off transient, outside the settle window after each
    # designed switch of the reference (§5.3: front -> over at uav_front_until_s; a planned
    # change is not a loss), and while the controller still runs (not after a safe stop)
    settle = _settle_window(t, sc, reachable)
    late = (t >= sc.transient_s) & ~settle & reachable
    stopped_at = world_meta(log, "stopped_at")
    if stopped_at is not None:
        late &= t < stopped_at
    lost = late & ((ugv_err > LOST_UGV_M) | (uav_err > LOST_UAV_M))
    singularity = log["singularity"][:, 0]
    singular = singularity < SINGULAR_THRESHOLD  # NaN (outside the description): not singular
    frames = np.rint(log["frame"][:, 0])
    u = log["command"]
    dt_ctrl = float(t[1] - t[0]) if n > 1 else None

    def mx(a, mask=late):
        return float(a[mask].max()) if np.any(mask) else None

    jumps, explained = _cluster_jumps(log["c_continuous"], log["r_measured"], formation)
    e, e_des = log["e"], log["e_des"]
    unreachable_at = log.meta["unreachable_at"]
    return {
        "scenario": sc.name,
        "profile": sc.profile,
        "controller": f"ugv-uav-{formation}",
        "formation": formation,
        "duration_s": float(t[-1]) if n else 0.0,
        "transient_s": sc.transient_s,
        "dt_s": sc.dt_s,
        "control_period_s": dt_ctrl if dt_ctrl is not None else sc.control_period_s,
        "metrics_from_s": sc.transient_s,
        "unreachable_reference": unreachable_at is not None,
        "first_unreachable_time_s": unreachable_at,
        "unreachable_message": log.meta["unreachable_message"] or None,
        "unreachable_reference_s": float((~reachable).sum() * dt_ctrl) if dt_ctrl is not None else 0.0,
        "singularity_detected": bool(singular.any()),
        "first_singular_time_s": float(t[np.argmax(singular)]) if singular.any() else None,
        "min_singularity_measure": float(np.nanmin(singularity)) if np.isfinite(singularity).any() else None,
        "reference_lost": bool(lost.any()),
        "first_lost_time_s": float(t[np.argmax(lost)]) if lost.any() else None,
        "max_cluster_position_error_m": mx(ugv_err),
        "max_shape_error_m": mx(np.abs(sep - sc.d_c)),
        "max_orientation_error_rad": mx(orient),
        "max_robot_position_error_m": mx(np.maximum(ugv_err, uav_err)),
        "max_ugv_position_error_m": mx(ugv_err),
        "max_uav_position_error_m": mx(uav_err),
        "max_uav_yaw_error_rad": mx(yaw_err),
        "max_robot_yaw_error_rad": mx(yaw_err),
        "max_command_speed_m_s": float(np.abs(u[:, V_P]).max()) if n else 0.0,
        "measured_outside_description_s": float((log["outside"][:, 0] > 0.5).sum() * dt_ctrl)
        if dt_ctrl is not None else 0.0,
        "min_robot_separation_m": float(sep.min()) if len(sep) else None,
        "max_recovered_euclidean_error_rad": mx(np.abs(wrap_angle(e[:, _BETA_C] - e_des[:, _BETA_C]))),
        "max_cluster_state_jump": float(jumps.max()) if len(jumps) else 0.0,
        "max_unexplained_cluster_jump": float(np.maximum(jumps - explained, 0.0).max()) if len(jumps) else 0.0,
        "max_uav_position_error_m_at_switch": mx(uav_err, settle) if sc.uav_front_until_s > 0 else None,
        "mocap_dropped_frames": int((frames == 1).sum()),
        "mocap_rejected_frames": int((frames == 2).sum()),
        "mocap_held_frames": int((log["held"][:, 0] > 0.5).sum()),
        "no_frame_time_s": float((log["no_frame"][:, 0] > 0.5).sum() * dt_ctrl) if dt_ctrl is not None else 0.0,
        "run_stopped": stopped_at is not None,
        "run_stopped_at_s": stopped_at,
        "run_stopped_reason": world_meta(log, "stop_reason") or None,
        "nonfinite_commands": int((log["raw_finite"][:, 0] < 0.5).sum()),
        "uav_model_k": list(log.meta["uav_model_k"]),
        "max_uav_command_fraction": float(np.abs(u[:, BEBOP_COMMAND]).max()) if n else 0.0,
        "uav_command_chatter": float(np.sqrt(np.mean(np.diff(u[late][:, UAV_XY_COMMAND], axis=0) ** 2)))
        if late.sum() > 1 else 0.0,
    }


def switch_times(t, sc: UgvUavScenario, reachable) -> list[float]:
    """Times the reference changes by design: the front -> over switch of seed 001 §5.3 at
    ``uav_front_until_s``, and each return of the reference into the description
    (``reachable``: bool per sample of the times ``t``, s)."""
    times = [sc.uav_front_until_s] if sc.uav_front_until_s > 0 else []
    if len(t) > 1:
        times += [float(s) for s in t[1:][reachable[1:] & ~reachable[:-1]]]
    return sorted(set(times))


def _settle_window(t, sc, reachable):
    """Samples within ``switch_transient_s`` after a designed switch (:func:`switch_times`)."""
    out = np.zeros(len(t), dtype=bool)
    for ts in switch_times(t, sc, reachable):
        out |= (t >= ts) & (t < ts + sc.switch_transient_s)
    return out


def _cluster_jumps(c, r_measured, formation: str):
    """How much the formation recovered from the measurements (``c``, (T, n_c)) moves between
    samples, and how much of that the measured robot motion (``r_measured``, (T, 6)) explains.

    Quaternion description: the sign-invariant angle between consecutive ``q_c`` against
    the angle the measured segment turned; the Euclidean descriptions: the change of their
    angles against the same. A recovered state that is continuous has no unexplained part;
    a description that is undefined somewhere (``alpha_c`` overhead) jumps there.
    """
    if len(c) < 2:
        return np.zeros(0), np.zeros(0)
    p = UGV_UAV_LAYOUT.positions(r_measured)
    d = p[:, _UAV] - p[:, _UGV]
    u = d / np.linalg.norm(d, axis=1)[:, None]
    turned = np.arccos(np.clip(np.einsum("ij,ij->i", u[1:], u[:-1]), -1, 1))
    ok = np.all(np.isfinite(c[1:]), axis=1) & np.all(np.isfinite(c[:-1]), axis=1) & np.isfinite(turned)
    c1, c0 = c[1:][ok], c[:-1][ok]
    variables = UGV_UAV_FORMATIONS[formation].variables
    q = _of_kind(variables, "quaternion")
    if q is not None:
        jump = q_angle_between(c1[:, q], c0[:, q])
    else:
        angles = _of_kind(variables, "angle")
        jump = np.abs(wrap_angle(c1[:, angles] - c0[:, angles])).max(axis=1, initial=0.0)
    return jump, turned[ok] + 1e-9


# --------------------------------------------------------------------------- the kind


class UgvUavKind(ScenarioKind):
    """``kind = "ugv-uav"``: seed 001's Pioneer + Bebop scenarios."""

    name = "ugv-uav"
    scenario_type = UgvUavScenario
    options = (
        Option("formation", "the UGV-UAV description (Marciano 2021 §4)", tuple(UGV_UAV_FORMATIONS), "quaternion"),
        Option("physics", "the robots' models (kinematic) or MuJoCo physics", UGV_UAV_PHYSICS, "kinematic"),
        Option("mocap_noise_m", "motion-capture position noise, m (standard deviation; default: the scenario's)",
               None, None, float),
        Option("mocap_latency_s", "motion-capture latency, s (default: the scenario's)", None, None, float),
        Option("profile", "the world: ideal, or the lab of Marciano 2021 (its keys over the scenario's; default: "
               "the scenario's)", tuple(PROFILES), None),
    )
    compare_over = "formation"
    table_columns = UGV_UAV_COLUMNS

    def from_dict(self, data: dict, where: str) -> UgvUavScenario:
        return ugv_uav_scenario_from_dict(data, where)

    def experiment(self, scenario: UgvUavScenario, formation: str = "quaternion", physics: str = "kinematic",
                   mocap_noise_m: float | None = None, mocap_latency_s: float | None = None,
                   profile: str | None = None) -> Experiment:
        """The run of ``scenario`` with the description ``formation`` on ``physics``; ``profile``
        sets its keys over the scenario's (:func:`with_profile`), then the motion-capture
        overrides, checked with the scenario's own bounds."""
        for opt, value in (("formation", formation), ("physics", physics)):
            choices = next(o.choices for o in self.options if o.name == opt)
            if value not in choices:
                raise InvalidInputError(f"unknown {opt} {value!r}{checks.nearest(value, choices)}; choose "
                                        f"{', '.join(choices)}")
        if profile is not None:
            scenario = with_profile(scenario, profile)
        changes = {key: value for key, value in (("mocap_noise_m", mocap_noise_m),
                                                  ("mocap_latency_s", mocap_latency_s)) if value is not None}
        if changes:
            scenario = dataclasses.replace(scenario, **changes)
            check_ugv_uav_scenario(scenario, f"scenario {scenario.name} with --mocap-noise-m/--mocap-latency-s")
        if physics == "mujoco":
            return mujoco_experiment(scenario, formation)
        return ugv_uav_experiment(scenario, formation)


def with_profile(sc: UgvUavScenario, profile: str) -> UgvUavScenario:
    """``sc`` in the world ``profile``: the profile's keys set over the scenario's (an unknown
    name is refused in one line naming the valid ones).

    The keys ``sc``'s own profile stood in for (those still holding that profile's value)
    first go back to their defaults, so ``ideal`` over a file of ``profile = "lab"`` is the
    ideal world with the file's own keys, not the lab's world named ideal. A file key given
    the very value of its profile's is read as the profile's."""
    chosen = profile_named(profile, f"scenario {sc.name}")
    fields = UgvUavScenario.__dataclass_fields__
    own = {key: fields[key].default for key, value in PROFILES[sc.profile].values().items()
           if getattr(sc, key) == value}
    out = dataclasses.replace(sc, profile=chosen.name, **(own | chosen.values()))
    check_ugv_uav_scenario(out, f"scenario {sc.name} with profile {chosen.name!r}")
    return out


def mujoco_experiment(sc: UgvUavScenario, formation: str = "quaternion", **controller_options) -> Experiment:
    """The run of Fig. 18 on a Pioneer-like UGV and an IRIS in Bebop-like attitude mode in
    MuJoCo (:func:`quatform.sim.plants.mujoco.ugv_uav_plant`), with the same motion capture;
    the controller's compensation (4.47) uses the ``K1..K8`` identified from that quadrotor.

    The finished log's meta adds ``physics_record`` (for the picture,
    :func:`quatform.report.physics_render.render_or_fallback`) and ``physics_metrics``; the
    metrics add ``physics``, ``collisions``, ``physics_timestep_s``, ``gains``,
    ``gains_source`` and ``gains_source_note``. It does not re-run the kinematic models
    (comparing them is a compare over the ``physics`` option). ``controller_options``
    override the scenario's ``[gains]`` (``compensation=False``: no (4.47)); the recorded
    ``gains_source`` is then ``"argument"``.
    """
    from ..sim.mujoco_backend import IRIS_IDENTIFIED_K, PHYSICS_LABEL, ugv_uav_controller_gains
    from ..sim.plants.mujoco import physics_metrics, physics_record, ugv_uav_plant

    holder = {}

    def plant(x0, floor):
        holder["plant"] = made = ugv_uav_plant(sc, x0, floor, IRIS_IDENTIFIED_K)
        return made

    # the model ugv_uav_plant's uav_model is: K1..K8 identified from the simulated IRIS
    bebop = Bebop(k=tuple(IRIS_IDENTIFIED_K), max_fraction=sc.max_fraction)
    exp = ugv_uav_experiment(sc, formation, plant=plant, bebop=bebop, physics=PHYSICS_LABEL, **controller_options)
    gains, source = ugv_uav_controller_gains(exp.controller, "argument" if controller_options else "scenario")

    def finish(log: Log) -> Log:
        log = exp.finish(log)
        made = holder["plant"]
        record = physics_record(made, log, f"{sc.name}: {formation} formation", gains, source)
        return log.with_channels(physics_record=record, physics_metrics=physics_metrics(made))

    def metrics(log: Log) -> dict:
        return {**ugv_uav_metrics(log), **log.meta["physics_metrics"], **log.meta["physics_record"].metrics()}

    return dataclasses.replace(exp, finish=finish, metrics=metrics)


#: The registered kind.
UGV_UAV_KIND = KINDS[UgvUavKind.name]


# --------------------------------------------------------------------------- the reader


#: Bounds of the scenario's numbers: ``key: (low, low_open, high, high_open)``.
_NUMBER_BOUNDS = {
    "duration_s": (0.0, True, None, False),
    "r_x": (0.0, True, None, False),
    "r_y": (0.0, True, None, False),
    "omega": (None, False, None, False),  # nonzero, checked below
    "d_c": (0.0, True, None, False),
    "uav_front_until_s": (0.0, False, None, False),
    "dt_s": (0.0, True, None, False),
    "control_period_s": (0.0, True, None, False),  # >= dt_s, checked below
    "mocap_rate_hz": (0.0, True, None, False),
    "mocap_noise_m": (0.0, False, 1.0, False),  # a 1 m standard deviation is no motion capture
    "mocap_noise_rad": (0.0, False, math.pi, False),
    "mocap_latency_s": (0.0, False, None, False),
    "odometry_period_s": (0.0, True, None, False),
    "max_fraction": (0.0, True, 1.0, False),
    "transient_s": (0.0, False, None, False),
    "switch_transient_s": (0.0, False, None, False),
    "floor_below_platform_m": (0.0, False, None, False),
    "mocap_dropout_rate": (0.0, False, 1.0, True),
    "mocap_glitch_rate": (0.0, False, 1.0, True),
    "mocap_max_hold_s": (0.0, True, None, False),
    "pioneer_accel_m_s2": (0.0, False, None, False),
    "pioneer_accel_rad_s2": (0.0, False, None, False),
}
#: ``[gains]`` keys (keywords of :class:`~quatform.control.UgvUavController`) and how many
#: numbers each takes (1: a number; n > 1: a number or a list of n), or ``bool``.
_GAIN_KEYS = {"k_x": 3, "k_d": 1, "k_w": 3, "k_psi": 1, "l_d": 4, "wall_gain": 1, "wall_margin": 1,
              "derivative_filter_s": 1, "compensation": bool, "feedforward": bool}
#: Generous costs of one control tick, for :func:`quatform.checks.check_work`: the logs and
#: the post-processed arrays keep about 200 floats plus the list entries of the loop, and
#: one plant step of the Pioneer and Bebop models takes well under a millisecond.
_BYTES_PER_TICK = 4000.0
_SECONDS_PER_PLANT_STEP = 1e-3


def _gains(data, where):
    g_ = checks.table(data, "gains", where, default={})
    checks.check_keys(g_, _GAIN_KEYS, where, "[gains]", "see docs/scenarios.md; the keywords of UgvUavController")
    out = {}
    for key, n in _GAIN_KEYS.items():
        if key not in g_:
            continue
        if n is bool:
            out[key] = checks.flag(g_, key, where, place="[gains]")
        elif isinstance(g_[key], (list, tuple)) and n > 1:
            out[key] = checks.vector(g_, key, n, where, place="[gains]")
            for v in out[key]:
                checks.number({key: v}, key, where, place="[gains]", low=0.0, low_open=True)
        else:
            low_open = key not in ("wall_margin", "derivative_filter_s")
            out[key] = checks.number(g_, key, where, place="[gains]", low=0.0, low_open=low_open)
            if n > 1:
                out[key] = (out[key],) * n
    return out


def _last_sample_s(kw) -> float:
    """Time of the last control sample of a run (the last of :func:`_ticks`)."""
    steps = max(1, int(round(kw["control_period_s"] / kw["dt_s"])))
    return float(int(kw["duration_s"] / (steps * kw["dt_s"])) * steps * kw["dt_s"])


def _check_report_times(kw, where: str) -> None:
    """Refuse times that leave the report without meaning: a metrics window (after
    ``transient_s``) that holds no sample, where every error would read null (the two-robot
    rule for ``metrics_from_s``), and a §5.3 front -> over switch (``uav_front_until_s > 0``)
    that would come after the last sample, so never happen."""
    last = _last_sample_s(kw)
    for key, active, what, fix in (
            ("transient_s", True, "errors are taken after it, so no sample would be measured and every error "
             "metric would read null", "lower transient_s or lengthen duration_s"),
            ("uav_front_until_s", kw["uav_front_until_s"] > 0, "the UAV would stay in front for the whole run and "
             "the front -> over switch of Marciano 2021 §5.3 would never happen",
             "lower uav_front_until_s, or set it to 0 for no front phase")):
        if active:
            checks.check_within_run(where, key, kw[key], kw["duration_s"], last, f"{what}; {fix}")


def _scenario_fields(data, where: str, report: bool = True) -> dict:
    """The keyword arguments of :class:`UgvUavScenario` read from ``data``, each typed and
    range-checked by :mod:`quatform.checks` (one line naming the key on any mistake).

    ``report``: also refuse times that leave the report without meaning
    (:func:`_check_report_times`). A scenario file must pass; a run made in code (a few
    seconds of the dynamics in a test, no metrics) need not."""
    fields = UgvUavScenario.__dataclass_fields__
    checks.check_keys(data, set(fields) | {"kind"}, where)
    kw = {"name": checks.text(data, "name", where)}
    # the profile's values stand in for the defaults of the keys the file does not set
    kw["profile"] = checks.text(data, "profile", where, default=DEFAULT_PROFILE, choices=tuple(PROFILES))
    defaults = {key: f.default for key, f in fields.items()} | PROFILES[kw["profile"]].values()
    for key in ("title", "source"):
        kw[key] = checks.text(data, key, where, default=fields[key].default)
    kw["path"] = checks.text(data, "path", where, default=fields["path"].default, choices=("circle", "lemniscate"))
    for key, (low, low_open, high, high_open) in _NUMBER_BOUNDS.items():
        default = checks.MISSING if key == "duration_s" else defaults[key]
        kw[key] = checks.number(data, key, where, default, low=low, low_open=low_open, high=high,
                                high_open=high_open)
    if (kw["pioneer_accel_m_s2"] > 0) != (kw["pioneer_accel_rad_s2"] > 0):
        raise InvalidInputError(
            f"{where}: pioneer_accel_m_s2 = {kw['pioneer_accel_m_s2']!r} and pioneer_accel_rad_s2 = "
            f"{kw['pioneer_accel_rad_s2']!r}: give both (the Pioneer's acceleration limits) or neither (0: it "
            "follows its commands at once)")
    if kw["omega"] == 0.0:
        raise InvalidInputError(f"{where}: omega = 0.0 must be nonzero (rad/s; the path would stand still)")
    if kw["mocap_latency_s"] >= kw["duration_s"]:
        raise InvalidInputError(
            f"{where}: mocap_latency_s = {kw['mocap_latency_s']!r} must be < duration_s = {kw['duration_s']!r} "
            "(the controller would never see a frame)")
    if kw["control_period_s"] < kw["dt_s"]:
        raise InvalidInputError(f"{where}: control_period_s = {kw['control_period_s']!r} must be >= dt_s = "
                                f"{kw['dt_s']!r} (the controller runs every whole number of plant steps)")
    ratio = kw["control_period_s"] / kw["dt_s"]
    if abs(ratio - round(ratio)) > 1e-9 * max(1.0, ratio):
        raise InvalidInputError(
            f"{where}: control_period_s = {kw['control_period_s']!r} is not a whole multiple of dt_s = "
            f"{kw['dt_s']!r} ({ratio:.6g} plant steps); the controller runs every whole number of plant steps: "
            f"use control_period_s = {max(1, round(ratio)) * kw['dt_s']:.6g}")
    for key in ("center", "uav_start"):
        kw[key] = checks.vector(data, key, 3, where, default=fields[key].default)
    if kw["uav_start"][2] < -kw["floor_below_platform_m"]:
        raise InvalidInputError(
            f"{where}: uav_start z = {kw['uav_start'][2]!r} m is below the floor (floor_below_platform_m = "
            f"{kw['floor_below_platform_m']!r}); the UAV starts at or above -floor_below_platform_m")
    kw["seed"] = checks.integer(data, "seed", where, default=fields["seed"].default, low=0, high=2**63 - 1)
    kw["gains"] = _gains(data, where)
    if report:
        _check_report_times(kw, where)
    return kw


def check_ugv_uav_scenario(sc: UgvUavScenario, where: str | None = None) -> None:
    """Refuse a scenario (also one changed with :func:`dataclasses.replace`) whose values are
    out of range, and one whose run cannot fit in memory or the time budget (estimated up
    front, :func:`quatform.checks.check_work`, naming ``duration_s``)."""
    where = where or f"scenario {sc.name}"
    data = {key: getattr(sc, key) for key in UgvUavScenario.__dataclass_fields__}
    _scenario_fields(data, where, report=False)
    substeps = max(1, round(sc.control_period_s / sc.dt_s))
    plant_steps = sc.duration_s / sc.dt_s + 1  # the plant's steps; one control tick every `substeps`
    checks.check_work(where, "duration_s / dt_s", plant_steps, bytes_per_step=_BYTES_PER_TICK / substeps,
                      seconds_per_step=_SECONDS_PER_PLANT_STEP * (1 + 1 / substeps),
                      fix="shorten duration_s or lengthen dt_s (and control_period_s, a multiple of it)")


def ugv_uav_scenario_from_dict(data: dict, where: str) -> UgvUavScenario:
    """Build a :class:`UgvUavScenario` from parsed TOML (``kind = "ugv-uav"``).

    Every key is typed and range-checked (``docs/scenarios.md``); an unknown key names the
    nearest valid one; the run's memory and time are estimated up front.
    """
    sc = UgvUavScenario(**_scenario_fields(data, where))
    check_ugv_uav_scenario(sc, where)
    sc.controller("quaternion")  # the gains make a controller
    return sc


