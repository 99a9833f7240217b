"""Report layer: PNG figures of team (N-robot) runs, like Mas & Kitts 2017 (seed 000) Figs. 9-13, 19-20.

Every function draws on its own Agg figure (:mod:`.figures`), reads one world's
:class:`~quatform.sim.log.Log` of the team kind and decimates its lines to
:data:`~.figures.MAX_POINTS` samples.

* :func:`plot_team_paths_3d` - every robot's path in 3-D with the formation's edges drawn as
  a time-lapse (seed 000 Figs. 19-20);
* :func:`plot_team_centroid` - the centroid against the reference;
* :func:`plot_team_attitude` - the attitude quaternion and, for reading, its z-y-x Euler
  angles (:meth:`TeamChart.reading`) against the reference;
* :func:`plot_team_shape` - each robot's distance from the centroid ``|s_i|`` (or, for a
  large team, their spread) against the reference;
* :func:`plot_team_errors` - the robots' position and heading errors: the worst robot, the
  median, and the band between the best and the worst;
* :func:`plot_team_separation` - the closest pair's distance, with the barrier's ``d_min``;
* :func:`plot_team_singularity` - the singularity measure of the controller's description;
* :func:`plot_team_compare` - the errors of several controllers (seed 000 Fig. 13).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.lines import Line2D
from matplotlib.ticker import MaxNLocator
from mpl_toolkits.mplot3d import Axes3D  # noqa: F401  (registers the '3d' projection)

from ..algebra import q_continuous
from ..formations import TeamChart
from ..formations.geometry import unwrap_near
from ..papers import with_names
from ..sim.log import Log
from ..sim.metrics import errors_from_robots, min_separations, singular_threshold
from .figures import (
    DES_STYLE,
    MEAS_STYLE,
    break_wraps,
    check_runs,
    decimate,
    finite,
    floor_ylim,
    intervals,
    new_figure,
    save,
    set_equal_3d,
    shade,
    time_xlim,
)
from .figure_set import FIGURES, FigureSet

__all__ = ["plot_team_paths_3d", "plot_team_centroid", "plot_team_attitude", "plot_team_shape", "plot_team_errors",
           "plot_team_separation", "plot_team_singularity", "plot_team_compare", "formation_edges",
           "write_team_run_plots", "write_team_compare_plots"]

#: Teams up to this size get one line (and one legend entry) per robot; larger ones bands.
_EACH_ROBOT_UP_TO = 10


def _title(log: Log) -> str:
    source = with_names(log.meta.get("source", ""))
    return (f"{log.meta['scenario']} - {log.meta['controller']} ({log.meta['n_robots']} robots)"
            + (f"\n{source}" if source else ""))


def _runs_title(runs) -> str:
    names = ", ".join(dict.fromkeys(log.meta["scenario"] for log in runs))
    sources = ", ".join(dict.fromkeys(with_names(log.meta["source"]) for log in runs if log.meta.get("source")))
    return names + (f" ({sources})" if sources else "")


def _spans(log: Log):
    sing = np.asarray(log["singularity"])[:, 0]
    threshold = singular_threshold(log.meta["layout"].n)
    return intervals(log.t, np.isfinite(sing) & (np.nan_to_num(sing, nan=1.0) < threshold))


def _style(ax, ylabel):
    ax.set_ylabel(ylabel, fontsize=9)
    ax.tick_params(labelsize=8)
    ax.grid(True, lw=0.4, alpha=0.5)


def formation_edges(template) -> tuple[np.ndarray, np.ndarray]:
    """The edges drawn between robots: each robot to every robot within 1.05 times its nearest
    neighbour's distance in ``template`` (``(N, 3)``): a ring's neighbours, a grid's four, a
    tetrahedron's six. Returns index arrays ``(i, j)``, ``i < j``."""
    p = np.asarray(template, dtype=float)
    n = p.shape[0]
    d = np.linalg.norm(p[:, None, :] - p[None, :, :], axis=-1)
    d[np.arange(n), np.arange(n)] = np.inf
    near = d <= 1.05 * d.min(axis=1, keepdims=True)
    near = near | near.T
    i, j = np.nonzero(np.triu(near, 1))
    return i, j


