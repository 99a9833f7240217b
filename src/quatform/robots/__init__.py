"""Robots layer: plant models that turn commands into motion (above formations).

A robot model validates and saturates the commands it is given (they are always finite
and within the robot's limits) and advances its state.
"""

from .bebop import TABLE2_K, Bebop, yaw_matrix
from .holonomic import HolonomicRobot, Team
from .pioneer import Pioneer

__all__ = ["HolonomicRobot", "Team", "Pioneer", "Bebop", "TABLE2_K", "yaw_matrix"]
