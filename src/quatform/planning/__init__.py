"""Planning layer: motions planned ahead of time (above robots and control, below sim).

Seed 004 (Belta & Kumar 2001): near-optimal rigid-formation motion on SE(3) by projection
from GA(3) (:mod:`.se3`, :mod:`.rigid_formation`).
"""

from .rigid_formation import (
    AIRPLANE_CASES,
    RigidFormationPlan,
    RigidFormationSample,
    airplane_constraint_matrix,
    airplanes_plan,
    airplanes_spec,
    formation_metric,
    rigid_plan_from_spec,
    twist_null_space,
)
from .se3 import (
    ProjectedCurve,
    g_from_w,
    metric_ga,
    metric_gl,
    metric_se3,
    metric_so3,
    project_to_se3,
    project_to_so3,
    projected_rotation_rates,
    w_from_g,
)

__all__ = [
    "AIRPLANE_CASES",
    "ProjectedCurve",
    "RigidFormationPlan",
    "RigidFormationSample",
    "airplane_constraint_matrix",
    "airplanes_plan",
    "airplanes_spec",
    "formation_metric",
    "g_from_w",
    "metric_ga",
    "metric_gl",
    "metric_se3",
    "metric_so3",
    "project_to_se3",
    "project_to_so3",
    "projected_rotation_rates",
    "rigid_plan_from_spec",
    "twist_null_space",
    "w_from_g",
]
