"""Robots layer: robot models that turn commands into motion, and teams of them (above formations).

A robot model (:class:`~quatform.robots.model.RobotModel`) offers a formation a point,
turns a rate of that point into its commands (``actuate``), validates and saturates the
commands (they are always finite and within the robot's limits) and advances its state.
A :class:`Team` is a tuple of models.
"""

from .bebop import TABLE2_K, Bebop, BebopMemory, yaw_matrix
from .holonomic import HolonomicRobot
from .model import RobotModel
from .pioneer import Pioneer
from .team import Team

__all__ = ["RobotModel", "HolonomicRobot", "Team", "Pioneer", "Bebop", "BebopMemory", "TABLE2_K", "yaw_matrix"]
