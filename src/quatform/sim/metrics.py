"""Run metrics of one world's log of the team kind, in either chart: ``metrics.json``.

Sim layer. The errors that compare controllers are computed from the robots' measured
points against the desired ones, the same way for every description and every team
(:func:`error_signals`, written once on the array namespace: a log's time series here, a
batched rollout's tick in :mod:`.jax_rollout`):

* ``cluster_position``: the centroids' distance (seed 000 eq. (9) for N robots);
* the best-fit rotation ``Q`` of the desired centred robots onto the measured ones (Horn
  1987, :func:`~quatform.formations.team_chart.fit_attitude`, ties broken toward the
  identity: for two robots the minimal rotation between the two segments, seed 000 eqs.
  (14)-(15));
* ``shape``: ``max_i |Q^T c_i - d_i|`` (``c_i, d_i`` measured and desired positions about
  their centroids; for two robots ``| |p1 - p2| / 2 - d_c |``);
* ``orientation``: the angle of ``Q`` (for two robots the angle between the measured and
  desired robot-to-robot directions, seed 000 eq. (3)'s ``beta_c, gamma_c``);
* ``robot_position`` / ``robot_yaw``: the worst robot; ``separation``: the closest pair;
* the recovered chart's error: where the log's chart is seed 000's Euclidean variables
  (seed 000's two-robot files, eqs. (1)-(8)) the largest wrapped angle error of ``beta_c, gamma_c,
  phi_1, phi_2``; where it is the team chart the attitude's angle and the
  worst heading.

The log is one world of the team kind (:mod:`quatform.scenarios.team`; seed 000's chart:
:mod:`quatform.scenarios.pair`): channels ``points`` (the robots' points; a seed-000 run's
``state`` is its points), ``r_des``, ``e`` / ``e_des`` (the chart recovered by the
controller's description and the desired one), ``command``, ``raw_finite``, ``singularity``
(NaN where not computed) and, when the separation barrier runs, ``safety_active``; optional
``reading`` / ``reading_des``; meta ``layout``, ``team``, ``chart`` (:data:`EUCLIDEAN_CHART`
or :data:`TEAM_CHART`), ``scenario``, ``controller``, ``formation``, ``dt_s``,
``metrics_from_s``, ``feedforward`` and ``safety``. A batched log (leading batch axes) is
measured one world at a time: ``compute_metrics(log.world(i))``.
"""

from __future__ import annotations

import functools

import numpy as np

from ..algebra import wrap_angle
from ..algebra.kernels import array_namespace as namespace
from ..errors import InvalidInputError, ShapeError
from ..formations import geometry as g
from ..formations.team_chart import fit_attitude, team_positions
from .log import Log

__all__ = ["compute_metrics", "error_signals", "errors_from_robots", "command_speed", "measured_samples",
           "first_time", "min_separations", "rotation_angle", "singular_threshold", "SINGULAR_THRESHOLD",
           "LOST_POSITION_M", "LOST_ANGLE_RAD", "EUCLIDEAN_CHART", "TEAM_CHART"]

#: A two-robot state whose singularity measure falls below this is reported singular
#: (:func:`singular_threshold` for N robots).
SINGULAR_THRESHOLD = 0.02
#: Errors beyond these (after ``metrics_from_s``) mean the controller lost the reference.
LOST_POSITION_M = 0.1
LOST_ANGLE_RAD = 0.1
#: The log's chart (meta ``chart``): seed 000's Euclidean variables of two robots, eqs. (1)-(8)
#: (``x_c, y_c, z_c, beta_c, gamma_c, d_c, phi_1, phi_2``), or the team chart
#: (:class:`~quatform.formations.team_chart.TeamChart`: ``x_c, q_c``, shape, headings).
EUCLIDEAN_CHART = "euclidean"
TEAM_CHART = "team"
#: The angles of seed 000's Euclidean variables (``beta_c, gamma_c, phi_1, phi_2``).
_EUCLIDEAN_ANGLES = [3, 4, 6, 7]
#: Samples whose reference lies within this of the vertical (``|cos gamma_c| <`` it, about 3
#: degrees) are left out of the Euler reading's error: there ``beta_c`` and ``alpha_c`` are not
#: separate (seed 000 eq. (5)'s singular pose) and a millimetre reads as a large angle.
READING_POLE_COS = 0.05
#: Most pair distances held at once by the log's signals (time chunks of the run).
_PAIR_CHUNK = 2_000_000


