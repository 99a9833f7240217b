"""Run files: ``timeseries.csv`` and ``metrics.json``.

Sim layer. The time series holds, for every logged variable, the measured value ``v``
and the desired ``v_des`` side by side: the robots (``x1 ... theta2``), the controller's
own cluster variables (quaternion components ``q_c_w, q_c_x, ...``), the Euclidean
variables recovered from the measurements (prefix ``euclid_``), the commands
(``u_x1 ...``) and the singularity measure.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..formations import EUCLIDEAN_VARIABLES, ROBOT_PAIR_VARIABLES
from .runner import Run

__all__ = ["timeseries_columns", "write_columns", "write_timeseries", "write_metrics"]


def timeseries_columns(run: Run):
    """Column names and the ``(T, n)`` array of the time series."""
    names, cols = ["t"], [run.t[:, None]]

    def add(vars_, meas, des, prefix=""):
        for i, v in enumerate(vars_):
            names.extend([prefix + v.name, prefix + v.name + "_des"])
            cols.extend([meas[:, i:i + 1], des[:, i:i + 1]])

    add(ROBOT_PAIR_VARIABLES, run.r, run.r_des)
    F = run.controller.formation
    if F.name not in ("robot",):
        add(F.variables, run.c, run.c_des)
    add(EUCLIDEAN_VARIABLES, run.e, run.e_des, prefix="euclid_")
    names.extend("u_" + v.name for v in ROBOT_PAIR_VARIABLES)
    cols.append(run.u)
    names.append("singularity_measure")
    cols.append(run.singularity[:, None])
    return names, np.hstack(cols)


def write_columns(names, data, path) -> Path:
    """A CSV file with a header row ``names`` and the ``(T, n)`` array ``data`` (9 digits)."""
    path = Path(path)
    np.savetxt(path, data, delimiter=",", header=",".join(names), comments="", fmt="%.9g")
    return path


def write_timeseries(run: Run, path) -> Path:
    return write_columns(*timeseries_columns(run), path)


def write_metrics(metrics: dict, path) -> Path:
    path = Path(path)
    path.write_text(json.dumps(metrics, indent=2) + "\n")
    return path
