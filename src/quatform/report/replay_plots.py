"""Report layer: ``commands.png`` of ``quatform replay`` (commanded against measured, per robot).

Above the robots (it reads a model's ``state_columns``, ``command_columns`` and
``passthrough``); nothing here knows the ROS 2 bridge. Per robot, the left column holds its
measured state and the right its commands, one axes per unit (positions in m beside angles in
rad would hide one another), each labelled with its unit. For a robot whose commands are its
state's world rates (``passthrough``), the measured rate (the per-tick difference of the
measured state, which multiplies the motion-capture noise by the tick rate) is drawn beneath
the command: thin and faint, with its moving mean over :data:`RATE_WINDOW_S` dashed, and the
y-range set by the commands and that mean, so the noise cannot hide the commands (drawn on
top, solid).

* :func:`column_unit` - the unit of a robot's state or command column (its model's ``column_units``);
* :func:`replay_commands_figure` - the figure; :func:`plot_replay_commands` - written to a PNG.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ..robots import ROBOT_MODELS
from ..robots.model import column_unit as robot_column_unit
from .figures import intervals, new_figure, save

__all__ = ["RATE_WINDOW_S", "COMMAND_ZORDER", "RATE_MEAN_ZORDER", "RATE_ZORDER", "RATE_ALPHA", "column_unit",
           "plot_replay_commands", "replay_commands_figure"]

#: Width of the moving mean drawn over a measured rate, s.
RATE_WINDOW_S = 0.5
#: Drawing order: commands over the measured rate's mean over the raw measured rate.
COMMAND_ZORDER, RATE_MEAN_ZORDER, RATE_ZORDER = 3.0, 2.0, 1.0
#: Opacity of the raw measured rate.
RATE_ALPHA = 0.3

def column_unit(column: str, model=None) -> str:
    """The unit of a robot model's state or command column (its model's ``column_units``; no
    ``model``: the first registered model's that has the column; ``"-"``: dimensionless or unknown)."""
    if model is not None:
        return robot_column_unit(model, column)
    return next((cls.column_units[column] for cls in ROBOT_MODELS.values()
                 if isinstance(cls.column_units, dict) and column in cls.column_units), "-")


def _groups(model, columns) -> dict:
    """``{unit: [index, ...]}`` of ``model``'s ``columns``, in order of first appearance."""
    out: dict = {}
    for j, c in enumerate(columns):
        out.setdefault(column_unit(c, model), []).append(j)
    return out


def _moving_mean(y, t, window_s):
    """Centred moving mean of ``y`` over about ``window_s`` seconds of the (near-uniform) ticks
    ``t``; near the ends (and around NaN) over the samples the window holds."""
    if len(t) < 3:
        return y
    dt = float(np.median(np.diff(t)))
    k = int(max(1, round(window_s / dt))) if dt > 0 else 1
    if k < 2:
        return y
    ok = np.isfinite(y)
    kernel = np.ones(k)
    total = np.convolve(np.where(ok, y, 0.0), kernel, mode="same")
    count = np.convolve(ok.astype(float), kernel, mode="same")
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, total / count, np.nan)


def _ylim(ax, *series):
    vals = np.concatenate([np.ravel(s) for s in series])
    vals = vals[np.isfinite(vals)]
    if vals.size == 0:
        return
    lo, hi = float(vals.min()), float(vals.max())
    half = max(0.5 * (hi - lo) * 1.15, 1e-3)
    mid = 0.5 * (lo + hi)
    ax.set_ylim(mid - half, mid + half)


def plot_replay_commands(t, states, commands, held, names, models, state_slices, command_slices,
                         command_names, path) -> Path:
    """:func:`replay_commands_figure` written to ``path`` (PNG); returns the path."""
    return save(replay_commands_figure(t, states, commands, held, names, models, state_slices, command_slices,
                                       command_names), path)