def plot_team_paths_3d(run: Log, path, n_frames: int | None = None) -> Path:
    """Every robot's path in 3-D (measured solid, desired dashed) and the formation's edges at
    ``n_frames + 1`` evenly spaced times (grey: measured; the edges of the desired shape at
    ``t = 0``), a time-lapse like seed 000 Figs. 19-20. ``n_frames`` defaults to 8, 4 for a
    team larger than 10, which also draws its paths thin and without a legend entry per robot."""
    L = run.meta["layout"]
    n_frames = (8 if L.n <= _EACH_ROBOT_UP_TO else 4) if n_frames is None else n_frames
    P, Pd = L.positions(finite(run["points"])), L.positions(finite(run["r_des"]))
    n = L.n
    fig = new_figure((8.0, 6.8))
    ax = fig.add_subplot(projection="3d")
    idx = decimate(P.shape[0])
    i, j = formation_edges(Pd[0] - Pd[0].mean(axis=0))
    ks = np.unique(np.linspace(0, P.shape[0] - 1, max(1, int(n_frames)) + 1).round().astype(int))
    for k in ks:  # each frame's edges as one line broken by NaN
        seg = np.stack([P[k, i], P[k, j], np.full((len(i), 3), np.nan)], axis=1).reshape(-1, 3)
        ax.plot(*seg.T, color="0.55", lw=0.7, alpha=0.8)
        ax.scatter(*P[k].T, color="0.3", s=6, depthshade=False)
    few = n <= _EACH_ROBOT_UP_TO
    for r in range(n):
        color = f"C{r % 10}"
        ax.plot(*P[idx, r].T, color=color, lw=1.2 if few else 0.5, label=f"robot {r + 1}" if few else None)
        ax.plot(*Pd[idx, r].T, color=color, lw=0.8, ls="--", alpha=0.7 if few else 0.3)
    handles, _ = ax.get_legend_handles_labels()
    handles += [Line2D([], [], color="0.55", lw=0.7, label=f"formation ({len(ks)} times)"),
                Line2D([], [], color="k", lw=0.8, ls="--", label="desired")]
    ax.legend(handles=handles, fontsize=7, loc="upper left", ncols=2 if few else 1)
    set_equal_3d(ax, np.concatenate([P.reshape(-1, 3), Pd.reshape(-1, 3)]))
    for axis, name in ((ax.xaxis, "x"), (ax.yaxis, "y"), (ax.zaxis, "z")):
        axis.set_major_locator(MaxNLocator(5))
        axis.set_tick_params(labelsize=8)
        axis.set_label_text(f"{name} [m]")
    ax.set_title(_title(run), fontsize=10)
    return save(fig, path)


def _measured_desired_grid(run: Log, path, rows, title):
    """One axes per ``(label, measured (T,), desired (T,), is_angle)`` row."""
    fig = new_figure((9.0, 1.7 * len(rows) + 1.2))
    axes = fig.subplots(len(rows), 1, sharex=True, squeeze=False)[:, 0]
    idx = decimate(run.t.size)
    spans = _spans(run)
    for ax, (label, y, yd, angle) in zip(axes, rows):
        y, yd = finite(y)[idx], finite(yd)[idx]
        if angle:
            y, yd = break_wraps(y), break_wraps(yd)
        shade(ax, spans)
        ax.plot(run.t[idx], y, **MEAS_STYLE)
        ax.plot(run.t[idx], yd, **DES_STYLE)
        floor_ylim(ax, y, yd)
        _style(ax, label)
    time_xlim(axes[-1], float(run.t[0]), float(run.t[-1]))
    axes[-1].set_xlabel("time [s]")
    fig.legend(handles=[Line2D([], [], **MEAS_STYLE, label="measured"), Line2D([], [], **DES_STYLE, label="desired")],
               loc="outside lower center", ncols=2, fontsize=9, frameon=False)
    fig.suptitle(f"{_title(run)}\n{title}", fontsize=10)
    return save(fig, path)


def plot_team_centroid(run: Log, path) -> Path:
    """The centroid ``x_c, y_c, z_c`` of the measured robots against the reference's."""
    e, ed = np.asarray(run["e"]), np.asarray(run["e_des"])
    rows = [(f"{a}_c [m]", e[:, k], ed[:, k], False) for k, a in enumerate("xyz")]
    return _measured_desired_grid(run, path, rows, "centroid (the robots' mean)")


