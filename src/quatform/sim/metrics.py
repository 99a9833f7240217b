"""Run metrics: the numbers ``metrics.json`` holds.

Sim layer. Errors that compare controllers are computed from the robots' measured poses,
the same way for every description; the recovered Euclidean error uses each controller's
own description (``formation.euclidean``), as its operator would see the formation.
"""

from __future__ import annotations

import numpy as np

from ..algebra import wrap_angle
from ..errors import InvalidInputError
from ..formations import segment_direction
from .runner import Run

__all__ = ["compute_metrics", "SINGULAR_THRESHOLD", "LOST_POSITION_M", "LOST_ANGLE_RAD"]

#: A measured state whose singularity measure falls below this is reported singular.
SINGULAR_THRESHOLD = 0.02
#: Errors beyond these (after ``metrics_from_s``) mean the controller lost the reference.
LOST_POSITION_M = 0.1
LOST_ANGLE_RAD = 0.1


def _first(t, mask):
    idx = np.flatnonzero(mask)
    return float(t[idx[0]]) if idx.size else None


def errors_from_robots(run: Run) -> dict:
    """Representation-independent error signals, each shape ``(T,)``."""
    r, rd = run.r, run.r_des
    mid = 0.5 * (r[:, 0:3] + r[:, 4:7])
    mid_d = 0.5 * (rd[:, 0:3] + rd[:, 4:7])
    delta = r[:, 0:3] - r[:, 4:7]
    D = np.linalg.norm(delta, axis=1)
    u = delta / D[:, None]
    u_d = segment_direction(run.e_des[:, 3], run.e_des[:, 4])
    return {
        "cluster_position": np.linalg.norm(mid - mid_d, axis=1),
        "shape": np.abs(0.5 * D - run.e_des[:, 5]),
        "orientation": np.arccos(np.clip(np.einsum("ij,ij->i", u, u_d), -1.0, 1.0)),
        "robot_position": np.maximum(np.linalg.norm(r[:, 0:3] - rd[:, 0:3], axis=1),
                                     np.linalg.norm(r[:, 4:7] - rd[:, 4:7], axis=1)),
        "robot_yaw": np.maximum(np.abs(wrap_angle(r[:, 3] - rd[:, 3])), np.abs(wrap_angle(r[:, 7] - rd[:, 7]))),
        "separation": D,
        "recovered_euclidean": np.max(np.abs(wrap_angle(run.e[:, [3, 4, 6, 7]] - run.e_des[:, [3, 4, 6, 7]])), axis=1),
    }


def compute_metrics(run: Run) -> dict:
    """The metrics of one run as a JSON-ready dict (units in the key names)."""
    late = run.t >= run.scenario.metrics_from_s
    if not late.any():  # every max error would read 0: a failed run would look perfect
        last = float(run.t[-1]) if len(run.t) else float("nan")
        raise InvalidInputError(
            f"scenario {run.scenario.name!r}: metrics_from_s = {run.scenario.metrics_from_s:g} s is after the "
            f"run's last sample ({last:g} s), so no error would be measured; choose metrics_from_s < duration_s")
    err = errors_from_robots(run)
    singular = run.singularity < SINGULAR_THRESHOLD
    lost = late & ((err["cluster_position"] > LOST_POSITION_M) | (err["orientation"] > LOST_ANGLE_RAD)
                   | (err["robot_position"] > LOST_POSITION_M))

    def mx(key):
        return float(err[key][late].max())

    return {
        "controller": run.controller.name,
        "formation": run.controller.formation.name,
        "scenario": run.scenario.name,
        "duration_s": float(run.t[-1]),
        "dt_s": run.scenario.dt_s,
        "metrics_from_s": run.scenario.metrics_from_s,
        "feedforward": bool(getattr(run.controller, "feedforward", True)),
        "singularity_detected": bool(singular.any()),
        "first_singular_time_s": _first(run.t, singular),
        "min_singularity_measure": float(run.singularity.min()),
        "reference_lost": bool(lost.any()),
        "first_lost_time_s": _first(run.t, lost),
        "max_cluster_position_error_m": mx("cluster_position"),
        "max_shape_error_m": mx("shape"),
        "max_orientation_error_rad": mx("orientation"),
        "max_robot_position_error_m": mx("robot_position"),
        "max_robot_yaw_error_rad": mx("robot_yaw"),
        "min_robot_separation_m": float(err["separation"].min()),
        "max_recovered_euclidean_error_rad": mx("recovered_euclidean"),
        "nonfinite_commands": int((~run.raw_finite).sum()),
        "max_command_speed_m_s": float(max(np.linalg.norm(run.u[:, 0:3], axis=1).max(),
                                            np.linalg.norm(run.u[:, 4:7], axis=1).max())),
    }
