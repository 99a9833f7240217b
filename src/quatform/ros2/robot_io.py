"""Measured poses to a robot model's state, and its commands to twists (ROS 2 bridge layer).

Each robot model carries its conversions (:attr:`RobotModel.ros_io
<quatform.robots.model.RobotModel.ros_io>`, a :class:`~quatform.robots.ros_io.RobotIO`: how a
measured pose becomes its state, which frame its commands live in, how they become a twist);
:func:`robot_io` reads them and :data:`ROBOT_IO` lists them by model class.

:data:`PLANT_ROBOTS` maps a plant class to its robots (models and the slices of the plant
state and command each owns): the kinematic team of the pair and team kinds, the Pioneer and
Bebop of the UGV-UAV kind.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..errors import InvalidInputError
from ..registry import RegistryView
from ..robots import ROBOT_MODELS
from ..robots.ros_io import RobotIO, heading_rotate
from ..sim.plants import KinematicTeam
from ..sim.plants.ugv_uav import PioneerBebopPlant

__all__ = ["PoseSample", "RobotIO", "ROBOT_IO", "PLANT_ROBOTS", "PlantRobots", "robot_io", "plant_robots",
           "heading_rotate"]


@dataclass(frozen=True)
class PoseSample:
    """One measured pose.

    Attributes
    ----------
    t : float
        Its time stamp, s.
    position : ndarray, shape (3,)
        m, world (ENU).
    quaternion : ndarray, shape (4,)
        ``(w, x, y, z)``, body (FLU) to world, unit.
    twist : tuple of two ndarrays (3,) or None
        Body-frame (FLU) linear, m/s, and angular, rad/s, velocity (``nav_msgs/Odometry``'s
        twist is in its ``child_frame_id``, the body, REP-105), or None.
    """

    t: float
    position: np.ndarray
    quaternion: np.ndarray
    twist: tuple | None = None


#: The conversions of each robot model class (its ``ros_io``).
ROBOT_IO: Mapping = RegistryView(
    lambda: {cls: cls.ros_io for cls in ROBOT_MODELS.values() if cls.ros_io is not None}, "ROBOT_IO")


def robot_io(model) -> RobotIO:
    """The :class:`RobotIO` of a robot model (its class's ``ros_io``); another is one line."""
    io = getattr(type(model), "ros_io", None)
    if io is None:
        raise InvalidInputError(f"the ROS 2 bridge has no conversions for a {type(model).__name__} robot; it drives "
                                f"{', '.join(c.__name__ for c in ROBOT_IO)}")
    return io


@dataclass(frozen=True)
class PlantRobots:
    """A plant's robots: their models and the slices of the plant state and command each owns."""

    models: tuple
    state_slices: tuple
    command_slices: tuple


def _team_robots(plant: KinematicTeam) -> PlantRobots:
    t = plant.team
    return PlantRobots(tuple(t.robots), tuple(t.state_slices), tuple(t.command_slices))


def _ugv_uav_robots(plant: PioneerBebopPlant) -> PlantRobots:
    return PlantRobots((plant.pioneer, plant.bebop), (slice(0, 3), slice(3, 11)), (slice(0, 2), slice(2, 6)))


#: The robots of each plant class the bridge drives (the kinematic plants of the scenario kinds).
PLANT_ROBOTS = {KinematicTeam: _team_robots, PioneerBebopPlant: _ugv_uav_robots}


def plant_robots(plant, where: str) -> PlantRobots:
    """The :class:`PlantRobots` of ``plant`` (``where``: the scenario, for the message)."""
    make = PLANT_ROBOTS.get(type(plant))
    if make is None:
        raise InvalidInputError(f"{where}: the ROS 2 bridge drives the robots of a kinematic plant (pair, team and "
                                f"ugv-uav scenarios); this scenario's plant is a {type(plant).__name__}")
    return make(plant)