def replay_commands_figure(t, states, commands, held, names, models, state_slices, command_slices,
                           command_names) -> Figure:
    """The replay's commands against the measured state, per robot (the module docstring).

    Parameters
    ----------
    t : ndarray, shape (T,)
        Tick times, s (drawn from the first).
    states : ndarray, shape (T, n_state)
        Measured plant state at each tick (NaN before a robot's first pose).
    commands : ndarray, shape (T, n_command)
        The controller's commands at each tick.
    held : ndarray of bool, shape (T,)
        Ticks whose commands were held (stale pose or e-stop): shaded grey.
    names : sequence of str
        Robot names.
    models : sequence of RobotModel
        Each robot's model (units from its ``state_columns`` / ``command_columns``).
    state_slices, command_slices : sequence of slice
        Each robot's columns of ``states`` and ``commands``.
    command_names : sequence of str
        The controller's command names (legend).

    Returns
    -------
    matplotlib.figure.Figure
    """
    t = np.asarray(t, dtype=float)
    t = t - t[0]
    rows = []  # (robot, [(unit, state idx)], [(unit, command idx)])
    for i, model in enumerate(models):
        rows.append((i, list(_groups(model, model.state_columns).items()), list(_groups(model, model.command_columns).items())))
    n_rows = sum(max(len(s), len(c)) for _, s, c in rows)
    fig = new_figure((11, 1.9 * n_rows + 0.6))
    axes = fig.subplots(n_rows, 2, squeeze=False, sharex=True)
    spans = intervals(t, np.asarray(held, dtype=bool))
    r = 0
    for i, sgroups, cgroups in rows:
        model, ss, cs = models[i], state_slices[i], command_slices[i]
        x, u = states[:, ss], commands[:, cs]
        ucols = list(command_names)[cs]
        for k in range(max(len(sgroups), len(cgroups))):
            ax = axes[r + k, 0]
            if k < len(sgroups):
                unit, idx = sgroups[k]
                for j in idx:
                    ax.plot(t, x[:, j], lw=1.1, label=model.state_columns[j])
                ax.set_ylabel(f"{names[i]} measured [{unit}]", fontsize=8)
                ax.legend(fontsize=7, ncol=len(idx), loc="upper right")
                ax.grid(True, lw=0.3)
            else:
                ax.set_visible(False)
            ax = axes[r + k, 1]
            if k < len(cgroups):
                unit, idx = cgroups[k]
                shown = []
                for j in idx:
                    line, = ax.plot(t, u[:, j], lw=1.5, zorder=COMMAND_ZORDER, gid="command",
                                    label=f"{ucols[j]} ({model.command_columns[j]})")
                    shown.append(u[:, j])
                    if model.passthrough and len(t) > 2:  # its commands are its state's world rates
                        rate = np.gradient(x[:, j], t)
                        mean = _moving_mean(rate, t, RATE_WINDOW_S)
                        ax.plot(t, rate, lw=0.5, alpha=RATE_ALPHA, color=line.get_color(), zorder=RATE_ZORDER,
                                gid="measured rate")
                        ax.plot(t, mean, lw=1.0, ls="--", color=line.get_color(), zorder=RATE_MEAN_ZORDER,
                                gid="measured rate mean")
                        shown.append(mean)
                _ylim(ax, *shown)
                for a, b in spans:
                    ax.axvspan(a, b, color="0.85", lw=0, zorder=0)
                ax.set_ylabel(f"{names[i]} command [{unit}]", fontsize=8)
                ax.legend(fontsize=7, ncol=len(idx), loc="upper right")
                ax.grid(True, lw=0.3)
            else:
                ax.set_visible(False)
        r += max(len(sgroups), len(cgroups))
    for ax in axes[-1]:
        ax.set_xlabel("time since the first tick [s]")
    for ax in axes[:-1].ravel():
        ax.tick_params(labelbottom=True)
    passthrough = any(m.passthrough for m in models)
    fig.suptitle("measured state (left) and commands (right); grey: held (stale pose or e-stop)"
                 + (f"\nsolid: commanded, dashed: measured rate ({RATE_WINDOW_S:g} s moving mean), "
                    "faint: measured rate per tick" if passthrough else ""), fontsize=9)
    return fig
