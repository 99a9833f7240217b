"""Teleoperation layer (seed 003): arms, Euler-parameter stiffness control (beside formations).

Reuses :mod:`quatform.algebra` only. It holds the serial-arm kinematics in the modified
Denavit-Hartenberg convention, the Kraft master of the seed, a 7-DOF slave with a mass
matrix and the kinetic-energy-weighted inverse of eq. (13), the Euler-parameter task
Jacobians (eqs. (15)-(19)) and the RPY baseline, the control laws (:mod:`quatform.control.stiffness`: eqs.
(14a), (14b), force reflection, redundancy torque, preload, virtual walls) and
:class:`TeleopController`, which puts them together for real arms or the simulator
(:mod:`quatform.sim.teleop`).
"""

from .arm import DHLink, SerialArm
from .controller import (
    ORIENTATION_ERRORS,
    Registration,
    TeleopCommand,
    TeleopController,
    TeleopMeasurement,
    VirtualWall,
)
from .kraft import KRAFT_DEADBAND, KRAFT_FULL_SCALE, KRAFT_MASTER, KRAFT_PRELOAD
from .slave import PANDA, PANDA_SLAVE, PANDA_TORQUE_LIMITS, RigidArm
from .task import orientation_error, rpy_error, rpy_from_q, rpy_task_jacobian, task_jacobian

__all__ = ["DHLink", "SerialArm", "KRAFT_MASTER", "KRAFT_FULL_SCALE", "KRAFT_DEADBAND", "KRAFT_PRELOAD", "PANDA",
           "PANDA_SLAVE", "PANDA_TORQUE_LIMITS", "RigidArm", "orientation_error", "task_jacobian", "rpy_from_q",
           "rpy_error", "rpy_task_jacobian", "ORIENTATION_ERRORS", "Registration", "VirtualWall",
           "TeleopMeasurement", "TeleopCommand", "TeleopController"]
