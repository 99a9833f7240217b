"""Planning layer: motions of robot teams planned ahead (above formations and references).

* Seed 002 (Belta & Kumar 2002): geodesics of a shaped kinetic-energy metric that range
  from the uniform straight lines of independent robots (``alpha = 0.5``) to the optimal
  rigid motion of the formation (``alpha -> 1``). A :class:`Plan` samples any planned
  motion at any rate and is saved as ``plan.npz``; :class:`PlanPairPath` feeds a
  two-robot spatial plan to the seed 000 pair controllers.
* Seed 004 (Belta & Kumar 2001): near-optimal rigid-formation motion on SE(3) by
  projection from GA(3) (:mod:`.se3`, :mod:`.rigid_formation`), for fully actuated and
  airplane-like robots.

Imports algebra, formations and references; never sim, report or cli.
"""

from .geodesic import GeodesicSolution, plan_from_geodesic, solve_geodesic
from .measures import (
    min_separation,
    pair_separations,
    rigid_motion,
    straight_line_motion,
)
from .pair_reference import PlanPairPath
from .plan import Plan, load_plan
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
from .shaping import (
    christoffel_symbols,
    geodesic_acceleration,
    geodesic_jacobian,
    horizontal_basis,
    metric_energy,
    rigid_generators,
    shaped_metric,
    shaped_metric_derivative,
    shaped_metric_inverse,
)
from .spec import (
    PLANNERS,
    PlanSpec,
    builtin_plan_specs,
    load_plan_spec,
    make_plan,
    plan_metrics,
    rigid_formation_dict,
)

__all__ = [
    "AIRPLANE_CASES",
    "PLANNERS",
    "airplane_constraint_matrix",
    "airplanes_plan",
    "airplanes_spec",
    "builtin_plan_specs",
    "christoffel_symbols",
    "formation_metric",
    "g_from_w",
    "geodesic_acceleration",
    "geodesic_jacobian",
    "GeodesicSolution",
    "horizontal_basis",
    "load_plan",
    "load_plan_spec",
    "make_plan",
    "metric_energy",
    "metric_ga",
    "metric_gl",
    "metric_se3",
    "metric_so3",
    "min_separation",
    "pair_separations",
    "Plan",
    "plan_from_geodesic",
    "plan_metrics",
    "PlanPairPath",
    "PlanSpec",
    "project_to_se3",
    "project_to_so3",
    "projected_rotation_rates",
    "ProjectedCurve",
    "rigid_generators",
    "rigid_motion",
    "rigid_formation_dict",
    "rigid_plan_from_spec",
    "RigidFormationPlan",
    "RigidFormationSample",
    "shaped_metric",
    "shaped_metric_derivative",
    "shaped_metric_inverse",
    "solve_geodesic",
    "straight_line_motion",
    "twist_null_space",
    "w_from_g",
]
