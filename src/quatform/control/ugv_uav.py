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
Their named entries (:mod:`quatform.robots.pioneer_bebop`) and the robots' points in the
formation's robot state (:mod:`quatform.formations.ugv_uav`) are importable from here too.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, replace

import numpy as np

from ..algebra.kernels import as_floats, common_namespace, concrete
from ..algebra.validate import as_array
from ..errors import InvalidInputError, QuatformError
from ..formations import UgvUavQuaternion, UgvUavRestricted
from ..formations import pair_kernels as kern
from ..formations.base import MAX_MAGNITUDE, Formation
from ..formations.ugv_uav import UAV_POINT, UGV_POINT
from ..robots import Bebop, BebopMemory, Pioneer, Team
from ..robots.model import column_unit
from ..robots.pioneer_bebop import (BEBOP_COMMAND, BEBOP_PART, MOCAP_PART, N_MEASURED, ODOMETRY_PART, PIONEER_BEBOP,
                                    PIONEER_COMMAND, PIONEER_PART, PSI_B, PSI_P, UAV_XY_COMMAND, UAV_XYZ,
                                    UGV_UAV_COMMAND_NAMES, UGV_UAV_MEASURED_NAMES, UGV_XY, V_P)
from . import contract
from .base import Reference
from .cluster import ClusterController
from .filters import FRAME_DROPPED, FRAME_GOOD, FRAME_REJECTED, ArenaWalls, HeadingLaw, MocapScreen
from .laws import Block, BlockLaw

__all__ = ["UgvUavController", "UgvUavState", "UGV_UAV_MEASURED_NAMES", "UGV_UAV_COMMAND_NAMES",
           "FRAME_CODES", "STOP_MOTION_CAPTURE", "MOCAP_PART", "ODOMETRY_PART", "PIONEER_PART", "BEBOP_PART",
           "PIONEER_COMMAND", "BEBOP_COMMAND", "UGV_XY", "PSI_P", "UAV_XYZ", "PSI_B", "V_P", "UAV_XY_COMMAND",
           "UGV_POINT", "UAV_POINT", "N_MEASURED"]


#: The measured entries the robots' points are made of: ``(robot number, its state column, entry)``.
_POINT_ENTRIES = tuple((k, robot.state_columns[j - part.start], j)
                       for k, (robot, part, point) in enumerate(zip(PIONEER_BEBOP.robots, PIONEER_BEBOP.state_slices,
                                                                    (UGV_XY, UAV_XYZ)))
                       for j in range(point.start, point.stop))

#: The ``frame`` signal's code of each frame class (:meth:`MocapScreen.frame_code`).
FRAME_CODES = {FRAME_GOOD: 0, FRAME_DROPPED: 1, FRAME_REJECTED: 2}
#: :attr:`UgvUavState.stop_code` of the screen's stop (no good frame for longer than
#: ``max_hold_s``); 0 is not stopped, ``2 + i`` the ``i``-th distinct reason given to
#: :meth:`UgvUavController.emergency_stop` in this process (:data:`_STOP_REASONS`).
STOP_MOTION_CAPTURE = 1
#: The words of the emergency stops' codes (code ``2 + i`` is ``_STOP_REASONS[i]``): the state
#: holds arrays only, so an operator's reason is a code.
_STOP_REASONS: list = []


def _stop_code(reason: str) -> int:
    """The code of an emergency stop's ``reason`` (each distinct reason one code)."""
    reason = str(reason)
    if reason not in _STOP_REASONS:
        _STOP_REASONS.append(reason)
    return 2 + _STOP_REASONS.index(reason)


def motion_capture_stop_reason(t: float, bad_since: float, max_hold_s: float) -> str:
    """Why the screen stopped both robots at ``t`` after bad frames since ``bad_since``, s."""
    return (f"motion capture: no good frame for {t - bad_since:.3g} s (more than max_hold_s = "
            f"{max_hold_s:g} s) from t = {bad_since:.6g} s; both robots stopped")


#: The array fields of :class:`UgvUavState` (its pytree children), in order.
_ARRAY_FIELDS = ("v_r", "mem_t", "v_dot", "stopped", "stop_code", "stop_t", "stop_since", "good", "good_t",
                 "bad_since", "hold_s")