def first_time(t, mask):
    """The first time ``t[k]`` where ``mask[k]`` (s), or None."""
    idx = np.flatnonzero(mask)
    return float(t[idx[0]]) if idx.size else None


def rotation_angle(q):
    """The angle (rad, in ``[0, pi]``) of the rotations ``q`` ``(..., 4)``: ``2 atan2(|q_vec|, |q_w|)``
    (accurate near 0, sign-free; any array namespace)."""
    xp = namespace(q)
    q = xp.asarray(q, dtype=float) if xp is np else q
    return 2.0 * xp.arctan2(xp.sqrt(xp.sum(q[..., 1:] * q[..., 1:], axis=-1)), xp.abs(q[..., 0]))


def singular_threshold(n_robots: int) -> float:
    """The singularity measure below which an N-robot state is reported singular:
    :data:`SINGULAR_THRESHOLD` (the pair's 0.02) times ``2 / N``.

    The measure is the reciprocal condition number of an ``n_r x n_c`` inverse Jacobian, and
    a regular formation's conditioning worsens with N (the Euclidean team of a flat ring of 10
    robots reads 0.0135 away from any singular pose; its singular poses read 1e-6 and less), so
    the pair's threshold would flag every large team from t = 0; for two robots it is the
    pair's.
    """
    return SINGULAR_THRESHOLD * 2.0 / max(int(n_robots), 2)


@functools.lru_cache(maxsize=None)
def _heading_entries(layout) -> np.ndarray:
    """The team chart's heading entries that are yaws (one per yaw robot; a pose robot's four
    are a quaternion, read by the attitude): indices into ``e``."""
    kinds = []
    for k in layout.kinds:
        if k in ("xy_yaw", "xyz_yaw"):
            kinds.append(True)
        elif k == "pose":
            kinds += [False] * 4
    return 7 + 3 * layout.n + np.flatnonzero(kinds)


def _pair_fit_errors(xp, delta, delta_des):
    """``(shape, orientation)`` of the best fit for two robots, whose segments are ``delta``
    and ``delta_des`` (``(..., 3)``, robot 2 to robot 1): :func:`fit_attitude` breaks the tie
    (the twist about the segment) toward the minimal rotation between the segments (seed 000
    eqs. (14)-(15)), so ``Q^T c_i`` lies along ``d_i`` and the shape error is ``| |delta| -
    |delta_des| | / 2``, the orientation error the angle between the segments,
    ``atan2(|delta x delta_des|, delta . delta_des)`` (accurate near 0 and pi)."""
    n, n_des = xp.linalg.norm(delta, axis=-1), xp.linalg.norm(delta_des, axis=-1)
    cross = xp.linalg.norm(xp.cross(delta, delta_des), axis=-1)
    return 0.5 * xp.abs(n - n_des), xp.arctan2(cross, xp.sum(delta * delta_des, axis=-1))


