"""Holonomic 4-DOF kinematic robot (velocity commands in x, y, z and yaw), seed 000 §4.1.

Robots layer. State ``(x, y, z, theta)``; command ``(v_x, v_y, v_z, omega_z)`` in the world
frame, held constant over a step, so the step is exact. A command beyond the limits
(linear speed in norm, yaw rate in magnitude) is scaled down as a whole, its direction
kept; a team of them scales all its robots' commands by one factor (:mod:`quatform.robots.team`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..algebra.kernels import as_floats, concrete
from ..algebra.validate import as_array
from ..checks import number
from ..errors import InvalidInputError
from . import limits
from .model import RobotModel
from .ros_io import RobotIO, heading_rotate, pose_yaw, z_vector

__all__ = ["HolonomicRobot"]


# ROS 2 conversions (seed 000 §4.1): state (x, y, z, theta); commands world (v_x, v_y, v_z, omega_z)
def _ros_state(model, pose, prev):
    return np.r_[pose.position, pose_yaw(pose, None if prev is None else prev[3])]


def _ros_world(model, u, state):
    return np.asarray(u[..., 0:3], dtype=float), z_vector(u[..., 3])


def _ros_body(model, u, state, q):
    return heading_rotate(state[..., 3], u[..., 0:3], inverse=True), z_vector(u[..., 3])


@dataclass(frozen=True)
class HolonomicRobot(RobotModel):
    """A holonomic robot that takes velocity commands in x, y, z and yaw.

    Parameters
    ----------
    max_speed : float
        Largest linear speed ``||(v_x, v_y, v_z)||``, m/s.
    max_yaw_rate : float
        Largest ``|omega_z|``, rad/s.
    """

    max_speed: float = 2.5
    max_yaw_rate: float = 3.0

    name = "holonomic"
    #: It offers a formation its whole state, a 4-DOF point.
    point_kind = "xyz_yaw"
    state_columns = ("x", "y", "z", "theta")
    command_columns = ("v_x", "v_y", "v_z", "omega_z")
    column_units = {"x": "m", "y": "m", "z": "m", "theta": "rad", "v_x": "m/s", "v_y": "m/s", "v_z": "m/s",
                    "omega_z": "rad/s"}
    #: Entries of the rate :meth:`actuate` takes: the point's.
    n_rate = 4
    #: Its commands are its point's rates (a controller may skip :meth:`actuate`).
    passthrough = True
    #: Its commands scale as a whole (:meth:`limit_factor`), so a team may share one factor.
    holonomic = True
    #: Team files: ``holonomic`` (seed 000 §4.1's defaults) and ``quadrotor`` (a Bebop-like
    #: multirotor under velocity commands: the Bebop 2's vertical top speed and yaw rate,
    #: Marciano 2021 Table 3.1, ``robots.Bebop().max_velocity``: the binding limits of a
    #: norm-limited command).
    file_names = ("quadrotor", "holonomic")
    limit_keys = ("max_speed_m_s", "max_yaw_rate_rad_s")
    ros_io = RobotIO("4-DOF holonomic robot", "world", _ros_state, _ros_body, _ros_world, setpoint=True)

    @classmethod
    def from_file(cls, table, where, place, file_name="holonomic"):
        if file_name == "quadrotor":
            from .bebop import Bebop

            top = Bebop().max_velocity
            speed, yaw_rate = round(float(top[2]), 3), round(float(top[3]), 3)
        else:
            speed, yaw_rate = 2.5, 3.0
        return cls(max_speed=number(table, "max_speed_m_s", where, speed, place=place, low=0.0, low_open=True),
                   max_yaw_rate=number(table, "max_yaw_rate_rad_s", where, yaw_rate, place=place, low=0.0,
                                       low_open=True))

    def __post_init__(self):
        for name in ("max_speed", "max_yaw_rate"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise InvalidInputError(f"{name} must be a positive finite number, got {v!r}")

    def point(self, x) -> np.ndarray:
        """The 4-DOF point: the state itself, shape ``(..., 4)``."""
        return as_floats(x)

    def initial_memory(self, batch: tuple = ()):
        """None: its actuation remembers nothing."""
        return None

    def actuate(self, x, rate, t: float, memory=None):
        """The commands are the point's world rates (seed 000 §4.1): ``(rate, memory)``."""
        return as_floats(rate), memory

    def brake(self, x, memory=None):
        """Commands that stop the robot: zero, shape ``(..., 4)``."""
        return np.zeros(np.shape(x)[:-1] + (4,)), memory

    def saturate(self, u) -> np.ndarray:
        """Commands limited to the robot's speeds, direction kept; non-finite ones become zero.

        Parameters
        ----------
        u : array_like, shape (..., 4)

        Returns
        -------
        ndarray, shape (..., 4)
        """
        return limits.saturate(u, self.limit_factor, 4, "4-DOF robot")  # a non-finite command stops the robot

    def limit_factor(self, u) -> np.ndarray:
        """Largest ``s`` in ``[0, 1]`` with ``s u`` within the limits (0 for a non-finite ``u``).

        Parameters
        ----------
        u : ndarray, shape (..., 4)

        Returns
        -------
        ndarray, shape (...)
        """
        return limits.limit_factor(u, 3, self.max_speed, self.max_yaw_rate)

    def limit_factor_floats(self, vx, vy, vz, wz):
        """:meth:`limit_factor` for one command of Python floats."""
        if not (math.isfinite(vx) and math.isfinite(vy) and math.isfinite(vz) and math.isfinite(wz)):
            return 0.0
        s = 1.0
        speed = math.hypot(vx, vy, vz)
        if speed > self.max_speed:
            s = self.max_speed / speed
        if abs(wz) * s > self.max_yaw_rate:
            s = self.max_yaw_rate / abs(wz)
        return s

    def step(self, x, u, dt: float) -> np.ndarray:
        """State after ``dt`` seconds of the saturated command ``u`` (exact)."""
        return (as_array(x, "x", 4) if concrete(x) else x) + dt * self.saturate(u)