_REGISTERED = []


def _register_pytree() -> None:
    """Register :class:`UgvUavState` as a JAX pytree (its arrays the children), once, where JAX
    is imported; JAX is never imported here. Called wherever a state is made and by
    :meth:`UgvUavController.reference_arrays` (a driver asks for the references before it
    compiles the tick)."""
    if _REGISTERED or "jax" not in sys.modules:
        return
    import jax

    def unflatten(aux, children):
        out = object.__new__(UgvUavState)
        for name, v in zip(_ARRAY_FIELDS, children):
            object.__setattr__(out, name, v)
        return out

    jax.tree_util.register_pytree_node(UgvUavState, lambda s: (tuple(getattr(s, k) for k in _ARRAY_FIELDS), None),
                                       unflatten)
    _REGISTERED.append(True)


@dataclass(frozen=True)
class UgvUavState:
    """The UGV-UAV controller's state between ticks: arrays only, whose leading axes are the
    batch's (``batch = ()`` for one world); a JAX pytree once JAX is imported.

    Attributes
    ----------
    v_r : array, shape (*batch, 4)
        The Bebop's previous body-frame velocity reference of (4.47) (NaN: none).
    mem_t : array, shape (*batch)
        Its time, s (NaN: none).
    v_dot : array, shape (*batch, 4)
        The filtered derivative of ``v_r``.
    stopped : bool array, shape (*batch)
        The emergency stop holds (:meth:`UgvUavController.emergency_stop`, or the screen's).
    stop_code : int array, shape (*batch)
        Why: 0 not stopped, :data:`STOP_MOTION_CAPTURE`, ``>= 2`` a reason given to
        :meth:`UgvUavController.emergency_stop` (:attr:`stop_reason` has the words).
    stop_t, stop_since : arrays, shape (*batch)
        The time of the screen's stop and the start of the bad frames that caused it, s (NaN).
    good : array, shape (*batch, 11)
        The last good motion-capture frame, with the odometry it used (NaN: none yet).
    good_t : array, shape (*batch)
        Its time, s (NaN: none yet).
    bad_since : array, shape (*batch)
        Time of the first bad frame of the current run of them, s (NaN while frames are good).
    hold_s : array, shape (*batch)
        The screen's ``max_hold_s``, s (the words of its stop).
    """

    v_r: np.ndarray
    mem_t: np.ndarray
    v_dot: np.ndarray
    stopped: np.ndarray
    stop_code: np.ndarray
    stop_t: np.ndarray
    stop_since: np.ndarray
    good: np.ndarray
    good_t: np.ndarray
    bad_since: np.ndarray
    hold_s: np.ndarray

    def __post_init__(self):
        _register_pytree()

    @classmethod
    def start(cls, batch: tuple = (), max_hold_s: float = 0.5) -> UgvUavState:
        """No previous reference or frame, not stopped."""
        batch = tuple(batch)
        nan = np.full(batch, np.nan)
        memory = BebopMemory.start(batch)
        return cls(memory.v_r, memory.t, memory.v_dot, np.zeros(batch, dtype=bool), np.zeros(batch, dtype=np.int64),
                   nan, nan.copy(), np.full(batch + (N_MEASURED,), np.nan), nan.copy(), nan.copy(),
                   np.full(batch, float(max_hold_s)))

    @property
    def batch(self) -> tuple:
        return tuple(np.shape(self.good_t))

    @property
    def memory(self) -> tuple:
        """The team's actuation memory (:meth:`Team.initial_memory`): ``(None, BebopMemory)``."""
        return (None, BebopMemory(self.v_r, self.mem_t, self.v_dot))

    @staticmethod
    def _reason(code, t, since, hold_s) -> str:
        code = int(code)
        if code == 0:
            return ""
        if code == STOP_MOTION_CAPTURE:
            return motion_capture_stop_reason(float(t), float(since), float(hold_s))
        return _STOP_REASONS[code - 2]

    @property
    def stop_reason(self):
        """Why both robots are stopped ("" when not): a str, or an object array of them for a batch."""
        code, t, since, hold = (np.asarray(a) for a in (self.stop_code, self.stop_t, self.stop_since, self.hold_s))
        if code.ndim == 0:
            return self._reason(code, t, since, hold)
        out = np.empty(code.shape, dtype=object)
        for i in np.ndindex(code.shape):
            out[i] = self._reason(code[i], t[i], since[i], hold[i])
        return out


