"""Run metrics of a two-robot (seed 000) log: the numbers ``metrics.json`` holds.

Sim layer. The metrics read a :class:`~quatform.sim.log.Log` of the pair kind
(:mod:`quatform.scenarios.pair`): the channels ``state`` (measured robots), ``r_des``,
``e`` / ``e_des`` (Euclidean variables recovered by the controller's own description,
``formation.to_chart``, and the desired ones), ``command``, ``raw_finite`` and
``singularity``, and the meta keys ``scenario``, ``controller``, ``formation``, ``dt_s``,
``metrics_from_s`` and ``feedforward``. Errors that compare controllers are computed from
the robots' measured poses, the same way for every description. A batched log (leading
batch axes) is measured one world at a time: ``compute_metrics(log.world(i))``.
"""

from __future__ import annotations

import functools

import numpy as np

from ..algebra import wrap_angle
from ..algebra.kernels import array_namespace as namespace
from ..algebra.kernels import dot_last
from ..errors import InvalidInputError, ShapeError
from ..formations import segment_direction
from ..formations.base import PAIR_LAYOUT
from .log import Log

__all__ = ["compute_metrics", "measured_samples", "first_time", "errors_from_robots", "robot_errors",
           "SINGULAR_THRESHOLD", "LOST_POSITION_M", "LOST_ANGLE_RAD"]

#: A measured state whose singularity measure falls below this is reported singular.
SINGULAR_THRESHOLD = 0.02
#: Errors beyond these (after ``metrics_from_s``) mean the controller lost the reference.
LOST_POSITION_M = 0.1
LOST_ANGLE_RAD = 0.1


def first_time(t, mask):
    """The first time ``t[k]`` where ``mask[k]`` (s), or None."""
    idx = np.flatnonzero(mask)
    return float(t[idx[0]]) if idx.size else None


def errors_from_robots(log: Log) -> dict:
    """Representation-independent error signals of one world, each of shape ``(T,)``.

    ``cluster_position`` (midpoints, m), ``shape`` (``|p1 - p2| / 2 - d_c``, m),
    ``orientation`` (angle between the measured and desired robot-to-robot directions, rad,
    seed 000 eq. (3)'s ``beta_c, gamma_c``), ``robot_position`` and ``robot_yaw`` (the worse
    robot), ``separation`` (m) and ``recovered_euclidean`` (largest wrapped angle error of
    the recovered Euclidean variables, rad).
    """
    r, rd, e, e_des = log["state"], log["r_des"], log["e"], log["e_des"]
    with np.errstate(invalid="ignore", divide="ignore"):  # a failed world held on each other reads NaN
        errs = robot_errors(r, rd, e_des)
    return {**errs,
            "recovered_euclidean": np.max(np.abs(wrap_angle(e[:, [3, 4, 6, 7]] - e_des[:, [3, 4, 6, 7]])), axis=1)}


def robot_errors(r, r_des, e_des) -> dict:
    """The error signals of :func:`errors_from_robots` but ``recovered_euclidean``, of robot
    states with any leading axes (a time series, a batch of worlds at one tick ...), on NumPy
    or JAX arrays (a batched rollout reduces them tick by tick).

    Parameters
    ----------
    r, r_des : array_like, shape (..., 8)
        Measured and desired robots (seed 000's pair), m and rad.
    e_des : array_like, shape (..., 8)
        Desired Euclidean cluster variables (eqs. (1)-(8)).

    Returns
    -------
    dict of arrays, shape (...)
    """
    xp = namespace(r)
    p, p_d = PAIR_LAYOUT.positions(r), PAIR_LAYOUT.positions(r_des)  # (..., 2, 3)
    mid = 0.5 * (p[..., 0, :] + p[..., 1, :])
    mid_d = 0.5 * (p_d[..., 0, :] + p_d[..., 1, :])
    delta = p[..., 0, :] - p[..., 1, :]
    D = xp.linalg.norm(delta, axis=-1)
    u = delta / D[..., None]
    u_d = segment_direction(e_des[..., 3], e_des[..., 4])
    return {
        "cluster_position": xp.linalg.norm(mid - mid_d, axis=-1),
        "shape": xp.abs(0.5 * D - e_des[..., 5]),
        "orientation": xp.arccos(xp.clip(dot_last(u, u_d), -1.0, 1.0)),
        "robot_position": xp.max(xp.linalg.norm(p - p_d, axis=-1), axis=-1),
        # each robot's yaw apart (the compiled rollout then wraps the two yaws alone, not all 8 entries)
        "robot_yaw": functools.reduce(xp.maximum, [xp.abs(wrap_angle(r[..., q] - r_des[..., q]))
                                                   for q in PAIR_LAYOUT.yaw_indices]),
        "separation": D,
    }


