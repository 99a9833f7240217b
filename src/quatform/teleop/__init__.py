"""Teleoperation layer (seed 003): arms, Euler-parameter stiffness control (beside formations).

Reuses :mod:`quatform.algebra` only. This first part holds the serial-arm kinematics in the
modified Denavit-Hartenberg convention, the Kraft master of the seed, and the
Euler-parameter task Jacobians (eqs. (15)-(19)); the controllers, the slave's dynamics and
the closed-loop simulation come next (issue 6).
"""

from .arm import DHLink, SerialArm
from .kraft import KRAFT_MASTER
from .task import orientation_error, task_jacobian

__all__ = ["DHLink", "SerialArm", "KRAFT_MASTER", "orientation_error", "task_jacobian"]