def _positive(values, n, name):
    v = np.broadcast_to(np.asarray(values, dtype=float), (n,)).copy()
    if not np.all(np.isfinite(v)) or np.any(v <= 0):
        raise InvalidInputError(f"{name} must be {n} positive numbers, got {values!r}")
    return v


def _check_state(state, what: str) -> None:
    """One line when ``state`` is not a :class:`UgvUavState` (the controller's ``init``)."""
    if not isinstance(state, UgvUavState):
        raise InvalidInputError(f"UgvUavController.{what}: state must be the controller's UgvUavState "
                                f"(from init(batch) or the last update), got {type(state).__name__}")


class UgvUavController(ClusterController):
    """Seed 001's formation controller for a Pioneer 3-DX and a Bebop 2: a
    :class:`~quatform.control.cluster.ClusterController` of a UGV-UAV description, the tanh
    law (4.43)-(4.45), the Pioneer-Bebop team and three filters (``filters``: the
    motion-capture screen, the arena walls, the UAV's heading law), with a state
    (:class:`UgvUavState`, arrays) threaded through one pure, branch-free :meth:`tick` on the
    array namespace (NumPy, or JAX under ``jax.jit``); :meth:`update` is the host checks and
    :meth:`tick`. Frozen, as every controller.

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
        if not abs(self.z_ugv) <= MAX_MAGNITUDE:
            raise InvalidInputError(f"z_ugv = {self.z_ugv!r} m must be finite within {MAX_MAGNITUDE:g} (the UGV's "
                                    "platform height)")
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
                     self.speed_margin * self.bebop.max_speed)
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
        ``held``, ``no_frame`` (1 where no good frame has come yet: both robots brake),
        ``outside`` and ``used`` (the 11 measured values the step used)."""
        names = self.formation.names
        return {"cluster": names, "error": names,
                "robot_rates": ("x_dot_p", "y_dot_p", "z_dot_p", "x_dot_b", "y_dot_b", "z_dot_b"),
                "raw_finite": ("raw_finite",), "stopped": ("stopped",), "frame": ("frame",),
                "held": ("held",), "no_frame": ("no_frame",), "outside": ("outside",),
                "used": UGV_UAV_MEASURED_NAMES}

    # -- state: the compensation's derivative, the screening and the emergency stop -----
    def init(self, batch: tuple = ()):
        """The state before the first tick (:meth:`UgvUavState.start`): no previous reference
        or frame, not stopped; arrays with ``batch`` leading axes."""
        return UgvUavState.start(batch, self.max_hold_s)

    def emergency_stop(self, state, reason: str = "emergency stop"):
        """``state`` with both robots halted until :meth:`release` (every world of a batch): the
        UGV stops, the UAV brakes to a hover (the compensation law with a zero velocity
        reference, rate ``L_d``); ``state.stop_reason`` is ``reason``."""
        _check_state(state, "emergency_stop")
        return replace(state, stopped=np.ones(state.batch, dtype=bool),
                       stop_code=np.full(state.batch, _stop_code(reason), dtype=np.int64),
                       stop_t=np.full(state.batch, np.nan), stop_since=np.full(state.batch, np.nan))

    def release(self, state):
        """``state`` with the emergency stop released and the derivative of (4.47) restarted
        (the last good frame is kept)."""
        _check_state(state, "release")
        fresh = UgvUavState.start(state.batch, self.max_hold_s)
        return replace(fresh, good=state.good, good_t=state.good_t)

    def stop_reason(self, t: float, bad_since: float) -> str:
        """Why the screen stopped both robots at ``t`` after bad frames since ``bad_since``, s."""
        return motion_capture_stop_reason(t, bad_since, self.max_hold_s)

    # -- the chain of Fig. 18 ---------------------------------------------------------
    pure = True
    #: What the tick refuses (:meth:`update` raises the description's own one-line error).
    failure_reasons = {
        1: "the restricted description's robot-space fallback cannot invert the reference (INVKIN(c_des))",
        2: "a measured position is beyond the magnitude quatform accepts",
    }

    def step(self, t: float, measured, reference=None) -> np.ndarray:
        """Commands ``(..., 6)`` for ``measured`` (``(..., 11)``) from the initial state."""
        return self.update(t, measured, reference, self.init(np.shape(measured)[:-1])).u

    def reference_arrays(self, reference):
        """The tick's reference: ``{"c", "c_dot"}`` of shape ``(..., n_c)`` (NaN rows: hold,
        the robots brake; ``reference=None`` is one NaN row) and ``"invertible"`` (``(...)``:
        whether the restricted description's robot-space fallback can invert ``c``; True
        elsewhere). Checked as :meth:`update` checks a reference it uses (one-line errors):
        ``c`` and ``c_dot`` finite where ``c`` holds no NaN, and the quaternion description's
        ``q_c`` a unit quaternion there (every row, whether or not a frame comes).

        Raises
        ------
        InvalidInputError, ShapeError, NonFiniteError
        """
        _register_pytree()  # a driver asks for the references before it compiles the tick
        F = self.formation
        n_c = F.n_c
        if reference is None:
            nan = np.full(n_c, np.nan)
            return {"c": nan, "c_dot": nan.copy(), "invertible": np.ones((), dtype=bool)}
        if not isinstance(reference, Reference):
            raise InvalidInputError(f"{self.name} controller: reference must be a Reference(c, c_dot), got "
                                    f"{type(reference).__name__}")
        try:
            c, cd = np.asarray(reference.c, dtype=float), np.asarray(reference.c_dot, dtype=float)
        except (TypeError, ValueError):
            c, cd = as_array(reference.c, "reference.c", n_c), as_array(reference.c_dot, "reference.c_dot", n_c)
        if c.shape[-1:] != (n_c,) or cd.shape[-1:] != (n_c,):
            as_array(reference.c, "reference.c", n_c)
            as_array(reference.c_dot, "reference.c_dot", n_c)
        batch = np.broadcast_shapes(c.shape[:-1], cd.shape[:-1])
        c, cd = np.broadcast_to(c, batch + (n_c,)), np.broadcast_to(cd, batch + (n_c,))
        hold = np.any(np.isnan(c), axis=-1)
        used = ~hold

        def worlds():  # each world's own words, in order
            return [tuple(int(k) for k in i) for i in np.argwhere(used)]

        if np.any(used & ~(np.all(np.isfinite(c), axis=-1) & np.all(np.isfinite(cd), axis=-1))):
            for i in worlds():
                as_array(c[i], "reference.c", n_c)
                as_array(cd[i], "reference.c_dot", n_c)
        if isinstance(F, UgvUavQuaternion) and np.any(used):
            try:
                F.check_cluster_state(c if used.all() else c[used], "near_c")
            except QuatformError:
                for i in worlds():
                    F.check_cluster_state(c[i], "near_c")
        invertible = np.ones(batch, dtype=bool)
        if isinstance(F, UgvUavRestricted):
            invertible = used & F.invertible(c) | hold  # what F.inverse accepts (hold: not asked)
        return {"c": np.array(c), "c_dot": np.array(cd), "invertible": invertible}

    def update(self, t: float, measured, reference, state) -> contract.Step:
        """One step of Fig. 18: the checks, :meth:`reference_arrays` and :meth:`tick`.

        Parameters
        ----------
        t : float
            Time, s.
        measured : array_like, shape (..., 11)
            :data:`UGV_UAV_MEASURED_NAMES`; leading axes are worlds (NaN: a dropped frame).
        reference : Reference
            ``c``, ``c_dot`` of shape ``(..., n_c)`` (or one for every world). A ``c`` with a
            NaN (or ``reference=None``) means no reference the description can express: both
            robots brake (the UGV stops, the UAV brakes to a hover or stays on the floor).
        state : UgvUavState (from :meth:`init`)

        Returns
        -------
        Step
            ``u`` of shape ``(..., 6)``, the next state and the signals of :meth:`signal_columns`.

        Raises
        ------
        ShapeError
            ``measured`` not ``(..., 11)``.
        UnreachableError, InvalidInputError
            The restricted description's fallback with a reference it cannot invert (the
            description's own words); a measured position beyond ``MAX_MAGNITUDE`` (the robot,
            its state column and value, and the world of a batch); for the first such world.
        """
        m = np.asarray(measured, dtype=float)
        if m.shape[-1:] != (N_MEASURED,):
            m = as_array(measured, "measured state", N_MEASURED)
        ref = self.reference_arrays(reference)
        batch = np.broadcast_shapes(m.shape[:-1], state.batch, ref["c"].shape[:-1])
        tk = self.tick(_broadcast_state(state, batch), np.broadcast_to(m, batch + (N_MEASURED,)), ref, t)
        if np.any(tk.code):
            i = tuple(int(k) for k in np.argwhere(np.asarray(tk.code) > 0)[0])
            if tk.code[i] == 1:
                self.formation.inverse(np.broadcast_to(ref["c"], batch + (self.formation.n_c,))[i])
                raise InvalidInputError(f"{self.name} controller: {self.failure_reasons[1]}")
            raise InvalidInputError(f"{self.name} controller: {self._beyond_magnitude(tk.signals['used'][i], i)}")
        return contract.Step(tk.u, tk.state, tk.signals)

    def _beyond_magnitude(self, used, world: tuple) -> str:
        """The words of a measured position beyond ``MAX_MAGNITUDE`` (code 2): the robot, its
        state column and value in the frame used (``used``, 11 values) of ``world``, and the fix."""
        k, column, j = max(_POINT_ENTRIES, key=lambda e: abs(float(used[e[2]])))
        robot = self.team.robots[k]
        at = f" in world {world}" if world else ""
        return (f"measured {robot.name} {column} = {float(used[j]):.6g} {column_unit(robot, column)}{at} is beyond "
                f"the {MAX_MAGNITUDE:g} quatform accepts (squared lengths would overflow); express the state in "
                "larger units or nearer the origin")

    def tick(self, state, measured, ref, t) -> contract.Tick:
        """One pure, branch-free step of Fig. 18 on the array namespace of its operands (NumPy,
        or JAX under ``jax.jit``); every branch is computed and selected per world.

        The motion-capture screen (:meth:`MocapScreen.frame_code`): a good frame is used and
        remembered (a non-finite odometry entry replaced by the last good frame's, or 0); a
        dropped or rejected one is replaced by the last good frame (the odometry read now where
        finite) for up to ``max_hold_s``, then both robots stop (``stopped``, code
        :data:`STOP_MOTION_CAPTURE`); without a good frame yet both robots brake. On the frame
        used: the cluster state (the reference as hint), the law (4.43)-(4.45), the robot
        rates (4.42), or, where the restricted description cannot express the robots, the
        position law of (4.43) in robot space toward ``INVKIN(c_des)`` (seed 000 §3.1); non-finite
        rates read as 0; :attr:`walls`; the UAV's yaw rate (4.50)-(4.51); the team's actuation
        (3.5), (3.10), (4.47)-(4.49) and saturation. A reference row with a NaN (hold), no
        frame or the stop: both robots brake (the UGV stops, the UAV's (4.47) with
        ``v_r = 0``), and the compensation forgets its reference.

        Parameters
        ----------
        state : UgvUavState
            Arrays with leading axes ``batch``.
        measured : array, shape (*batch, 11)
            :data:`UGV_UAV_MEASURED_NAMES` (NaN entries: a dropped frame or odometry sample).
        ref : dict
            :meth:`reference_arrays` (leading axes ``batch`` or none).
        t : float or scalar array
            Time, s.

        Returns
        -------
        Tick
            ``u (*batch, 6)``, the next state, the signals of :meth:`signal_columns` and the
            code (:attr:`failure_reasons`).
        """
        F, p, b = self.formation, self.pioneer, self.bebop
        restricted = isinstance(F, UgvUavRestricted)
        m = as_floats(measured)
        xp = common_namespace(m, state.good, ref["c"], t)
        batch = tuple(m.shape[:-1])
        n_c = F.n_c

        def rows(mask):  # a (*batch) mask against (*batch, k) arrays
            return mask[..., None]

        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            # -- the screen (seed 001's lab): good, dropped or rejected
            good, good_t, bad_since, stopped = state.good, state.good_t, state.bad_since, state.stopped
            has_good = xp.isfinite(good_t)
            finite = xp.all(xp.isfinite(m[..., MOCAP_PART]), axis=-1)
            frame = self.mocap.frame_code(t, self.measured_points(m), finite, self.measured_points(good), good_t)
            ok = frame == 0
            odo, odo_good = m[..., ODOMETRY_PART], good[..., ODOMETRY_PART]
            odo_ok = xp.isfinite(odo)
            m_good = xp.concatenate([m[..., MOCAP_PART],
                                     xp.where(odo_ok, odo, xp.where(rows(has_good), odo_good, 0.0))], axis=-1)
            m_held = xp.concatenate([good[..., MOCAP_PART], xp.where(odo_ok, odo, odo_good)], axis=-1)
            used = xp.where(rows(ok), m_good, m_held)
            none = ~ok & ~has_good  # nothing to go on
            held = ~ok & has_good
            good = xp.where(rows(ok), m_good, good)
            good_t = xp.where(ok, t, good_t)
            bad_since = xp.where(ok, np.nan, xp.where(xp.isnan(bad_since), t, bad_since))
            expire = ~ok & ~stopped & self.mocap.expired(t, bad_since)
            stopped = stopped | expire
            stop_code = xp.where(expire, STOP_MOTION_CAPTURE, state.stop_code)
            stop_t = xp.where(expire, t, state.stop_t)
            stop_since = xp.where(expire, bad_since, state.stop_since)
            # -- the reference: held (a NaN) or tracked
            c_des = xp.broadcast_to(as_floats(ref["c"]), batch + (n_c,))
            c_dot = xp.broadcast_to(as_floats(ref["c_dot"]), batch + (n_c,))
            hold = xp.any(xp.isnan(c_des), axis=-1)
            # -- the chain on the frame used: (4.43)-(4.45), (4.42)
            points = self.measured_points(used)
            r = xp.concatenate(points, axis=-1)
            c = F.forward_arrays(r, c_des)
            err, c_rate = self.cluster_rates(c, c_des, c_dot)
            x_rate = _matvec(xp, F.inverse_jacobian_arrays(c), c_rate)
            if restricted:  # robot-space control toward INVKIN(c_des) where F cannot express r (seed 000 §3.1)
                inside = F.reachable(r)
                if _taken(xp, ~inside):
                    r_des = F.inverse_arrays(c_des)
                    ff = 1.0 if self.feedforward else 0.0
                    x_space = ff * _matvec(xp, F.inverse_jacobian_arrays(c_des), c_dot) - \
                        np.r_[self.k_x, self.k_x] * xp.tanh(r - r_des)
                    x_rate = xp.where(rows(inside), x_rate, x_space)
                c = xp.where(rows(inside), c, np.nan)
                err = xp.where(rows(inside), err, np.nan)
            else:
                inside = xp.ones(batch, dtype=bool)
            rates_finite = xp.all(xp.isfinite(x_rate), axis=-1)
            x_rate = self.walls.limit(points, xp.where(rows(rates_finite), x_rate, 0.0))
            # -- the commands: the team's actuation, or a brake (no frame, hold, stopped)
            memory = BebopMemory(state.v_r, state.mem_t, state.v_dot)
            psi_rate = self.heading.rate(used[..., PSI_P], used[..., PSI_B])  # (4.50)-(4.51), psi_bd = psi_p
            u_p, _ = p.actuate(used[..., PIONEER_PART], x_rate[..., UGV_POINT], t)
            rate_b = xp.concatenate([x_rate[..., UAV_POINT], psi_rate[..., None]], axis=-1)
            u_b, mem = b.actuate(used[..., BEBOP_PART], rate_b, t, memory)
            u_b_brake, mem_brake = b.brake(xp.where(rows(none), m, used)[..., BEBOP_PART], memory)
            brake = none | hold | stopped
            u = xp.concatenate([xp.where(rows(brake), 0.0, p.saturate(u_p)),
                                b.saturate(xp.where(rows(brake), u_b_brake, u_b))], axis=-1)
            v_r = xp.where(rows(brake), mem_brake.v_r, mem.v_r)
            mem_t = xp.where(brake, mem_brake.t, mem.t)
            v_dot = xp.where(rows(brake), mem_brake.v_dot, mem.v_dot)
            # -- the signals; where it holds, the cluster of the robots as they are
            outside_free = ~F.reachable(r) if restricted else xp.zeros(batch, dtype=bool)
            braking = none | hold
            c_free = F.forward_arrays(r, None) if _taken(xp, hold) else c  # the robots' cluster where it holds
            cluster = xp.where(rows(none | (hold & outside_free)), np.nan, xp.where(rows(hold), c_free, c))
            one = xp.ones(batch)
            signals = {
                "cluster": cluster, "error": xp.where(rows(braking), np.nan, err),
                "robot_rates": xp.where(rows(braking), 0.0, x_rate),
                "raw_finite": xp.where(none, 0.0, xp.where(hold, 1.0, rates_finite * one))[..., None],
                "stopped": (stopped * one)[..., None], "frame": (frame * one)[..., None],
                "held": (held * one)[..., None], "no_frame": (none * one)[..., None],
                "outside": (xp.where(none, False, xp.where(hold, outside_free, ~inside)) * one)[..., None],
                "used": xp.where(rows(none), np.nan, used)}
            # -- what the description refuses (update raises its words)
            big = ~(xp.max(xp.abs(r), axis=-1) <= MAX_MAGNITUDE)
            code = xp.where(~none & big & ~(hold & outside_free), 2, 0)
            if restricted:
                invertible = xp.broadcast_to(as_floats(ref["invertible"]) > 0, batch)
                code = xp.where(~none & ~hold & ~inside & ~invertible & (code == 0), 1, code)
        nxt = UgvUavState(v_r, mem_t, v_dot, stopped, stop_code, stop_t, stop_since, good, good_t, bad_since,
                          state.hold_s)
        return contract.Tick(nxt, u, signals, code)

    def cluster_rates(self, c, c_des, c_dot_des):
        """Cluster error and rate reference, eqs. (4.43)-(4.45) (:attr:`law`), ``(..., n_c)``
        each (any namespace; one world's on Python floats, as the law is written)."""
        F = self.formation
        e = None if isinstance(F, UgvUavQuaternion) else kern.unpack(F.errors(c, c_des))  # angles wrapped
        err, rate = self.law(kern.unpack(c), kern.unpack(c_des), kern.unpack(c_dot_des), e)
        return kern.pack(err), kern.pack(rate)

    def measured_points(self, m):
        """The robots' positions in the 11 measured values (the Pioneer's at ``z_ugv``), ``(..., 3)``
        each (any namespace)."""
        if concrete(m) and np.ndim(m) == 1:
            return (np.array([*m[UGV_XY], self.z_ugv]), m[UAV_XYZ])
        xp = common_namespace(m)
        return (xp.concatenate([m[..., UGV_XY], xp.full(m.shape[:-1] + (1,), self.z_ugv, dtype=m.dtype)], axis=-1),
                m[..., UAV_XYZ])


def _taken(xp, mask) -> bool:
    """Whether a branch selected where ``mask`` is computed: always on a traced namespace (JAX:
    both branches, selected); on NumPy only where some world takes it (the values selected
    are the same)."""
    return xp is not np or bool(np.any(mask))


def _matvec(xp, J, v):
    """``J v`` per world, ``(..., n, k) (..., k) -> (..., n)``: a stacked ``matmul`` (on NumPy
    the same sums as one world's ``J @ v`` of a contiguous ``J``)."""
    if xp is np:
        J = np.ascontiguousarray(J)
    return xp.matmul(J, v[..., None])[..., 0]


def _broadcast_state(state: UgvUavState, batch: tuple) -> UgvUavState:
    """``state`` with its arrays broadcast to ``batch`` leading axes (one state for every world)."""
    if state.batch == tuple(batch):
        return state
    n = len(state.batch)  # each field's entries after the batch axes
    return replace(state, **{k: np.broadcast_to(getattr(state, k), tuple(batch) + np.shape(getattr(state, k))[n:])
                             for k in _ARRAY_FIELDS})