def plot_team_attitude(run: Log, path) -> Path:
    """The formation's attitude: ``q_c`` (the chart the controller's description recovers,
    continuous along the run, its first sign nearest the reference) against the reference,
    and the z-y-x Euler angles of both (:meth:`TeamChart.reading`: for reading only; yaw and
    roll are not separate at pitch +-90 deg, seed 000 eq. (5))."""
    e, ed = np.asarray(run["e"]), np.asarray(run["e_des"])
    q, qd = finite(e[:, 3:7]), ed[:, 3:7]
    ok = np.all(np.isfinite(q), axis=-1)
    if ok.any():  # continuous along the run (q and -q are one attitude), first sign nearest the reference
        q[ok] = q_continuous(q[ok], axis=0)
        q[ok] *= -1.0 if np.dot(q[ok][0], qd[ok][0]) < 0 else 1.0
    eud = TeamChart.reading(ed)
    eu = unwrap_near(TeamChart.reading(e), eud)  # whole turns only: +-pi of one attitude read alike
    rows = [(f"q_c_{a} [-]", q[:, k], qd[:, k], False) for k, a in enumerate("wxyz")]
    rows += [(f"{a} [rad]", eu[:, k], eud[:, k], True) for k, a in enumerate(("yaw", "pitch", "roll"))]
    return _measured_desired_grid(run, path, rows, "attitude: quaternion, and z-y-x Euler angles for reading "
                                  "(principal values: yaw and roll jump by pi at pitch +-90 deg)")


def plot_team_reading(run: Log, path) -> Path:
    """The formation's attitude in seed 000's Euclidean angles (``beta_c``, ``gamma_c``,
    ``alpha_c``) as the controller's description reports it, against the reference's read
    continuously through the vertical (seed 000 Figs. 5-8's angle panels: robot space reads
    the formation folded past pitch 90 deg, ``beta_c + pi``, ``pi - gamma_c``)."""
    ad = np.asarray(run["reading_des"])
    a = finite(np.asarray(run["reading"]))
    if np.isfinite(a).all() and len(a):  # continuous in time (whole turns only: a fold, pi, stays in view)
        a = np.unwrap(a, axis=0)
        a += 2.0 * np.pi * np.round((ad[0] - a[0]) / (2.0 * np.pi))
    rows = [(f"{name} [rad]", a[:, k], ad[:, k], False) for k, name in enumerate(run.columns("reading"))]
    return _measured_desired_grid(run, path, rows, "Euler reading of the formation (as the description reports it)")


def plot_team_shape(run: Log, path) -> Path:
    """The shape: each robot's distance from the centroid ``|s_i|`` (m) against the
    reference's; a team of more than 10 robots draws the root mean square of the ``|s_i|``
    (the formation's size) and the band of the largest and smallest."""
    L = run.meta["layout"]
    P, Pd = L.positions(finite(run["points"])), L.positions(finite(run["r_des"]))
    s = np.linalg.norm(P - P.mean(axis=-2, keepdims=True), axis=-1)
    sd = np.linalg.norm(Pd - Pd.mean(axis=-2, keepdims=True), axis=-1)
    idx = decimate(run.t.size)
    fig = new_figure((9.0, 4.6))
    ax = fig.add_subplot()
    if L.n <= _EACH_ROBOT_UP_TO:
        for r in range(L.n):
            ax.plot(run.t[idx], s[idx, r], color=f"C{r % 10}", lw=1.2, label=f"|s_{r + 1}|")
            ax.plot(run.t[idx], sd[idx, r], color=f"C{r % 10}", lw=0.9, ls="--")
    else:
        for vals, style, lab in ((s, MEAS_STYLE, "measured"), (sd, DES_STYLE, "desired")):
            rms = np.sqrt(np.mean(vals ** 2, axis=-1))
            ax.plot(run.t[idx], rms[idx], **style, label=f"rms |s_i| {lab}")
            ax.fill_between(run.t[idx], vals[idx].min(axis=-1), vals[idx].max(axis=-1), color=style["color"],
                            alpha=0.15, lw=0)
    shade(ax, _spans(run))
    time_xlim(ax, float(run.t[0]), float(run.t[-1]))
    ax.set_xlabel("time [s]")
    _style(ax, "distance from the centroid [m]")
    ax.legend(fontsize=8, ncols=min(5, L.n), loc="best")
    ax.set_title(f"{_title(run)}\nshape (dashed: desired)", fontsize=10)
    return save(fig, path)


