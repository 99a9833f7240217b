"""Report layer: PNG figures of runs, like Mas & Kitts 2017 (seed 000) Figs. 9-13 (above sim).

Every function draws on its own :class:`matplotlib.figure.Figure` attached to an Agg
canvas, so nothing here touches pyplot's global state or needs a display. Lines are
decimated to at most ``MAX_POINTS`` samples; the singular-pose shading is computed on
every sample.

* :func:`plot_cluster_variables` - each variable of the controller's own description,
  measured against desired (seed Figs. 9, 11, 12; the recovered Euclidean variables for
  the robot-space controller, as in Fig. 10).
* :func:`plot_euclidean` - the eight Euclidean variables an operator monitors (written
  for the quaternion and dual-quaternion runs only; the others' cluster variables are
  these).
* :func:`plot_paths_3d` - both robots' paths in 3-D, with the segment between them drawn
  as a time-lapse.
* :func:`plot_compare` - errors of several controllers on one scenario (Fig. 13).
* :func:`plot_separation` - robot separation against time (Fig. 4).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import FuncFormatter, MaxNLocator, MultipleLocator
from mpl_toolkits.mplot3d import Axes3D  # noqa: F401  (registers the '3d' projection)

from ..algebra import wrap_angle
from ..formations import EUCLIDEAN_VARIABLES
from ..formations.base import PAIR_LAYOUT
from ..papers import with_names
from ..sim import Log, errors_from_robots
from ..sim.metrics import SINGULAR_THRESHOLD
from .figures import (DES_STYLE, DPI, MAX_POINTS, MEAS_STYLE, SINGULAR_COLOR,
                      break_wraps, check_runs, decimate, finite, floor_ylim, intervals, new_figure, save,
                      set_equal_3d, shade, time_xlim, unwrap)
from .figure_set import FIGURES, FigureSet

__all__ = [
    "DPI",
    "MAX_POINTS",
    "plot_cluster_variables",
    "plot_compare",
    "plot_euclidean",
    "plot_paths_3d",
    "plot_separation",
    "write_compare_plots",
    "write_run_plots",
]


# --------------------------------------------------------------------------- helpers


#: A desired angle that moves more than this between samples has stepped (a [[path.steps]]).
_STEP_RAD = 0.5


def _angle_traces(meas, des, idx):
    """Measured and desired angle traces, at the samples ``idx``, that draw no wrap artefact.

    The desired trace is unwrapped on every sample, so a reference through +-pi stays
    continuous; after a step (a jump of more than ``_STEP_RAD``) it continues on the 2 pi
    branch nearest the measured trace (a step of pi to +pi or to -pi is the same formation).
    The measured trace is drawn on the branch nearest the desired, ``des + wrap(meas -
    des)``, so the gap between the two lines is the wrapped error, never a 2 pi that is not
    there. Where a drawn trace turns by more than pi between drawn samples (the error
    passing +-pi) it is broken instead of joined by a vertical line.
    """
    d, m = unwrap(des), unwrap(meas)
    fin = np.flatnonzero(np.isfinite(d))
    if fin.size:
        cuts = fin[1:][np.abs(np.diff(d[fin])) > _STEP_RAD]
        for a, b in zip(cuts, [*cuts[1:], fin[-1] + 1]):  # each segment after a step
            gap = (m[a:b] - d[a:b])[np.isfinite(m[a:b] - d[a:b])]
            if gap.size:
                d[a:b] += 2 * np.pi * np.round(np.median(gap) / (2 * np.pi))
    meas = np.asarray(meas, dtype=float)
    aligned = np.where(np.isfinite(d), d + wrap_angle(np.nan_to_num(meas - d)), m)
    aligned[~np.isfinite(meas)] = np.nan
    return break_wraps(aligned[idx]), break_wraps(d[idx])


def _angle_axis(ax, *series):
    """y limits spanning at least [-pi, pi] about the data, ticks at multiples of pi/2."""
    vals = np.concatenate([np.ravel(v) for v in series])
    vals = vals[np.isfinite(vals)]
    lo, hi = (float(vals.min()), float(vals.max())) if vals.size else (-np.pi, np.pi)
    if hi - lo < 2 * np.pi:
        mid = 0.5 * (lo + hi) if vals.size else 0.0
        mid = np.pi / 2 * np.round(mid / (np.pi / 2))  # centre on a tick
        lo, hi = min(lo, mid - np.pi), max(hi, mid + np.pi)
    ax.set_ylim(lo - 0.35, hi + 0.35)
    step = np.pi / 2 * max(1, int(np.ceil((hi - lo) / (4 * np.pi))))  # at most about 9 ticks
    ax.yaxis.set_major_locator(MultipleLocator(step))
    ax.yaxis.set_major_formatter(FuncFormatter(_pi_label))


def _pi_label(value, _pos=None) -> str:
    """``value`` in multiples of pi/2: ``-π/2``, ``0``, ``π``, ``3π/2`` ..."""
    n = int(np.round(value / (np.pi / 2)))
    if abs(value - n * np.pi / 2) > 1e-6:
        return f"{value:.2g}"
    if n == 0:
        return "0"
    if n % 2 == 0:
        k = n // 2
        return "π" if k == 1 else "-π" if k == -1 else f"{k}π"
    return f"{'-' if n < 0 else ''}{'' if abs(n) == 1 else abs(n)}π/2"


def _physics(runs) -> str:
    """``" on MuJoCo physics"`` where a run's robots were not the kinematic models, else ``""``."""
    labels = dict.fromkeys(log.meta["physics_label"] for log in runs if log.meta["physics"] != "kinematic")
    return f" on {', '.join(labels)}" if labels else ""


