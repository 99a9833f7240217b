"""Parrot Bebop 2 as a 4-DOF velocity-commanded vehicle with its identified dynamics (seed 001 §3.1.2).

Robots layer. Commands ``u = (u_x, u_y, u_z, u_psi)`` in the body frame, each a fraction
of the vehicle's full command range ``[-1, 1]`` (eq. (3.6)). Kinematics, eqs. (3.7)-(3.10):
``X_dot = A_b v`` with ``v`` the body-frame velocity ``(v_x, v_y, z_dot, psi_dot)`` and
``A_b`` the yaw rotation. Dynamics (Santana et al., Pinto et al.), eqs. (3.11)-(3.13):
``v_dot = K_u u - K_v v`` in the body frame, ``K_u = diag(K1, K3, K5, K7)``,
``K_v = diag(K2, K4, K6, K8)`` (Table 2). The thesis prints it in the world frame as
``X_ddot = A_b K_u u - A_b K_v X_dot``, which applies the body-frame drag to world-frame
velocities; the dynamic compensation (4.47) it uses is the body-frame law, so quatform
integrates that one (``docs/derivations.md``).

As a robot model (:mod:`quatform.robots.model`) it offers a formation its position ``xyz``;
its yaw is controlled outside the formation (seed 001 §4.3.3), so :meth:`Bebop.actuate`
takes the world rate of its position with the yaw rate appended and turns it into commands
by eq. (3.10) and the dynamic compensation (4.47)-(4.49), whose differentiated velocity
reference is the ``memory`` (:class:`BebopMemory`) the caller carries between steps.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..algebra.kernels import as_floats as _float
from ..algebra.kernels import common_namespace as _xp
from ..algebra.kernels import concrete
from ..algebra.validate import as_array
from ..errors import InvalidInputError
from ..formations import geometry as g
from .model import RobotModel, column_entries
from .ros_io import RobotIO, heading_rotate, pose_yaw, z_vector

__all__ = ["Bebop", "BebopMemory", "TABLE2_K", "yaw_matrix"]

#: Seed 001 Table 2: K1 ... K8 of the identified model.
TABLE2_K = (0.8417, 0.1823, 0.8354, 0.1710, 3.966, 4.001, 9.8524, 4.7295)


def yaw_matrix(psi) -> np.ndarray:
    """``A_b`` of eq. (3.7), shape ``(..., 4, 4)`` (any namespace)."""
    psi = _float(psi)
    xp = _xp(psi)
    c, s = xp.cos(psi), xp.sin(psi)
    o, i = xp.zeros_like(c), xp.ones_like(c)
    return xp.stack([xp.stack(row, axis=-1) for row in ((c, -s, o, o), (s, c, o, o), (o, o, i, o), (o, o, o, i))],
                    axis=-2)


@dataclass(frozen=True)
class BebopMemory:
    """What the dynamic compensation (4.47) remembers between steps.

    Attributes
    ----------
    v_r : ndarray, shape (..., 4)
        The previous body-frame velocity reference (NaN where there is none: at the start
        and after a brake the next derivative is not taken).
    t : ndarray, shape (...)
        Its time, s (NaN where none).
    v_dot : ndarray, shape (..., 4)
        The filtered derivative of ``v_r``.
    """

    v_r: np.ndarray
    t: np.ndarray
    v_dot: np.ndarray

    @classmethod
    def start(cls, batch: tuple = ()) -> BebopMemory:
        """No previous reference, a zero derivative."""
        batch = tuple(batch)
        return cls(np.full(batch + (4,), np.nan), np.full(batch, np.nan), np.zeros(batch + (4,)))


# ROS 2 conversions (seed 001 §3.1.2): (x, y, z, psi, v_x, v_y, z_dot, psi_dot), body (v_x, v_y) by eq. (3.8)
def _ros_state(model, pose, prev):
    if pose.twist is None:
        raise InvalidInputError("a Bebop's measured state holds its velocity: give it pose_type = 'odometry' "
                                "(nav_msgs/Odometry, e.g. bebop_autonomy's odom) or 'px4'")
    q = np.asarray(pose.quaternion, dtype=float)
    psi = pose_yaw(pose, None if prev is None else prev[3])
    lin, ang = (np.asarray(a, dtype=float) for a in pose.twist)
    v_world = g.rotate(q, lin)
    v_heading = heading_rotate(psi, v_world, inverse=True)  # eq. (3.8): world to the Bebop frame
    w, x, y, z = q
    roll = np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2.0 * (w * y - z * x), -1.0, 1.0))
    # the z-y-x yaw rate of body rates (p, q, r): (q sin(roll) + r cos(roll)) / cos(pitch)
    # (Beard & McLain 2012, Small Unmanned Aircraft, §3.2); seed 001 §3.1.2 keeps roll and pitch
    # within 5 deg, where it is r to within 0.4 %
    psi_dot = (ang[1] * np.sin(roll) + ang[2] * np.cos(roll)) / np.cos(pitch)
    return np.r_[pose.position, psi, v_heading[0], v_heading[1], v_world[2], psi_dot]


def _ros_body(model, u, state, q):
    # bebop_autonomy's cmd_vel: linear.x forward, linear.y left, linear.z up, angular.z yaw, fractions of [-1, 1]
    return np.asarray(u[..., 0:3], dtype=float), z_vector(u[..., 3])


@dataclass(frozen=True)
class Bebop(RobotModel):
    """The identified high-level model of a Bebop 2.

    Parameters
    ----------
    k : tuple of 8 floats
        ``K1 ... K8`` (Table 2).
    max_fraction : float
        Largest ``|u_i|`` as a fraction of the full command (1.0; 0.4 in seed 001 §5.3).
    dynamic : bool
        ``True``: the dynamic model; ``False``: the kinematic model (velocities follow the
        command at once, ``v = (K_u/K_v) u``).
    l_d : tuple of 4 floats
        ``L_d`` of the dynamic compensation (4.47), ``diag(2, 2, 1.8, 5)`` (seed 001 §5).
    compensation : bool
        :meth:`actuate` uses (4.47); otherwise the kinematic command ``u = K_u^-1 K_v v_r``.
    derivative_filter_s : float
        Time constant, s, of the first-order filter on the differentiated velocity reference
        ``v_r_dot`` of (4.47) (the thesis differentiates without one; 0 disables it).
    """

    k: tuple = field(default=TABLE2_K)
    max_fraction: float = 1.0
    dynamic: bool = True
    l_d: tuple = (2.0, 2.0, 1.8, 5.0)
    compensation: bool = True
    derivative_filter_s: float = 0.1

    name = "bebop"
    #: It offers a formation its position; its yaw is controlled outside the formation.
    point_kind = "xyz"
    state_columns = ("x", "y", "z", "psi", "v_x", "v_y", "z_dot", "psi_dot")
    command_columns = ("u_x", "u_y", "u_z", "u_psi")
    #: Units of its state and command columns: its commands are fractions of their limits (eq. (3.10)).
    column_units = {"x": "m", "y": "m", "z": "m", "psi": "rad", "v_x": "m/s", "v_y": "m/s", "z_dot": "m/s",
                    "psi_dot": "rad/s", "u_x": "-", "u_y": "-", "u_z": "-", "u_psi": "-"}
    #: Entries of the rate :meth:`actuate` takes: the position's world rate and the yaw rate.
    n_rate = 4
    #: Its commands are body-frame fractions through the dynamic compensation, not its rates.
    passthrough = False
    #: Not holonomic in the team sense: its commands are clipped per axis.
    holonomic = False
    ros_io = RobotIO("Bebop 2 (command fractions)", "body", _ros_state, _ros_body, needs_twist=True)

    def __post_init__(self):
        k = np.asarray(self.k, dtype=float)
        if k.shape != (8,) or not np.all(np.isfinite(k)) or np.any(k <= 0):
            raise InvalidInputError(f"Bebop k must be 8 positive numbers K1..K8, got {self.k!r}")
        if not (0 < self.max_fraction <= 1):
            raise InvalidInputError(f"max_fraction must be in (0, 1], got {self.max_fraction!r}")
        object.__setattr__(self, "k", tuple(float(x) for x in k))
        l_d = np.broadcast_to(np.asarray(self.l_d, dtype=float), (4,)) if np.size(self.l_d) in (1, 4) else None
        if l_d is None or not np.all(np.isfinite(l_d)) or np.any(l_d <= 0):
            raise InvalidInputError(f"l_d must be 4 positive numbers, got {self.l_d!r}")
        object.__setattr__(self, "l_d", tuple(float(x) for x in l_d))
        if not (np.isfinite(self.derivative_filter_s) and self.derivative_filter_s >= 0):
            raise InvalidInputError(f"derivative_filter_s must be >= 0, got {self.derivative_filter_s!r}")
        object.__setattr__(self, "compensation", bool(self.compensation))

    def point(self, x) -> np.ndarray:
        """The position ``(x, y, z)`` of the state, shape ``(..., 3)``."""
        return _float(x)[..., 0:3]

    def initial_memory(self, batch: tuple = ()) -> BebopMemory:
        """The compensation's memory before the first step (:meth:`BebopMemory.start`)."""
        return BebopMemory.start(batch)

    def actuate(self, x, rate, t: float, memory: BebopMemory):
        """Commands for the world rate ``rate = (x_dot, y_dot, z_dot, psi_dot)`` of the state ``x``.

        The body-frame velocity reference ``v_r = A_b^-1 rate`` (eq. (3.10), ``A_b^-1 =
        A_b(-psi)``) and the dynamic compensation (4.47)-(4.49), ``u = K_u^-1 (v_r_dot +
        L_d (v_r - v) + K_v v)``, with ``v_r_dot`` differentiated from the previous ``v_r``
        in ``memory`` and filtered (``derivative_filter_s``); without compensation
        ``u = K_u^-1 K_v v_r``. Unsaturated (:meth:`saturate`).

        Parameters
        ----------
        x : array_like, shape (..., 8)
        rate : array_like, shape (..., 4)
            World rates, m/s and rad/s.
        t : float
            Time, s.
        memory : BebopMemory

        Returns
        -------
        u : ndarray, shape (..., 4)
        memory : BebopMemory
            With this step's ``v_r`` and ``t``.
        """
        x, rate = _float(x), _float(rate)
        xp = _xp(x, rate, t, memory.t)
        A = yaw_matrix(-x[..., 3])
        v_r = A @ rate if rate.ndim == 1 else xp.einsum("...ij,...j->...i", A, rate)  # (3.10)
        v_dot = memory.v_dot
        if self.compensation:
            t_prev = memory.t
            new = xp.isfinite(t_prev) & (t > t_prev)
            if xp is not np or np.any(new):  # on JAX both branches, selected
                with np.errstate(invalid="ignore", divide="ignore"):
                    raw = (v_r - memory.v_r) / (t - t_prev)[..., None]
                    # first-order filter on the differentiated reference (it carries the noise)
                    alpha = ((t - t_prev) / (self.derivative_filter_s + t - t_prev))[..., None]
                    v_dot = xp.where(new[..., None], v_dot + alpha * (raw - v_dot), v_dot)
            v = x[..., 4:8]
            u = (v_dot + np.asarray(self.l_d) * (v_r - v) + self.k_v * v) / self.k_u  # (4.47)-(4.49)
        else:
            u = self.k_v / self.k_u * v_r
        t_now = np.broadcast_to(np.float64(t), np.shape(memory.t)).copy() if xp is np else \
            xp.broadcast_to(xp.asarray(t, dtype=v_r.dtype), np.shape(memory.t))
        return u, BebopMemory(v_r, t_now, v_dot)

    def brake(self, x, memory: BebopMemory):
        """Commands that brake to a hover: (4.47) with ``v_r = 0`` and no derivative,
        ``u = K_u^-1 (-L_d v + K_v v)`` (non-finite velocities read as 0); the memory
        forgets its reference (the next derivative is not taken)."""
        v = _float(x)[..., 4:8]
        xp = _xp(v, memory.v_r)
        v = xp.where(xp.isfinite(v), v, 0.0)
        u = (-np.asarray(self.l_d) * v + self.k_v * v) / self.k_u
        return u, BebopMemory(xp.full_like(memory.v_r, np.nan), xp.full_like(memory.t, np.nan), memory.v_dot)

    @property
    def k_u(self) -> np.ndarray:
        return np.array(self.k[0::2])

    @property
    def k_v(self) -> np.ndarray:
        return np.array(self.k[1::2])

    @property
    def max_velocity(self) -> np.ndarray:
        """Steady body velocities at ``max_fraction``: ``(K_u/K_v) max_fraction``, (m/s, m/s, m/s, rad/s)."""
        return self.k_u / self.k_v * self.max_fraction

    @property
    def max_speed(self) -> float:
        """Steady speed of its position at ``max_fraction`` on every axis: the norm of the
        linear entries ``(v_x, v_y, z_dot)`` of :attr:`max_velocity` (ordered as its state's
        velocity columns), m/s."""
        velocity = self.state_columns[self.state_entries("v_x"):]
        return float(np.linalg.norm(self.max_velocity[column_entries(velocity, ("v_x", "v_y", "z_dot"))]))

    def saturate(self, u) -> np.ndarray:
        """Commands clipped to ``+-max_fraction``; non-finite commands become zero (any namespace)."""
        u = _float(u)
        xp = _xp(u)
        u = xp.where(xp.all(xp.isfinite(u), axis=-1, keepdims=True), u, 0.0)
        return xp.clip(u, -self.max_fraction, self.max_fraction)

    def step(self, state, u, dt: float) -> np.ndarray:
        """State ``(x, y, z, psi, v_x, v_y, z_dot, psi_dot)`` (body velocities) after ``dt`` s.

        The body velocity relaxes exactly (first-order lag, command held); the pose is
        integrated with the mean velocity over the step and the mid-step yaw.
        """
        state = as_array(state, "Bebop state", 8) if concrete(state) else state
        xp = _xp(state, u)
        u = self.saturate(u)
        pose, v0 = state[..., :4], state[..., 4:]
        v_inf = self.k_u / self.k_v * u
        if self.dynamic:
            decay = np.exp(-self.k_v * dt)
            v1 = v_inf + (v0 - v_inf) * decay
            mean = v_inf + (v0 - v_inf) * (1.0 - decay) / (self.k_v * dt)
        else:
            v1 = mean = v_inf
        psi_mid = pose[..., 3] + 0.5 * dt * mean[..., 3]
        world = xp.einsum("...ij,...j->...i", yaw_matrix(psi_mid), mean)
        return xp.concatenate([pose + dt * world, v1], axis=-1)

