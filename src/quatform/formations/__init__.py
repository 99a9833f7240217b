"""Formations layer: cluster-space descriptions of robot teams (seeds 000 and 001).

Sits above :mod:`quatform.algebra` and below robots, control and references. Every
description implements :class:`Formation` over a :class:`RobotLayout`: ``forward`` and
``inverse`` (branch choices as keywords: ``near_c``, ``near_r``), the rate maps
``cluster_rate`` and ``robot_rate`` (the dense ``jacobian``, ``inverse_jacobian_at`` and
``inverse_jacobian`` derive from them), ``singularity_measure``, the operator's chart
(``to_chart``, ``from_chart``; ``euclidean`` and ``from_euclidean`` are aliases),
``reachable``, ``sample_robot_state`` and ``special_sets``. A new description is one
module: a :class:`Formation` subclass with a ``key`` registers itself in
:data:`FORMATION_TYPES` when it is defined, :data:`FORMATIONS` holds its ``examples()``
(and :data:`TEAM_FORMATIONS` the classes with ``team = True``; a :class:`Preset` of a team
description, e.g. ``EuclideanPair``, is a formation of its own key only), and
``tests/test_formation_contract.py`` runs
:func:`quatform.formations.testing.check_formation` over every one.
"""

from .base import (FORMATION_TYPES, FORMATIONS, PAIR_LAYOUT, ROBOT_PAIR_VARIABLES, TEAM_FORMATIONS, Formation, Preset,
                   Variable)
from .layout import POINT_KINDS, RobotLayout
from .special_sets import SpecialSet
from .dual_quaternion_team import DualQuaternionPair, DualQuaternionTeam
from .euclidean_team import EUCLIDEAN_VARIABLES, EuclideanPair, EuclideanTeam, segment_direction
from .quaternion_team import QuaternionPair, QuaternionTeam
from .robot_space_team import RobotSpace, RobotSpaceTeam
from .team_chart import LawGroup, TeamChart, default_template, fit_attitude
from .ugv_uav import (
    SPHERICAL_VARIABLES,
    UGV_UAV_LAYOUT,
    UGV_UAV_VARIABLES,
    UgvUavQuaternion,
    UgvUavRestricted,
    UgvUavSpherical,
)

__all__ = [
    "Formation",
    "Preset",
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
    "FORMATION_TYPES",
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
