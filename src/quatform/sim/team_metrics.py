"""Run metrics of a team (N-robot) log: representation-independent numbers for ``metrics.json``.

Sim layer. Like :mod:`.metrics` for pairs, the errors that compare controllers are computed
from the robots' measured points against the desired ones, the same way for every team
description; for two robots they are the pair's keys with the pair's values:

* ``cluster_position``: the centroids' distance (seed 000 eq. (9) for N robots);
* the best-fit rotation ``Q`` of the desired centred robots onto the measured ones (Horn
  1987, :func:`~quatform.formations.team_chart.fit_attitude`, ties broken toward the
  identity: for two robots the minimal rotation between the two segments, seed 000 eqs.
  (14)-(15));
* ``shape``: ``max_i |Q^T c_i - d_i|`` (``c_i, d_i`` measured and desired positions about
  their centroids; for two robots ``| |p1 - p2| / 2 - d_c |``);
* ``orientation``: the angle of ``Q`` (for two robots the angle between the measured and
  desired robot-to-robot directions, the pair's);
* ``robot_position`` / ``robot_yaw``: the worst robot; ``separation``: the closest pair.

The log is one world of the team kind (:mod:`quatform.scenarios.team`): channels ``points``
(the robots' points), ``r_des``, ``e`` / ``e_des`` (the chart recovered by the controller's
description and the desired one), ``command``, ``raw_finite``, ``singularity`` (NaN where
not computed) and, when the separation barrier runs, ``min_separation`` / ``safety_active``;
meta ``layout``, ``team``, ``scenario``, ``controller``, ``formation``, ``dt_s``,
``metrics_from_s``, ``feedforward``, ``safety``.
"""

from __future__ import annotations

import numpy as np

from ..algebra import wrap_angle
from ..formations import geometry as g
from ..formations.team_chart import fit_attitude
from .log import Log
from .metrics import LOST_ANGLE_RAD, LOST_POSITION_M, SINGULAR_THRESHOLD, first_time, measured_samples

__all__ = ["singular_threshold", "team_errors", "team_metrics", "min_separations", "rotation_angle"]

#: Most pair distances held at once by :func:`min_separations` (time chunks of the run).
_PAIR_CHUNK = 2_000_000


def rotation_angle(q) -> np.ndarray:
    """The angle (rad, in ``[0, pi]``) of the rotations ``q`` ``(..., 4)``: ``2 atan2(|q_vec|, |q_w|)``
    (accurate near 0, sign-free)."""
    q = np.asarray(q, dtype=float)
    return 2.0 * np.arctan2(np.linalg.norm(q[..., 1:], axis=-1), np.abs(q[..., 0]))