def _title(log: Log) -> str:
    source = with_names(log.meta.get("source", ""))
    return f"{log.meta['scenario']} - {log.meta['controller']}{_physics([log])}" + (f" ({source})" if source else "")


def _runs_title(runs) -> str:
    names = ", ".join(dict.fromkeys(log.meta["scenario"] for log in runs))
    sources = ", ".join(dict.fromkeys(with_names(log.meta["source"]) for log in runs if log.meta.get("source")))
    return names + _physics(runs) + (f" ({sources})" if sources else "")


def _unit_label(var) -> str:
    unit = "-" if var.unit in ("1", "") else var.unit
    return f"{var.name} [{unit}]"


def _singularity(log: Log) -> np.ndarray:
    """The singularity measure of each sample, shape ``(T,)``."""
    return log["singularity"][:, 0]


def _signal_grid(fig, run: Log, meas, des, variables, ncols=4):
    """Fill ``fig`` with one small axes per variable: measured (solid) vs desired (dashed)."""
    n = len(variables)
    nrows = int(np.ceil(n / ncols))
    axes = fig.subplots(nrows, ncols, sharex=True, squeeze=False)
    idx = decimate(run.t.size)
    t = run.t[idx]
    spans = intervals(run.t, _singularity(run) < SINGULAR_THRESHOLD)
    for k, var in enumerate(variables):
        ax = axes.flat[k]
        if var.kind == "angle":  # on every sample, then decimated
            y, yd = _angle_traces(finite(meas[:, k]), finite(des[:, k]), idx)
            _angle_axis(ax, y, yd)
        else:
            y, yd = finite(meas[idx, k]), finite(des[idx, k])
            floor_ylim(ax, y, yd)
        shade(ax, spans)
        ax.plot(t, y, **MEAS_STYLE)
        ax.plot(t, yd, **DES_STYLE)
        ax.set_ylabel(_unit_label(var), fontsize=9)
        ax.tick_params(labelsize=8)
        ax.grid(True, lw=0.4, alpha=0.5)
        time_xlim(ax, float(run.t[0]), float(run.t[-1]))
    for ax in axes.flat[n:]:
        ax.set_visible(False)
    for k in range(n):
        if k + ncols >= n:  # lowest visible axes of its column
            axes.flat[k].set_xlabel("time [s]", fontsize=9)
            axes.flat[k].xaxis.set_tick_params(labelbottom=True)
    handles = [Line2D([], [], **MEAS_STYLE, label="measured"),
               Line2D([], [], **DES_STYLE, label="desired")]
    if spans:
        handles.append(Patch(color=SINGULAR_COLOR, alpha=0.6,
                             label=f"singular (measure < {SINGULAR_THRESHOLD:g})"))
    fig.legend(handles=handles, loc="outside lower center", ncols=len(handles), fontsize=9,
               frameon=False)
    return axes


def _grid_figsize(n, ncols=4):
    nrows = int(np.ceil(n / ncols))
    return (3.2 * ncols, 1.9 * nrows + 1.1)


