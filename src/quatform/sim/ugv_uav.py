"""UGV-UAV scenarios of seed 001 §5: references, motion capture, the closed loop, metrics.

Sim layer. A scenario (TOML, ``kind = "ugv-uav"``) gives the cluster path (circle or
lemniscate of the UGV, eqs. (5.1)-(5.7)), the UAV's place relative to the UGV (over it,
eq. (5.3); or in front of it at platform level, then over it), the robots' limits and the
measurement: motion-capture rate, noise and latency, and the Bebop's odometry period
(200 ms). The plant is integrated every ``dt_s``; the controller runs every
``control_period_s`` on the measurements available then (zero-order hold).
"""

from __future__ import annotations

import math
from types import SimpleNamespace
from dataclasses import dataclass, field

import numpy as np

from ..algebra import q_angle_between, q_from_axis_angle, wrap_angle
from ..control import UGV_UAV_COMMAND_NAMES, Reference, UgvUavController
from .. import checks
from ..errors import InvalidInputError, UnreachableError
from ..formations import UgvUavQuaternion, UgvUavRestricted, UgvUavSpherical
from ..formations import geometry as g
from ..robots import Bebop
from .loop import History, closed_loop
from .metrics import SINGULAR_THRESHOLD

#: Errors after the transient beyond these mean the formation lost the reference.
LOST_UGV_M = 0.1
LOST_UAV_M = 0.4

__all__ = ["UgvUavScenario", "UgvUavRun", "simulate_ugv_uav", "ugv_uav_metrics", "UGV_UAV_FORMATIONS",
           "ugv_uav_scenario_from_dict"]

UGV_UAV_FORMATIONS = {"spherical": UgvUavSpherical, "restricted": UgvUavRestricted, "quaternion": UgvUavQuaternion}


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
        e = np.zeros(t.shape + (6,))
        ed = np.zeros_like(e)
        e[..., 0], e[..., 1], e[..., 2], e[..., 3] = x, y, cz, self.d_c
        ed[..., 0], ed[..., 1] = xd, yd
        front = t < self.uav_front_until_s
        heading = np.unwrap(np.arctan2(yd, xd)) if t.ndim else np.arctan2(yd, xd)
        e[..., 4] = np.where(front, heading, 0.0)  # §5.3: alpha_c = atan2(y_dot, x_dot), beta_c = 0
        ed[..., 4] = np.where(front, (xd * ydd - yd * xdd) / (xd * xd + yd * yd), 0.0)
        e[..., 5] = np.where(front, 0.0, 0.5 * np.pi)  # over the UGV: beta_c = 90 deg, (5.3)
        return e, ed

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
            return UgvUavController(UGV_UAV_FORMATIONS[formation](), bebop=bebop, z_ugv=cz, arena=arena,
                                    **{**self.gains, **options})
        except TypeError as exc:
            raise InvalidInputError(f"scenario {self.name}: [gains]: {exc}") from None


@dataclass(frozen=True)
class UgvUavRun:
    """Logged signals (T samples of the control loop): ``t``; true ``ugv`` (x, y, psi) and
    ``uav`` (x, y, z, psi, body velocities); ``measured`` robot positions (6); ``c``,
    ``c_des`` (the controller's, hinted by the reference); ``c_continuous`` (the formation
    recovered from the measurements, each sample continued from the previous); ``e``,
    ``e_des`` (spherical variables recovered through the formation, and desired);
    ``u`` (6); ``raw_finite``; ``singularity``; ``unreachable_at`` (first time the
    reference left the description's reachable set, or None); ``reachable``: per sample,
    whether it could express the reference (elsewhere the robots wait, braking, and
    ``c_des`` is NaN); ``uav_model_k``: the
    ``K1..K8`` of eq. (3.11) the controller's UAV model (its compensation (4.47)) used;
    ``mocap_frame``: per sample 0 (good), 1 (dropped, NaN) or 2 (rejected as implausible);
    ``held``: the controller used the last good frame instead; ``outside``: the measured
    robots were outside the description; ``stopped_at``, ``stop_reason``: when and why the
    controller stopped both robots (too long without a good frame), or None.
    ``measured`` holds the robot positions the controller used (held frames repeated; NaN
    where it had none)."""

    scenario: UgvUavScenario
    formation: str
    t: np.ndarray
    ugv: np.ndarray
    uav: np.ndarray
    measured: np.ndarray
    c: np.ndarray
    c_des: np.ndarray
    e: np.ndarray
    e_des: np.ndarray
    u: np.ndarray
    raw_finite: np.ndarray
    singularity: np.ndarray
    unreachable_at: float | None
    unreachable_message: str = ""
    c_continuous: np.ndarray | None = None
    uav_model_k: tuple | None = None
    mocap_frame: np.ndarray | None = None
    held: np.ndarray | None = None
    outside: np.ndarray | None = None
    stopped_at: float | None = None
    stop_reason: str = ""
    reachable: np.ndarray | None = None
    backend: str = "kinematic"


