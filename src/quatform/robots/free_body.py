"""6-DOF free body commanded by its world linear and angular velocity (the ``pose`` point kind).

Robots layer. State ``(x, y, z, q_w, q_x, q_y, q_z)``: position, m, and the unit quaternion of
its orientation in the world. Command ``(v_x, v_y, v_z, w_x, w_y, w_z)``: the world-frame
linear velocity, m/s, and angular velocity, rad/s, held over a step. The orientation obeys
``q_dot = 1/2 w q`` (``w`` a pure quaternion in the world frame; seed 001 eq. (2.32), the
world-frame form of the quaternion derivative), whose solution for a held ``w`` is
``q(t) = exp(t w / 2) q(0)`` (seed 001 eq. (2.28), the exponential of a pure
quaternion), so a step is exact; the result is renormalised (eq. (2.37)) against roundoff.

It offers a formation its whole state (a ``pose`` point); :meth:`FreeBodyRobot.actuate`
turns a rate of that point ``(p_dot, q_dot)`` into ``(p_dot, w)``, ``w = 2 q_dot q*``
(vector part). Limits: the linear speed and the angular speed in norm; a command beyond them
is scaled down as a whole, so a team of holonomic robots may share one factor. Its actuation,
limits and step run on NumPy and on JAX arrays alike (:func:`quatform.algebra.kernels.array_namespace`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..algebra.kernels import array_namespace as namespace
from ..algebra.kernels import as_floats, concrete
from ..algebra.validate import as_array
from ..checks import number
from ..errors import InvalidInputError
from ..formations import geometry as g
from . import limits
from .model import RobotModel
from .ros_io import RobotIO

__all__ = ["FreeBodyRobot"]


# ROS 2 conversions: state (x, y, z, q_w, q_x, q_y, q_z); commands world (v, w)
def _ros_state(model, pose, prev):
    q = np.asarray(pose.quaternion, dtype=float)
    q = q / np.linalg.norm(q)
    if prev is not None:
        q = g.closest_sign(q, prev[3:7])  # q and -q are one orientation: stay on the previous side
    return np.r_[pose.position, q]


def _ros_world(model, u, state):
    return np.asarray(u[..., 0:3], dtype=float), np.asarray(u[..., 3:6], dtype=float)


def _ros_body(model, u, state, q):
    qc = g.conj(np.asarray(state[..., 3:7], dtype=float))
    return g.rotate(qc, np.asarray(u[..., 0:3], dtype=float)), g.rotate(qc, np.asarray(u[..., 3:6], dtype=float))


@dataclass(frozen=True)
class FreeBodyRobot(RobotModel):
    """A rigid body that takes world linear and angular velocity commands.

    Parameters
    ----------
    max_speed : float
        Largest linear speed ``||(v_x, v_y, v_z)||``, m/s.
    max_angular_rate : float
        Largest angular speed ``||(w_x, w_y, w_z)||``, rad/s.
    """

    max_speed: float = 2.5
    max_angular_rate: float = 3.0

    name = "free-body"
    #: It offers a formation its whole state, a pose point.
    point_kind = "pose"
    state_columns = ("x", "y", "z", "q_w", "q_x", "q_y", "q_z")
    command_columns = ("v_x", "v_y", "v_z", "w_x", "w_y", "w_z")
    column_units = {"x": "m", "y": "m", "z": "m", "q_w": "-", "q_x": "-", "q_y": "-", "q_z": "-", "v_x": "m/s",
                    "v_y": "m/s", "v_z": "m/s", "w_x": "rad/s", "w_y": "rad/s", "w_z": "rad/s"}
    #: Entries of the rate :meth:`actuate` takes: the pose point's (position and quaternion rates).
    n_rate = 7
    #: Its commands are not its point's rates (an angular velocity, not a quaternion rate).
    passthrough = False
    #: Its commands scale as a whole (:meth:`limit_factor`), so a team may share one factor.
    holonomic = True
    #: Team files: ``free-body`` (a 6-DOF free body under world linear and angular velocity commands).
    file_names = ("free-body",)
    limit_keys = ("max_speed_m_s", "max_angular_rate_rad_s")
    ros_io = RobotIO("free body", "world", _ros_state, _ros_body, _ros_world)

    @classmethod
    def from_file(cls, table, where, place, file_name="free-body"):
        return cls(max_speed=number(table, "max_speed_m_s", where, 2.5, place=place, low=0.0, low_open=True),
                   max_angular_rate=number(table, "max_angular_rate_rad_s", where, 3.0, place=place, low=0.0,
                                           low_open=True))

    def __post_init__(self):
        for name in ("max_speed", "max_angular_rate"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float, np.floating, np.integer)) and np.isfinite(v) and v > 0):
                raise InvalidInputError(f"FreeBodyRobot {name} must be a positive finite number, got {v!r}")

    def point(self, x) -> np.ndarray:
        """The pose point: the state itself, shape ``(..., 7)``."""
        return as_floats(x)

    def initial_memory(self, batch: tuple = ()):
        """None: its actuation remembers nothing."""
        return None

    def actuate(self, x, rate, t: float, memory=None):
        """Commands ``(p_dot, w)`` for the pose rate ``rate = (p_dot, q_dot)``, ``w = 2 vec(q_dot q*)``.

        From ``q_dot = 1/2 w q`` (seed 001 eq. (2.32)): ``w = 2 q_dot q*`` (eq. (2.33)) for a unit ``q``. The
        part of ``q_dot`` along ``q`` (which would change its norm) gives the real part of
        ``2 q_dot q*`` and is dropped.

        Parameters
        ----------
        x : array_like, shape (..., 7)
        rate : array_like, shape (..., 7)
            m/s and 1/s.

        Returns
        -------
        u : ndarray, shape (..., 6)
        memory : None
        """
        x, rate = as_floats(x), as_floats(rate)
        xp = namespace(rate)
        w = 2.0 * g.mul(rate[..., 3:7], g.conj(x[..., 3:7]))[..., 1:]
        shape = np.broadcast_shapes(rate.shape[:-1], w.shape[:-1])
        return xp.concatenate([xp.broadcast_to(rate[..., 0:3], shape + (3,)), w], axis=-1), memory

    def brake(self, x, memory=None):
        """Commands that stop the body: zero, shape ``(..., 6)``."""
        return np.zeros(np.shape(x)[:-1] + (6,)), memory

    def limit_factor(self, u) -> np.ndarray:
        """Largest ``s`` in ``[0, 1]`` with ``s u`` within the limits (0 for a non-finite ``u``).

        Parameters
        ----------
        u : ndarray, shape (..., 6)

        Returns
        -------
        ndarray, shape (...)
        """
        return limits.limit_factor(u, 3, self.max_speed, self.max_angular_rate)

    def saturate(self, u) -> np.ndarray:
        """Commands limited to the body's speeds, direction kept; non-finite ones become zero.

        Parameters
        ----------
        u : array_like, shape (..., 6)

        Returns
        -------
        ndarray, shape (..., 6)
        """
        return limits.saturate(u, self.limit_factor, 6, "free-body (v_x, v_y, v_z, w_x, w_y, w_z)")

    def step(self, x, u, dt: float) -> np.ndarray:
        """State after ``dt`` s of the saturated command ``u``: exact for a held command.

        ``p + dt v`` and ``q(dt) = exp(dt w / 2) q`` (seed 001 eq. (2.28)), renormalised (eq. (2.37)).

        Parameters
        ----------
        x : array_like, shape (..., 7)
        u : array_like, shape (..., 6)
        dt : float
            s.

        Returns
        -------
        ndarray, shape (..., 7)
        """
        x = as_array(x, "free-body state", 7) if concrete(x) else x
        u = self.saturate(u)
        xp = namespace(u)
        half = 0.5 * dt * u[..., 3:6]
        a = xp.linalg.norm(half, axis=-1)
        # exp of the pure quaternion (0, half): (cos|half|, sinc|half| half), seed 001 eq. (2.28)
        e = xp.concatenate([xp.cos(a)[..., None], xp.sinc(a / np.pi)[..., None] * half], axis=-1)
        q = g.mul(e, x[..., 3:7])
        q = q / xp.linalg.norm(q, axis=-1, keepdims=True)  # eq. (2.37)
        return xp.concatenate([x[..., 0:3] + dt * u[..., 0:3], q], axis=-1)
