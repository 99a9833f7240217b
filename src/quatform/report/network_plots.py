"""Report layer: PNG figures of decentralised (network) runs.

Every function draws on its own Agg figure (:mod:`.figures`) from one world's
:class:`~quatform.sim.log.Log` of the network kind (:mod:`quatform.scenarios.network`):

* :func:`plot_consensus_error` - the consensus error on a log scale against the decay that
  λ₂ predicts (``exp(-rate t)`` from where the measured rate is fitted), the figure of Cui et
  al. 2025 and Olfati-Saber & Murray 2004;
* :func:`plot_message_age` - what the links delivered at each tick and the oldest message a
  robot used, against the links' ``max_age_s``;
* :func:`plot_graph_snapshots` - the robots (top view) at the start, the middle and the end
  with the edges of the graph active then (arrows from sender to receiver for a directed
  graph);
* :func:`plot_compare_consensus_error` - the consensus error of every run of a compare (one
  scenario, one run per law) on one log-scale axes.

Titles are wrapped to the figure's width, so a long ``source`` is never clipped.
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

from ..papers import with_names
from ..sim.log import Log
from .figure_set import FIGURES, FigureSet
from .figures import decimate, new_figure, save, time_xlim

__all__ = ["plot_consensus_error", "plot_message_age", "plot_graph_snapshots", "plot_compare_consensus_error",
           "write_network_run_plots", "write_network_compare_plots"]

#: Largest number of edges drawn in one snapshot (a swarm's are thinned evenly).
_MAX_EDGES = 4000


#: Title font size, pt.
_TITLE_PT = 10


def _title(log: Log, law: bool = True) -> str:
    """The scenario (and ``law``: the law and team size) and its source, one line each."""
    source = with_names(log.meta.get("source", ""))
    head = f"{log.meta['scenario']} - {log.meta['law']} ({log.meta['n_robots']} robots)" if law else \
        str(log.meta["scenario"])
    return head + (f"\n{source}" if source else "")


def _wrapped(text: str, width_in: float) -> list[str]:
    """The lines of ``text``, each wrapped to ``width_in`` inches of title (an average glyph is
    about 0.55 em wide; 0.6 leaves a margin)."""
    width = max(20, int(width_in * 72.0 / (0.6 * _TITLE_PT)))
    return [part for line in text.split("\n") for part in (textwrap.wrap(line, width) or [""])]


def _suptitle(fig, text: str) -> None:
    """``text`` as the figure's title, wrapped to the figure's width so no line is clipped."""
    fig.suptitle("\n".join(_wrapped(text, fig.get_figwidth())), fontsize=_TITLE_PT)


def _style(ax, ylabel):
    ax.set_ylabel(ylabel, fontsize=9)
    ax.tick_params(labelsize=8)
    ax.grid(True, lw=0.4, alpha=0.5)


def plot_consensus_error(run: Log, path, measured_rate=None) -> Path:
    """The consensus error (log scale) and the predicted decay ``e(t0) exp(-rate (t - t0))``."""
    from ..scenarios.network import measured_rate as fit

    t = run.t
    err = np.asarray(run["consensus_error"], dtype=float)[:, 0]
    idx = decimate(len(t))
    fig = new_figure((7.0, 4.0))
    ax = fig.add_subplot(1, 1, 1)
    ax.semilogy(t[idx], np.maximum(err[idx], 1e-300), lw=1.2, label="measured")
    rate = run.meta.get("predicted_rate")
    t0 = float(run.meta.get("metrics_from_s", 0.0))
    after = (t >= t0) & np.isfinite(err)
    # anchored where the fit of the measured rate starts: the error at half its largest value
    k0 = int(np.argmax(after & (err <= 0.5 * np.max(err[after], initial=0.0)))) if after.any() else len(t)
    predicted = rate is not None and np.isfinite(rate) and k0 < len(t) and err[k0] > 0
    if predicted:
        tt = t[idx][t[idx] >= t[k0]]
        ax.semilogy(tt, err[k0] * np.exp(-rate * (tt - t[k0])), "--", lw=1.0,
                    label=f"predicted by lambda2: rate {rate:.3g} 1/s")
    got = fit(t, err, t0) if measured_rate is None else measured_rate
    if got is not None:
        ax.plot([], [], " ", label=f"measured rate {got:.3g} 1/s")
    floor = max(float(np.nanmin(err[err > 0])) if np.any(err > 0) else 1e-16, 1e-16)
    ax.set_ylim(bottom=floor / 3)
    _style(ax, "consensus error")
    ax.set_xlabel("time [s]")
    time_xlim(ax, float(t[0]), float(t[-1]))
    ax.legend(fontsize=8)
    _suptitle(fig, f"{_title(run)}\nconsensus error" + (" against the rate lambda2 predicts" if predicted else ""))
    return save(fig, path)


def plot_message_age(run: Log, path) -> Path:
    """Messages sent, lost and delivered per tick, and the oldest message held, s."""
    t = run.t
    net = np.asarray(run["network"], dtype=float)
    idx = decimate(len(t))
    fig = new_figure((7.0, 5.0))
    a1, a2 = fig.add_subplot(2, 1, 1), fig.add_subplot(2, 1, 2, sharex=None)
    for q, label in ((0, "sent"), (1, "lost"), (2, "delivered")):
        a1.plot(t[idx], net[idx, q], lw=0.8, label=label)
    _style(a1, "messages per tick")
    a1.legend(fontsize=8, ncols=3)
    a2.plot(t[idx], net[idx, 3], lw=0.8, label="oldest message held")
    age = run.meta.get("graph", {}).get("links", {}).get("max_age_s")
    if age is not None:
        a2.axhline(age, color="k", ls=":", lw=0.8, label=f"max_age_s = {age:g} s (older: stale)")
    _style(a2, "message age [s]")
    a2.set_xlabel("time [s]")
    a2.legend(fontsize=8)
    for ax in (a1, a2):
        time_xlim(ax, float(t[0]), float(t[-1]))
    _suptitle(fig, f"{_title(run)}\nwhat the links carried")
    return save(fig, path)


def plot_graph_snapshots(run: Log, path) -> Path:
    """The robots from above at three times with the edges of the graph active then."""
    t = run.t
    p = run.meta["layout"].positions(np.asarray(run["measured"], dtype=float))
    graph = run.meta.get("graph", {})
    graphs = graph.get("graphs", [])
    starts = [(-np.inf if g["start_s"] is None else g["start_s"]) for g in graphs]
    ks = sorted({0, len(t) // 2, len(t) - 1})
    lo, hi = np.nanmin(p[..., :2], axis=(0, 1)), np.nanmax(p[..., :2], axis=(0, 1))
    pad = 0.05 * max(float(np.max(hi - lo)), 1e-9)
    # the height follows the robots' extent (equal axes: y span / x span of a panel about 3.5 in
    # wide) with room to spare, so each panel's box shrinks in height, never in width, and its x
    # label stays inside the figure; the rest is the wrapped title, the panel titles and labels
    span = np.maximum(hi - lo, 1e-9) + 2.0 * pad
    title = f"{_title(run)}\nthe graph over time (undirected; an arrow runs from sender to receiver)"
    lines = len(_wrapped(title, 4.0 * len(ks)))
    fig = new_figure((4.0 * len(ks), 3.6 * float(np.clip(span[1] / span[0], 0.25, 2.0)) + 1.1 + 0.2 * lines))
    directed = True
    for col, k in enumerate(ks):
        ax = fig.add_subplot(1, len(ks), col + 1)
        active = max([q for q, s in enumerate(starts) if s <= t[k] + 1e-12] or [0])
        edges = np.asarray(graphs[active]["edges"], dtype=int) - 1 if graphs else np.zeros((0, 2), dtype=int)
        if len(edges) > _MAX_EDGES:
            edges = edges[np.linspace(0, len(edges) - 1, _MAX_EDGES).astype(int)]
        pk = p[k]
        if len(edges):
            rev = {(int(a), int(b)) for a, b in edges}
            directed = any((b, a) not in rev for a, b in rev)
            for i, j in edges:  # j sends to i
                ax.annotate("", xy=pk[i, :2], xytext=pk[j, :2],
                            arrowprops={"arrowstyle": "->" if directed else "-", "lw": 0.5, "color": "0.5",
                                        "shrinkA": 3, "shrinkB": 3})
        ax.scatter(pk[:, 0], pk[:, 1], s=12 if len(pk) <= 50 else 2, zorder=3)
        if len(pk) <= 20:
            for i, q in enumerate(pk):
                ax.annotate(str(i + 1), q[:2], fontsize=7, xytext=(3, 3), textcoords="offset points")
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
        ax.set_aspect("equal", adjustable="box")
        ax.set_title(f"t = {t[k]:.3g} s" + (f", graph #{active + 1}" if len(graphs) > 1 else ""), fontsize=9)
        ax.set_xlabel("x [m]", fontsize=9)
        if col == 0:
            ax.set_ylabel("y [m]", fontsize=9)
        ax.tick_params(labelsize=8)
    _suptitle(fig, f"{_title(run)}\nthe graph over time ({'directed' if directed else 'undirected'}; "
                   f"an arrow runs from sender to receiver)")
    return save(fig, path)


def write_network_run_plots(run: Log, out_dir) -> list[Path]:
    """Write ``consensus_error.png``, ``message_age.png`` and ``graph.png`` of one network run."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    return [plot_consensus_error(run, out / "consensus_error.png"), plot_message_age(run, out / "message_age.png"),
            plot_graph_snapshots(run, out / "graph.png")]