def _reachable(F, e, ed, t):
    """Cluster references and rates where the description can express them (NaN rows
    elsewhere), the mask of those samples, the first time it cannot, and why."""
    try:
        c, cd = F.from_euclidean(e, ed)
        return c, cd, np.ones(len(t), dtype=bool), None, ""
    except UnreachableError as exc:
        message = str(exc)
    ok = np.ones(len(t), dtype=bool)
    for k in range(len(t)):
        try:
            F.from_euclidean(e[k])
        except UnreachableError:
            ok[k] = False
    c, cd = np.full((len(t), F.n_c), np.nan), np.full((len(t), F.n_c), np.nan)
    if ok.any():
        c[ok], cd[ok] = F.from_euclidean(e[ok], ed[ok])
    return c, cd, ok, float(t[np.argmin(ok)]), message


class MotionCapture:
    """Seed 001 §3.2: the lab's measurements of the two robots.

    Poses come from the motion-capture system at ``rate_hz``, ``latency_s`` old, each
    position coordinate with Gaussian noise of ``noise_m``, the orientation as a quaternion
    (rotated by a random angle of standard deviation ``noise_rad``) from which the yaw is
    read; the Bebop's body velocity comes from its own odometry every ``odometry_period_s``
    (200 ms). ``read`` returns the controller's 11 values (see ``control.ugv_uav``).
    Faults for testing: each frame is lost (all NaN) with probability ``dropout_rate``, or
    else reads the UAV's marker at the UGV (at height ``ugv_z``) with ``glitch_rate``.
    """

    def __init__(self, rate_hz=100.0, noise_m=0.0, noise_rad=0.0, latency_s=0.0, odometry_period_s=0.2,
                 seed=0, dropout_rate=0.0, glitch_rate=0.0, ugv_z=0.0):
        if not (rate_hz > 0 and noise_m >= 0 and noise_rad >= 0 and latency_s >= 0 and odometry_period_s > 0
                and 0 <= dropout_rate < 1 and 0 <= glitch_rate < 1):
            raise InvalidInputError("motion capture: rate_hz, odometry_period_s > 0, noise, latency >= 0 and "
                                    "dropout_rate, glitch_rate in [0, 1)")
        self.rate, self.noise_m, self.noise_rad = rate_hz, noise_m, noise_rad
        self.latency, self.odo = latency_s, odometry_period_s
        self.rng = np.random.default_rng(seed)
        # faults from their own stream, so the noise is the same with and without them
        self.dropout_rate, self.glitch_rate, self.ugv_z = dropout_rate, glitch_rate, ugv_z
        self.fault_rng = np.random.default_rng([seed, 1])
        self.history = History(latency_s + odometry_period_s + 1.0)
        self._frame_t, self._pose = None, None

    def observe(self, t, x):
        self.history.add(t, x)

    def _orientation(self, psi):
        q = g.q_yaw(psi)
        if self.noise_rad > 0:
            axis = self.rng.normal(size=3)
            q = g.mul(q_from_axis_angle(axis / np.linalg.norm(axis), self.rng.normal(0.0, self.noise_rad)), q)
        return g.yaw_of(q)  # the lab receives a quaternion; the controllers need the yaw

    def read(self, t):
        frame_t = math.floor(t * self.rate + 1e-9) / self.rate
        if frame_t != self._frame_t:
            x = self.history.at(frame_t - self.latency)
            noise = self.rng.normal(0.0, self.noise_m, 5) if self.noise_m > 0 else np.zeros(5)
            self._pose = np.r_[x[0:2] + noise[0:2], self._orientation(x[2]), x[3:6] + noise[2:5],
                               self._orientation(x[6])]
            if self.dropout_rate > 0 and self.fault_rng.random() < self.dropout_rate:
                self._pose[:] = np.nan  # a lost frame
            elif self.glitch_rate > 0 and self.fault_rng.random() < self.glitch_rate:
                self._pose[3:6] = [self._pose[0], self._pose[1], self.ugv_z]  # the UAV's marker read at the UGV
            self._frame_t = frame_t
        odo_t = math.floor(t / self.odo + 1e-9) * self.odo
        return np.r_[self._pose, self.history.at(odo_t)[7:11]]


