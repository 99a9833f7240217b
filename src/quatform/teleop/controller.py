"""The bilateral teleoperation controller of seed 003, usable on real arms or in simulation.

Teleop layer, at the control level (it implements :class:`quatform.control.contract.Controller`
and uses the law of :mod:`quatform.control.stiffness`). :class:`TeleopController` turns one
measurement of both arms (joint angles and rates, the slave's wrist force) into the master's
and the slave's joint torques:
eqs. (14a)/(14b) with the Euler-parameter error (or, as the baseline the seed argues
against, a roll-pitch-yaw error), force reflection ``v J_mf^T F_s``, the null-space
redundancy torque, virtual walls in the master's Cartesian space, the preload function
on the master's actuators, and saturation to each joint's limit. Settings and
measurements are validated, so commands are finite; should a torque still come out
non-finite, both arms get zero torque and the cycle is reported. (The RPY baseline at
gimbal lock is finite but huge, ``1 / cos(pitch)`` ~ 1e16, and is saturated.) Gravity is
taken as compensated on both arms (``tau_grav`` of (11)-(12)).

As a :class:`~quatform.control.contract.Controller` it is stateless (``init()`` is None):
``update(t, measured, None, None)`` takes the stacked measurement (columns
:attr:`TeleopController.measured_columns`: ``q_m``, ``qd_m``, ``q_s``, ``qd_s``, ``F_s``) or a
:class:`TeleopMeasurement` and returns the 13 torques (:attr:`TeleopController.command_names`,
master first) with the signals :meth:`TeleopController.signal_columns` names (the poses,
the task error, the walls' force and the flags of :class:`TeleopCommand`); ``step`` returns
``(tau_m, tau_s)`` as on a real arm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ..algebra import matrix_from_q, qconj, qmul
from ..algebra.kernels import array_namespace
from ..algebra.validate import as_array, as_unit_quaternion
from ..checks import short
from ..control.contract import Controller, Step, Tick
from ..control.stiffness import StiffnessGains, force_stability_term, virtual_wall_force
from ..errors import InvalidInputError, NonFiniteError, ShapeError
from .arm import SerialArm
from .kernels import over_worlds, q_from_rotation
from .kraft import KRAFT_FULL_SCALE, KRAFT_MASTER, KRAFT_PRELOAD
from .slave import PANDA_SLAVE, PANDA_TORQUE_LIMITS, RigidArm
from .task import rpy_from_matrix, rpy_rates, wrap_angle

__all__ = ["ORIENTATION_ERRORS", "MAX_WALL_STIFFNESS", "MAX_JOINT_ANGLE", "MAX_JOINT_RATE", "MAX_WRIST_FORCE",
           "MAX_WRIST_MOMENT", "Registration", "VirtualWall", "TeleopMeasurement",
           "TeleopCommand", "TeleopController"]

#: The orientation errors a controller can use.
ORIENTATION_ERRORS = ("euler-parameters", "rpy")

#: The stiffest virtual wall a :class:`VirtualWall` accepts, N/m. A sampled controller holds a
#: wall of stiffness k on a tool of effective mass m stably only while k dt^2 + 2 c dt < 4 m
#: (:func:`quatform.control.stiffness.explicit_stiffness_limit`): 1e9 N/m would need a 1 kg
#: tool and a 10 kHz loop with no damping; the simulator checks the limit of its own master and period.
MAX_WALL_STIFFNESS = 1e9


@dataclass(frozen=True)
class Registration:
    """The fixed map of the master's tool pose into the slave's workspace.

    ``p -> scale R_base (p - p_master0) + p_slave0`` and ``q -> q_base q q_tool``: the
    master's base axes are turned onto the slave's by ``q_base`` (identity: pushing the
    handle forward moves the slave forward), and the constant tool offset ``q_tool`` makes
    the two home orientations coincide. A master rotation about a base axis becomes the
    same rotation of the slave about the corresponding base axis.
    """

    base: np.ndarray
    tool: np.ndarray
    p_master0: np.ndarray
    p_slave0: np.ndarray
    scale: float = 1.0

    def __post_init__(self):
        object.__setattr__(self, "base", as_unit_quaternion(self.base, "base"))
        object.__setattr__(self, "tool", as_unit_quaternion(self.tool, "tool"))
        object.__setattr__(self, "p_master0", as_array(self.p_master0, "p_master0", 3))
        object.__setattr__(self, "p_slave0", as_array(self.p_slave0, "p_slave0", 3))
        if not (np.isfinite(self.scale) and self.scale > 0):
            raise InvalidInputError(f"registration scale must be finite and > 0, got {self.scale!r}")

    @classmethod
    def from_homes(cls, master: SerialArm, slave: SerialArm, q_m0, q_s0, scale: float = 1.0,
                   base=(1.0, 0.0, 0.0, 0.0)) -> Registration:
        """The registration that makes the tool poses at ``q_m0`` and ``q_s0`` coincide."""
        p_m0, r_m0 = master.forward(q_m0)
        p_s0, r_s0 = slave.forward(q_s0)
        base = as_unit_quaternion(base, "base")
        return cls(base, qmul(qconj(qmul(base, r_m0)), r_s0), p_m0, p_s0, float(scale))

    def apply(self, p_m, r_m, J_mf):
        """The master's tool position, orientation and Jacobian in the slave's workspace."""
        R = matrix_from_q(self.base)
        J = np.array(J_mf, dtype=float)
        J[..., 0:3, :] = self.scale * (R @ J[..., 0:3, :])
        J[..., 3:6, :] = R @ J[..., 3:6, :]
        p = self.scale * np.einsum("ij,...j->...i", R, np.asarray(p_m) - self.p_master0) + self.p_slave0
        return p, qmul(qmul(self.base, r_m), self.tool), J


@dataclass(frozen=True)
class VirtualWall:
    """A plane in the master's Cartesian space the tool point must not cross (seed 003 §7).

    The forbidden side is ``normal . p > offset`` (master base frame, m). The wall pushes
    back with ``resist_force_n / thickness_m`` N per metre of depth (plus ``damping``
    against motion into it): a spring, not a hard stop. A push of ``F`` below
    ``resist_force_n`` still takes the tool ``F / stiffness`` into the zone (and a slave that
    follows the master as far into the matching zone); at rest a push of more than
    ``resist_force_n`` (plus what the master's own friction holds) gets through its
    ``thickness_m``. Its stiffness must be finite and at most :data:`MAX_WALL_STIFFNESS`; a
    given master and control period hold less
    (:func:`quatform.control.stiffness.explicit_stiffness_limit`).
    """

    normal: tuple
    offset: float
    resist_force_n: float = 8.0
    thickness_m: float = 0.02
    damping: float = 20.0

    def __post_init__(self):
        try:
            n = np.asarray(self.normal, float)
        except (TypeError, ValueError):
            n = None
        if n is None or n.shape != (3,) or not np.all(np.isfinite(n)) or np.linalg.norm(n) < 1e-9:
            raise InvalidInputError(f"virtual wall normal must be a nonzero 3-vector of finite numbers, "
                                    f"got {short(self.normal)}")
        for name, low in (("offset", None), ("resist_force_n", 0.0), ("thickness_m", 0.0), ("damping", 0.0)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
                raise InvalidInputError(f"virtual wall {name} = {short(v)} must be a number")
            if not math.isfinite(v) or (low is not None and (v < low if name == "damping" else v <= low)):
                unit = {"offset": "m", "resist_force_n": "N", "thickness_m": "m", "damping": "N s/m"}[name]
                cond = "finite" if low is None else ("finite and >= 0" if name == "damping" else "finite and > 0")
                raise InvalidInputError(f"virtual wall {name} = {short(v)} must be {cond} ({unit})")
        # resist_force_n / thickness_m can overflow (1e300 / 1e-300): an infinite stiffness
        # makes an infinite force, whose torques the controller would zero on both arms
        k = self.resist_force_n / self.thickness_m
        if not (math.isfinite(k) and k <= MAX_WALL_STIFFNESS):
            raise InvalidInputError(
                f"virtual wall resist_force_n / thickness_m = {self.resist_force_n:g} / {self.thickness_m:g} N/m "
                f"= {k:g} N/m is beyond any sampled controller's reach (at most {MAX_WALL_STIFFNESS:g} N/m here; "
                "the limit of a given master and control period is control.stiffness.explicit_stiffness_limit); "
                "make the wall thicker or its resist force smaller")

    @property
    def stiffness(self) -> float:
        return self.resist_force_n / self.thickness_m

    def depth(self, p) -> np.ndarray:
        n = np.asarray(self.normal, float)
        return np.asarray(p, float) @ (n / np.linalg.norm(n)) - self.offset

    def force(self, p, p_dot) -> np.ndarray:
        return virtual_wall_force(p, p_dot, self.normal, self.offset, self.stiffness, self.damping)


@dataclass(frozen=True)
class TeleopMeasurement:
    """What a teleoperator reads each cycle (SI units).

    ``q_m``, ``qd_m``: master joints ``(n_m,)``; ``q_s``, ``qd_s``: slave joints ``(n_s,)``;
    ``F_s``: the wrench the slave exerts on its environment (wrist sensor, base axes),
    ``(6,)`` ``[force; moment]``; :meth:`TeleopController.update` also takes fields with
    leading batch axes (worlds; the batch is ``q_m``'s). The controller refuses a measurement that is not finite or
    is beyond what the arms can do: an angle beyond :data:`MAX_JOINT_ANGLE`, a rate beyond
    :data:`MAX_JOINT_RATE`, a force or moment beyond :data:`MAX_WRIST_FORCE` /
    :data:`MAX_WRIST_MOMENT`.
    """

    q_m: np.ndarray
    qd_m: np.ndarray
    q_s: np.ndarray
    qd_s: np.ndarray
    F_s: np.ndarray = field(default_factory=lambda: np.zeros(6))


@dataclass(frozen=True)
class TeleopCommand:
    """Torques to send (finite, saturated) and what they came from.

    ``tau_m`` ``(n_m,)`` after preload and saturation (zero on unactuated joints), ``tau_s``
    ``(n_s,)``; ``e`` the task error (position m; ``delta_eps`` or RPY rad); ``p_m``, ``r_m``
    the master's registered pose, ``p_s``, ``r_s`` the slave's; ``wall_force`` the virtual
    walls' force on the master (master axes); ``raw_finite`` False if a torque was not finite
    (both arms then get zero torque); ``saturated`` True if any torque hit its limit;
    ``null_space_ok`` False if the slave was at a kinematic singularity and the redundancy
    torque was left out; ``J_mf``, ``J_sf`` the arms' own Jacobians and ``M_s`` the slave's
    mass matrix at the measured configuration.
    """

    tau_m: np.ndarray
    tau_s: np.ndarray
    e: np.ndarray
    p_m: np.ndarray
    r_m: np.ndarray
    p_s: np.ndarray
    r_s: np.ndarray
    wall_force: np.ndarray
    raw_finite: bool
    saturated: bool
    null_space_ok: bool
    J_mf: np.ndarray
    J_sf: np.ndarray
    M_s: np.ndarray


#: Columns of the signals :meth:`TeleopController.update` returns.
_SIGNAL_COLUMNS = {
    "p_m": ("p_m_x", "p_m_y", "p_m_z"), "r_m": ("r_m_w", "r_m_x", "r_m_y", "r_m_z"),
    "p_s": ("p_s_x", "p_s_y", "p_s_z"), "r_s": ("r_s_w", "r_s_x", "r_s_y", "r_s_z"),
    "e": tuple(f"e_{i + 1}" for i in range(6)), "wall_force": ("wall_force_x", "wall_force_y", "wall_force_z"),
    "raw_finite": ("raw_finite",), "saturated": ("saturated",), "null_space_ok": ("null_space_ok",),
}


def _limits(values, n, name):
    a = np.broadcast_to(np.asarray(values, float), (n,)).copy()
    if not np.all(np.isfinite(a)) or np.any(a < 0):
        raise InvalidInputError(f"{name} must be finite and >= 0 for each of {n} joints, got {values!r}")
    return a


@dataclass(frozen=True)
class TeleopController(Controller):
    """Seed 003's master and slave stiffness controllers as one object.

    Parameters
    ----------
    registration : Registration
        Master tool pose -> slave workspace (:meth:`Registration.from_homes`).
    q_rest : array_like, shape (n_s,)
        The slave posture the null-space torque pulls toward (the redundancy of joint 7).
    gains_master, gains_slave : StiffnessGains
        ``K_pm, K_vm`` and ``K_ps, K_vs``.
    orientation_error : {"euler-parameters", "rpy"}
    reflection : float
        The constant ``v`` of eq. (11) (negative), used when ``k_for`` is None.
    k_for : float, optional
        State-dependent ``v = -k_for x_m_dot^T F_s``.
    preload_nm : array_like, shape (n_m,), optional
        Preload offsets of the master's actuators (N m); None: off.
    master_limits, slave_limits : array_like
        Torque limits, N m (0 on an unactuated joint).
    walls : tuple of VirtualWall
    """

    registration: Registration
    q_rest: np.ndarray
    master: SerialArm = KRAFT_MASTER
    slave: RigidArm = PANDA_SLAVE
    gains_master: StiffnessGains = StiffnessGains()
    gains_slave: StiffnessGains = StiffnessGains()
    orientation_error: str = "euler-parameters"
    reflection: float = -0.5
    k_for: float | None = None
    preload_nm: np.ndarray | None = None
    master_limits: np.ndarray = field(default_factory=lambda: np.array(KRAFT_FULL_SCALE))
    slave_limits: np.ndarray = field(default_factory=lambda: np.array(PANDA_TORQUE_LIMITS))
    walls: tuple = ()
    k_null: float = 5.0
    d_null: float = 1.0

    #: Name in files and logs.
    name = "teleop"

    def __post_init__(self):
        if self.orientation_error not in ORIENTATION_ERRORS:
            raise InvalidInputError(f"orientation_error must be one of {', '.join(ORIENTATION_ERRORS)}, "
                                    f"got {self.orientation_error!r}")
        n_m, n_s = self.master.n, self.slave.arm.n
        object.__setattr__(self, "q_rest", as_array(self.q_rest, "q_rest", n_s).copy())
        object.__setattr__(self, "master_limits", _limits(self.master_limits, n_m, "master_limits"))
        object.__setattr__(self, "slave_limits", _limits(self.slave_limits, n_s, "slave_limits"))
        if self.preload_nm is not None:
            object.__setattr__(self, "preload_nm", _limits(self.preload_nm, n_m, "preload_nm"))
        force_stability_term(constant=self.reflection)  # validates: finite, v < 0
        if self.k_for is not None:
            force_stability_term(np.zeros(3), np.zeros(3), k_for=self.k_for)  # validates: finite, >= 0
        for name in ("k_null", "d_null"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise InvalidInputError(f"{name} must be finite and >= 0, got {v!r}")
        if not isinstance(self.registration, Registration):
            raise InvalidInputError(f"registration must be a Registration, got {type(self.registration).__name__}; "
                                    "use Registration.from_homes(master, slave, q_m0, q_s0)")

    @classmethod
    def default_preload(cls) -> np.ndarray:
        """Seed 003's preload: ~10 % of full scale, 5 % on wrist pitch and yaw (N m)."""
        return np.asarray(KRAFT_PRELOAD) * np.asarray(KRAFT_FULL_SCALE)

    # -- the controller contract (quatform.control.contract) --------------------------
    @cached_property
    def command_names(self) -> tuple[str, ...]:
        """``tau_m1 ... tau_m{n_m}`` then ``tau_s1 ... tau_s{n_s}`` (N m)."""
        return (tuple(f"tau_m{i + 1}" for i in range(self.master.n))
                + tuple(f"tau_s{i + 1}" for i in range(self.slave.arm.n)))

    @cached_property
    def measured_columns(self) -> tuple[str, ...]:
        """Columns of the stacked measurement :meth:`update` takes: ``q_m``, ``qd_m`` (rad,
        rad/s), ``q_s``, ``qd_s``, then ``F_s`` (``F_s_x, F_s_y, F_s_z`` N, ``M_s_x, M_s_y,
        M_s_z`` N m)."""
        n_m, n_s = self.master.n, self.slave.arm.n
        return (tuple(f"q_m{i + 1}" for i in range(n_m)) + tuple(f"qd_m{i + 1}" for i in range(n_m))
                + tuple(f"q_s{i + 1}" for i in range(n_s)) + tuple(f"qd_s{i + 1}" for i in range(n_s))
                + ("F_s_x", "F_s_y", "F_s_z", "M_s_x", "M_s_y", "M_s_z"))

    def signal_columns(self) -> dict[str, tuple[str, ...]]:
        """The :class:`TeleopCommand` fields a log keeps: the registered master pose ``p_m``
        (m), ``r_m`` (unit quaternion), the slave's ``p_s``, ``r_s``, the task error ``e``, the
        virtual walls' force ``wall_force`` (N, master axes) and the flags ``raw_finite``,
        ``saturated``, ``null_space_ok`` (1 true, 0 false)."""
        return dict(_SIGNAL_COLUMNS)

    def measurement_of(self, measured) -> TeleopMeasurement:
        """``measured`` as a :class:`TeleopMeasurement`: one already, or the stacked vectors
        of :attr:`measured_columns` (shape ``(..., 32)`` for the Kraft master and the Panda;
        leading axes are worlds), its fields ``(..., k)``."""
        if isinstance(measured, TeleopMeasurement):
            return measured
        cols = self.measured_columns
        try:
            a = np.asarray(measured, dtype=float)
        except (TypeError, ValueError):
            raise InvalidInputError(f"measurement {short(measured)} must be a TeleopMeasurement or {len(cols)} "
                                    f"numbers ({cols[0]} ... {cols[-1]}, SI units)") from None
        if a.shape[-1:] != (len(cols),):
            raise ShapeError(f"a stacked teleop measurement must have shape (..., {len(cols)}) "
                             f"({cols[0]} ... {cols[-1]}; leading axes are worlds), got {a.shape}")
        n_m, n_s = self.master.n, self.slave.arm.n
        i = np.cumsum([n_m, n_m, n_s, n_s])
        return TeleopMeasurement(a[..., :i[0]], a[..., i[0]:i[1]], a[..., i[1]:i[2]], a[..., i[2]:i[3]],
                                 a[..., i[3]:])

    #: :meth:`tick` is pure and branch-free (it runs under ``jax.jit``).
    pure = True
    #: Why a world's cycle failed (:attr:`~quatform.control.contract.Tick.code`).
    failure_reasons = {1: "the measurement is not finite or beyond what the arms can be"}

    def reference_arrays(self, reference) -> dict:
        """Nothing: each arm's reference is the other arm."""
        return {}

    @cached_property
    def _bounds(self) -> np.ndarray:
        """Each measured entry's bound (what :func:`_measured` accepts), ``(n_m,)``."""
        n_m, n_s = self.master.n, self.slave.arm.n
        return np.concatenate([np.full(n_m, MAX_JOINT_ANGLE), np.full(n_m, MAX_JOINT_RATE),
                               np.full(n_s, MAX_JOINT_ANGLE), np.full(n_s, MAX_JOINT_RATE), _WRENCH_BOUND])

    def tick(self, state, measured, reference, t) -> Tick:
        """One pure cycle of every world: ``measured`` ``(*batch, n_m)`` (:attr:`measured_columns`)
        in, :class:`~quatform.control.contract.Tick` out (state None; code 1 where the
        measurement is not finite or beyond :func:`_measured`'s bounds). The law of one world
        (:meth:`law`) on NumPy or JAX arrays, a batch world by world
        (:func:`~quatform.teleop.kernels.over_worlds`)."""
        n_m, n_s = self.master.n, self.slave.arm.n
        i = np.cumsum([n_m, n_m, n_s, n_s])
        bounds = self._bounds

        def world(m):
            xp = array_namespace(m)
            ok = xp.all(xp.isfinite(m) & (xp.abs(m) <= bounds))
            out = self.law(m[:i[0]], m[i[0]:i[1]], m[i[1]:i[2]], m[i[2]:i[3]], m[i[3]:], True)
            tau_m, tau_s, e, p_m, r_m, p_s, r_s, wall, finite, saturated, null_ok = out[:11]
            flags = tuple(xp.where(f, 1.0, 0.0)[None] for f in (finite, saturated, null_ok))
            signals = (p_m, xp.stack(r_m), p_s, xp.stack(r_s), e, wall) + flags
            return xp.concatenate([tau_m, tau_s]), signals, xp.where(ok, 0, 1)

        u, signals, code = over_worlds(world, np.ndim(measured) - 1, measured)
        return Tick(None, u, dict(zip(_SIGNAL_COLUMNS, signals)), code)

    def _checked(self, measured) -> np.ndarray:
        """The stacked measurement ``(*batch, n)`` of :attr:`measured_columns`, every world's
        fields checked by :func:`_measured` (one-line errors; a batch's name the world)."""
        mm = self.measurement_of(measured)
        M, S = self.master, self.slave.arm
        fields = (("q_m", M.n), ("qd_m", M.n), ("q_s", S.n), ("qd_s", S.n), ("F_s", 6))
        batch = np.shape(mm.q_m)[:-1]
        if not batch:
            return np.concatenate([_measured(getattr(mm, name), name, n) for name, n in fields])
        parts = []
        for name, n in fields:
            try:
                a = np.asarray(getattr(mm, name), dtype=float)
            except (TypeError, ValueError):
                raise InvalidInputError(f"measurement {name} = {short(getattr(mm, name))} must be {n} numbers per "
                                        "world (SI units); check the sensor reading") from None
            try:
                a = np.broadcast_to(a, batch + (n,))
            except ValueError:
                raise ShapeError(f"measurement {name} must have shape {batch + (n,)} (q_m's worlds) or one for "
                                 f"every world ({n},), got {a.shape}") from None
            for world in np.ndindex(*batch):
                _measured(a[world], name, n, world)
            parts.append(a)
        return np.concatenate(parts, axis=-1)

    def update(self, t: float, measured, reference=None, state=None) -> Step:
        """One cycle of every world: ``Step(u, None, signals)``, ``u`` the torques of
        :attr:`command_names`, ``(..., n_m + n_s)``.

        ``measured``: the stacked vectors of :attr:`measured_columns` (``(..., 32)``, leading
        axes are worlds) or a :class:`TeleopMeasurement` (fields ``(..., k)``), each world
        checked (one-line errors naming the world of a batch); then :meth:`tick`.
        ``reference`` and ``state`` are unused (each arm's reference is the other arm; the
        controller keeps no state).
        """
        out = self.tick(None, self._checked(measured), {}, t)
        if np.any(out.code > 0):  # the checks above refuse every such measurement first
            raise InvalidInputError(f"teleop controller: {self.failure_reasons[int(np.max(out.code))]}")
        return Step(out.u, None, dict(out.signals))

    def step(self, t: float, measured, reference=None) -> tuple[np.ndarray, np.ndarray]:
        """Master and slave torques ``(tau_m, tau_s)`` (N m, ``(..., n_m)`` and ``(..., n_s)``).

        ``measured``: a :class:`TeleopMeasurement` (or the stacked vectors :meth:`update`
        takes); one world runs the law directly, a batch through :meth:`update`. In bilateral
        teleoperation each arm's reference is the other arm, so ``reference`` is unused
        (accepted for the common controller signature).
        """
        mm = self.measurement_of(measured)
        if np.ndim(mm.q_m) <= 1:
            return self._cycle(mm, details=False)
        u = self.update(t, mm).u
        return u[..., :self.master.n], u[..., self.master.n:]

    @cached_property
    def _fixed(self):
        """Per-controller constants: the registration as a 6x6 block map, gains, masks."""
        R = matrix_from_q(self.registration.base)
        G6 = np.zeros((6, 6))
        G6[0:3, 0:3], G6[3:6, 3:6] = self.registration.scale * R, R
        act = np.array([1.0 if a else 0.0 for a in (self.master.actuated or (True,) * self.master.n)])
        gm, gs = self.gains_master, self.gains_slave
        quarter = np.r_[1.0, 1.0, 1.0, 0.25, 0.25, 0.25]
        off = np.zeros(self.master.n) if self.preload_nm is None else self.preload_nm
        switch = off / 2.0  # the preload function's ramp (control.preload's default)
        aligned = bool(np.array_equal(R, np.eye(3)) and self.registration.scale == 1.0)
        return {"R_base": R, "R_tool": matrix_from_q(self.registration.tool), "G6": G6, "actuated": act,
                "aligned": aligned,
                "kp_m": gm.kp, "kv_m": gm.kv, "kp_s": gs.kp, "kv_s": gs.kv, "kp_m_rpy": quarter * gm.kp,
                "kv_m_rpy": quarter * gm.kv, "kp_s_rpy": quarter * gs.kp, "kv_s_rpy": quarter * gs.kv,
                "preload": off, "inv_switch": np.where(switch > 0, 1.0 / np.where(switch > 0, switch, 1.0), 0.0)}

    def compute(self, t: float, measured: TeleopMeasurement) -> TeleopCommand:
        """:meth:`step` with everything it computed (:class:`TeleopCommand`)."""
        return self._cycle(self.measurement_of(measured), details=True)

    def _cycle(self, measured: TeleopMeasurement, details: bool):
        """One control cycle; ``details``: return a :class:`TeleopCommand`, else the torques.

        One configuration of each arm: the arms' frames are computed once and shared by
        the forward kinematics, the Jacobians and the mass matrix; the orientation error
        comes from ``R_M^T R_S`` directly. ``tests/test_teleop_controller.py`` checks it
        against the general functions of :mod:`.control` and :mod:`.task`.
        """
        M, S = self.master, self.slave.arm
        q_m, qd_m = _measured(measured.q_m, "q_m", M.n), _measured(measured.qd_m, "qd_m", M.n)
        q_s, qd_s = _measured(measured.q_s, "q_s", S.n), _measured(measured.qd_s, "qd_s", S.n)
        F_s = _measured(measured.F_s, "F_s", 6)
        out = self.law(q_m, qd_m, q_s, qd_s, F_s, details)
        if not details:
            return out
        tau_m, tau_s, e, p_m, r_m, p_s, r_s, wall, finite, saturated, null_ok, J_mf, J_sf, M_s = out
        return TeleopCommand(tau_m, tau_s, e, p_m, np.array(r_m), p_s, np.array(r_s), wall, bool(finite),
                             bool(saturated), bool(null_ok), J_mf, J_sf, M_s)

    def law(self, q_m, qd_m, q_s, qd_s, F_s, details: bool = True):
        """The control law of one cycle on measurements already checked (:func:`_measured`):
        NumPy or JAX arrays (:func:`quatform.algebra.kernels.array_namespace`; the teleop
        :meth:`tick` runs it compiled). Returns ``(tau_m,
        tau_s)``, or with ``details`` the fields of :class:`TeleopCommand` in order (the
        quaternions as component tuples, the flags as booleans of the namespace)."""
        xp = array_namespace(q_m)
        M, S, K = self.master, self.slave.arm, self._fixed
        Fm, Fs = M.frames_unchecked(q_m), S.frames_unchecked(q_s)  # each arm's frames once per cycle
        J_mf, J_sf = M.jacobian(q_m, Fm), S.jacobian(q_s, Fs)
        reg = self.registration
        if K["aligned"]:  # base axes aligned, scale 1 (the default): no products needed
            p_m = M.tool(Fm) - reg.p_master0 + reg.p_slave0
            R_m, Jm = Fm[-1, 0:3, 0:3] @ K["R_tool"], J_mf
        else:
            p_m = reg.scale * (K["R_base"] @ (M.tool(Fm) - reg.p_master0)) + reg.p_slave0
            R_m = K["R_base"] @ Fm[-1, 0:3, 0:3] @ K["R_tool"]
            Jm = K["G6"] @ J_mf  # the master's Jacobian in the slave's workspace
        p_s, R_s = S.tool(Fs), Fs[-1, 0:3, 0:3]
        I3, O3 = np.eye(3), np.zeros((3, 3))
        if self.orientation_error == "euler-parameters":
            # seed 003 eqs. (8)-(10): {d_eps4, d_eps_hat} of R_M^T R_S, the short way (d_eps4 >= 0)
            w, x, y, z = q_from_rotation(R_m.T @ R_s)
            # seed 003 eq. (19): d/dt d_eps_hat = W (omega_S - omega_M), W = 1/2 (d_eps4 I - [d_eps_hat]x) R_M^T
            rot = 0.5 * xp.asarray([[w, z, -y], [-z, w, x], [y, -x, w]]) @ R_m.T
            e = xp.concatenate([p_s - p_m, xp.asarray([x, y, z])])
            T6 = xp.block([[I3, O3], [O3, rot]])
            J_m, J_s = T6 @ Jm, T6 @ J_sf  # seed 003 eqs. (16), (18)
            kp_m, kv_m, kp_s, kv_s = K["kp_m"], K["kv_m"], K["kp_s"], K["kv_s"]
        else:
            rpy_m, rpy_s = rpy_from_matrix(R_m), rpy_from_matrix(R_s)
            e = xp.concatenate([p_s - p_m, wrap_angle(rpy_s - rpy_m)])
            with np.errstate(divide="ignore", invalid="ignore"):  # E^-1 divides by cos(pitch)
                J_m = xp.block([[I3, O3], [O3, rpy_rates(rpy_m)]]) @ Jm
                J_s = xp.block([[I3, O3], [O3, rpy_rates(rpy_s)]]) @ J_sf
            # gains kp_rot / 4: at pitch 0 the same small-angle stiffness and damping as the
            # Euler-parameter law, whose moment per radian is kp_rot / 4 (delta_eps ~ angle / 2,
            # W ~ R^T / 2); elsewhere the RPY law's is (kp_rot / 4) E^-T E^-1, whose eigenvalues
            # are 1 / (1 + |sin pitch|), 1 and 1 / (1 - |sin pitch|) (x0.53, x1, x9.2 at pitch
            # -63 deg, unbounded toward +-90 deg; docs/derivations.md, "Teleoperation measurements and the gimbal-lock band")
            kp_m, kv_m, kp_s, kv_s = K["kp_m_rpy"], K["kv_m_rpy"], K["kp_s_rpy"], K["kv_s_rpy"]
        e_dot = J_s @ qd_s - J_m @ qd_m
        tau_m = J_m.T @ (kp_m * e + kv_m * e_dot)  # seed 003 eq. (14a)
        tau_s = -(J_s.T @ (kp_s * e + kv_s * e_dot))  # seed 003 eq. (14b)
        # tau_red = (I - J^T J_bar^T) y with J_bar = M^-1 J^T (J M^-1 J^T)^-1 (eq. (13)):
        # J^T J_bar^T y = J^T (J X)^-1 X^T y, X = M^-1 J^T
        M_s = self.slave.mass_matrix(q_s, Fs)
        X = xp.linalg.solve(M_s, J_sf.T)
        y_null = -self.k_null * (q_s - self.q_rest) - self.d_null * qd_s
        try:
            tau_red = y_null - J_sf.T @ xp.linalg.solve(J_sf @ X, X.T @ y_null)
            null_ok = xp.all(xp.isfinite(tau_red))
        except np.linalg.LinAlgError:  # the slave at a kinematic singularity: J M^-1 J^T singular (NumPy)
            tau_red, null_ok = y_null, np.False_
        tau_s = xp.where(null_ok, tau_s + tau_red, tau_s)
        # force reflection, seed 003 eq. (11): v J_mf^T F_s, with the registered J_mf
        # (F_s is in the slave's base axes)
        v = self.reflection if self.k_for is None else force_stability_term(Jm @ qd_m, F_s, self.k_for)
        tau_m = tau_m + v * (Jm.T @ F_s)
        wall = xp.zeros(3)
        if self.walls:
            p_master, v_master = M.tool(Fm), J_mf[0:3] @ qd_m
            for wl in self.walls:
                wall = wall + wl.force(p_master, v_master)
            tau_m = tau_m + J_mf[0:3].T @ wall
        tau_m = tau_m * K["actuated"]
        # one sum per arm: NaN or inf in any component makes it non-finite
        finite = xp.isfinite(xp.sum(tau_m)) & xp.isfinite(xp.sum(tau_s))
        # never send part of a broken command: hold both arms
        tau_m, tau_s = xp.where(finite, tau_m, 0.0), xp.where(finite, tau_s, 0.0)
        if self.preload_nm is not None:
            # seed 003 §6, the inverse of the deadband: preload(tau_m, preload_nm) with its
            # constants precomputed (tests check the two agree)
            tau_m = tau_m + K["preload"] * xp.minimum(xp.maximum(tau_m * K["inv_switch"], -1.0), 1.0)
        lim_m, lim_s = self.master_limits, self.slave_limits
        saturated = xp.any(xp.abs(tau_m) > lim_m) | xp.any(xp.abs(tau_s) > lim_s)
        tau_m = xp.minimum(xp.maximum(tau_m, -lim_m), lim_m)
        tau_s = xp.minimum(xp.maximum(tau_s, -lim_s), lim_s)
        if not details:
            return tau_m, tau_s
        return (tau_m, tau_s, e, p_m, q_from_rotation(R_m), p_s, q_from_rotation(R_s), wall, finite, saturated,
                null_ok, J_mf, J_sf, M_s)


#: Largest joint angle a measurement may hold, rad: a revolute joint wound many turns (an
#: unlimited wrist roll) stays far below; 1e3 rad is 159 turns. Beyond it the reading is a
#: sensor fault (a unit mistake, a raw encoder count), not a pose.
MAX_JOINT_ANGLE = 1e3
#: Largest joint rate a measurement may hold, rad/s: 38 times the fastest rated joint of the
#: Panda slave (2.61 rad/s, :data:`.slave.PANDA_VELOCITY_LIMITS`) and 6 times the fastest the
#: simulator reaches (15.7 rad/s: the RPY baseline held at gimbal lock, whose simulated slave
#: has no speed limit); a hand-driven master is slower still.
MAX_JOINT_RATE = 100.0
#: Largest wrist force, N, and moment, N m, a measurement ``F_s`` may hold: ten times what the
#: slave's strongest joint (87 N m, :data:`.slave.PANDA_TORQUE_LIMITS`) balances at a 0.1 m
#: lever arm (a moment at the tool loads each joint by ``z_i . m``, with no lever arm: ten times
#: 87 N m). An arm pushed beyond them is back-driven or broken, not measured.
MAX_WRIST_FORCE = 10.0 * max(PANDA_TORQUE_LIMITS) / 0.1
MAX_WRIST_MOMENT = 10.0 * max(PANDA_TORQUE_LIMITS)
_ANGLE = (MAX_JOINT_ANGLE, "rad", "a joint angle", "MAX_JOINT_ANGLE")
_RATE = (MAX_JOINT_RATE, "rad/s", "a joint rate", "MAX_JOINT_RATE")
_BOUNDS = {"q_m": _ANGLE, "q_s": _ANGLE, "qd_m": _RATE, "qd_s": _RATE}
_FORCE = (MAX_WRIST_FORCE, "N", "a wrist force", "MAX_WRIST_FORCE")
_MOMENT = (MAX_WRIST_MOMENT, "N m", "a wrist moment", "MAX_WRIST_MOMENT")
#: Each entry's bound of ``F_s`` (forces, then moments).
_WRENCH_BOUND = np.r_[np.full(3, MAX_WRIST_FORCE), np.full(3, MAX_WRIST_MOMENT)]


def _measured(x, name, n, world: tuple = ()):
    """A measured vector as a float array of shape ``(n,)``, finite and physically possible.

    Each entry within :data:`MAX_JOINT_ANGLE`, :data:`MAX_JOINT_RATE` or (``F_s``)
    :data:`MAX_WRIST_FORCE` / :data:`MAX_WRIST_MOMENT`. One reduction per field in the usual
    case (the largest magnitude); only a field that fails it is searched entry by entry.
    ``world``: the index of the world of a batch it is, named in the errors.
    """
    at = f" in world {world}" if world else ""
    try:
        a = np.asarray(x, dtype=float)
    except (TypeError, ValueError):
        raise InvalidInputError(f"measurement {name}{at} = {short(x)} must be {n} numbers (SI units); "
                                "check the sensor reading") from None
    if a.shape != (n,):
        raise ShapeError(f"measurement {name}{at} must have shape ({n},), got {a.shape}")
    # the one cheap reduction: the largest magnitude (NaN propagates, no overflow) within the
    # field's bound (for F_s the smaller, the moments') means every entry is finite and within
    # its own; anything else falls through to the exact, per-entry test
    wrench = name == "F_s"
    bound, unit, what, const = _MOMENT if wrench else _BOUNDS[name]
    if float(np.abs(a).max()) <= bound:
        return a
    if not np.isfinite(a).all():
        raise NonFiniteError(f"measurement {name}{at} = {short(a.tolist())} is not finite; a controller cannot act "
                             "on NaN or inf measurements - check the sensor reading")
    over = np.abs(a) / (_WRENCH_BOUND if wrench else bound)
    i = int(np.argmax(over))
    if over[i] > 1.0:
        if wrench and i < 3:
            bound, unit, what, const = _FORCE
        raise InvalidInputError(
            f"measurement {name}[{i}]{at} = {a[i]:g} {unit} is beyond +-{bound:g} {unit}, more than {what} of these "
            f"arms can be (teleop.controller.{const}); check the sensor reading and its units")
    return a