# --------------------------------------------------------------------------- one run


def plot_cluster_variables(run: Log, path) -> Path:
    """Each cluster variable of the controller's description, measured against desired.

    Like seed 000 Figs. 9, 11 and 12: one small axes per variable of
    the controller's formation (``run.meta["cluster_variables"]``: 8 for the Euclidean
    description, 16 for the quaternion and dual-quaternion ones), channel ``cluster``
    solid against ``c_des`` dashed, over time. For the robot-space controller (formation
    ``'robot'``) the Euclidean variables it recovers, ``e`` against ``e_des``, are drawn
    instead, as in Fig. 10. Angles are
    drawn without wrap artefacts: the desired trace unwrapped (after a step, on the branch
    nearest the measured one), the measured one on the branch nearest it, so the gap
    between them is the wrapped error (a fold of the description shows as a gap of pi, a
    2 pi wind as none); a trace is broken where it turns by more than pi between samples. Times where the singularity measure is
    below ``SINGULAR_THRESHOLD`` (0.02) are shaded light red. The title names the paper
    the scenario comes from (``source``, "seed 000" read as "Mas & Kitts 2017").

    Parameters
    ----------
    run : Log
        One world of a pair run (:func:`quatform.scenarios.pair.run_pair`).
    path : str or Path
        PNG file to write; its folder is created if missing.

    Returns
    -------
    Path
        The file written.
    """
    formation = run.meta["formation"]
    if formation == "robot":
        variables, meas, des = EUCLIDEAN_VARIABLES, run["e"], run["e_des"]
        subtitle = "recovered Euclidean variables"
    else:
        variables, meas, des = run.meta["cluster_variables"], run["cluster"], run["c_des"]
        subtitle = f"{formation} cluster variables"
    fig = new_figure(_grid_figsize(len(variables)))
    _signal_grid(fig, run, np.asarray(meas), np.asarray(des), variables)
    fig.suptitle(f"{_title(run)}\n{subtitle}", fontsize=11)
    return save(fig, path)


def plot_euclidean(run: Log, path) -> Path:
    """The eight Euclidean variables recovered by the controller's description.

    The operator's monitoring view: channel ``e`` (solid) against ``e_des`` (dashed) for
    ``x_c, y_c, z_c, beta_c, gamma_c, d_c, phi_1, phi_2``; angles and singular times
    drawn as in :func:`plot_cluster_variables`.

    Parameters
    ----------
    run : Log
        A closed-loop run.
    path : str or Path
        PNG file to write.

    Returns
    -------
    Path
        The file written.
    """
    fig = new_figure(_grid_figsize(len(EUCLIDEAN_VARIABLES)))
    _signal_grid(fig, run, np.asarray(run["e"]), np.asarray(run["e_des"]), EUCLIDEAN_VARIABLES)
    fig.suptitle(f"{_title(run)}\nEuclidean variables (monitoring view)", fontsize=11)
    return save(fig, path)


def plot_paths_3d(run: Log, path, n_segments: int = 10) -> Path:
    """Both robots' paths in 3-D, measured (solid) and desired (dashed).

    Start points are marked (circle: measured, hollow square: desired) and the segment
    between the robots is drawn as a thin grey line at ``n_segments + 1`` evenly spaced
    times (about every 10 % of the run), a time-lapse of the formation's attitude. The
    axes share one scale (each spans at least a quarter of the largest extent).

    Parameters
    ----------
    run : Log
        A closed-loop run.
    path : str or Path
        PNG file to write.
    n_segments : int, optional
        Number of intervals of the time-lapse (default 10).

    Returns
    -------
    Path
        The file written.
    """
    r, rd = finite(run["state"]), finite(run["r_des"])
    fig = new_figure((8.0, 6.8))
    ax = fig.add_subplot(projection="3d")
    idx = decimate(r.shape[0])
    ks = np.unique(np.linspace(0, r.shape[0] - 1, max(1, int(n_segments)) + 1).round().astype(int))
    P, P_d = PAIR_LAYOUT.positions(r), PAIR_LAYOUT.positions(rd)  # (T, 2, 3)
    for k in ks:  # first, so the paths are drawn over them
        ax.plot(*P[k].T, color="0.6", lw=0.8, alpha=0.8)
    for i, color in enumerate(("C0", "C1"), start=1):
        p, pd = P[:, i - 1], P_d[:, i - 1]
        ax.plot(*p[idx].T, color=color, lw=1.4, ls="-", label=f"robot {i} measured")
        ax.plot(*pd[idx].T, color=color, lw=1.0, ls="--", alpha=0.8, label=f"robot {i} desired")
        ax.scatter(*p[0], color=color, marker="o", s=40, depthshade=False)
        ax.scatter(*pd[0], facecolors="none", edgecolors=color, marker="s", s=60, depthshade=False)
    handles, _ = ax.get_legend_handles_labels()
    handles += [Line2D([], [], color="0.6", lw=0.8, label="segment (every ~10 %)"),
                Line2D([], [], color="k", marker="o", ls="none", label="start (measured)"),
                Line2D([], [], color="k", marker="s", mfc="none", ls="none", label="start (desired)")]
    ax.legend(handles=handles, fontsize=8, loc="upper left")
    set_equal_3d(ax, np.concatenate([P.reshape(-1, 3), P_d.reshape(-1, 3)]))
    for axis, name in ((ax.xaxis, "x"), (ax.yaxis, "y"), (ax.zaxis, "z")):
        axis.set_major_locator(MaxNLocator(5))
        axis.set_tick_params(labelsize=8)
        axis.set_label_text(f"{name} [m]")
        axis.labelpad = 8
    ax.set_title(_title(run), fontsize=11)
    return save(fig, path)


