"""Teleoperation layer (seed 003): arms, Euler-parameter stiffness control (beside formations).

Reuses :mod:`quatform.algebra` only. This first part holds the serial-arm kinematics in the
modified Denavit-Hartenberg convention, the Kraft master of the seed, a 7-DOF slave with a
mass matrix and the kinetic-energy-weighted inverse of eq. (13), the Euler-parameter
task Jacobians (eqs. (15)-(19)) and the control laws (:mod:`.control`: eqs. (14a), (14b),
force reflection, redundancy torque, preload, virtual walls); the closed-loop simulation,
scenarios and CLI come next (issue 6).
"""

from .arm import DHLink, SerialArm
from .kraft import KRAFT_MASTER
from .slave import PANDA, PANDA_SLAVE, RigidArm
from .task import orientation_error, task_jacobian

__all__ = ["DHLink", "SerialArm", "KRAFT_MASTER", "PANDA", "PANDA_SLAVE", "RigidArm", "orientation_error",
           "task_jacobian"]