def plot_compare_consensus_error(runs, path) -> Path:
    """The consensus error of every run (log scale) against time, labelled by each run's law."""
    runs = list(runs)
    fig = new_figure((7.0, 4.0))
    ax = fig.add_subplot(1, 1, 1)
    floor, start, end = np.inf, np.inf, -np.inf
    for k, run in enumerate(runs):
        t = run.t
        err = np.asarray(run["consensus_error"], dtype=float)[:, 0]
        idx = decimate(len(t))
        ax.semilogy(t[idx], np.maximum(err[idx], 1e-300), lw=1.2, color=f"C{k}",
                    label=run.meta.get("law", f"run {k + 1}"))
        if np.any(err > 0):
            floor = min(floor, float(np.nanmin(err[err > 0])))
        start, end = min(start, float(t[0])), max(end, float(t[-1]))
    if runs:
        ax.set_ylim(bottom=max(floor if np.isfinite(floor) else 1e-16, 1e-16) / 3)
        time_xlim(ax, start, end)
        ax.legend(fontsize=8)
    _style(ax, "consensus error")
    ax.set_xlabel("time [s]")
    head = _title(runs[0], law=False) if runs else "network"
    _suptitle(fig, f"{head}\nconsensus error of each law (each law measures its own error, in its own unit)")
    return save(fig, path)


def write_network_compare_plots(runs, out_dir) -> list[Path]:
    """Write ``compare_consensus_error.png``: the runs of one scenario, one per law, on one axes."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    return [plot_compare_consensus_error(runs, out / "compare_consensus_error.png")]


FIGURES.add("network", FigureSet(write_network_run_plots, write_network_compare_plots))