def simulate_ugv_uav(sc: UgvUavScenario, formation: str = "quaternion", progress=None, plant_factory=None,
                     bebop: Bebop | None = None, **controller_options) -> UgvUavRun:
    """Run the closed loop of Fig. 18 on the Pioneer and Bebop models with motion capture.

    ``plant_factory(x0, floor) -> (x0, plant_step)`` replaces the models by another plant
    (the physics backend) that starts near ``x0`` (11 values, see ``control.ugv_uav``);
    ``bebop`` and ``controller_options`` go to :meth:`UgvUavScenario.controller`.
    """
    check_ugv_uav_scenario(sc)
    ctrl = sc.controller(formation, bebop=bebop, **controller_options)
    F = ctrl.formation
    pioneer, bebop = ctrl.pioneer, ctrl.bebop
    steps_per_control = max(1, int(round(sc.control_period_s / sc.dt_s)))
    n_ctrl = int(sc.duration_s / (steps_per_control * sc.dt_s)) + 1
    t_ctrl = np.arange(n_ctrl) * steps_per_control * sc.dt_s
    e_des, ed_des = sc.e_reference(t_ctrl)
    c_des, cd_des, reachable, unreachable_at, message = _reachable(F, e_des, ed_des, t_ctrl)
    n = len(c_des)
    # initial state: the UGV on the path heading along it, the UAV on the ground at
    # uav_start in the UGV's frame (x ahead, y to its left): (0, -0.6) is 0.6 m to its right
    heading0 = math.atan2(ed_des[0, 1], ed_des[0, 0])
    ugv = np.array([e_des[0, 0], e_des[0, 1], heading0])
    ch, sh = math.cos(heading0), math.sin(heading0)
    sx, sy = float(sc.uav_start[0]), float(sc.uav_start[1])
    uav = np.r_[ugv[0] + ch * sx - sh * sy, ugv[1] + sh * sx + ch * sy, sc.center[2] + sc.uav_start[2], heading0,
                np.zeros(4)]
    floor = sc.center[2] - sc.floor_below_platform_m

    def plant(x, u, dt):
        b = bebop.step(x[3:11], u[2:6], dt)
        b[2] = max(b[2], floor)  # the floor
        return np.r_[pioneer.step(x[0:3], u[0:2], dt), b]

    x0 = np.r_[ugv, uav]
    if plant_factory is not None:
        x0, plant = plant_factory(x0, floor)

    mocap = MotionCapture(sc.mocap_rate_hz, sc.mocap_noise_m, sc.mocap_noise_rad, sc.mocap_latency_s,
                          sc.odometry_period_s, sc.seed, sc.mocap_dropout_rate, sc.mocap_glitch_rate, sc.center[2])
    steps = []  # the signals of each step: what the controller made of each frame (the loop logs the raw frame)
    held_state = [ctrl.init()]
    nan_c = np.full(F.n_c, np.nan)

    def compute(t, m, k):
        # where the description cannot express the reference (c = NaN), the robots wait (brake)
        s = ctrl.update(t, m, Reference(c_des[k], cd_des[k]) if reachable[k] else Reference(nan_c, nan_c),
                        held_state[0])
        held_state[0] = s.state
        steps.append(s.signals)
        return SimpleNamespace(commands=s.u, cluster=s.signals["cluster"], raw_finite=s.signals["raw_finite"][0] > 0.5)

    log = closed_loop(t_ctrl[:n], steps_per_control, sc.dt_s, x0, plant, mocap, compute, lambda k: k, progress)
    ugv_log, uav_log = log.states[:, 0:3], log.states[:, 3:11]

    r_true = np.c_[ugv_log[:, 0:2], np.full(n, sc.center[2]), uav_log[:, 0:3]]
    c_log = log.cluster.reshape(n, F.n_c)
    e_rec = F.to_chart(c_log, near_e=e_des[:n], r=r_true) if n else np.zeros((0, 6))
    # the singularity measure where the description exists (NaN where it cannot express the robots)
    sing = np.full(n, np.nan)
    inside = ~F.outside(r_true)
    for rows, hint in ((inside & reachable, c_des), (inside & ~reachable, None)):
        if rows.any():
            sing[rows] = F.singularity_measure(r_true[rows], near_c=None if hint is None else hint[rows])
    frame = np.array([s_["frame"][0] for s_ in steps], dtype=np.int8)
    used = np.array([s_["used"] for s_ in steps]).reshape(n, 11)
    outside = np.array([s_["outside"][0] > 0.5 for s_ in steps], dtype=bool)
    stopped = [k for k, s_ in enumerate(steps) if s_["stopped"][0] > 0.5]
    # the formation as recovered from the measurements used, each sample continued from the
    # last (NaN where the controller had none or the description cannot express them)
    r_meas = np.c_[used[:, [0, 1]], np.full(n, sc.center[2]), used[:, [3, 4, 5]]]
    c_cont = np.full((n, F.n_c), np.nan)
    ok = np.all(np.isfinite(r_meas), axis=1) & ~F.outside(np.where(np.isfinite(r_meas), r_meas, 0.0))
    for k in range(n):
        if ok[k]:
            hint = c_cont[k - 1] if k and ok[k - 1] else (c_des[k] if reachable[k] else None)
            c_cont[k] = F.forward(r_meas[k], near_c=hint)
    return UgvUavRun(sc, formation, t_ctrl[:n], ugv_log, uav_log, r_meas, c_log, c_des, e_rec, e_des[:n],
                     log.commands.reshape(n, 6), log.raw_finite, sing, unreachable_at,
                     message, c_cont, tuple(bebop.k), frame, np.array([s_["held"][0] > 0.5 for s_ in steps], dtype=bool),
                     outside, float(t_ctrl[stopped[0]]) if stopped else None,
                     held_state[0].stop_reason if stopped else "", reachable)