def measured_samples(log: Log, who: str) -> np.ndarray:
    """The samples at or after ``meta["metrics_from_s"]`` of one world's log, ``(T,)`` bool.

    Raises
    ------
    ShapeError
        For a batched log (``who`` names the metrics function in the message).
    InvalidInputError
        When there is none: every max error would read 0 and a failed run would look perfect.
    """
    if log.batch_shape:
        raise ShapeError(f"{who}: the log holds a batch of worlds {log.batch_shape}; measure one world at a time "
                         f"with {who}(log.world(i))")
    meta, t = log.meta, log.t
    late = t >= meta["metrics_from_s"]
    if not late.any():
        last = float(t[-1]) if len(t) else float("nan")
        raise InvalidInputError(
            f"scenario {meta['scenario']!r}: metrics_from_s = {meta['metrics_from_s']:g} s is after the "
            f"run's last sample ({last:g} s), so no error would be measured; choose metrics_from_s < duration_s")
    return late


def compute_metrics(log: Log) -> dict:
    """The metrics of one world's run as a JSON-ready dict (units in the key names).

    Raises
    ------
    ShapeError
        For a batched log (measure each world: ``log.world(i)``).
    InvalidInputError
        When no sample lies at or after ``metrics_from_s``.
    """
    meta, t = log.meta, log.t
    late = measured_samples(log, "compute_metrics")
    err = errors_from_robots(log)
    sing = log["singularity"][:, 0]
    u = log["command"]
    singular = sing < SINGULAR_THRESHOLD
    lost = late & ((err["cluster_position"] > LOST_POSITION_M) | (err["orientation"] > LOST_ANGLE_RAD)
                   | (err["robot_position"] > LOST_POSITION_M))

    def mx(key):
        return float(err[key][late].max())

    return {
        "controller": meta["controller"],
        "formation": meta["formation"],
        "scenario": meta["scenario"],
        "duration_s": float(t[-1]),
        "dt_s": meta["dt_s"],
        "metrics_from_s": meta["metrics_from_s"],
        "feedforward": bool(meta["feedforward"]),
        "singularity_detected": bool(singular.any()),
        "first_singular_time_s": first_time(t, singular),
        "min_singularity_measure": float(sing.min()),
        "reference_lost": bool(lost.any()),
        "first_lost_time_s": first_time(t, lost),
        "max_cluster_position_error_m": mx("cluster_position"),
        "max_shape_error_m": mx("shape"),
        "max_orientation_error_rad": mx("orientation"),
        "max_robot_position_error_m": mx("robot_position"),
        "max_robot_yaw_error_rad": mx("robot_yaw"),
        "min_robot_separation_m": float(err["separation"].min()),
        "max_recovered_euclidean_error_rad": mx("recovered_euclidean"),
        "nonfinite_commands": int((log["raw_finite"][:, 0] < 0.5).sum()),
        "max_command_speed_m_s": float(np.linalg.norm(PAIR_LAYOUT.positions(u), axis=-1).max()),
    }
