"""Robots layer: robot models that turn commands into motion, and teams of them (above formations).

A robot model (:class:`~quatform.robots.model.RobotModel`) offers a formation a point,
turns a rate of that point into its commands (``actuate``), validates and saturates the
commands (they are always finite and within the robot's limits) and advances its state.
A :class:`Team` is a tuple of models, vectorised over groups of equal models. Models: the
4-DOF :class:`HolonomicRobot` (seed 000), the planar :class:`PlanarHolonomicRobot`, the 6-DOF
:class:`FreeBodyRobot`, the unicycle :class:`Pioneer` and the :class:`Bebop` (seed 001), the
teleoperation arms (:mod:`.arms`). A :class:`RobotModel` subclass registers itself in
:data:`ROBOT_MODELS` when it is defined, with its team-file keys and its ROS 2 conversions
(:mod:`.ros_io`): a new model is one module here. :mod:`.pioneer_bebop` names where each value
of seed 001's Pioneer-Bebop team sits in its stacked state and commands.
"""

from .bebop import TABLE2_K, Bebop, BebopMemory, yaw_matrix
from .free_body import FreeBodyRobot
from .holonomic import HolonomicRobot
from .model import ROBOT_MODELS, RobotModel, file_models
from .pioneer import Pioneer
from .planar import PlanarHolonomicRobot
from .team import GroupIndex, RobotGroup, Team

__all__ = ["RobotModel", "ROBOT_MODELS", "file_models", "HolonomicRobot", "PlanarHolonomicRobot", "FreeBodyRobot", "Team", "RobotGroup",
           "GroupIndex", "Pioneer", "Bebop", "BebopMemory", "TABLE2_K", "yaw_matrix"]
