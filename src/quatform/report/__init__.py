"""Report layer: figures of runs (above sim; below cli)."""

from .plots import (
    plot_cluster_variables,
    plot_compare,
    plot_euclidean,
    plot_paths_3d,
    plot_separation,
    write_compare_plots,
    write_run_plots,
)

__all__ = [
    "plot_cluster_variables",
    "plot_compare",
    "plot_euclidean",
    "plot_paths_3d",
    "plot_separation",
    "write_compare_plots",
    "write_run_plots",
]
