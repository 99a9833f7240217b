"""Formations layer: cluster-space descriptions of robot teams (seed 000).

Sits above :mod:`quatform.algebra` and below robots, control and references. Every
description implements :class:`Formation`: ``forward``, ``inverse``, ``jacobian``,
``inverse_jacobian``, ``singularity_measure``, ``euclidean`` and ``from_euclidean``.
"""

from .base import ROBOT_PAIR_VARIABLES, Formation, Variable
from .dual_quaternion_pair import DualQuaternionPair
from .euclidean_pair import (
    EUCLIDEAN_VARIABLES,
    EuclideanPair,
    RobotSpace,
    segment_direction,
)
from .quaternion_pair import QuaternionPair
from .ugv_uav import (
    SPHERICAL_VARIABLES,
    UGV_UAV_VARIABLES,
    UgvUavQuaternion,
    UgvUavRestricted,
    UgvUavSpherical,
)

#: Descriptions by name.
FORMATIONS = {
    f.name: f for f in (EuclideanPair(), RobotSpace(), QuaternionPair(), DualQuaternionPair())
}

__all__ = [
    "Formation",
    "Variable",
    "ROBOT_PAIR_VARIABLES",
    "EUCLIDEAN_VARIABLES",
    "EuclideanPair",
    "RobotSpace",
    "QuaternionPair",
    "DualQuaternionPair",
    "FORMATIONS",
    "segment_direction",
    "UgvUavSpherical",
    "UgvUavRestricted",
    "UgvUavQuaternion",
    "UGV_UAV_VARIABLES",
    "SPHERICAL_VARIABLES",
]