# --------------------------------------------------------------------------- several runs


@np.errstate(invalid="ignore", divide="ignore")
def _compare_signals(run: Log) -> dict:
    r, rd = np.asarray(run["state"]), np.asarray(run["r_des"])
    P, P_d = PAIR_LAYOUT.positions(r), PAIR_LAYOUT.positions(rd)
    d_mid = 0.5 * (P[:, 0] + P[:, 1]) - 0.5 * (P_d[:, 0] + P_d[:, 1])
    D = PAIR_LAYOUT.separations(r)[:, 0]
    return {
        "x_c": d_mid[:, 0],
        "y_c": d_mid[:, 1],
        "z_c": d_mid[:, 2],
        "d_c": 0.5 * D - np.asarray(run["e_des"])[:, 5],
        "orientation": errors_from_robots(run)["orientation"],
    }


_COMPARE_ROWS = (
    ("x_c", r"$e_{x_c}$ [m]"),
    ("y_c", r"$e_{y_c}$ [m]"),
    ("z_c", r"$e_{z_c}$ [m]"),
    ("d_c", r"$e_{d_c}$ [m]"),
    ("orientation", "orientation\nerror [rad]"),
)


def plot_compare(runs, path, linthresh: float = 1e-3) -> Path:
    """Errors of several controllers on one scenario, like seed 000 Fig. 13.

    Five rows sharing the time axis: the signed errors of the centroid ``x_c, y_c, z_c``
    (midpoint of the measured robots minus midpoint of the desired ones), of the
    half-separation ``d_c`` (``|p1 - p2| / 2 - d_c_des``) and the angle between the
    measured and desired robot-to-robot directions. All are computed from the robots'
    poses, so every controller is measured the same way. One line per run. The y axes are
    symmetric-logarithmic (linear within ``linthresh``), so a controller that loses the
    reference does not flatten the others; the limits ignore non-finite samples.

    Parameters
    ----------
    runs : sequence of Log
        Runs of the same scenario with different controllers.
    path : str or Path
        PNG file to write.
    linthresh : float, optional
        Half-width of the linear band of the symlog scale (default 1e-3).

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    InvalidInputError
        If ``runs`` is empty.
    """
    runs = check_runs(runs)
    sig = [_compare_signals(run) for run in runs]
    fig = new_figure((9.0, 10.0))
    axes = fig.subplots(len(_COMPARE_ROWS), 1, sharex=True)
    for row, (key, label) in enumerate(_COMPARE_ROWS):
        ax = axes[row]
        peak = 0.0
        for j, (run, s) in enumerate(zip(runs, sig)):
            idx = decimate(run.t.size)
            y = finite(s[key])
            if np.isfinite(y).any():
                peak = max(peak, float(np.nanmax(np.abs(y))))
            ax.plot(run.t[idx], y[idx], color=f"C{j}", lw=1.1, label=run.meta["controller"])
        ax.set_yscale("symlog", linthresh=linthresh)
        lim = max(peak, linthresh) * 1.5
        ax.set_ylim(0.0 if key == "orientation" else -lim, lim)
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_ylabel(label, fontsize=9)
        ax.tick_params(labelsize=8)
        ax.grid(True, lw=0.4, alpha=0.5)
    t_end = max(float(run.t[-1]) for run in runs)
    time_xlim(axes[-1], min(float(run.t[0]) for run in runs), t_end)
    axes[-1].set_xlabel("time [s]")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncols=min(len(runs), 4), fontsize=9,
               frameon=False)
    fig.suptitle(f"{_runs_title(runs)}\nerrors by controller (symlog, linear within ±{linthresh:g})",
                 fontsize=11)
    return save(fig, path)