def ugv_uav_metrics(run: UgvUavRun) -> dict:
    """metrics.json of a UGV-UAV run (errors from the true robot poses, after the transient)."""
    sc = run.scenario
    r_des = UgvUavSpherical().inverse(run.e_des) if len(run.t) else np.zeros((0, 6))
    ugv_err = np.linalg.norm(run.ugv[:, 0:2] - r_des[:, 0:2], axis=1)
    uav_err = np.linalg.norm(run.uav[:, 0:3] - r_des[:, 3:6], axis=1)
    d_true = run.uav[:, 0:3] - np.c_[run.ugv[:, 0:2], np.full(len(run.t), sc.center[2])]
    sep = np.linalg.norm(d_true, axis=1)
    d_des = r_des[:, 3:6] - r_des[:, 0:3]
    cosang = np.einsum("ij,ij->i", d_true, d_des) / np.maximum(sep * np.linalg.norm(d_des, axis=1), 1e-300)
    orient = np.arccos(np.clip(cosang, -1, 1))
    yaw_err = np.abs(wrap_angle(run.ugv[:, 2] - run.uav[:, 3]))
    # errors count after the take-off transient, outside the settle window after each
    # designed switch of the reference (§5.3: front -> over at uav_front_until_s; a planned
    # change is not a loss), and while the controller still runs (not after a safe stop)
    settle = _settle_window(run)
    late = (run.t >= sc.transient_s) & ~settle
    if run.reachable is not None:
        late &= run.reachable
    if run.stopped_at is not None:
        late &= run.t < run.stopped_at
    lost = late & ((ugv_err > LOST_UGV_M) | (uav_err > LOST_UAV_M))
    singular = run.singularity < SINGULAR_THRESHOLD  # NaN (outside the description): not singular
    frames = run.mocap_frame if run.mocap_frame is not None else np.zeros(len(run.t), dtype=np.int8)

    def mx(a, mask=late):
        return float(a[mask].max()) if np.any(mask) else None

    jumps, explained = _quaternion_jumps(run)
    first_sing = float(run.t[np.argmax(singular)]) if singular.any() else None
    return {
        "scenario": sc.name,
        "controller": f"ugv-uav-{run.formation}",
        "formation": run.formation,
        "duration_s": float(run.t[-1]) if len(run.t) else 0.0,
        "transient_s": sc.transient_s,
        "dt_s": sc.dt_s,
        "control_period_s": float(run.t[1] - run.t[0]) if len(run.t) > 1 else sc.control_period_s,
        "metrics_from_s": sc.transient_s,
        "unreachable_reference": run.unreachable_at is not None,
        "first_unreachable_time_s": run.unreachable_at,
        "unreachable_message": run.unreachable_message or None,
        "unreachable_reference_s": float((~run.reachable).sum() * (run.t[1] - run.t[0]))
        if run.reachable is not None and len(run.t) > 1 else 0.0,
        "singularity_detected": bool(singular.any()),
        "first_singular_time_s": first_sing,
        "min_singularity_measure": float(np.nanmin(run.singularity)) if np.isfinite(run.singularity).any() else None,
        "reference_lost": bool(lost.any()),
        "first_lost_time_s": float(run.t[np.argmax(lost)]) if lost.any() else None,
        "max_cluster_position_error_m": mx(ugv_err),
        "max_shape_error_m": mx(np.abs(sep - sc.d_c)),
        "max_orientation_error_rad": mx(orient),
        "max_robot_position_error_m": mx(np.maximum(ugv_err, uav_err)),
        "max_ugv_position_error_m": mx(ugv_err),
        "max_uav_position_error_m": mx(uav_err),
        "max_uav_yaw_error_rad": mx(yaw_err),
        "max_robot_yaw_error_rad": mx(yaw_err),
        "max_command_speed_m_s": float(np.abs(run.u[:, 0]).max()) if len(run.t) else 0.0,
        "measured_outside_description_s": _outside_time(run),
        "min_robot_separation_m": float(sep.min()) if len(sep) else None,
        "max_recovered_euclidean_error_rad": mx(np.abs(wrap_angle(run.e[:, 5] - run.e_des[:, 5]))),
        "max_cluster_state_jump": float(jumps.max()) if len(jumps) else 0.0,
        "max_unexplained_cluster_jump": float(np.maximum(jumps - explained, 0.0).max()) if len(jumps) else 0.0,
        "max_uav_position_error_m_at_switch": mx(uav_err, settle) if sc.uav_front_until_s > 0 else None,
        "mocap_dropped_frames": int((frames == 1).sum()),
        "mocap_rejected_frames": int((frames == 2).sum()),
        "mocap_held_frames": int(run.held.sum()) if run.held is not None else 0,
        "run_stopped": run.stopped_at is not None,
        "run_stopped_at_s": run.stopped_at,
        "run_stopped_reason": run.stop_reason or None,
        "nonfinite_commands": int((~run.raw_finite).sum()),
        "uav_model_k": list(run.uav_model_k) if run.uav_model_k is not None else None,
        "max_uav_command_fraction": float(np.abs(run.u[:, 2:6]).max()) if len(run.t) else 0.0,
        "uav_command_chatter": float(np.sqrt(np.mean(np.diff(run.u[late][:, 2:4], axis=0) ** 2)))
        if late.sum() > 1 else 0.0,
    }


