"""Shared figure helpers of the report layer: Agg figures, decimation, angle traces, shading.

Report layer. Every figure module of :mod:`quatform.report` draws with these, so a new figure
looks like the others: :func:`new_figure` (an Agg canvas, no pyplot state), :func:`save`
(PNG at :data:`DPI`), :func:`decimate` (at most :data:`MAX_POINTS` samples per line),
:func:`break_wraps` (no vertical line where an angle wraps), :func:`intervals` and
:func:`shade` (time spans, e.g. near a singular pose), axis limits and styles.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..errors import InvalidInputError
from ..sim.output import writing

__all__ = ["MAX_POINTS", "DPI", "MEAS_STYLE", "DES_STYLE", "SINGULAR_COLOR", "ANGLE_TICKS", "ANGLE_LABELS",
           "MIN_HALF_SPAN", "new_figure", "save", "finite", "decimate", "break_wraps", "unwrap", "intervals",
           "shade", "time_xlim", "floor_ylim", "check_runs", "set_equal_3d"]

#: Most samples drawn per line.
MAX_POINTS = 2000
#: Resolution of the written PNG files.
DPI = 110
#: Line styles of a measured and a desired signal.
MEAS_STYLE = {"color": "C0", "lw": 1.2, "ls": "-"}
DES_STYLE = {"color": "C3", "lw": 1.0, "ls": "--"}
#: Shading of the time spans near a singular pose.
SINGULAR_COLOR = "#f4b6b6"
#: Ticks of a wrapped-angle axes and their labels.
ANGLE_TICKS = (-np.pi, -np.pi / 2, 0.0, np.pi / 2, np.pi)
ANGLE_LABELS = ("-π", "-π/2", "0", "π/2", "π")
#: Smallest half-height of a non-angle axes, so round-off (1e-16) is not blown up to fill it.
MIN_HALF_SPAN = 1e-3


def new_figure(figsize) -> Figure:
    """A constrained-layout figure on its own Agg canvas (no pyplot state, no display)."""
    fig = Figure(figsize=figsize, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def save(fig: Figure, path) -> Path:
    """Write ``fig`` as a PNG at :data:`DPI` (folders made as needed); return the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with writing(path):  # a full disk names the figure
        fig.savefig(path, dpi=DPI)
    return path


def finite(a):
    """A float copy of ``a`` with infinities replaced by NaN (matplotlib skips NaN)."""
    a = np.array(a, dtype=float)
    a[~np.isfinite(a)] = np.nan
    return a


def decimate(n: int, max_points: int = MAX_POINTS) -> np.ndarray:
    """Indices of at most about ``max_points`` evenly strided samples, last one kept."""
    if n <= max_points:
        return np.arange(n)
    step = int(np.ceil(n / max_points))
    idx = np.arange(0, n, step)
    if idx[-1] != n - 1:
        idx = np.append(idx, n - 1)
    return idx


def break_wraps(y, limit=np.pi):
    """Insert NaN where an angle trace jumps by more than ``limit`` (rad) between samples, so
    no vertical line is drawn."""
    y = np.asarray(y, dtype=float)
    if y.size < 2:
        return y
    with np.errstate(invalid="ignore"):
        jump = np.abs(np.diff(y)) > limit
    out = y.copy()
    out[1:][jump] = np.nan
    return out


def unwrap(y):
    """``np.unwrap`` of the finite samples of ``y`` (NaN stays NaN and does not spread)."""
    y = np.array(y, dtype=float)
    ok = np.isfinite(y)
    if ok.any():
        y[ok] = np.unwrap(y[ok])
    return y


def intervals(t, mask):
    """``(start, stop)`` times of the runs of True in ``mask``."""
    mask = np.asarray(mask, dtype=bool)
    if not mask.any():
        return []
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    starts = np.flatnonzero(edges == 1)
    stops = np.flatnonzero(edges == -1) - 1
    dt = float(t[1] - t[0]) if t.size > 1 else 0.0
    return [(float(t[a]), float(t[b]) + dt) for a, b in zip(starts, stops)]


def shade(ax, spans):
    for a, b in spans:
        ax.axvspan(a, b, color=SINGULAR_COLOR, alpha=0.6, lw=0, zorder=0)


def time_xlim(ax, t0: float, t1: float):
    if t1 > t0:
        ax.set_xlim(t0, t1)


def floor_ylim(ax, *series):
    """Give flat signals an axes at least ``2 * MIN_HALF_SPAN`` high, with no offset text."""
    ax.ticklabel_format(axis="y", useOffset=False)
    vals = np.concatenate([np.ravel(s) for s in series])
    vals = vals[np.isfinite(vals)]
    if vals.size == 0:
        return
    lo, hi = float(vals.min()), float(vals.max())
    if hi - lo < 2 * MIN_HALF_SPAN:
        mid = 0.5 * (lo + hi)
        ax.set_ylim(mid - 1.1 * MIN_HALF_SPAN, mid + 1.1 * MIN_HALF_SPAN)


def check_runs(runs) -> list:
    runs = list(runs)
    if not runs:
        raise InvalidInputError("runs: need at least one Run to compare")
    return runs


def set_equal_3d(ax, pts, min_fraction=0.25):
    """Limits with one scale on every axis; an axis spans at least ``min_fraction`` of the largest."""
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if pts.size == 0:
        return
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    center = 0.5 * (lo + hi)
    span = hi - lo
    big = max(float(span.max()), 1e-3)
    span = np.maximum(span, min_fraction * big) * 1.1
    ax.set_xlim(center[0] - span[0] / 2, center[0] + span[0] / 2)
    ax.set_ylim(center[1] - span[1] / 2, center[1] + span[1] / 2)
    ax.set_zlim(center[2] - span[2] / 2, center[2] + span[2] / 2)
    ax.set_box_aspect(tuple(span / big))
