"""Report layer: figures of planned motions, like seed 002 Figs. 3-4 (above planning).

* :func:`plot_plan_paths` - every robot's path (dashed) over the optimal rigid motion
  (solid, where defined), with snapshots of the formation at evenly spaced times; a
  spatial plan is drawn in the two views x-y and x-z.
* :func:`plot_plan_separation` - the smallest and every pairwise separation against time.
* :func:`plot_alpha_panels` - one panel per alpha, stacked as in the seed's figures (by
  increasing alpha, one x-y scale, equal on both axes; a legend naming each alpha).

Agg canvases only; nothing touches pyplot's global state.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from ..planning import Plan, pair_separations, rigid_motion

__all__ = ["plot_alpha_panels", "plot_plan_paths", "plot_plan_separation", "write_plan_plots"]

DPI = 120
SNAPSHOTS = 7


def _figure(w, h):
    fig = Figure(figsize=(w, h))
    FigureCanvasAgg(fig)
    return fig


def _draw(ax, plan: Plan, axes=(0, 1), title=""):
    t = np.linspace(plan.times[0], plan.times[-1], 401)
    pos, _, _ = plan.sample(t)
    s = (t - t[0]) / (t[-1] - t[0])
    # the uniform rigid reference of seed 002 (not drawn for seed 004's projected curves)
    rigid = None if plan.info.get("kind") == "rigid-se3" else rigid_motion(pos[0], pos[-1], plan.masses, s)
    i, j = axes
    colors = [f"C{k}" for k in range(plan.n_robots)]
    for k in range(plan.n_robots):
        if rigid is not None:
            ax.plot(rigid[:, k, i], rigid[:, k, j], "-", color="0.55", lw=1.0)
        ax.plot(pos[:, k, i], pos[:, k, j], "--", color=colors[k], lw=1.4, label=f"robot {k + 1}")
    snaps = np.linspace(0, t.size - 1, SNAPSHOTS).astype(int)
    for n in snaps:
        P = pos[n][:, [i, j]]
        ring = np.vstack([P, P[:1]]) if plan.n_robots > 2 else P
        ax.plot(ring[:, 0], ring[:, 1], "-", color="k", lw=0.6, alpha=0.6)
        ax.scatter(P[:, 0], P[:, 1], c=colors, s=18 * np.sqrt(plan.masses / plan.masses.min()), zorder=3)
    names = "xyz"
    ax.set_xlabel(f"{names[i]} (m)")
    ax.set_ylabel(f"{names[j]} (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, lw=0.3)
    if title:
        ax.set_title(title, fontsize=9)


def plot_plan_paths(plan: Plan, title: str = "") -> Figure:
    """Paths (dashed), optimal rigid motion (solid grey) and formation snapshots."""
    views = [(0, 1)] if plan.dim == 2 else [(0, 1), (0, 2)]
    fig = _figure(6.5, 3.6 * len(views))
    for k, v in enumerate(views):
        ax = fig.add_subplot(len(views), 1, k + 1)
        _draw(ax, plan, v, title if k == 0 else "")
        if k == 0:
            ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    return fig


def plot_plan_separation(plan: Plan, clearance_m: float | None = None) -> Figure:
    """Pairwise separations against time (and the clearance that flags ``robots_meet``)."""
    t = np.linspace(plan.times[0], plan.times[-1], 401)
    pos, _, _ = plan.sample(t)
    D = pair_separations(pos)
    fig = _figure(6.5, 3.0)
    ax = fig.add_subplot(1, 1, 1)
    for a in range(plan.n_robots):
        for b in range(a + 1, plan.n_robots):
            ax.plot(t, D[:, a, b], lw=1.0, label=f"{a + 1}-{b + 1}" if plan.n_robots <= 5 else None)
    if clearance_m:
        ax.axhline(clearance_m, color="r", lw=0.8, ls=":", label="clearance")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("separation (m)")
    ax.set_ylim(bottom=0)
    ax.grid(True, lw=0.3)
    ax.legend(fontsize=7, ncol=4)
    fig.tight_layout()
    return fig


def _extent(plans, axes=(0, 1)):
    """Lower and upper corners of every plan's paths (and rigid reference) in the view ``axes``."""
    pts = []
    for plan in plans:
        t = np.linspace(plan.times[0], plan.times[-1], 201)
        pos, _, _ = plan.sample(t)
        pts.append(pos[..., list(axes)].reshape(-1, 2))
        if plan.info.get("kind") != "rigid-se3":
            s = (t - t[0]) / (t[-1] - t[0])
            pts.append(rigid_motion(pos[0], pos[-1], plan.masses, s)[..., list(axes)].reshape(-1, 2))
    pts = np.concatenate(pts)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    return pts.min(axis=0), pts.max(axis=0)


def plot_alpha_panels(plans: dict, title: str = "") -> Figure:
    """One panel per ``alpha`` (``{alpha: Plan}``), as in seed 002 Figs. 3-4.

    The panels are stacked by increasing alpha (the seed's order: alpha = 0.2 on top, 0.99 at
    the bottom), share one x-y scale (metres, equal on both axes: a circle looks round), and
    each names its alpha in its legend; the figure's legend names the robots (with their
    masses), the optimal rigid motion (solid grey) and the formation snapshots.
    """
    items = sorted(plans.items(), key=lambda kv: float(kv[0]))
    lo, hi = _extent([p for _, p in items])
    pad = 0.06 * float(max(hi - lo))
    lo, hi = lo - pad, hi + pad
    width = 6.5
    panel_h = float(np.clip((width - 1.0) * (hi[1] - lo[1]) / (hi[0] - lo[0]), 1.0, 6.0)) + 0.55  # + tick labels
    fig = Figure(figsize=(width, panel_h * len(items) + 0.9), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(len(items), 1, sharex=True, sharey=True, squeeze=False)[:, 0]
    for ax, (alpha, plan) in zip(axes, items):
        _draw(ax, plan, (0, 1))
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal", adjustable="box")
        ax.tick_params(labelbottom=True)
        ax.legend(handles=[Line2D([], [], color="k", ls="--", lw=1.4, label=f"α = {float(alpha):g}")],
                  loc="upper right", fontsize=9, handlelength=2.5)
    plan = items[0][1]
    shared = [Line2D([], [], color=f"C{k}", ls="--", lw=1.4, marker="o", ms=4,
                     label=f"robot {k + 1} (m = {plan.masses[k]:g} kg), geodesic of the shaped metric")
              for k in range(plan.n_robots)]
    if plan.info.get("kind") != "rigid-se3":
        shared.append(Line2D([], [], color="0.55", lw=1.0, label="optimal rigid motion (SE(2))"))
    shared.append(Line2D([], [], color="k", lw=0.6, alpha=0.6, label=f"formation at {SNAPSHOTS} instants"))
    fig.legend(handles=shared, loc="outside lower center", ncol=2, fontsize=7)
    if title:
        fig.suptitle(title, fontsize=9)
    return fig


def write_plan_plots(plan: Plan, out, title: str = "", clearance_m: float | None = None) -> list[Path]:
    """Write ``plan_paths.png`` and ``plan_separation.png`` into ``out``."""
    out = Path(out)
    files = [out / "plan_paths.png", out / "plan_separation.png"]
    plot_plan_paths(plan, title).savefig(files[0], dpi=DPI)
    plot_plan_separation(plan, clearance_m).savefig(files[1], dpi=DPI)
    return files