def min_separations(layout, r) -> np.ndarray:
    """The closest two robots' distance at each sample, m, shape ``(T,)`` (time chunks, so a
    large team's ``N (N - 1) / 2`` distances are never all held)."""
    r = np.asarray(r, dtype=float)
    n_pairs = max(1, layout.n * (layout.n - 1) // 2)
    step = max(1, _PAIR_CHUNK // n_pairs)
    return np.concatenate([layout.min_separation(r[k:k + step]) for k in range(0, r.shape[0], step)]) \
        if r.shape[0] else np.zeros(0)


def team_errors(log: Log) -> dict:
    """The error signals of one world, each ``(T,)`` (module docstring), plus ``robot_position_each``
    ``(T, N)``, ``recovered_attitude`` (rad: the attitude the controller's description recovers
    against the desired one) and ``recovered_heading`` (rad, the worst robot)."""
    L = log.meta["layout"]
    r, rd = np.asarray(log["points"]), np.asarray(log["r_des"])
    p, pd = L.positions(r), L.positions(rd)
    xc, xcd = p.mean(axis=-2), pd.mean(axis=-2)
    c, d = p - xc[..., None, :], pd - xcd[..., None, :]
    Q = fit_attitude(d, c)
    back = g.rotate(g.conj(Q)[..., None, :], c)
    each = np.linalg.norm(p - pd, axis=-1)
    out = {
        "cluster_position": np.linalg.norm(xc - xcd, axis=-1),
        "shape": np.max(np.linalg.norm(back - d, axis=-1), axis=-1),
        "orientation": rotation_angle(Q),
        "robot_position": np.max(each, axis=-1),
        "robot_position_each": each,
        "separation": min_separations(L, r),
    }
    heading = []
    if L.yaw_indices:
        heading.append(np.abs(wrap_angle(L.yaws(r) - L.yaws(rd))))
    if len(L.orientation_index):
        heading.append(rotation_angle(g.mul(g.conj(L.orientations(rd)), L.orientations(r))))
    out["robot_yaw"] = np.max(np.concatenate(heading, axis=-1), axis=-1) if heading else None
    e, ed = np.asarray(log["e"]), np.asarray(log["e_des"])
    out["recovered_attitude"] = rotation_angle(g.mul(g.conj(ed[..., 3:7]), e[..., 3:7]))
    n_yaw = len(L.yaw_indices)
    if n_yaw:
        idx = 7 + 3 * L.n + np.flatnonzero([k in ("xy_yaw", "xyz_yaw") for k in _chart_heading_kinds(L)])
        out["recovered_heading"] = np.max(np.abs(wrap_angle(e[..., idx] - ed[..., idx])), axis=-1)
    else:
        out["recovered_heading"] = None
    return out


def _chart_heading_kinds(L):
    """The point kind of each heading entry of the chart (one per yaw, four per pose robot)."""
    out = []
    for k in L.kinds:
        if k in ("xy_yaw", "xyz_yaw"):
            out.append(k)
        elif k == "pose":
            out += ["pose"] * 4
    return out


#: Samples whose reference lies within this of the vertical (``|cos gamma_c| <`` it, about 3
#: degrees) are left out of the Euler reading's error: there ``beta_c`` and ``alpha_c`` are not
#: separate (seed 000 eq. (5)'s singular pose) and a millimetre reads as a large angle.
READING_POLE_COS = 0.05


def _reading_metrics(log: Log, late) -> dict:
    """``max_reading_error_rad`` (the formation's Euler reading against the reference's, the
    worst angle, away from the vertical) and ``reading_folded_time_s`` (how long ``beta_c`` read
    more than pi/2 off the reference's: the reading folded, seed 000's robot-space finding);
    None without a ``reading`` channel (a team no minimal Euclidean chart takes)."""
    if "reading" not in log:
        return {"max_reading_error_rad": None, "reading_folded_time_s": None}
    a, ad = np.asarray(log["reading"]), np.asarray(log["reading_des"])
    away = np.abs(np.cos(ad[:, 1])) >= READING_POLE_COS if ad.shape[1] > 1 else np.ones(len(ad), dtype=bool)
    use = late & away
    err = np.abs(wrap_angle(a - ad))
    folded = use & (err[:, 0] > 0.5 * np.pi)
    tick = float(log.t[1] - log.t[0]) if log.t.size > 1 else 0.0
    return {"max_reading_error_rad": float(err[use].max()) if use.any() else None,
            "reading_folded_time_s": float(folded.sum() * tick)}


def _command_speed(team, u) -> float:
    """The fastest commanded robot, m/s: the norm of each robot's linear-velocity commands
    (the columns named ``v``, ``v_x``, ``v_y``, ``v_z``)."""
    u = np.asarray(u, dtype=float)
    best = 0.0
    for robot, sl in zip(team.robots, team.command_slices):
        lin = [i for i, name in enumerate(robot.command_columns) if name in ("v", "v_x", "v_y", "v_z")]
        if lin and u.shape[0]:
            best = max(best, float(np.linalg.norm(u[..., sl][..., lin], axis=-1).max()))
    return best


def singular_threshold(n_robots: int) -> float:
    """The singularity measure below which an N-robot state is reported singular:
    :data:`~quatform.sim.metrics.SINGULAR_THRESHOLD` (the pair's 0.02) times ``2 / N``.

    The measure is the reciprocal condition number of an ``n_r x n_c`` inverse Jacobian, and
    a regular formation's conditioning worsens with N (the Euclidean team of a flat ring of 10
    robots reads 0.0135 away from any singular pose; its singular poses read 1e-6 and less), so
    the pair's threshold would flag every large team from t = 0; for two robots it is the
    pair's.
    """
    return SINGULAR_THRESHOLD * 2.0 / max(int(n_robots), 2)


def team_metrics(log: Log) -> dict:
    """The metrics of one world's team run as a JSON-ready dict (units in the key names).

    The pair's keys (:func:`quatform.sim.metrics.compute_metrics`, same definitions for two
    robots) and the team's: ``n_robots``, ``robot_position_error_median_m`` (the median over
    the robots of each one's largest error), ``max_recovered_attitude_error_rad``,
    ``max_recovered_heading_error_rad``, ``singularity_samples``, and the barrier's
    ``safety_enabled``, ``safety_applied``, ``safety_min_separation_m`` and (when it ran)
    ``safety_active_time_s``.

    Raises
    ------
    ShapeError
        For a batched log.
    InvalidInputError
        When no sample lies at or after ``metrics_from_s``.
    """
    meta, t = log.meta, log.t
    late = measured_samples(log, "team_metrics")
    err = team_errors(log)
    sing = np.asarray(log["singularity"])[:, 0]
    measured = np.isfinite(sing)
    singular = measured & (np.where(measured, sing, 1.0) < singular_threshold(int(meta["layout"].n)))
    lost = late & ((err["cluster_position"] > LOST_POSITION_M) | (err["orientation"] > LOST_ANGLE_RAD)
                   | (err["robot_position"] > LOST_POSITION_M))

    def mx(key):
        return None if err[key] is None else float(err[key][late].max())

    safety = dict(meta.get("safety", {}))
    out = {
        "controller": meta["controller"],
        "formation": meta["formation"],
        "scenario": meta["scenario"],
        "n_robots": int(meta["layout"].n),
        "duration_s": float(t[-1]),
        "dt_s": meta["dt_s"],
        "metrics_from_s": meta["metrics_from_s"],
        "feedforward": bool(meta["feedforward"]),
        "singularity_detected": bool(singular.any()),
        "first_singular_time_s": first_time(t, singular),
        "min_singularity_measure": float(sing[measured].min()) if measured.any() else None,
        "singularity_samples": int(measured.sum()),
        "reference_lost": bool(lost.any()),
        "first_lost_time_s": first_time(t, lost),
        "max_cluster_position_error_m": mx("cluster_position"),
        "max_shape_error_m": mx("shape"),
        "max_orientation_error_rad": mx("orientation"),
        "max_robot_position_error_m": mx("robot_position"),
        "robot_position_error_median_m": float(np.median(err["robot_position_each"][late].max(axis=0))),
        "max_robot_yaw_error_rad": mx("robot_yaw"),
        "min_robot_separation_m": float(err["separation"].min()),
        "max_recovered_attitude_error_rad": mx("recovered_attitude"),
        "max_recovered_heading_error_rad": mx("recovered_heading"),
        "nonfinite_commands": int((np.asarray(log["raw_finite"])[:, 0] < 0.5).sum()),
        "max_command_speed_m_s": _command_speed(meta["team"], log["command"]),
        "safety_enabled": bool(safety.get("enabled", False)),
        "safety_applied": bool(safety.get("applied", False)),
        "safety_min_separation_m": safety.get("min_separation_m"),
    }
    out.update(_reading_metrics(log, late))
    if "safety_active" in log:
        active = np.asarray(log["safety_active"])[:, 0] > 0.5
        tick = float(t[1] - t[0]) if t.size > 1 else 0.0
        out["safety_active_time_s"] = float(active.sum() * tick)
    return out
