"""Report layer: PNG figures of UGV-UAV runs, like seed 001 Figs. 19-39 (above sim).

The figures of a finished UGV-UAV :class:`~quatform.sim.log.Log` (the ``ugv-uav`` scenario
kind, :mod:`quatform.scenarios.ugv_uav`): a Pioneer (UGV) and a Bebop (UAV)
in one of the descriptions ``'quaternion'``, ``'spherical'`` or ``'restricted'``. As in
:mod:`quatform.report.plots` (whose helpers are reused), every function draws on its own
:class:`matplotlib.figure.Figure` attached to an Agg canvas, lines are decimated to at
most ``MAX_POINTS`` samples, and the singular-pose shading is computed on every sample.

The robots are drawn at their logged (true) poses, the log's ``state`` and ``r_true``,
against the desired ones ``r_des`` (``UgvUavSpherical().inverse(e_des)``). A run whose reference the
description cannot express from the start has no samples; its figures then carry the
reason instead of axes.

* :func:`plot_ugv_uav_paths_3d` - both robots' paths in 3-D, with the segment between them
  drawn as a time-lapse.
* :func:`plot_ugv_uav_cluster` - the cluster variables of the run's description against
  desired, and their errors.
* :func:`plot_ugv_uav_robots` - each robot's position and heading against its reference.
* :func:`plot_ugv_uav_compare` - several descriptions on one scenario: robot errors, the
  recovered ``alpha_c`` and the singularity measure.
"""

from __future__ import annotations

import textwrap
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import MaxNLocator
from mpl_toolkits.mplot3d import Axes3D  # noqa: F401  (registers the '3d' projection)

