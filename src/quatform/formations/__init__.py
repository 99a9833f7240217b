"""Formations layer: cluster-space descriptions of robot teams (seeds 000 and 001).

Sits above :mod:`quatform.algebra` and below robots, control and references. Every
description implements :class:`Formation` over a :class:`RobotLayout`: ``forward`` and
``inverse`` (branch choices as keywords: ``near_c``, ``near_r``), the rate maps
``cluster_rate`` and ``robot_rate`` (the dense ``jacobian``, ``inverse_jacobian_at`` and
``inverse_jacobian`` derive from them), ``singularity_measure``, the operator's chart
(``to_chart``, ``from_chart``; ``euclidean`` and ``from_euclidean`` are aliases),
``reachable``, ``sample_robot_state`` and ``special_sets``. A new description is one
module here and one entry in :data:`FORMATIONS`; ``tests/test_formation_contract.py``
then runs :func:`quatform.formations.testing.check_formation` over it.
"""

from .base import PAIR_LAYOUT, ROBOT_PAIR_VARIABLES, Formation, Variable
from .layout import POINT_KINDS, RobotLayout
from .special_sets import SpecialSet
from .dual_quaternion_pair import DualQuaternionPair
from .dual_quaternion_team import DualQuaternionTeam
from .euclidean_team import EuclideanTeam
from .euclidean_pair import (
    EUCLIDEAN_VARIABLES,
    EuclideanPair,
    RobotSpace,
    segment_direction,
)
from .quaternion_pair import QuaternionPair
from .quaternion_team import QuaternionTeam
from .robot_space_team import RobotSpaceTeam
from .team_chart import LawGroup, TeamChart, default_template, fit_attitude
from .ugv_uav import (
    SPHERICAL_VARIABLES,
    UGV_UAV_LAYOUT,
    UGV_UAV_VARIABLES,
    UgvUavQuaternion,
    UgvUavRestricted,
    UgvUavSpherical,
)

#: Every description by a unique key: the two-robot ones of seed 000 by their name
#: (``euclidean``, ``robot``, ``quaternion``, ``dual-quaternion``), the UGV-UAV ones of seed
#: 001 as ``ugv-uav-<name>`` (``ugv-uav-spherical``, ``ugv-uav-restricted``, ``ugv-uav-quaternion``).
FORMATIONS = {
    **{f.name: f for f in (EuclideanPair(), RobotSpace(), QuaternionPair(), DualQuaternionPair())},
    **{f"ugv-uav-{f.name}": f for f in (UgvUavSpherical(), UgvUavRestricted(), UgvUavQuaternion())},
    "robot-space-team": RobotSpaceTeam(layout=RobotLayout(("xyz_yaw", "xy_yaw", "pose", "xyz_yaw"))),
    "euclidean-team": EuclideanTeam(layout=RobotLayout(("xyz_yaw", "xyz", "xyz_yaw", "xyz_yaw", "xyz"))),
    # a ground robot under spatial ones, robots 1-3 of the template on a line (robot 4 plays robot 3)
    "euclidean-team-ground": EuclideanTeam(layout=RobotLayout(("xy_yaw", "xyz_yaw", "xyz_yaw", "xyz", "xyz_yaw")),
                                           template=[[0, 0, 0], [1, 0, 1], [2, 0, 2], [0, 1, 1], [1, 1, 1]]),
    "dual-quaternion-team": DualQuaternionTeam(layout=RobotLayout(("xyz_yaw", "xy_yaw", "pose", "xyz_yaw", "xyz"))),
    "quaternion-team": QuaternionTeam(layout=RobotLayout(("xyz_yaw", "xy_yaw", "pose", "xyz"))),
}

#: The team descriptions (N robots of any point kinds) by key, as classes:
#: ``TEAM_FORMATIONS[key](n=None, *, layout=None, template=None)``.
TEAM_FORMATIONS = {"robot-space-team": RobotSpaceTeam, "euclidean-team": EuclideanTeam,
                   "dual-quaternion-team": DualQuaternionTeam, "quaternion-team": QuaternionTeam}

__all__ = [
    "Formation",
    "Variable",
    "RobotLayout",
    "POINT_KINDS",
    "PAIR_LAYOUT",
    "UGV_UAV_LAYOUT",
    "SpecialSet",
    "ROBOT_PAIR_VARIABLES",
    "EUCLIDEAN_VARIABLES",
    "EuclideanPair",
    "RobotSpace",
    "QuaternionPair",
    "DualQuaternionPair",
    "FORMATIONS",
    "TEAM_FORMATIONS",
    "RobotSpaceTeam",
    "EuclideanTeam",
    "DualQuaternionTeam",
    "QuaternionTeam",
    "TeamChart",
    "LawGroup",
    "fit_attitude",
    "default_template",
    "segment_direction",
    "UgvUavSpherical",
    "UgvUavRestricted",
    "UgvUavQuaternion",
    "UGV_UAV_VARIABLES",
    "SPHERICAL_VARIABLES",
]
