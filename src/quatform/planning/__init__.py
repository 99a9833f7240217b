"""Planning layer: motions of robot teams planned ahead (above formations and references).

Seed 002 (Belta & Kumar 2002): geodesics of a shaped kinetic-energy metric that range from
the uniform straight lines of independent robots (``alpha = 0.5``) to the optimal rigid
motion of the formation (``alpha -> 1``). A :class:`Plan` samples any planned motion at any
rate and is saved as ``plan.npz``; :class:`PlanPairPath` feeds a two-robot spatial plan to
the seed 000 pair controllers. Imports algebra, formations and references; never sim,
report or cli.
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
)

__all__ = [
    "PLANNERS",
    "GeodesicSolution",
    "Plan",
    "PlanPairPath",
    "PlanSpec",
    "builtin_plan_specs",
    "christoffel_symbols",
    "geodesic_acceleration",
    "geodesic_jacobian",
    "horizontal_basis",
    "load_plan",
    "load_plan_spec",
    "make_plan",
    "metric_energy",
    "min_separation",
    "pair_separations",
    "plan_from_geodesic",
    "plan_metrics",
    "rigid_generators",
    "rigid_motion",
    "shaped_metric",
    "shaped_metric_derivative",
    "shaped_metric_inverse",
    "solve_geodesic",
    "straight_line_motion",
]
