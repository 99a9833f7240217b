"""A robot model's ROS 2 conversions: a measured pose to its state, its commands to twists.

Robots layer (NumPy only; the ROS 2 bridge, :mod:`quatform.ros2`, reads them through
:attr:`RobotModel.ros_io <quatform.robots.model.RobotModel.ros_io>`). Each model says

* how a measured pose (position, orientation ``(w, x, y, z)`` body FLU to world ENU, and for
  the Bebop its body twist) becomes the model's state: the yaw read from the quaternion
  (z-y-x, :func:`quatform.formations.geometry.yaw_of`) and unwound next to the previous one,
  the Pioneer's control point a distance ``a`` ahead of the wheel axis (seed 001 §3.1.1,
  Fig. 10), a free body's unit quaternion on the previous one's side;
* which frame its commands live in (:attr:`RobotIO.natural_frame`): world-frame velocities for
  the 4-DOF, planar and free-body robots (seed 000 §4.1); the Pioneer's ``(v, omega)``
  (seed 001 eq. (3.1)) and the Bebop's command fractions ``(u_x, u_y, u_z, u_psi)`` (eq. (3.6),
  body frame through eq. (3.10); bebop_autonomy's ``cmd_vel``) in the body frame;
* how its command becomes a twist ``(linear (3,), angular (3,))`` in the world frame or its
  body frame (the 4-DOF and planar robots' body frame is their heading frame, eq. (3.8)'s yaw
  rotation: they have no attitude of their own), and whether it has the world velocity and
  yaw rate a PX4 or MAVROS velocity setpoint takes.

A pose is any object with ``position (3,)``, ``quaternion (4,)`` and ``twist`` (two ``(3,)``
body-frame vectors, or None): :class:`quatform.ros2.robot_io.PoseSample`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..formations import geometry as g

__all__ = ["RobotIO", "heading_rotate", "pose_yaw", "z_vector", "xy_vector"]


@dataclass(frozen=True)
class RobotIO:
    """A robot model's measurement and command conversions (see the module docstring).

    Attributes
    ----------
    kind : str
        The model in words (messages, docs).
    natural_frame : str
        ``world`` or ``body``: the frame its commands are in.
    needs_twist : bool
        Its state holds velocities (the Bebop): its pose must come with a twist (odometry).
    setpoint : bool
        Its commands are a world velocity and a yaw rate (a PX4 / MAVROS velocity setpoint).
    state : callable ``(model, pose, previous state or None) -> ndarray (k,)``
    world_twist : callable ``(model, u, state) -> (linear, angular)`` or None
        The command as world-frame velocities (None: it has none); ``u (..., k_u)``,
        ``state (..., k_x)``, results ``(..., 3)``: any number of robots of one model at once.
    body_twist : callable ``(model, u, state, quaternion) -> (linear, angular)``
        The command in the body frame (the same shapes, ``quaternion (..., 4)``).
    """

    kind: str
    natural_frame: str
    state: Callable
    body_twist: Callable
    world_twist: Callable | None = None
    needs_twist: bool = False
    setpoint: bool = False

    def twist(self, model, u, state, quaternion, frame: str):
        """``(linear (..., 3), angular (..., 3))`` of the commands ``u`` in ``frame`` (``world``/``body``)."""
        if frame == "world":
            return self.world_twist(model, u, state)
        return self.body_twist(model, u, state, quaternion)


def heading_rotate(yaw, v, inverse: bool = False) -> np.ndarray:
    """``R_z(yaw) v`` (``inverse``: ``R_z(-yaw) v``, seed 001 eq. (3.8)) of ``(..., 3)`` vectors."""
    yaw = -np.asarray(yaw, dtype=float) if inverse else np.asarray(yaw, dtype=float)
    return g.rotate(g.q_yaw(yaw), np.asarray(v, dtype=float))


def pose_yaw(pose, previous) -> float:
    """The z-y-x yaw of ``pose.quaternion``, rad, unwound next to ``previous`` (None: in (-pi, pi])."""
    yaw = g.yaw_of(pose.quaternion)
    return float(yaw if previous is None else g.unwrap_near(yaw, previous))


def z_vector(w) -> np.ndarray:
    """``(0, 0, w)`` of ``(...)`` values: ``(..., 3)``."""
    w = np.asarray(w, dtype=float)
    return np.stack([np.zeros_like(w), np.zeros_like(w), w], axis=-1)


def xy_vector(x, y) -> np.ndarray:
    """``(x, y, 0)``: ``(..., 3)``."""
    x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
    return np.stack([x, y, np.zeros_like(x)], axis=-1)