def error_signals(layout, r, r_des, e=None, e_des=None, *, chart: str = TEAM_CHART) -> dict:
    """The error signals of robots ``r`` against ``r_des`` (module docstring), on any leading
    axes (a time series, a batch of worlds at one tick ...) and any array namespace (NumPy,
    JAX under ``jax.jit``).

    Parameters
    ----------
    layout : RobotLayout
        The robots' points.
    r, r_des : array_like, shape (..., layout.size)
        Measured and desired points (m, rad).
    e, e_des : array_like, shape (..., k), optional
        Recovered and desired chart values; without them no recovered error is returned.
    chart : {EUCLIDEAN_CHART, TEAM_CHART}
        Which chart ``e`` is.

    Returns
    -------
    dict of arrays
        ``cluster_position``, ``shape``, ``robot_position``, ``separation`` (m),
        ``orientation`` (rad), each ``(...)``; ``robot_position_each`` ``(..., N)`` (m);
        ``robot_yaw`` (rad, where a robot has a heading); with ``e``: ``recovered_euclidean``
        (rad, Euclidean chart) or ``recovered_attitude`` and, where a robot has a yaw,
        ``recovered_heading`` (rad, team chart).
    """
    xp = namespace(r)
    p, pd = team_positions(layout, r), team_positions(layout, r_des)  # (..., N, 3)
    xc, xcd = xp.mean(p, axis=-2), xp.mean(pd, axis=-2)
    each = xp.linalg.norm(p - pd, axis=-1)
    i, j = layout.pairs
    if layout.n == 2:  # the fit's closed form (a static choice of the layout, no eigensolver per sample)
        shape, orientation = _pair_fit_errors(xp, p[..., 0, :] - p[..., 1, :], pd[..., 0, :] - pd[..., 1, :])
    else:
        c, d = p - xc[..., None, :], pd - xcd[..., None, :]
        Q = fit_attitude(d, c)
        shape = xp.max(xp.linalg.norm(g.rotate(g.conj(Q)[..., None, :], c) - d, axis=-1), axis=-1)
        orientation = rotation_angle(Q)
    out = {
        "cluster_position": xp.linalg.norm(xc - xcd, axis=-1),
        "shape": shape,
        "orientation": orientation,
        "robot_position": xp.max(each, axis=-1),
        "robot_position_each": each,
        "separation": (xp.min(xp.linalg.norm(p[..., i, :] - p[..., j, :], axis=-1), axis=-1) if layout.n > 1
                       else xp.full(each.shape[:-1], np.inf)),
    }
    heading = []
    if layout.yaw_indices:
        yaw = list(layout.yaw_indices)
        heading.append(xp.abs(wrap_angle(r[..., yaw] - r_des[..., yaw])))
    if len(layout.orientation_index):
        o = layout.orientation_index
        heading.append(rotation_angle(g.mul(g.conj(r_des[..., o]), r[..., o])))
    if heading:
        out["robot_yaw"] = xp.max(xp.concatenate(heading, axis=-1), axis=-1)
    if e is None:
        return out
    if chart == EUCLIDEAN_CHART:
        a = _EUCLIDEAN_ANGLES
        out["recovered_euclidean"] = xp.max(xp.abs(wrap_angle(e[..., a] - e_des[..., a])), axis=-1)
        return out
    out["recovered_attitude"] = rotation_angle(g.mul(g.conj(e_des[..., 3:7]), e[..., 3:7]))
    idx = _heading_entries(layout)
    if idx.size:
        out["recovered_heading"] = xp.max(xp.abs(wrap_angle(e[..., idx] - e_des[..., idx])), axis=-1)
    return out


def _points(log: Log):
    """The robots' measured points of a log: its ``points`` channel, else its ``state``."""
    return np.asarray(log["points"] if "points" in log else log["state"], dtype=float)


