"""Report layer: PNG figures of planned rigid-formation motions, like seed 004 Fig. 4.

Above :mod:`quatform.planning`. As in :mod:`quatform.report.plots` (whose helpers are
reused), every function draws on its own :class:`matplotlib.figure.Figure` attached to an
Agg canvas; nothing touches pyplot's global state or needs a display.

* :func:`draw_rigid_formation` - one plan on a given 3-D axes: each robot's path, the
  centroid's path (O), and a time-lapse of the robots drawn as small airplanes (nose
  along body x, wings along body y) with the formation's edges between them.
* :func:`plot_rigid_formation_paths` - one plan, written to a PNG.
* :func:`plot_airplanes_figure4` - seed 004 Fig. 4: the five airplanes, holonomic and
  cases (a) and (b), side by side.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.lines import Line2D
from matplotlib.ticker import MaxNLocator
from mpl_toolkits.mplot3d import Axes3D  # noqa: F401  (registers the '3d' projection)
from mpl_toolkits.mplot3d.art3d import Poly3DCollection

from ..algebra import matrix_from_q
from ..errors import InvalidInputError
from ..planning import AIRPLANE_CASES, RigidFormationPlan, airplanes_plan
from .figures import new_figure, save, set_equal_3d

__all__ = ["draw_rigid_formation", "plot_airplanes_figure4", "plot_rigid_formation_paths"]

#: Airplane glyph in its body frame, in units of its length: a dart (nose, wing tips,
#: tail notch) and a fin.
_DART = np.array([[0.6, 0.0, 0.0], [-0.4, 0.55, 0.0], [-0.2, 0.0, 0.0], [-0.4, -0.55, 0.0]])
_FIN = np.array([[-0.2, 0.0, 0.0], [-0.4, 0.0, 0.3]])
_TITLES = {"holonomic": "i) holonomic", "a": "ii) case (a)", "b": "iii) case (b)"}


def draw_rigid_formation(ax, plan: RigidFormationPlan, n_markers: int = 6, title: str | None = None):
    """Draw ``plan`` on the 3-D axes ``ax``.

    Parameters
    ----------
    ax : mpl_toolkits.mplot3d.Axes3D
    plan : RigidFormationPlan
    n_markers : int
        Number of instants (evenly spaced, both ends included) at which the robots are
        drawn as airplanes and the formation's edges as thin grey lines.
    title : str, optional

    Returns
    -------
    list of matplotlib.lines.Line2D
        Legend handles (robots, centroid, time-lapse).
    """
    if not isinstance(plan, RigidFormationPlan):
        raise InvalidInputError(f"plan must be a RigidFormationPlan, got {type(plan).__name__}")
    s = plan.sample(plan.times)
    pos, cen = s.positions, s.centroid
    n = pos.shape[1]
    extent = float(np.ptp(pos.reshape(-1, 3), axis=0).max())
    size = 0.08 * max(extent, 1e-3)
    handles = []
    for i in range(n):
        (line,) = ax.plot(*pos[:, i].T, color=f"C{i}", lw=1.4, label=f"robot {i + 1}")
        handles.append(line)
    (line,) = ax.plot(*cen.T, color="k", lw=1.2, ls="--", label="centroid O")
    handles.append(line)
    ax.text(*cen[0], " O", fontsize=8)
    ks = np.unique(np.linspace(0, plan.times.size - 1, max(2, int(n_markers))).round().astype(int))
    idx = [(i, j) for i in range(n) for j in range(i + 1, n)]
    for k in ks:
        for i, j in idx:
            ax.plot(*np.stack([pos[k, i], pos[k, j]]).T, color="0.7", lw=0.5)
        R = matrix_from_q(s.orientations[k])
        for i in range(n):
            dart = pos[k, i] + size * _DART @ R[i].T
            ax.add_collection3d(Poly3DCollection([dart], facecolor=f"C{i}", edgecolor="k", lw=0.4, alpha=0.9))
            fin = pos[k, i] + size * _FIN @ R[i].T
            ax.plot(*fin.T, color="k", lw=0.6)
    handles.append(Line2D([], [], color="0.7", lw=0.5, label="formation (time-lapse)"))
    set_equal_3d(ax, np.concatenate([pos.reshape(-1, 3), cen]))
    for axis, name in ((ax.xaxis, "x"), (ax.yaxis, "y"), (ax.zaxis, "z")):
        axis.set_major_locator(MaxNLocator(5))
        axis.set_tick_params(labelsize=7)
        axis.set_label_text(f"{name} [m]")
    if title:
        ax.set_title(title, fontsize=10)
    return handles


def plot_rigid_formation_paths(plan: RigidFormationPlan, path, title: str | None = None,
                               n_markers: int = 6) -> Path:
    """One plan's robot and centroid paths in 3-D, with airplane markers; written as PNG.

    Parameters
    ----------
    plan : RigidFormationPlan
    path : str or Path
        PNG file to write.
    title : str, optional
    n_markers : int
        Instants drawn as airplanes (see :func:`draw_rigid_formation`).

    Returns
    -------
    Path
        The file written.
    """
    fig = new_figure((7.5, 6.5))
    ax = fig.add_subplot(projection="3d")
    handles = draw_rigid_formation(ax, plan, n_markers, title)
    ax.legend(handles=handles, fontsize=7, loc="upper left")
    return save(fig, path)


def plot_airplanes_figure4(path, plans: dict | None = None, n_markers: int = 6) -> Path:
    """Belta & Kumar 2001 (seed 004) Fig. 4: the five airplanes (m = 1, a = 5, h = 10, X = Y = 20).

    Parameters
    ----------
    path : str or Path
        PNG file to write.
    plans : dict, optional
        ``{"holonomic": plan, "a": plan, "b": plan}``; planned with
        :func:`quatform.planning.airplanes_plan` when omitted.
    n_markers : int

    Returns
    -------
    Path
    """
    plans = {c: airplanes_plan(c) for c in AIRPLANE_CASES} if plans is None else plans
    missing = [c for c in AIRPLANE_CASES if c not in plans]
    if missing:
        raise InvalidInputError(f"plans lacks the cases {missing}; give all of {AIRPLANE_CASES}")
    fig = new_figure((16.0, 5.8))
    handles = None
    for k, case in enumerate(AIRPLANE_CASES):
        ax = fig.add_subplot(1, 3, k + 1, projection="3d")
        handles = draw_rigid_formation(ax, plans[case], n_markers, _TITLES[case])
    fig.legend(handles=handles, loc="outside lower center", ncol=len(handles), fontsize=8)
    fig.suptitle("Belta & Kumar 2001, Fig. 4: five airplanes in rigid formation, m = 1, a = 5, h = 10, X = Y = 20",
                 fontsize=11)
    return save(fig, path)
