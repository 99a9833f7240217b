"""Report layer: figures, tables and writers that read a run's Log (above scenarios; below runs, cli).

* :data:`FIGURES` - the figure registry: ``{kind name: FigureSet(run, compare)}``, filled by
  the figure modules (``FIGURES.add`` beside their functions), read by :mod:`quatform.runs`
  for every scenario kind through :func:`figures_of`;
* :mod:`.figures` - the shared figure helpers; :mod:`.writers` - ``timeseries.csv`` and strict
  JSON for every kind;
* one figure module per kind (:mod:`.plots` for seed 000's pairs, :mod:`.ugv_uav_plots`,
  :mod:`.teleop_plots`, :mod:`.team_plots` for teams of N robots); the planners' figures
  (:mod:`.plan_plots`, :mod:`.planning_plots`) and the replay's ``commands.png``
  (:mod:`.replay_plots`).
"""

from .figure_set import FIGURES, NO_FIGURES, FigureSet, figures_of
from .plots import (
    plot_cluster_variables,
    plot_compare,
    plot_euclidean,
    plot_paths_3d,
    plot_separation,
    write_compare_plots,
    write_run_plots,
)

from .team_plots import write_team_compare_plots, write_team_run_plots
from .teleop_plots import write_teleop_compare_plots, write_teleop_plots
from .ugv_uav_plots import write_ugv_uav_compare_plots, write_ugv_uav_run_plots
from ..registry import import_package_modules

# every figure module registers its kind's FigureSet in FIGURES when imported
import_package_modules(__name__, __path__, suffix="plots")

__all__ = [
    "FIGURES",
    "FigureSet",
    "figures_of",
    "NO_FIGURES",
    "plot_cluster_variables",
    "plot_compare",
    "plot_euclidean",
    "plot_paths_3d",
    "plot_separation",
    "write_compare_plots",
    "write_run_plots",
]
