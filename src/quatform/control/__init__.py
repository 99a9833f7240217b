"""Control layer: the cluster-space controllers of seed 000 (above formations).

Every controller has ``step(t, measured_robot_state, reference) -> robot commands`` and
works without the simulator.
"""

from .base import Controller, Reference, StepResult
from .cluster_space import TABLE1, TABLE2, ClusterSpaceController, RobotSpaceController
from .quaternion import (
    DualQuaternionController,
    QuaternionController,
    dual_quaternion_law_lyapunov,
    dual_quaternion_lyapunov,
    quaternion_lyapunov,
)
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
]
