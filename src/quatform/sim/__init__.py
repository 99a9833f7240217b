"""Sim layer: plants, measurement models, the one closed loop and its log, metrics and run files
(above references and control, below scenarios)."""

from .log import Channel, Log
from .metrics import compute_metrics, errors_from_robots
from .output import write_columns, write_metrics, write_timeseries
from .scenario import builtin_scenarios, load_scenario
from .simulate import PerfectMeasurement, simulate

__all__ = ["simulate", "PerfectMeasurement", "Log", "Channel", "compute_metrics", "errors_from_robots",
           "load_scenario", "builtin_scenarios", "write_columns", "write_metrics", "write_timeseries"]
