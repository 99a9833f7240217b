"""Robots layer: plant models that turn commands into motion (above formations).

A robot model validates and saturates the commands it is given (they are always finite
and within the robot's limits) and advances its state.
"""

from .holonomic import HolonomicRobot, Team

__all__ = ["HolonomicRobot", "Team"]
