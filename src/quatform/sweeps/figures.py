"""Figures of a sweep: success rate against each varied parameter, heatmaps, error distributions.

Sweeps layer (draws with :mod:`quatform.report.figures`' Agg figures). Seed 000's story as
a map: which controller keeps the formation at which noise and latency.

* ``success_vs_<parameter>.png`` - success rate (mean over the other parameters) against
  the parameter, a line per controller;
* ``heatmap_<p>_<q>.png`` - success rate over two parameters, a panel per controller;
* ``errors_<metric>.png`` - the distribution of each success metric per controller (box
  plots over the trials that did not fail, log scale).

Each file is drawn to a temporary name and renamed into place.
"""

from __future__ import annotations

import itertools
import os
from pathlib import Path

import numpy as np

from ..report.figures import new_figure
from ..sim.output import writing

__all__ = ["sweep_figures"]

_DPI = 110


def _save(fig, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.stem}.tmp-{os.getpid()}{path.suffix}")
    try:
        with writing(path):  # a full disk names the figure
            fig.savefig(tmp, dpi=_DPI)
            os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    return path


def _rate(summary, key, choice, where: dict) -> float:
    """Success rate of ``choice``'s cells matching ``where`` (trial-weighted)."""
    sel = [s for s in summary if s[key] == choice and all(s[k] == v for k, v in where.items())]
    n = sum(s["trials"] for s in sel)
    return sum(s["success_rate"] * s["trials"] for s in sel) / n if n else np.nan


def sweep_figures(spec, values, summary: list[dict], folder) -> list[Path]:
    """Draw the sweep's figures into ``folder``; return their paths. ``values(metric)`` gives a
    success metric's values by choice over the trials that did not fail
    (:func:`~quatform.sweeps.results.metric_values`, ``shard_metric_values``)."""
    folder = Path(folder)
    key = spec.compare_key
    files = []
    title = spec.title or spec.name
    for axis in spec.axes:
        if len(axis.values) < 2:
            continue
        fig = new_figure((6.4, 4.0))
        ax = fig.add_subplot()
        xs = sorted(set(axis.values))
        for choice in spec.choices:
            ax.plot(xs, [_rate(summary, key, choice, {axis.name: x}) for x in xs], marker="o", label=choice)
        ax.set_xlabel(axis.label)
        ax.set_ylabel("success rate")
        ax.set_ylim(-0.03, 1.03)
        ax.set_title(f"{title}\nsuccess against {axis.name}", fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        files.append(_save(fig, folder / f"success_vs_{axis.name}.png"))
    multi = [a for a in spec.axes if len(a.values) >= 2]
    for a, b in itertools.combinations(multi, 2):
        xs, ys = sorted(set(a.values)), sorted(set(b.values))
        n = len(spec.choices)
        fig = new_figure((3.0 * n + 1.0, 3.4))
        axes = fig.subplots(1, n, squeeze=False)[0]
        im = None
        for ax, choice in zip(axes, spec.choices):
            grid = np.array([[_rate(summary, key, choice, {a.name: x, b.name: y}) for x in xs] for y in ys])
            im = ax.imshow(grid, origin="lower", vmin=0.0, vmax=1.0, cmap="RdYlGn", aspect="auto")
            for (i, j), v in np.ndenumerate(grid):
                if np.isfinite(v):
                    ax.text(j, i, f"{v:.2f}", ha="center", va="center", fontsize=7)
            ax.set_xticks(range(len(xs)), [f"{x:.3g}" for x in xs], fontsize=7)
            ax.set_yticks(range(len(ys)), [f"{y:.3g}" for y in ys], fontsize=7)
            ax.set_xlabel(a.label, fontsize=8)
            ax.set_title(choice, fontsize=9)
        axes[0].set_ylabel(b.label, fontsize=8)
        fig.colorbar(im, ax=list(axes), label="success rate", shrink=0.9)
        fig.suptitle(f"{title}: success rate", fontsize=9)
        files.append(_save(fig, folder / f"heatmap_{a.name}_{b.name}.png"))
    for metric in spec.success.below:
        fig = new_figure((6.4, 4.0))
        ax = fig.add_subplot()
        data = []
        by_choice = values(metric)
        for choice in spec.choices:
            v = by_choice[choice]
            v = v[np.isfinite(v) & (v > 0)]
            data.append(v if v.size else np.array([np.nan]))
        ax.boxplot(data, showfliers=True)
        ax.set_xticks(range(1, len(spec.choices) + 1), spec.choices, fontsize=8)
        ax.set_yscale("log")
        ax.axhline(spec.success.below[metric], color="k", ls="--", lw=0.8, label="success threshold")
        ax.set_ylabel(metric)
        ax.set_title(f"{title}\n{metric} per {key} (trials that did not fail)", fontsize=9)
        ax.legend(fontsize=8)
        files.append(_save(fig, folder / f"errors_{metric}.png"))
    return files