def _in_time_chunks(layout, T: int, fn):
    """``fn(k0, k1)`` over time chunks ``[k0, k1)`` of a ``T``-sample run, each dict's arrays
    concatenated on the time axis (a large team's ``N (N - 1) / 2`` distances are never all held)."""
    step = max(1, _PAIR_CHUNK // max(1, layout.n * (layout.n - 1) // 2))
    parts = [fn(k, min(k + step, T)) for k in range(0, max(T, 1), step)]
    return {key: np.concatenate([part[key] for part in parts]) for key in parts[0]}


def min_separations(layout, r) -> np.ndarray:
    """The closest two robots' distance at each sample, m, shape ``(T,)`` (time chunks)."""
    r = np.asarray(r, dtype=float)
    return _in_time_chunks(layout, r.shape[0], lambda k0, k1: {"s": layout.min_separation(r[k0:k1])})["s"]


def errors_from_robots(log: Log) -> dict:
    """The error signals of one world's log (:func:`error_signals` of its points, desired
    points and charts), each ``(T,)`` (``robot_position_each`` ``(T, N)``)."""
    L = log.meta["layout"]
    r, rd = _points(log), np.asarray(log["r_des"], dtype=float)
    e, ed = np.asarray(log["e"], dtype=float), np.asarray(log["e_des"], dtype=float)
    chart = log.meta.get("chart", TEAM_CHART)
    with np.errstate(invalid="ignore", divide="ignore"):  # a failed world held on each other reads NaN
        return _in_time_chunks(L, log.t.size, lambda k0, k1: error_signals(L, r[k0:k1], rd[k0:k1], e[k0:k1],
                                                                           ed[k0:k1], chart=chart))


@functools.lru_cache(maxsize=None)
def _linear_columns(team) -> np.ndarray:
    """Each robot's linear-velocity command columns (named ``v``, ``v_x``, ``v_y``, ``v_z``),
    ``(n_robots, k)`` indices into the command padded with a zero column (index ``n_u``)."""
    n_u = sum(len(robot.command_columns) for robot in team.robots)
    cols = [[sl.start + i for i, name in enumerate(robot.command_columns) if name in ("v", "v_x", "v_y", "v_z")]
            for robot, sl in zip(team.robots, team.command_slices)]
    k = max(1, max(len(c) for c in cols))
    return np.array([c + [n_u] * (k - len(c)) for c in cols], dtype=np.intp)


def command_speed(team, u):
    """The fastest commanded robot, m/s, shape ``(...)``: the largest norm of a robot's
    linear-velocity commands ``u`` ``(..., n_u)`` (any array namespace)."""
    xp = namespace(u)
    padded = xp.concatenate([u, xp.zeros(u.shape[:-1] + (1,), dtype=u.dtype)], axis=-1)
    return xp.max(xp.linalg.norm(padded[..., _linear_columns(team)], axis=-1), axis=-1)


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


def _reading_metrics(log: Log, late) -> dict:
    """``max_reading_error_rad`` (the formation's Euler reading against the reference's, the
    worst angle, away from the vertical) and ``reading_folded_time_s`` (how long ``beta_c`` read
    more than pi/2 off the reference's: the reading folded, seed 000's robot-space finding);
    None without a ``reading`` channel (seed 000's chart, a team no minimal Euclidean chart takes)."""
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


def compute_metrics(log: Log) -> dict:
    """The metrics of one world's run of the team kind (either chart), as a JSON-ready
    dict (units in the key names; ``docs/metrics.md`` lists every key).

    ``max_recovered_euclidean_error_rad`` where the log's chart is seed 000's Euclidean
    variables (seed 000's two-robot files); ``max_recovered_attitude_error_rad`` and
    ``max_recovered_heading_error_rad`` where it is the team chart.

    Raises
    ------
    ShapeError
        For a batched log (measure each world: ``log.world(i)``).
    InvalidInputError
        When no sample lies at or after ``metrics_from_s``.
    """
    meta, t = log.meta, log.t
    late = measured_samples(log, "compute_metrics")
    L = meta["layout"]
    err = errors_from_robots(log)
    sing = np.asarray(log["singularity"])[:, 0]
    measured = np.isfinite(sing)
    singular = measured & (np.where(measured, sing, 1.0) < singular_threshold(L.n))
    lost = late & ((err["cluster_position"] > LOST_POSITION_M) | (err["orientation"] > LOST_ANGLE_RAD)
                   | (err["robot_position"] > LOST_POSITION_M))

    def mx(key):
        return float(err[key][late].max()) if key in err else None

    safety = dict(meta.get("safety", {}))
    u = np.asarray(log["command"], dtype=float)
    out = {
        "controller": meta["controller"],
        "formation": meta["formation"],
        "scenario": meta["scenario"],
        "n_robots": int(L.n),
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
        "nonfinite_commands": int((np.asarray(log["raw_finite"])[:, 0] < 0.5).sum()),
        "max_command_speed_m_s": float(command_speed(meta["team"], u).max()) if u.shape[0] else 0.0,
        "safety_enabled": bool(safety.get("enabled", False)),
        "safety_applied": bool(safety.get("applied", safety.get("enabled", False))),
        "safety_min_separation_m": safety.get("min_separation_m"),
    }
    if meta.get("chart", TEAM_CHART) == EUCLIDEAN_CHART:
        out["max_recovered_euclidean_error_rad"] = mx("recovered_euclidean")
    else:
        out["max_recovered_attitude_error_rad"] = mx("recovered_attitude")
        out["max_recovered_heading_error_rad"] = mx("recovered_heading")
    out.update(_reading_metrics(log, late))
    if "safety_active" in log:
        active = np.asarray(log["safety_active"])[:, 0] > 0.5
        tick = float(t[1] - t[0]) if t.size > 1 else 0.0
        out["safety_active_time_s"] = float(active.sum() * tick)
    return out
