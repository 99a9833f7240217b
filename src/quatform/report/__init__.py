"""Report layer: figures, tables and writers that read a run's Log (above scenarios; below runs, cli).

* :data:`FIGURES` - the figure registry: ``{kind name: FigureSet(run, compare)}``, read by
  :mod:`quatform.runs` for every scenario kind;
* :mod:`.figures` - the shared figure helpers; :mod:`.writers` - ``timeseries.csv`` and strict
  JSON for every kind;
* one figure module per kind (:mod:`.plots` for seed 000's pairs, :mod:`.ugv_uav_plots`,
  :mod:`.teleop_plots`, :mod:`.team_plots` for teams of N robots); the planners' figures
  (:mod:`.plan_plots`, :mod:`.planning_plots`) and the replay's ``commands.png``
  (:mod:`.replay_plots`).
"""

from .figure_set import NO_FIGURES, FigureSet
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

#: Figures of each scenario kind, by the kind's name (every registered kind has an entry;
#: a kind without figures maps to :data:`NO_FIGURES`).
FIGURES: dict[str, FigureSet] = {
    "pair": FigureSet(write_run_plots, write_compare_plots),
    "ugv-uav": FigureSet(write_ugv_uav_run_plots, write_ugv_uav_compare_plots),
    "teleop": FigureSet(write_teleop_plots, write_teleop_compare_plots),
    "team": FigureSet(write_team_run_plots, write_team_compare_plots),
}

__all__ = [
    "FIGURES",
    "FigureSet",
    "NO_FIGURES",
    "plot_cluster_variables",
    "plot_compare",
    "plot_euclidean",
    "plot_paths_3d",
    "plot_separation",
    "write_compare_plots",
    "write_run_plots",
]
