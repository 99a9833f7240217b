"""Control layer: the cluster-space controllers of seeds 000 and 001 (above robots).

Every controller implements :class:`quatform.control.contract.Controller` (``init``,
``update``, ``step(t, measured, reference) -> commands``) and works without the simulator.
The laws are in :mod:`.laws`, the filters in :mod:`.filters`, the generic controller in
:mod:`.cluster`.
"""

from .base import Controller, Reference, StepResult
from .cluster import ClusterController
from .cluster_space import TABLE1, TABLE2, ClusterSpaceController, RobotSpaceController
from .quaternion import (
    DualQuaternionController,
    QuaternionController,
    dual_quaternion_law_lyapunov,
    dual_quaternion_lyapunov,
    quaternion_lyapunov,
)
from .safety import BarrierInfo, SafeController, SafeState, SeparationBarrier
from .team import TEAM_CONTROLLERS, TEAM_GAIN_KEYS, TeamController, team_controller, team_lyapunov
from .ugv_uav import UGV_UAV_COMMAND_NAMES, UGV_UAV_MEASURED_NAMES, UgvUavController, UgvUavState

#: Controller classes by command-line name.
CONTROLLERS = {
    "cluster-space": ClusterSpaceController,
    "robot-space": RobotSpaceController,
    "quaternion": QuaternionController,
    "dual-quaternion": DualQuaternionController,
}

__all__ = [
    "Controller",
    "Reference",
    "StepResult",
    "ClusterController",
    "ClusterSpaceController",
    "RobotSpaceController",
    "QuaternionController",
    "DualQuaternionController",
    "quaternion_lyapunov",
    "dual_quaternion_lyapunov",
    "dual_quaternion_law_lyapunov",
    "TABLE1",
    "TABLE2",
    "CONTROLLERS",
    "UgvUavController",
    "UgvUavState",
    "UGV_UAV_MEASURED_NAMES",
    "UGV_UAV_COMMAND_NAMES",
    "TeamController",
    "SafeController",
    "SafeState",
    "SeparationBarrier",
    "BarrierInfo",
    "team_controller",
    "team_lyapunov",
    "TEAM_CONTROLLERS",
    "TEAM_GAIN_KEYS",
]