def _band(ax, t, each, color, label):
    """The worst robot (solid), the median (dashed) and the band between best and worst."""
    ax.fill_between(t, each.min(axis=-1), each.max(axis=-1), color=color, alpha=0.2, lw=0)
    ax.plot(t, each.max(axis=-1), color=color, lw=1.2, label=f"{label}: worst robot")
    ax.plot(t, np.median(each, axis=-1), color=color, lw=1.0, ls="--", label=f"{label}: median")


def plot_team_errors(run: Log, path) -> Path:
    """Per-robot errors against time: position ``|p_i - p_i,des|`` and heading (wrapped yaw, or
    a pose robot's orientation angle), each as the worst robot, the median and the band."""
    from ..algebra import wrap_angle

    L = run.meta["layout"]
    err = errors_from_robots(run)
    idx = decimate(run.t.size)
    yaw = None
    if L.yaw_indices:
        yaw = np.abs(wrap_angle(L.yaws(np.asarray(run["points"])) - L.yaws(np.asarray(run["r_des"]))))
    fig = new_figure((9.0, 6.0 if yaw is not None else 3.6))
    axes = fig.subplots(2 if yaw is not None else 1, 1, sharex=True, squeeze=False)[:, 0]
    _band(axes[0], run.t[idx], err["robot_position_each"][idx], "C0", "position")
    _style(axes[0], "robot position error [m]")
    axes[0].legend(fontsize=8)
    if yaw is not None:
        _band(axes[1], run.t[idx], yaw[idx], "C1", "yaw")
        _style(axes[1], "robot yaw error [rad]")
        axes[1].legend(fontsize=8)
    for ax in axes:
        shade(ax, _spans(run))
        ax.set_ylim(bottom=0.0)
    time_xlim(axes[-1], float(run.t[0]), float(run.t[-1]))
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(f"{_title(run)}\nper-robot errors (band: best to worst robot)", fontsize=10)
    return save(fig, path)


def _d_min(run: Log):
    safety = run.meta.get("safety", {})
    return safety.get("min_separation_m") if safety.get("enabled") else None


def plot_team_separation(runs, path) -> Path:
    """The closest two robots' distance against time, one line per run, and the separation
    barrier's ``d_min`` (dotted; "not applied" in the legend where the run had no barrier)."""
    runs = check_runs(runs)
    fig = new_figure((9.0, 4.2))
    ax = fig.add_subplot()
    for k, run in enumerate(runs):
        idx = decimate(run.t.size)
        sep = errors_from_robots(run)["separation"]
        ax.plot(run.t[idx], finite(sep)[idx], color=f"C{k}", lw=1.2, label=run.meta["controller"])
    idx = decimate(runs[0].t.size)
    ax.plot(runs[0].t[idx], team_errors_desired(runs[0])[idx], color="k", lw=0.9, ls="--", label="desired")
    d_min = _d_min(runs[0])
    if d_min is not None:
        applied = runs[0].meta.get("safety", {}).get("applied", False)
        ax.axhline(d_min, color="C3", lw=1.0, ls=":", label=f"d_min = {d_min:g} m" + ("" if applied else
                                                                                        " (barrier not applied)"))
    ax.set_ylim(bottom=0.0)
    time_xlim(ax, float(runs[0].t[0]), max(float(r.t[-1]) for r in runs))
    ax.set_xlabel("time [s]")
    _style(ax, "closest pair [m]")
    ax.legend(fontsize=8)
    ax.set_title(f"{_runs_title(runs)}\nminimum pairwise separation", fontsize=10)
    return save(fig, path)


def team_errors_desired(run: Log) -> np.ndarray:
    """The desired robots' closest-pair distance at each sample, m, shape ``(T,)``."""
    return min_separations(run.meta["layout"], np.asarray(run["r_des"]))