def _switch_times(run):
    """Times the reference changes by design: the front -> over switch of seed 001 §5.3 at
    ``uav_front_until_s``, and each return of the reference into the description."""
    times = [run.scenario.uav_front_until_s] if run.scenario.uav_front_until_s > 0 else []
    if run.reachable is not None and len(run.t) > 1:
        times += [float(t) for t in run.t[1:][run.reachable[1:] & ~run.reachable[:-1]]]
    return sorted(set(times))


def _settle_window(run):
    """Samples within ``switch_transient_s`` after a designed switch (:func:`_switch_times`)."""
    out = np.zeros(len(run.t), dtype=bool)
    for ts in _switch_times(run):
        out |= (run.t >= ts) & (run.t < ts + run.scenario.switch_transient_s)
    return out


def _quaternion_jumps(run):
    """How much the formation recovered from the measurements moves between samples, and
    how much of that the measured robot motion explains.

    Quaternion description: the sign-invariant angle between consecutive ``q_c`` against
    the angle the measured segment turned; the Euclidean descriptions: the change of their
    angles against the same. A recovered state that is continuous has no unexplained part;
    a description that is undefined somewhere (``alpha_c`` overhead) jumps there.
    """
    c = run.c_continuous
    if c is None or len(c) < 2:
        return np.zeros(0), np.zeros(0)
    d = run.measured[:, 3:6] - run.measured[:, 0:3]
    u = d / np.linalg.norm(d, axis=1)[:, None]
    turned = np.arccos(np.clip(np.einsum("ij,ij->i", u[1:], u[:-1]), -1, 1))
    ok = np.all(np.isfinite(c[1:]), axis=1) & np.all(np.isfinite(c[:-1]), axis=1) & np.isfinite(turned)
    c1, c0 = c[1:][ok], c[:-1][ok]
    if run.formation == "quaternion":
        jump = q_angle_between(c1[:, 3:7], c0[:, 3:7])
    else:
        jump = np.abs(wrap_angle(c1[:, 4:6] - c0[:, 4:6])).max(axis=1, initial=0.0)
    return jump, turned[ok] + 1e-9


