"""Sim layer: scenarios, the closed loop and its metrics (above references and control)."""

from .metrics import compute_metrics, errors_from_robots
from .output import write_columns, write_metrics, write_timeseries
# the loop's module first: importing quatform.sim.simulate later then leaves the name
# `simulate` below (the two-robot run) as it is instead of binding it to the module
from .simulate import PerfectMeasurement
from .runner import Run, simulate
from .scenario import Scenario, builtin_scenarios, load_scenario

__all__ = ["Run", "simulate", "PerfectMeasurement", "compute_metrics", "errors_from_robots", "Scenario", "load_scenario",
           "builtin_scenarios", "write_columns", "write_metrics", "write_timeseries"]