def plot_team_singularity(runs, path) -> Path:
    """The singularity measure of each run's description (the samples where it was computed),
    with the threshold below which a pose is reported singular."""
    runs = check_runs(runs)
    fig = new_figure((9.0, 3.8))
    ax = fig.add_subplot()
    for k, run in enumerate(runs):
        s = np.asarray(run["singularity"])[:, 0]
        ok = np.isfinite(s)
        ax.plot(run.t[ok], s[ok], color=f"C{k}", lw=1.1, marker="." if ok.sum() < 200 else None,
                label=f"{run.meta['controller']} ({run.meta['formation']})")
    threshold = singular_threshold(runs[0].meta["layout"].n)
    ax.axhline(threshold, color="C3", lw=0.8, ls=":", label=f"singular below {threshold:.3g}")
    ax.set_yscale("log")
    time_xlim(ax, float(runs[0].t[0]), max(float(r.t[-1]) for r in runs))
    ax.set_xlabel("time [s]")
    _style(ax, "singularity measure\n(1 / condition number)")
    ax.legend(fontsize=8)
    ax.set_title(f"{_runs_title(runs)}\nsingularity measure of the description", fontsize=10)
    return save(fig, path)


_COMPARE_ROWS = (
    ("cluster_position", "centroid\nerror [m]"),
    ("shape", "shape\nerror [m]"),
    ("orientation", "attitude\nerror [rad]"),
    ("robot_position", "worst robot\nerror [m]"),
    ("recovered_attitude", "recovered\nattitude [rad]"),
)


def plot_team_compare(runs, path, linthresh: float = 1e-3) -> Path:
    """Errors of several controllers on one scenario, like seed 000 Fig. 13: the centroid,
    shape and attitude errors from the robots (every controller measured the same way), the
    worst robot's error and the attitude each description recovers from the robots, one
    line per run, symmetric-log axes (linear within ``linthresh``)."""
    runs = check_runs(runs)
    errs = [errors_from_robots(run) for run in runs]
    fig = new_figure((9.0, 10.0))
    axes = fig.subplots(len(_COMPARE_ROWS), 1, sharex=True)
    for ax, (key, label) in zip(axes, _COMPARE_ROWS):
        peak = 0.0
        for k, (run, err) in enumerate(zip(runs, errs)):
            idx = decimate(run.t.size)
            y = finite(err[key])
            if np.isfinite(y).any():
                peak = max(peak, float(np.nanmax(np.abs(y))))
            ax.plot(run.t[idx], y[idx], color=f"C{k}", lw=1.1, label=run.meta["controller"])
        ax.set_yscale("symlog", linthresh=linthresh)
        ax.set_ylim(0.0, max(peak, linthresh) * 1.5)
        _style(ax, label)
    time_xlim(axes[-1], min(float(r.t[0]) for r in runs), max(float(r.t[-1]) for r in runs))
    axes[-1].set_xlabel("time [s]")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncols=min(len(runs), 4), fontsize=9, frameon=False)
    fig.suptitle(f"{_runs_title(runs)}\nerrors by controller (symlog, linear within ±{linthresh:g})", fontsize=10)
    return save(fig, path)


def write_team_run_plots(run: Log, out_dir) -> list[Path]:
    """Write ``paths_3d.png``, ``centroid.png``, ``attitude.png``, ``shape.png``,
    ``robot_errors.png``, ``separation.png``, ``singularity.png`` and, where the team has a
    Euclidean reading, ``euler_reading.png`` of one team run."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = [plot_team_paths_3d(run, out / "paths_3d.png"), plot_team_centroid(run, out / "centroid.png"),
             plot_team_attitude(run, out / "attitude.png"), plot_team_shape(run, out / "shape.png"),
             plot_team_errors(run, out / "robot_errors.png"), plot_team_separation([run], out / "separation.png"),
             plot_team_singularity([run], out / "singularity.png")]
    if "reading" in run:
        files.append(plot_team_reading(run, out / "euler_reading.png"))
    return files


def write_team_compare_plots(runs, out_dir) -> list[Path]:
    """Write ``compare_errors.png``, ``separation.png`` and ``singularity.png`` of several runs."""
    runs = check_runs(runs)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    return [plot_team_compare(runs, out / "compare_errors.png"), plot_team_separation(runs, out / "separation.png"),
            plot_team_singularity(runs, out / "singularity.png")]


FIGURES.add("team", FigureSet(write_team_run_plots, write_team_compare_plots))
