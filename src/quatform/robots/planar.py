"""Planar holonomic ground robot (velocity commands in x, y and yaw): the team's ground kind.

Robots layer. State ``(x, y, theta)``; command ``(v_x, v_y, omega_z)`` in the world frame,
held over a step, so the step is exact: the planar analogue of the 4-DOF robot of seed 000
§4.1 (:class:`~quatform.robots.holonomic.HolonomicRobot`). It offers a formation its whole
state, an ``xy_yaw`` point (its position is ``(x, y, 0)``). A command beyond the limits
(speed in norm, yaw rate in magnitude) is scaled down as a whole, its direction kept; a team
of holonomic robots scales all its commands by one factor (:mod:`quatform.robots.team`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..algebra.kernels import as_floats, concrete
from ..algebra.validate import as_array
from ..checks import number
from ..errors import InvalidInputError
from . import limits
from .model import RobotModel
from .ros_io import RobotIO, heading_rotate, pose_yaw, xy_vector, z_vector

__all__ = ["PlanarHolonomicRobot"]


# ROS 2 conversions: state (x, y, theta); commands world (v_x, v_y, omega_z)
def _ros_state(model, pose, prev):
    return np.r_[pose.position[0:2], pose_yaw(pose, None if prev is None else prev[2])]


def _ros_world(model, u, state):
    return xy_vector(u[..., 0], u[..., 1]), z_vector(u[..., 2])


def _ros_body(model, u, state, q):
    return heading_rotate(state[..., 2], xy_vector(u[..., 0], u[..., 1]), inverse=True), z_vector(u[..., 2])


@dataclass(frozen=True)
class PlanarHolonomicRobot(RobotModel):
    """A holonomic ground robot that takes velocity commands in x, y and yaw.

    Parameters
    ----------
    max_speed : float
        Largest planar speed ``||(v_x, v_y)||``, m/s.
    max_yaw_rate : float
        Largest ``|omega_z|``, rad/s.
    """

    max_speed: float = 2.5
    max_yaw_rate: float = 3.0

    name = "planar-holonomic"
    #: It offers a formation its whole state, a planar point.
    point_kind = "xy_yaw"
    state_columns = ("x", "y", "theta")
    command_columns = ("v_x", "v_y", "omega_z")
    column_units = {"x": "m", "y": "m", "theta": "rad", "v_x": "m/s", "v_y": "m/s", "omega_z": "rad/s"}
    #: Entries of the rate :meth:`actuate` takes: the point's.
    n_rate = 3
    #: Its commands are its point's rates (a controller may skip :meth:`actuate`).
    passthrough = True
    #: Its commands scale as a whole (:meth:`limit_factor`), so a team may share one factor.
    holonomic = True
    #: Team files: ``planar`` (a planar holonomic ground robot under velocity commands).
    file_names = ("planar",)
    limit_keys = ("max_speed_m_s", "max_yaw_rate_rad_s")
    ros_io = RobotIO("planar holonomic robot", "world", _ros_state, _ros_body, _ros_world, setpoint=True)

    @classmethod
    def from_file(cls, table, where, place, file_name="planar"):
        return cls(max_speed=number(table, "max_speed_m_s", where, 2.5, place=place, low=0.0, low_open=True),
                   max_yaw_rate=number(table, "max_yaw_rate_rad_s", where, 3.0, place=place, low=0.0,
                                       low_open=True))

    def __post_init__(self):
        for name in ("max_speed", "max_yaw_rate"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float, np.floating, np.integer)) and np.isfinite(v) and v > 0):
                raise InvalidInputError(f"PlanarHolonomicRobot {name} must be a positive finite number, got {v!r}")

    def point(self, x) -> np.ndarray:
        """The planar point: the state itself, shape ``(..., 3)``."""
        return as_floats(x)

    def initial_memory(self, batch: tuple = ()):
        """None: its actuation remembers nothing."""
        return None

    def actuate(self, x, rate, t: float, memory=None):
        """The commands are the point's world rates: ``(rate, memory)``."""
        return as_floats(rate), memory

    def brake(self, x, memory=None):
        """Commands that stop the robot: zero, shape ``(..., 3)``."""
        return np.zeros(np.shape(x)[:-1] + (3,)), memory

    def limit_factor(self, u) -> np.ndarray:
        """Largest ``s`` in ``[0, 1]`` with ``s u`` within the limits (0 for a non-finite ``u``).

        Parameters
        ----------
        u : ndarray, shape (..., 3)

        Returns
        -------
        ndarray, shape (...)
        """
        return limits.limit_factor(u, 2, self.max_speed, self.max_yaw_rate)

    def saturate(self, u) -> np.ndarray:
        """Commands limited to the robot's speeds, direction kept; non-finite ones become zero.

        Parameters
        ----------
        u : array_like, shape (..., 3)

        Returns
        -------
        ndarray, shape (..., 3)
        """
        return limits.saturate(u, self.limit_factor, 3, "planar robot (v_x, v_y, omega_z)")

    def step(self, x, u, dt: float) -> np.ndarray:
        """State after ``dt`` s of the saturated command ``u`` (exact for a held command)."""
        return (as_array(x, "planar robot state", 3) if concrete(x) else x) + dt * self.saturate(u)