from ..algebra import wrap_angle
from ..formations import UGV_UAV_LAYOUT
from ..papers import PAPERS, with_names
from ..robots.pioneer_bebop import BEBOP_PART, PIONEER_PART
from ..scenarios.ugv_uav import UGV_UAV_FORMATIONS
from ..sim.log import Log
from ..sim.metrics import SINGULAR_THRESHOLD
from .figures import (
    ANGLE_LABELS,
    ANGLE_TICKS,
    DES_STYLE,
    MEAS_STYLE,
    SINGULAR_COLOR,
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

__all__ = [
    "plot_ugv_uav_cluster",
    "plot_ugv_uav_compare",
    "plot_ugv_uav_paths_3d",
    "plot_ugv_uav_robots",
    "write_ugv_uav_compare_plots",
    "write_ugv_uav_run_plots",
]

_SWITCH_STYLE = {"color": "0.35", "lw": 0.9, "ls": "--"}
_XYZ_COLORS = ("C0", "C1", "C2")
_Q_COLORS = ("C0", "C1", "C2", "C4")
#: Half-width of the linear band of the symlog error axes.
_LINTHRESH = 1e-3
#: Width of the centred moving mean drawn over noisy errors, s (with its min-max envelope).
FILTER_WINDOW_S = 0.5
_UNREACHABLE_COLOR = "0.82"
_PAPER = PAPERS["001"].short


@dataclass(frozen=True)
class _Run:
    """What the figures read of one finished log (:func:`_run_of`)."""

    scenario: object
    formation: str
    physics: str
    t: np.ndarray
    ugv: np.ndarray  # (T, 3): x_p, y_p, psi_p
    uav: np.ndarray  # (T, 8): x_b, y_b, z_b, psi_b, body velocities
    r_true: np.ndarray  # (T, 6)
    r_des: np.ndarray  # (T, 6)
    c: np.ndarray
    c_des: np.ndarray
    e: np.ndarray
    e_des: np.ndarray
    singularity: np.ndarray  # (T,)
    reachable: np.ndarray  # (T,) bool
    unreachable_at: float | None
    unreachable_message: str


def _run_of(log: Log) -> _Run:
    """The figures' view of a finished UGV-UAV log."""
    m, x = log.meta, log["state"]
    return _Run(m["scenario"], m["formation"], m["physics"], log.t, x[:, PIONEER_PART], x[:, BEBOP_PART], log["r_true"],
                log["r_des"], log["cluster"], log["c_des"], log["e"], log["e_des"], log["singularity"][:, 0],
                log["reachable"][:, 0] > 0.5, m["unreachable_at"], m["unreachable_message"])


# --------------------------------------------------------------------------- helpers


def _title(run: _Run) -> str:
    """``name - ugv-uav-<formation> (Marciano 2021 §..., Figs. ...)`` and the scenario title."""
    sc = run.scenario
    source = with_names(sc.source)
    paper = source if _PAPER in source else (f"{_PAPER}, {source}" if source else _PAPER)
    on = "" if run.physics == "kinematic" else f" on {run.physics}"
    head = f"{sc.name} - ugv-uav-{run.formation}{on} ({paper})"
    return f"{head}\n{sc.title}" if sc.title else head


def _filtered(t, y, window_s: float = FILTER_WINDOW_S, stride: int = 1):
    """Centred moving mean of ``y`` over ``window_s`` and the min-max envelope over the
    same window (at least ``2 stride + 1`` samples, so a plot decimated by ``stride`` still
    shows every sample's extent); NaN samples are skipped. Three arrays like ``y``."""
    y = np.asarray(y, dtype=float)
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    half = max(int(round(0.5 * window_s / dt)), 0)
    half_env = max(half, stride)
    pad = np.pad(y, max(half, half_env), constant_values=np.nan)
    windows = np.lib.stride_tricks.sliding_window_view
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN windows stay NaN
        off = half_env - half
        mean = np.nanmean(windows(pad[off:len(pad) - off], 2 * half + 1), axis=-1)
        env = windows(pad, 2 * half_env + 1)
        return mean, np.nanmin(env, axis=-1), np.nanmax(env, axis=-1)


def _unreachable_spans(run: _Run):
    """Intervals where the description could not express the reference (the robots waited)."""
    if run.reachable is None or run.t.size == 0:
        return []
    return intervals(run.t, ~np.asarray(run.reachable, dtype=bool))


def _shade_unreachable(ax, spans):
    for a, b in spans:
        ax.axvspan(a, b, color=_UNREACHABLE_COLOR, alpha=0.6, lw=0, zorder=0)


def _unreachable_text(run: _Run) -> str:
    msg = run.unreachable_message or "no samples"
    return f"reference unreachable for the {run.formation} description: {msg}"


def _unreachable_note(run: _Run) -> str:
    """Short tag for legends and titles: ``''`` for a run that kept its reference."""
    if run.unreachable_at is None:
        return ""
    if run.reachable is not None and run.t.size > 1:
        gone = float((~np.asarray(run.reachable)).sum() * (run.t[1] - run.t[0]))
        return f"reference unreachable {gone:.3g} s from t = {run.unreachable_at:g} s"
    return f"unreachable from t = {run.unreachable_at:g} s"


def _empty_figure(run: _Run, path, figsize) -> Path:
    """A figure with only the reason why ``run`` has no samples."""
    fig = new_figure(figsize)
    ax = fig.add_subplot()
    ax.set_axis_off()
    width = max(30, int(9.5 * figsize[0]))
    ax.text(0.5, 0.5, textwrap.fill(_unreachable_text(run), width), ha="center", va="center",
            fontsize=11, color="C3", transform=ax.transAxes)
    fig.suptitle(_title(run), fontsize=11)
    return save(fig, path)


def _desired_robots(run: _Run) -> np.ndarray:
    """Desired ``(x_p, y_p, z_p, x_b, y_b, z_b)`` of every sample, (T, 6)."""
    return np.asarray(run.r_des, dtype=float)


def _actual_robots(run: _Run) -> np.ndarray:
    """Logged (true) ``(x_p, y_p, z_p, x_b, y_b, z_b)``, the UGV at the platform height."""
    return np.asarray(run.r_true, dtype=float)


def _angle_axis(ax):
    ax.set_ylim(-np.pi - 0.35, np.pi + 0.35)
    ax.set_yticks(ANGLE_TICKS, ANGLE_LABELS)


def _wrapped(y):
    """``y`` folded into ``[-pi, pi)`` with NaN at the folds, so no vertical line is drawn."""
    return break_wraps(wrap_angle(finite(y)))


def _switch_time(run: _Run):
    """Time of the front -> over switch of seed 001 §5.3 inside the run, or None."""
    ts = float(run.scenario.uav_front_until_s)
    if ts <= 0 or run.t.size == 0 or not (run.t[0] <= ts <= run.t[-1]):
        return None
    return ts


def _decorate_time_axes(ax, run: _Run, spans):
    shade(ax, spans)
    _shade_unreachable(ax, _unreachable_spans(run))
    ts = _switch_time(run)
    if ts is not None:
        ax.axvline(ts, **_SWITCH_STYLE, zorder=1)
    ax.tick_params(labelsize=8)
    ax.grid(True, lw=0.4, alpha=0.5)
    time_xlim(ax, float(run.t[0]), float(run.t[-1]))


def _extra_handles(run: _Run, spans) -> list:
    """Legend entries of the singular shading and the switch line, where drawn."""
    handles = []
    if spans:
        handles.append(Patch(color=SINGULAR_COLOR, alpha=0.6,
                             label=f"singular (measure < {SINGULAR_THRESHOLD:g})"))
    if _unreachable_spans(run):
        handles.append(Patch(color=_UNREACHABLE_COLOR, alpha=0.6,
                             label=f"reference outside the {run.formation} description (robots wait)"))
    ts = _switch_time(run)
    if ts is not None:
        handles.append(Line2D([], [], **_SWITCH_STYLE, label=f"UAV front → over (t = {ts:g} s)"))
    return handles


def _subtitle_note(run: _Run) -> str:
    note = _unreachable_note(run)
    return f" ({note})" if note else ""


def _quaternion_angle(q, q_des):
    """Rotation angle between unit quaternions, ``2 acos|q_des . q|``, in ``[0, pi]``.

    Evaluated as ``4 atan2(|q - s q_des|, |q + s q_des|)`` with ``s = sign(q_des . q)``,
    which is the same angle without the loss of ``acos`` near 1.
    """
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    p = q_des / np.linalg.norm(q_des, axis=-1, keepdims=True)
    s = np.where(np.einsum("...i,...i->...", q, p) < 0, -1.0, 1.0)[..., None]
    return 4.0 * np.arctan2(np.linalg.norm(q - s * p, axis=-1), np.linalg.norm(q + s * p, axis=-1))


def _symlog_error_axis(ax, y, nonnegative=False):
    """Symmetric-log y axis (linear within ``_LINTHRESH``) sized to the finite samples of ``y``."""
    y = np.asarray(y, dtype=float)
    peak = float(np.nanmax(np.abs(y))) if np.isfinite(y).any() else 0.0
    ax.set_yscale("symlog", linthresh=_LINTHRESH)
    lim = max(peak, _LINTHRESH) * 1.5
    ax.set_ylim(0.0 if nonnegative else -lim, lim)
    ax.axhline(0.0, color="k", lw=0.5)


# --------------------------------------------------------------------------- one run


def plot_ugv_uav_paths_3d(log: Log, path, n_segments: int = 10) -> Path:
    """Both robots' paths in 3-D, logged (solid) and desired (dashed).

    Like seed 001 Figs. 19, 26 and 33: the UGV's control point at the platform height
    ``scenario.center[2]`` and the UAV's position. Start points are marked (circle:
    measured, hollow square: desired) and the segment between the robots is drawn as a
    thin grey line at ``n_segments + 1`` evenly spaced times (about every 10 % of the
    run). The axes share one scale (each spans at least a quarter of the largest extent).
    A run with no samples gets the reason its reference was unreachable instead.

    Parameters
    ----------
    log : Log
        A finished log of the ``ugv-uav`` kind (:mod:`quatform.scenarios.ugv_uav`).
    path : str or Path
        PNG file to write; its folder is created if missing.
    n_segments : int, optional
        Number of intervals of the time-lapse (default 10).

    Returns
    -------
    Path
        The file written.
    """
    run = _run_of(log)
    if run.t.size == 0:
        return _empty_figure(run, path, (8.0, 6.8))
    r, rd = finite(_actual_robots(run)), finite(_desired_robots(run))
    P, Pd = UGV_UAV_LAYOUT.positions(r), UGV_UAV_LAYOUT.positions(rd)  # (T, 2, 3): the UGV, the UAV
    fig = new_figure((8.0, 6.8))
    ax = fig.add_subplot(projection="3d")
    idx = decimate(r.shape[0])
    ks = np.unique(np.linspace(0, r.shape[0] - 1, max(1, int(n_segments)) + 1).round().astype(int))
    for k in ks:  # first, so the paths are drawn over them
        seg = P[k]
        ax.plot(*seg.T, color="0.6", lw=0.8, alpha=0.8)
    for i, color, name in ((0, "C0", "UGV"), (1, "C1", "UAV")):
        p, pd = P[:, i], Pd[:, i]
        ax.plot(*p[idx].T, color=color, lw=1.4, ls="-", label=f"{name} measured")
        ax.plot(*pd[idx].T, color=color, lw=1.0, ls="--", alpha=0.8, label=f"{name} desired")
        ax.scatter(*p[0], color=color, marker="o", s=40, depthshade=False)
        ax.scatter(*pd[0], facecolors="none", edgecolors=color, marker="s", s=60, depthshade=False)
    handles, _ = ax.get_legend_handles_labels()
    handles += [Line2D([], [], color="0.6", lw=0.8, label="segment (every ~10 %)"),
                Line2D([], [], color="k", marker="o", ls="none", label="start (measured)"),
                Line2D([], [], color="k", marker="s", mfc="none", ls="none", label="start (desired)")]
    ax.legend(handles=handles, fontsize=8, loc="upper left")
    set_equal_3d(ax, np.concatenate([P.reshape(-1, 3), Pd.reshape(-1, 3)]))
    for axis, name in ((ax.xaxis, "x"), (ax.yaxis, "y"), (ax.zaxis, "z")):
        axis.set_major_locator(MaxNLocator(5))
        axis.set_tick_params(labelsize=8)
        axis.set_label_text(f"{name} [m]")
        axis.labelpad = 8
    ax.set_title(f"{_title(run)}{_subtitle_note(run)}", fontsize=11)
    return save(fig, path)


def _cluster_rows(run: _Run):
    """``(label, measured, desired, error, kind)`` per row of :func:`plot_ugv_uav_cluster`.

    ``kind`` is ``'angle'``, ``'quaternion'`` (4 columns; the error is the rotation angle)
    or ``'linear'``.
    """
    c, cd = finite(run.c), finite(run.c_des)
    variables = UGV_UAV_FORMATIONS[run.formation].variables
    quat = [k for k, v in enumerate(variables) if v.kind == "quaternion"]
    if quat:  # the centroid, q_c as one row (its rotation angle), d_c's first entry (seed 001 §4.3)
        q = slice(quat[0], quat[-1] + 1)
        rows = [(f"{v.name} [m]", c[:, k], cd[:, k], c[:, k] - cd[:, k], "linear")
                for k, v in enumerate(variables) if v.kind == "position"]
        rows.append((f"{variables[q.start].name.rsplit('_', 1)[0]} [-]", c[:, q], cd[:, q],
                     _quaternion_angle(c[:, q], cd[:, q]), "quaternion"))
        d = next(k for k, v in enumerate(variables) if v.kind == "length")
        rows.append((f"{variables[d].name.rsplit('_', 1)[0]} [m]", c[:, d], cd[:, d], c[:, d] - cd[:, d], "linear"))
        return rows
    rows = []
    for k, var in enumerate(variables):
        if var.kind == "angle":
            rows.append((f"{var.name} [rad]", c[:, k], cd[:, k], wrap_angle(c[:, k] - cd[:, k]), "angle"))
        else:
            rows.append((f"{var.name} [m]", c[:, k], cd[:, k], c[:, k] - cd[:, k], "linear"))
    return rows


def plot_ugv_uav_cluster(log: Log, path) -> Path:
    """The cluster variables of the run's description against desired, and their errors.

    Like seed 001 Figs. 20-22, 27-29 and 34-36. Left column: each variable of the
    description, ``run.c`` (solid) against ``run.c_des`` (dashed), against time; for the
    quaternion description ``x_c, y_c, z_c``, the four components of ``q_c`` in one axes
    (one colour each) and ``d_c = c[:, 7]``; for the spherical and restricted ones their
    six variables, angles wrapped to ``[-pi, pi)``. Right column: the errors (measured
    minus desired, angles wrapped; for ``q_c`` the rotation angle ``2 acos|q_des . q|``)
    on symmetric-logarithmic axes, linear within 1e-3. Times where the singularity
    measure is below ``SINGULAR_THRESHOLD`` (0.02) are shaded light red, and the front ->
    over switch of seed 001 §5.3 (``scenario.uav_front_until_s``) is a grey dashed line.

    Parameters
    ----------
    log : Log
        A finished log of the ``ugv-uav`` kind (:mod:`quatform.scenarios.ugv_uav`).
    path : str or Path
        PNG file to write; its folder is created if missing.

    Returns
    -------
    Path
        The file written.
    """
    run = _run_of(log)
    if run.t.size == 0:
        return _empty_figure(run, path, (11.0, 6.0))
    rows = _cluster_rows(run)
    n = len(rows)
    fig = new_figure((11.0, 1.65 * n + 1.4))
    axes = fig.subplots(n, 2, sharex=True, squeeze=False)
    idx = decimate(run.t.size)
    t = run.t[idx]
    spans = intervals(run.t, np.asarray(run.singularity) < SINGULAR_THRESHOLD)
    for row, (label, y, yd, err, kind) in enumerate(rows):
        ax, ax_e = axes[row]
        _decorate_time_axes(ax, run, spans)
        _decorate_time_axes(ax_e, run, spans)
        if kind == "quaternion":
            for j, comp in enumerate("wxyz"):
                ax.plot(t, y[idx, j], color=_Q_COLORS[j], lw=1.2, ls="-", label=comp)
                ax.plot(t, yd[idx, j], color=_Q_COLORS[j], lw=1.0, ls="--")
            ax.set_ylim(-1.1, 1.1)
            ax.legend(fontsize=7, ncols=4, loc="lower right", framealpha=0.7, handlelength=1.2)
            ax_e.set_ylabel("q_c error:\nangle [rad]", fontsize=9)
        elif kind == "angle":
            ax.plot(t, _wrapped(y[idx]), **MEAS_STYLE)
            ax.plot(t, _wrapped(yd[idx]), **DES_STYLE)
            _angle_axis(ax)
            ax_e.set_ylabel(f"e({label.split(' ')[0]})\n[rad]", fontsize=9)
        else:
            ax.plot(t, y[idx], **MEAS_STYLE)
            ax.plot(t, yd[idx], **DES_STYLE)
            floor_ylim(ax, y[idx], yd[idx])
            ax_e.set_ylabel(f"e({label.split(' ')[0]})\n[m]", fontsize=9)
        ax.set_ylabel(label, fontsize=9)
        e = finite(err)
        mean, lo, hi = _filtered(run.t, e, stride=max(1, idx[1] - idx[0]) if len(idx) > 1 else 1)
        ax_e.fill_between(t, lo[idx], hi[idx], color="C2", alpha=0.25, lw=0)
        ax_e.plot(t, mean[idx], color="C2", lw=1.1)
        _symlog_error_axis(ax_e, e, nonnegative=(kind == "quaternion"))
    axes[0, 0].set_title(f"{run.formation} cluster variables", fontsize=10)
    axes[0, 1].set_title(f"errors (symlog, linear within ±{_LINTHRESH:g}); {FILTER_WINDOW_S:g} s mean",
                         fontsize=10)
    for ax in axes[-1]:
        ax.set_xlabel("time [s]", fontsize=9)
    handles = [Line2D([], [], **MEAS_STYLE, label="measured"),
               Line2D([], [], **DES_STYLE, label="desired"),
               Line2D([], [], color="C2", lw=1.1, label=f"error (measured - desired), {FILTER_WINDOW_S:g} s mean"),
               Patch(color="C2", alpha=0.25, label=f"error min-max over {FILTER_WINDOW_S:g} s")]
    handles += _extra_handles(run, spans)
    fig.legend(handles=handles, loc="outside lower center", ncols=min(len(handles), 3), fontsize=9,
               frameon=False)
    fig.suptitle(f"{_title(run)}{_subtitle_note(run)}", fontsize=11)
    return save(fig, path)


def plot_ugv_uav_robots(log: Log, path) -> Path:
    """Each robot's position and heading against its reference, 2 x 2 axes.

    Like seed 001 Figs. 23-24, 30-31 and 37-38. Top: the UGV's control point ``x, y``
    (solid) against desired (dashed), and its heading ``psi``. Bottom: the UAV's ``x, y,
    z`` against desired, and its yaw ``psi`` against the UGV's heading, which is its yaw
    reference (seed 001 eq. 4.50). Angles are wrapped to ``[-pi, pi)``; singular times
    shaded and the front -> over switch marked as in :func:`plot_ugv_uav_cluster`.

    Parameters
    ----------
    log : Log
        A finished log of the ``ugv-uav`` kind (:mod:`quatform.scenarios.ugv_uav`).
    path : str or Path
        PNG file to write; its folder is created if missing.

    Returns
    -------
    Path
        The file written.
    """
    run = _run_of(log)
    if run.t.size == 0:
        return _empty_figure(run, path, (11.0, 6.4))
    r, rd = finite(_actual_robots(run)), finite(_desired_robots(run))
    ugv_psi, uav_psi = finite(run.ugv[:, 2]), finite(run.uav[:, 3])
    fig = new_figure((11.0, 6.4))
    axes = fig.subplots(2, 2, sharex=True)
    idx = decimate(run.t.size)
    t = run.t[idx]
    spans = intervals(run.t, np.asarray(run.singularity) < SINGULAR_THRESHOLD)
    for row, (name, cols) in enumerate((("UGV", (0, 1)), ("UAV", (3, 4, 5)))):
        ax = axes[row, 0]
        _decorate_time_axes(ax, run, spans)
        series = []
        for j, col in enumerate(cols):
            ax.plot(t, r[idx, col], color=_XYZ_COLORS[j], lw=1.2, ls="-", label="xyz"[j])
            ax.plot(t, rd[idx, col], color=_XYZ_COLORS[j], lw=1.0, ls="--")
            series += [r[idx, col], rd[idx, col]]
        floor_ylim(ax, *series)
        ax.set_ylabel(f"{name} position [m]", fontsize=9)
        ax.legend(fontsize=8, ncols=len(cols), loc="upper right", framealpha=0.7, handlelength=1.5)
    ax = axes[0, 1]
    _decorate_time_axes(ax, run, spans)
    ax.plot(t, _wrapped(ugv_psi[idx]), color="C0", lw=1.2, label="UGV ψ")
    _angle_axis(ax)
    ax.set_ylabel("UGV heading ψ [rad]", fontsize=9)
    ax.legend(fontsize=8, loc="upper right", framealpha=0.7)
    ax = axes[1, 1]
    _decorate_time_axes(ax, run, spans)
    ax.plot(t, _wrapped(uav_psi[idx]), color="C1", lw=1.2, label="UAV ψ")
    ax.plot(t, _wrapped(ugv_psi[idx]), color="C0", lw=1.0, ls="--", label="reference (UGV ψ)")
    _angle_axis(ax)
    ax.set_ylabel("UAV yaw ψ [rad]", fontsize=9)
    ax.legend(fontsize=8, loc="upper right", framealpha=0.7)
    for ax in axes[-1]:
        ax.set_xlabel("time [s]", fontsize=9)
    handles = [Line2D([], [], color="k", lw=1.2, ls="-", label="measured"),
               Line2D([], [], color="k", lw=1.0, ls="--", label="desired")]
    handles += _extra_handles(run, spans)
    fig.legend(handles=handles, loc="outside lower center", ncols=min(len(handles), 3), fontsize=9,
               frameon=False)
    fig.suptitle(f"{_title(run)}{_subtitle_note(run)}\nrobots", fontsize=11)
    return save(fig, path)


# --------------------------------------------------------------------------- several runs


def _compare_label(run: _Run) -> str:
    note = _unreachable_note(run)
    return f"{run.formation} ({note})" if note else run.formation


@np.errstate(invalid="ignore")
def _robot_errors(run: _Run):
    """Position errors ``|p_ugv - p_ugv_des|`` (x, y) and ``|p_uav - p_uav_des|`` (x, y, z)."""
    p = UGV_UAV_LAYOUT.positions(finite(_actual_robots(run)))
    pd = UGV_UAV_LAYOUT.positions(finite(_desired_robots(run)))
    return (np.linalg.norm(p[:, 0, 0:2] - pd[:, 0, 0:2], axis=1),
            np.linalg.norm(p[:, 1] - pd[:, 1], axis=1))


def plot_ugv_uav_compare(logs, path) -> Path:
    """Several descriptions on one UGV-UAV scenario, one line per run.

    Like seed 001 Figs. 25, 32 and 39. Four rows sharing the time axis: the UGV's
    position error ``|(x, y) - (x, y)_des|``, the UAV's ``|(x, y, z) - (x, y, z)_des|``
    (both from the logged poses, so every description is measured the same way; symlog,
    linear within 1e-3), the azimuth ``alpha_c`` each description recovers (``run.e``,
    wrapped to ``[-pi, pi)``) against the desired one (black dashed), and the
    singularity measure with its threshold ``SINGULAR_THRESHOLD`` (dotted). A run whose
    reference became unreachable says so in its legend label (with no line if it has no
    samples). The front -> over switch is a grey dashed line.

    Parameters
    ----------
    logs : sequence of Log
        Runs of the same scenario with different formations.
    path : str or Path
        PNG file to write; its folder is created if missing.

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    InvalidInputError
        If ``logs`` is empty.
    """
    runs = [_run_of(log) for log in check_runs(logs)]
    fig = new_figure((9.0, 9.0))
    axes = fig.subplots(4, 1, sharex=True)
    peaks = [0.0, 0.0]
    for j, run in enumerate(runs):
        color, label = f"C{j}", _compare_label(run)
        if run.t.size == 0:
            for ax in axes:
                ax.plot([], [], color=color, lw=1.1, label=label)
            continue
        idx = decimate(run.t.size)
        t = run.t[idx]
        stride = max(1, idx[1] - idx[0]) if len(idx) > 1 else 1
        for row, err in enumerate(_robot_errors(run)):
            if np.isfinite(err).any():
                peaks[row] = max(peaks[row], float(np.nanmax(err)))
            mean, lo, hi = _filtered(run.t, err, stride=stride)
            axes[row].fill_between(t, lo[idx], hi[idx], color=color, alpha=0.2, lw=0)
            axes[row].plot(t, mean[idx], color=color, lw=1.1, label=label)
        axes[2].plot(t, _wrapped(np.asarray(run.e)[idx, 4]), color=color, lw=1.1, label=label)
        axes[3].plot(t, finite(run.singularity)[idx], color=color, lw=1.1, label=label)
    axes[0].set_title(f"position errors: {FILTER_WINDOW_S:g} s moving mean, band: min-max", fontsize=9)
    for row, label in enumerate(("UGV position\nerror [m]", "UAV position\nerror [m]")):
        ax = axes[row]
        ax.set_yscale("symlog", linthresh=_LINTHRESH)
        ax.set_ylim(0.0, max(peaks[row], _LINTHRESH) * 1.5)
        ax.set_ylabel(label, fontsize=9)
    longest = max(runs, key=lambda run: run.t.size)
    extra = []
    if longest.t.size:
        idx = decimate(longest.t.size)
        axes[2].plot(longest.t[idx], _wrapped(np.asarray(longest.e_des)[idx, 4]), color="k", lw=1.0,
                     ls="--", zorder=3)
        extra.append(Line2D([], [], color="k", lw=1.0, ls="--", label="desired α_c"))
        ts = _switch_time(longest)
        if ts is not None:
            for ax in axes:
                ax.axvline(ts, **_SWITCH_STYLE, zorder=1)
            extra.append(Line2D([], [], **_SWITCH_STYLE, label=f"UAV front → over (t = {ts:g} s)"))
    _angle_axis(axes[2])
    axes[2].set_ylabel("recovered α_c\n[rad]", fontsize=9)
    axes[3].axhline(SINGULAR_THRESHOLD, color="k", lw=0.8, ls=":")
    axes[3].set_ylim(bottom=0.0)
    axes[3].set_ylabel("singularity\nmeasure [-]", fontsize=9)
    extra.append(Line2D([], [], color="k", lw=0.8, ls=":", label=f"threshold {SINGULAR_THRESHOLD:g}"))
    for ax in axes:
        ax.tick_params(labelsize=8)
        ax.grid(True, lw=0.4, alpha=0.5)
    ran = [run for run in runs if run.t.size]
    if ran:
        time_xlim(axes[-1], min(float(run.t[0]) for run in ran),
                   max(float(run.t[-1]) for run in ran))
    axes[-1].set_xlabel("time [s]")
    handles, _ = axes[0].get_legend_handles_labels()
    handles += extra
    fig.legend(handles=handles, loc="outside lower center", ncols=min(len(handles), 3), fontsize=9,
               frameon=False)
    names = ", ".join(dict.fromkeys(run.scenario.name for run in runs))
    fig.suptitle(f"{names} - UGV-UAV descriptions compared ({_PAPER})", fontsize=11)
    return save(fig, path)


# --------------------------------------------------------------------------- files


def write_ugv_uav_run_plots(log: Log, out_dir) -> list[Path]:
    """Write ``paths_3d.png``, ``cluster_variables.png`` and ``robots.png`` of one run.

    Parameters
    ----------
    log : Log
        A finished log of the ``ugv-uav`` kind (:mod:`quatform.scenarios.ugv_uav`).
    out_dir : str or Path
        Folder to write into; created if missing.

    Returns
    -------
    list of Path
        The files written, in that order.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    return [plot_ugv_uav_paths_3d(log, out / "paths_3d.png"),
            plot_ugv_uav_cluster(log, out / "cluster_variables.png"),
            plot_ugv_uav_robots(log, out / "robots.png")]


def write_ugv_uav_compare_plots(logs, out_dir) -> list[Path]:
    """Write ``compare_formations.png`` of several runs of one scenario.

    Parameters
    ----------
    logs : sequence of Log
        Runs of one scenario, different formations.
    out_dir : str or Path
        Folder to write into; created if missing.

    Returns
    -------
    list of Path
        The files written.

    Raises
    ------
    InvalidInputError
        If ``logs`` is empty.
    """
    logs = check_runs(logs)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    return [plot_ugv_uav_compare(logs, out / "compare_formations.png")]


FIGURES.add("ugv-uav", FigureSet(write_ugv_uav_run_plots, write_ugv_uav_compare_plots))
