"""Teleoperation (seed 003): the arms' kinematics, the task space and the teleoperation controller.

The kinematics (:mod:`.arm`, :mod:`.kraft`, :mod:`.slave`, :mod:`.kernels`: serial arms in
the modified Denavit-Hartenberg convention, the Kraft master of the seed, a 7-DOF slave with
a mass matrix and the kinetic-energy-weighted inverse of eq. (13)) reuse
:mod:`quatform.algebra` only, so :mod:`quatform.robots.arms` builds the arms' robot models
on them. :mod:`.task` holds the Euler-parameter task Jacobians (eqs. (15)-(19)) and the RPY
baseline; :class:`TeleopController` (control level: it implements
:class:`quatform.control.contract.Controller` with the law of
:mod:`quatform.control.stiffness`: eqs. (14a), (14b), force reflection, redundancy torque,
preload, virtual walls) drives real arms or the plant of :mod:`quatform.sim.plants.teleop`
(the ``teleop`` scenario kind, :mod:`quatform.scenarios.teleop`).
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
