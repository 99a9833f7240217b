"""The UGV-UAV formation controller of seed 001 §4.3-4.4 (Fig. 18), with what a lab adds.

Control layer. One step: measured positions -> cluster state (forward kinematics, the
reference as hint) -> cluster rate references with tanh saturation, eqs. (4.43)-(4.45)
(the error quaternion order corrected as in seed 000) -> robot rates through the inverse
Jacobian (4.42) -> the UAV's yaw rate by eqs. (4.50)-(4.51) -> the team's actuation
(:mod:`quatform.robots`: the Pioneer's commands by eq. (3.5), the Bebop's body-frame
velocity reference by eq. (3.10) and the dynamic compensation (4.47)-(4.49), whose memory
is part of the controller's state :class:`UgvUavState`). Around it (:mod:`quatform.control.filters`):
the motion-capture screen, an arena box whose walls no command may push through, the
robots' limits, and an emergency stop (the thesis's joystick override) that halts both.

Measured state (11 values): ``(x_p, y_p, psi_p, x_b, y_b, z_b, psi_b, v_x, v_y, z_dot,
psi_dot)``: the Pioneer's control point and heading, the Bebop's pose and its body-frame
velocity (from its own odometry). Commands (6 values): ``(v, omega, u_x, u_y, u_z, u_psi)``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..algebra.kernels import common_namespace, concrete
from ..algebra.validate import as_array
from ..errors import InvalidInputError, UnreachableError
from ..formations import UgvUavQuaternion
from ..formations import pair_kernels as kern
from ..formations.base import Formation
from ..robots import Bebop, BebopMemory, Pioneer, Team
from . import contract
from .base import Reference
from .cluster import ClusterController
from .filters import FRAME_DROPPED, FRAME_GOOD, FRAME_REJECTED, ArenaWalls, HeadingLaw, MocapScreen
from .laws import Block, BlockLaw

__all__ = ["UgvUavController", "UgvUavState", "UGV_UAV_MEASURED_NAMES", "UGV_UAV_COMMAND_NAMES",
           "FRAME_CODES", "MOCAP_PART", "ODOMETRY_PART", "PIONEER_PART", "BEBOP_PART"]

#: Layout of the 11 measured values the UGV-UAV controller reads.
UGV_UAV_MEASURED_NAMES = ("x_p", "y_p", "psi_p", "x_b", "y_b", "z_b", "psi_b", "v_x_b", "v_y_b", "z_dot_b", "psi_dot_b")
#: Parts of the measured values: the motion capture's (both robots' poses) and the Bebop's
#: odometry; the Pioneer's and the Bebop's (what each robot's actuation reads).
MOCAP_PART = slice(0, UGV_UAV_MEASURED_NAMES.index("v_x_b"))
ODOMETRY_PART = slice(MOCAP_PART.stop, len(UGV_UAV_MEASURED_NAMES))
PIONEER_PART = slice(0, UGV_UAV_MEASURED_NAMES.index("x_b"))
BEBOP_PART = slice(PIONEER_PART.stop, len(UGV_UAV_MEASURED_NAMES))
#: Layout of the 6 commands it sends (the Pioneer's, then the Bebop's).
UGV_UAV_COMMAND_NAMES = ("v_p", "omega_p", "u_x_b", "u_y_b", "u_z_b", "u_psi_b")


#: The ``frame`` signal's code of each frame class.
FRAME_CODES = {FRAME_GOOD: 0, FRAME_DROPPED: 1, FRAME_REJECTED: 2}


@dataclass(frozen=True)
class UgvUavState:
    """The UGV-UAV controller's state between updates (one world).

    Attributes
    ----------
    memory : tuple
        The team's actuation memory (:meth:`Team.initial_memory`): ``(None, BebopMemory)``,
        the previous velocity reference of (4.47), its time and the filtered derivative.
    stopped : bool
        The emergency stop holds (:meth:`UgvUavController.emergency_stop`).
    stop_reason : str
        Why ("" when not stopped).
    good : ndarray, shape (11,), or None
        The last good motion-capture frame (with the odometry it used).
    good_t : float or None
        Its time, s.
    bad_since : float or None
        Time of the first bad frame of the current run of them (None while frames are good).
    """

    memory: tuple = (None, BebopMemory.start())
    stopped: bool = False
    stop_reason: str = ""
    good: np.ndarray | None = None
    good_t: float | None = None
    bad_since: float | None = None


def _each(state, f):
    """``f`` applied to one state, or to every world's state of a batched one (object array)."""
    if isinstance(state, UgvUavState):
        return f(state)
    out = np.empty(np.shape(state), dtype=object)
    for i in np.ndindex(out.shape):
        out[i] = f(state[i])
    return out