def _outside_time(run):
    """Seconds the measured robots spent where the description cannot express them (the
    restricted one: more than its tolerance, 1 deg, outside its angle range, or the UAV
    below the platform), as the controller found them (it then controls in robot space)."""
    if run.outside is None or len(run.t) < 2:
        return 0.0
    return float(run.outside.sum() * (run.t[1] - run.t[0]))


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
    """Time of the last control sample of a run (the ``t_ctrl`` of :func:`simulate_ugv_uav`)."""
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
    for key in ("title", "source"):
        kw[key] = checks.text(data, key, where, default=fields[key].default)
    kw["path"] = checks.text(data, "path", where, default=fields["path"].default, choices=("circle", "lemniscate"))
    for key, (low, low_open, high, high_open) in _NUMBER_BOUNDS.items():
        default = checks.MISSING if key == "duration_s" else fields[key].default
        kw[key] = checks.number(data, key, where, default, low=low, low_open=low_open, high=high,
                                high_open=high_open)
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


def ugv_uav_timeseries(run: UgvUavRun):
    """Column names and the ``(T, n)`` array of a UGV-UAV run's time series."""
    from ..formations import SPHERICAL_VARIABLES, UGV_UAV_VARIABLES

    F = UGV_UAV_FORMATIONS[run.formation]()
    r_des = UgvUavSpherical().inverse(run.e_des) if len(run.t) else np.zeros((0, 6))
    r_true = np.c_[run.ugv[:, 0:2], np.full(len(run.t), run.scenario.center[2]), run.uav[:, 0:3]]
    names, cols = ["t"], [run.t[:, None]]

    def add(vars_, meas, des, prefix=""):
        for i, v in enumerate(vars_):
            names.extend([prefix + v.name, prefix + v.name + "_des"])
            cols.extend([meas[:, i:i + 1], des[:, i:i + 1]])

    add(UGV_UAV_VARIABLES, r_true, r_des)
    names.extend(["psi_p", "psi_b", "psi_b_des"])
    cols.extend([run.ugv[:, 2:3], run.uav[:, 3:4], run.ugv[:, 2:3]])
    if run.formation != "spherical":
        add(F.variables, run.c, run.c_des)
    add(SPHERICAL_VARIABLES, run.e, run.e_des, prefix="euclid_")
    names.extend("u_" + n for n in UGV_UAV_COMMAND_NAMES)
    cols.append(run.u)
    names.append("singularity_measure")
    cols.append(run.singularity[:, None])
    return names, np.hstack(cols) if len(run.t) else np.zeros((0, len(names)))