def plot_separation(runs, path) -> Path:
    """Distance between the two robots ``|p1 - p2|`` against time, one line per run.

    For the yaw step (seed 000 Fig. 4) this shows the robot-space controller bringing the
    robots together while the cluster-space controllers keep them apart. The desired
    separation ``2 d_c`` of the first run is drawn dashed.

    Parameters
    ----------
    runs : sequence of Log
        Runs to draw (usually one scenario, several controllers).
    path : str or Path
        PNG file to write.

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    InvalidInputError
        If ``runs`` is empty.
    """
    runs = check_runs(runs)
    fig = new_figure((9.0, 4.2))
    ax = fig.add_subplot()
    for j, run in enumerate(runs):
        idx = decimate(run.t.size)
        r = finite(run["state"])
        D = PAIR_LAYOUT.separations(r)[:, 0]  # NaN where a robot is not finite
        ax.plot(run.t[idx], D[idx], color=f"C{j}", lw=1.2, label=run.meta["controller"])
    first = runs[0]
    idx = decimate(first.t.size)
    ax.plot(first.t[idx], 2.0 * finite(first["e_des"][idx, 5]), color="k", lw=1.0, ls="--",
            label="desired (2 d_c)")
    ax.set_ylim(bottom=0.0)
    time_xlim(ax, min(float(run.t[0]) for run in runs), max(float(run.t[-1]) for run in runs))
    ax.set_xlabel("time [s]")
    ax.set_ylabel("separation |p1 - p2| [m]")
    ax.grid(True, lw=0.4, alpha=0.5)
    ax.legend(fontsize=9, loc="lower right")
    ax.set_title(f"{_runs_title(runs)}\nrobot separation", fontsize=11)
    return save(fig, path)


# --------------------------------------------------------------------------- files


#: Descriptions whose ``cluster_variables.png`` already shows the Euclidean variables (the
#: cluster-space controller's own; the robot-space one's recovered ones, Fig. 10).
_EUCLIDEAN_SHOWN = ("euclidean", "robot")


def write_run_plots(run: Log, out_dir) -> list[Path]:
    """Write ``cluster_variables.png``, ``euclidean.png`` and ``paths_3d.png`` of one run.

    ``euclidean.png`` is written only for the quaternion and dual-quaternion descriptions:
    for the cluster-space and robot-space controllers ``cluster_variables.png`` already
    shows the same eight Euclidean variables, and a stale ``euclidean.png`` in ``out_dir``
    is removed.

    Parameters
    ----------
    run : Log
        A closed-loop run.
    out_dir : str or Path
        Folder to write into; created if missing.

    Returns
    -------
    list of Path
        The files written, in that order.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = [plot_cluster_variables(run, out / "cluster_variables.png")]
    if run.meta["formation"] in _EUCLIDEAN_SHOWN:
        (out / "euclidean.png").unlink(missing_ok=True)  # a previous run's, of another controller
    else:
        files.append(plot_euclidean(run, out / "euclidean.png"))
    files.append(plot_paths_3d(run, out / "paths_3d.png"))
    return files


def write_compare_plots(runs, out_dir) -> list[Path]:
    """Write ``compare_errors.png`` and ``separation.png`` of several runs of one scenario.

    Parameters
    ----------
    runs : sequence of Log
        Runs of one scenario, different controllers.
    out_dir : str or Path
        Folder to write into; created if missing.

    Returns
    -------
    list of Path
        The files written, in that order.
    """
    runs = check_runs(runs)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    return [plot_compare(runs, out / "compare_errors.png"),
            plot_separation(runs, out / "separation.png")]


FIGURES.add("pair", FigureSet(write_run_plots, write_compare_plots))