def _positive(values, n, name):
    v = np.broadcast_to(np.asarray(values, dtype=float), (n,)).copy()
    if not np.all(np.isfinite(v)) or np.any(v <= 0):
        raise InvalidInputError(f"{name} must be {n} positive numbers, got {values!r}")
    return v


class UgvUavController(ClusterController):
    """Seed 001's formation controller for a Pioneer 3-DX and a Bebop 2: a
    :class:`~quatform.control.cluster.ClusterController` of a UGV-UAV description, the tanh
    law (4.43)-(4.45), the Pioneer-Bebop team and three filters (``filters``: the
    motion-capture screen, the arena walls, the UAV's heading law), with a state
    (:class:`UgvUavState`) threaded through :meth:`update`. Frozen, as every controller.

    Parameters
    ----------
    formation : Formation
        ``UgvUavQuaternion`` (default), ``UgvUavSpherical`` or ``UgvUavRestricted``.
    k_x, k_d, k_w : gains of (4.43)-(4.45): ``K_x = I``, ``K_d = 1``, ``K_w = I`` (seed 001 §5).
        For the Euclidean descriptions ``k_w`` (first two) act on the two angles.
    k_psi : float
        UAV yaw gain (4.51), 3.
    l_d : array_like, shape (4,)
        ``L_d`` of the dynamic compensation (4.47), ``diag(2, 2, 1.8, 5)``.
    compensation : bool
        Use (4.47); otherwise the kinematic command ``u = K_u^-1 K_v v_r``.
    pioneer, bebop : robot models (limits, ``a``, ``K1..K8``).
    z_ugv : float
        Height of the UGV's landing platform, m (the cluster point's z).
    arena : ((x_min, x_max), (y_min, y_max), (z_min, z_max))
        The flight arena (seed 001 §3.4: 6 x 4 m, 3 m high; z from the floor below the
        platform). Velocity references toward a wall are limited to ``wall_gain`` times the
        distance left before ``wall_margin``, so the robots stop short of it.
    derivative_filter_s : float
        Time constant of the first-order filter on the differentiated velocity reference
        ``v_r_dot`` of (4.47) (the thesis differentiates without one; 0 disables it).
    max_hold_s : float
        Longest time, s, the last good measurement stands in for dropped (NaN) or rejected
        frames; beyond it the controller stops both robots (:meth:`emergency_stop`) and
        says so in the state's ``stop_reason``.
    speed_margin, jump_margin_m : float
        A frame is implausible when a robot moved farther since the last good frame than
        ``speed_margin`` times its top speed (the Pioneer's control point:
        ``hypot(max_v, a max_omega)``; the Bebop: ``|K_u / K_v| max_fraction``) allows, plus
        ``jump_margin_m`` (the measurement noise), or when the robots are closer than
        ``min_separation_m``.
    """

    def __init__(self, formation: Formation | None = None, k_x=1.0, k_d=1.0, k_w=1.0, k_psi=3.0,
                 l_d=(2.0, 2.0, 1.8, 5.0), compensation=True, feedforward=True, pioneer=None, bebop=None,
                 z_ugv=0.0, arena=((-3.0, 3.0), (-2.0, 2.0), (-0.5, 3.0)), wall_margin=0.3, wall_gain=1.0,
                 derivative_filter_s=0.1, max_hold_s=0.5, speed_margin=1.5, jump_margin_m=0.05,
                 min_separation_m=0.05):
        _set = object.__setattr__  # frozen: the configuration is set once, here
        _set(self, "formation", formation if formation is not None else UgvUavQuaternion())
        _set(self, "k_x", _positive(k_x, 3, "k_x"))
        _set(self, "k_d", float(_positive(k_d, 1, "k_d")[0]))
        _set(self, "k_w", _positive(k_w, 3, "k_w"))
        _set(self, "k_psi", float(_positive(k_psi, 1, "k_psi")[0]))
        _set(self, "l_d", _positive(l_d, 4, "l_d"))
        _set(self, "compensation", bool(compensation))
        _set(self, "feedforward", bool(feedforward))
        pioneer = pioneer if pioneer is not None else Pioneer()
        bebop = bebop if bebop is not None else Bebop()
        _set(self, "z_ugv", float(z_ugv))
        _set(self, "wall_margin", float(wall_margin))
        _set(self, "wall_gain", float(_positive(wall_gain, 1, "wall_gain")[0]))
        _set(self, "derivative_filter_s", float(derivative_filter_s))
        if not (self.derivative_filter_s >= 0 and self.wall_margin >= 0):
            raise InvalidInputError("derivative_filter_s and wall_margin must be >= 0")
        # the robots' actuation (seed 001 eqs. (3.5), (3.10), (4.47)) is the team's
        _set(self, "team", Team((replace(pioneer, z=self.z_ugv),
                                 replace(bebop, l_d=tuple(self.l_d.tolist()), compensation=self.compensation,
                                         derivative_filter_s=self.derivative_filter_s))))
        _set(self, "pioneer", self.team.robots[0])
        _set(self, "bebop", self.team.robots[1])
        _set(self, "max_hold_s", float(_positive(max_hold_s, 1, "max_hold_s")[0]))
        _set(self, "speed_margin", float(_positive(speed_margin, 1, "speed_margin")[0]))
        _set(self, "jump_margin_m", float(_positive(jump_margin_m, 1, "jump_margin_m")[0]))
        _set(self, "min_separation_m", float(_positive(min_separation_m, 1, "min_separation_m")[0]))
        # the law (4.43)-(4.45): tanh on the positions and the length; (4.45) prints q_c q_cd,
        # the body-frame error is q_cd* q_c (seed 000 eq. (20)); for the Euclidean
        # descriptions k_w (first two) act on the two angles
        kx, kw = tuple(self.k_x.tolist()), tuple(self.k_w.tolist())
        if isinstance(self.formation, UgvUavQuaternion):
            blocks = (Block("tanh", 0, 3, kx), Block("quaternion", 3, 4, kw), Block("tanh", 7, 1, (self.k_d,)),
                      Block("none", 8, self.formation.n_c - 8))  # d_c = (d, 0, 0)
        else:
            blocks = (Block("tanh", 0, self.formation.n_c, kx + (self.k_d,) + kw[:2]),)
        _set(self, "law", BlockLaw(blocks, self.feedforward))
        p = self.pioneer
        # the filters (control.filters): frame screening, arena walls, the UAV's yaw law
        top_speed = (self.speed_margin * float(np.hypot(p.max_v, p.a * p.max_omega)),
                     self.speed_margin * float(np.linalg.norm(self.bebop.max_velocity[0:3])))
        _set(self, "mocap", MocapScreen(top_speed, self.jump_margin_m, self.min_separation_m, self.max_hold_s))
        _set(self, "walls", ArenaWalls(arena, self.wall_margin, self.wall_gain, free=((0, 2),)))  # UGV's height fixed
        _set(self, "arena", self.walls.box)
        _set(self, "heading", HeadingLaw(self.k_psi))
        _set(self, "filters", (self.mocap, self.walls, self.heading))
        _set(self, "checks", ())

    @property
    def name(self) -> str:
        return self.formation.name

    command_names = UGV_UAV_COMMAND_NAMES

    def signal_columns(self) -> dict[str, tuple[str, ...]]:
        """``cluster``, ``error`` (the formation's variables), ``robot_rates`` (the 6 world rates
        of eq. (4.42)), ``raw_finite``, ``stopped``, ``frame`` (0 good, 1 dropped, 2 rejected),
        ``held``, ``outside`` and ``used`` (the 11 measured values the step used)."""
        names = self.formation.names
        return {"cluster": names, "error": names,
                "robot_rates": ("x_dot_p", "y_dot_p", "z_dot_p", "x_dot_b", "y_dot_b", "z_dot_b"),
                "raw_finite": ("raw_finite",), "stopped": ("stopped",), "frame": ("frame",),
                "held": ("held",), "outside": ("outside",), "used": UGV_UAV_MEASURED_NAMES}

    # -- state: the compensation's derivative, the screening and the emergency stop -----
    def init(self, batch: tuple = ()):
        """The state before the first update: no previous reference or frame, not stopped.

        With ``batch`` axes: an object array of that shape holding one :class:`UgvUavState`
        per world."""
        return _each(np.empty(tuple(batch), dtype=object) if batch else UgvUavState(),
                     lambda s: UgvUavState(memory=self.team.initial_memory()))

    def emergency_stop(self, state, reason: str = "emergency stop"):
        """``state`` with both robots halted until :meth:`release`: the UGV stops, the UAV
        brakes to a hover (the compensation law with a zero velocity reference, rate ``L_d``)."""
        return _each(state, lambda s: replace(s, stopped=True, stop_reason=reason))

    def release(self, state):
        """``state`` with the emergency stop released and the derivative of (4.47) restarted."""
        return _each(state, lambda s: replace(s, stopped=False, stop_reason="", bad_since=None,
                                              memory=self.team.initial_memory()))

    # -- the chain of Fig. 18 ---------------------------------------------------------
    def step(self, t: float, measured, reference=None) -> np.ndarray:
        """Commands ``(..., 6)`` for ``measured`` (``(..., 11)``) from the initial state."""
        return self.update(t, measured, reference, self.init(np.shape(measured)[:-1])).u

    def update(self, t: float, measured, reference, state) -> contract.Step:
        """One step of Fig. 18 (:meth:`_update_one` per world).

        Parameters
        ----------
        t : float
            Time, s.
        measured : array_like, shape (..., 11)
            :data:`UGV_UAV_MEASURED_NAMES`; leading axes are worlds.
        reference : Reference
            ``c``, ``c_dot`` of shape ``(..., n_c)`` (or one for every world). A ``c`` with a
            NaN (or ``reference=None``) means no reference the description can express: both
            robots brake (the UGV stops, the UAV brakes to a hover or stays on the floor).
        state : UgvUavState or object array of them (from :meth:`init`)

        Returns
        -------
        Step
            ``u`` of shape ``(..., 6)``, the next state and the signals of :meth:`signal_columns`.
        """
        if isinstance(state, UgvUavState):
            return self._update_one(t, measured, reference, state)
        m = np.asarray(measured, dtype=float)
        batch = np.shape(state)
        m = np.broadcast_to(m, batch + m.shape[-1:])
        c = None if reference is None else np.broadcast_to(np.asarray(reference.c, float), batch + (self.formation.n_c,))
        cd = None if reference is None else np.broadcast_to(np.asarray(reference.c_dot, float),
                                                            batch + (self.formation.n_c,))
        us, nxt, sig = [], np.empty(batch, dtype=object), {k: [] for k in self.signal_columns()}
        for i in np.ndindex(batch):
            ref = None if reference is None else Reference(c[i], cd[i])
            s = self._update_one(t, m[i], ref, state[i])
            us.append(s.u)
            nxt[i] = s.state
            for k, v in s.signals.items():
                sig[k].append(v)
        cols = self.signal_columns()
        return contract.Step(np.reshape(us, batch + (6,)), nxt,
                             {k: np.reshape(v, batch + (len(cols[k]),)) for k, v in sig.items()})

    def cluster_rates(self, c, c_des, c_dot_des):
        """Cluster error and rate reference, eqs. (4.43)-(4.45) (:attr:`law`)."""
        F = self.formation
        if not concrete(c):  # JAX (traced, (..., n_c)): the law on components
            e = None if isinstance(F, UgvUavQuaternion) else kern.unpack(F.errors(c, c_des))
            err, rate = self.law(kern.unpack(c), kern.unpack(c_des), kern.unpack(c_dot_des), e)
            return kern.pack(err), kern.pack(rate)
        e = None if isinstance(F, UgvUavQuaternion) else F.errors(c, c_des).tolist()  # angles wrapped
        err, rate = self.law(c.tolist(), c_des.tolist(), c_dot_des.tolist(), e)
        return np.array(err), np.array(rate)

    def _brake(self, state, m):
        """Commands that stop the UGV and brake the UAV to a hover (v_r = 0 in (4.47)), and the
        state whose compensation memory forgets its reference."""
        u, memory = self.team.brake(np.asarray(m, dtype=float), state.memory)
        return self.team.saturate(u), replace(state, memory=memory)

    def screen(self, state: UgvUavState, t: float, m: np.ndarray):
        """Classify the motion-capture frame ``m`` (11 values) at time ``t``.

        Returns ``(frame, measured, state)``: ``frame`` is ``"good"``, ``"dropped"`` (a NaN or
        infinity in the poses, the first 7 values) or ``"rejected"`` (the robots within
        ``min_separation_m`` of each other, or one of them farther from its last good
        position than its top speed allows in the time since, plus ``jump_margin_m``);
        ``measured`` is ``m`` if good, else the last good frame, or None if there is none
        yet; ``state`` remembers the good frame or the start of the run of bad ones.
        """
        finite = bool(np.all(np.isfinite(m[MOCAP_PART])))
        frame = self.mocap.classify(t, self.measured_points(m) if finite else None, finite,
                                    None if state.good is None else self.measured_points(state.good), state.good_t)
        if frame == FRAME_GOOD:
            odo = m[ODOMETRY_PART]
            if not np.all(np.isfinite(odo)):  # the Bebop's odometry: the last finite one, or rest
                m = np.r_[m[MOCAP_PART], np.where(np.isfinite(odo), odo,
                                                  0.0 if state.good is None else state.good[ODOMETRY_PART])]
            return frame, m, replace(state, good=m.copy(), good_t=t, bad_since=None)
        if state.bad_since is None:
            state = replace(state, bad_since=t)
        return frame, state.good, state

    def _screened(self, state, t, measured):
        """``(frame, measured to use or None, held, raw measured, state)`` (:meth:`screen`);
        stops both robots after ``max_hold_s`` without a good frame."""
        m = np.asarray(measured, dtype=float)
        if m.shape != (11,):
            m = as_array(measured, "measured state", 11)
        frame, used, state = self.screen(state, t, m)
        if frame != FRAME_GOOD and not state.stopped and self.mocap.expired(t, state.bad_since):
            state = replace(state, stopped=True, stop_reason=self.stop_reason(t, state.bad_since))
        if used is None or frame == FRAME_GOOD:
            return frame, used, False, m, state
        # the pose is held; the Bebop's own odometry is not from the motion capture
        odo = m[ODOMETRY_PART]
        return frame, np.r_[used[MOCAP_PART], np.where(np.isfinite(odo), odo, used[ODOMETRY_PART])], True, m, state

    def stop_reason(self, t: float, bad_since: float) -> str:
        """Why the screen stopped both robots at ``t`` after bad frames since ``bad_since``, s."""
        return (f"motion capture: no good frame for {t - bad_since:.3g} s (more than max_hold_s = "
                f"{self.max_hold_s:g} s) from t = {bad_since:.6g} s; both robots stopped")

    def _step(self, state, u, c, err, x_rate, finite, frame, held, outside, used) -> contract.Step:
        nan11 = np.full(11, np.nan)
        return contract.Step(u, state, {
            "cluster": c, "error": err, "robot_rates": x_rate, "raw_finite": np.array([float(finite)]),
            "stopped": np.array([float(state.stopped)]), "frame": np.array([float(FRAME_CODES[frame])]),
            "held": np.array([float(held)]), "outside": np.array([float(outside)]),
            "used": nan11 if used is None else np.asarray(used, dtype=float)})

    def _braking(self, state, m, c, frame, held=False, outside=False, used=None) -> contract.Step:
        u, state = self._brake(state, m)
        return self._step(state, u, c, np.full_like(c, np.nan), np.zeros(6),
                          used is not None, frame, held, outside, used)

    def _update_one(self, t: float, measured, reference, state: UgvUavState) -> contract.Step:
        """One step for one world. A dropped (NaN) or implausible motion-capture frame
        (:meth:`screen`) is replaced by the last good one for up to ``max_hold_s``; without
        one, or for longer, both robots brake (then stay stopped, :meth:`emergency_stop`).
        Robots the description cannot express (the restricted one, the UAV below the
        platform) are driven in robot space toward the reference's robot positions (seed
        000 §3.1). A reference ``c`` with a NaN: the frame is screened and both robots brake."""
        F = self.formation
        nan_c = np.full(F.n_c, np.nan)
        hold = reference is None
        if not hold:
            c_des = np.asarray(reference.c, dtype=float)
            hold = c_des.shape == (F.n_c,) and bool(np.any(np.isnan(c_des)))
        if not hold:
            c_des = as_array(reference.c, "reference.c", F.n_c)
            c_dot = as_array(reference.c_dot, "reference.c_dot", F.n_c)
        frame, m, held, raw, state = self._screened(state, t, measured)
        if m is None:  # nothing to go on: brake (the odometry's velocities where finite)
            return self._braking(state, raw, nan_c, frame)
        r = self.team.point(m)  # the Pioneer's control point at z_ugv, the Bebop's position
        if hold:
            outside = bool(F.outside(r))
            return self._braking(state, m, nan_c if outside else F.forward(r), frame, held, outside, m)
        ff = 1.0 if self.feedforward else 0.0
        try:
            c = F.forward(r, near_c=c_des)
            outside = False
            err, c_rate = self.cluster_rates(c, c_des, c_dot)
            x_rate = F.inverse_jacobian_at(c, r=r) @ c_rate  # (4.42)
        except UnreachableError:
            # robot-space control (seed 000 §3.1): track INVKIN(c_des) with the position law
            # of (4.43) on each robot, r_dot = r_dot_des - K_x tanh(r - r_des)
            c, err, outside = nan_c, nan_c, True
            r_des = F.inverse(c_des)
            x_rate = ff * (F.inverse_jacobian_at(c_des, r=r_des) @ c_dot) - np.r_[self.k_x, self.k_x] * np.tanh(r - r_des)
        finite = bool(np.all(np.isfinite(x_rate)))
        if not finite:
            x_rate = np.zeros(6)
        x_rate = self._keep_inside(m, x_rate)
        if state.stopped:
            u, state = self._brake(state, m)
            return self._step(state, u, c, err, x_rate, finite, frame, held, outside, m)
        u, state = self._commands(state, t, m, x_rate)
        return self._step(state, u, c, err, x_rate, finite, frame, held, outside, m)

    def _commands(self, state, t, m, x_rate):
        """Robot commands for the world rates ``x_rate``: the UAV's yaw rate (4.50)-(4.51) and
        the team's actuation, (3.5) for the Pioneer, (3.10) and (4.47)-(4.49) for the Bebop."""
        psi_rate = self.heading.rate(m[2], m[6])  # (4.50)-(4.51), psi_bd = psi_p
        u, memory = self.team.actuate(m, np.r_[x_rate, psi_rate], t, state.memory)
        return self.team.saturate(u), replace(state, memory=memory)

    def measured_points(self, m):
        """The robots' positions in the 11 measured values (the Pioneer's at ``z_ugv``), ``(..., 3)``
        each (any namespace)."""
        if concrete(m):
            return (np.array([m[0], m[1], self.z_ugv]), m[3:6])
        xp = common_namespace(m)
        return (xp.concatenate([m[..., 0:2], xp.full(m.shape[:-1] + (1,), self.z_ugv, dtype=m.dtype)], axis=-1),
                m[..., 3:6])

    def _keep_inside(self, m, x_rate):
        """:attr:`walls` on the robots' world rates."""
        return self.walls.limit(self.measured_points(m), x_rate)
