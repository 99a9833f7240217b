"""The figure registry's value type: what figures a scenario kind draws of one run and of a compare.

Report layer. :data:`FIGURES` maps a kind's name (its TOML ``kind``) to a :class:`FigureSet`,
added by the module that draws them (``FIGURES.add("team", FigureSet(run, compare))`` beside
its functions); :mod:`quatform.runs` calls :func:`figures_of` for every kind alike (a kind
without an entry draws none), so a new kind's figures are one module.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from ..registry import Registry

__all__ = ["FigureSet", "NO_FIGURES", "FIGURES", "figures_of"]


def _none(*args) -> list:
    return []


@dataclass(frozen=True)
class FigureSet:
    """The figures of one scenario kind.

    Attributes
    ----------
    run : callable ``(log, out) -> list of Path``
        Draws one run's figures from its :class:`~quatform.sim.log.Log` into the folder ``out``.
    compare : callable ``(logs, out) -> list of Path``
        Draws the figures of a compare (the runs' logs in the order run) into ``out``.
    """

    run: Callable = _none
    compare: Callable = _none


#: A kind without figures.
NO_FIGURES = FigureSet()


#: Figures of each scenario kind, by the kind's name (filled by the figure modules).
FIGURES = Registry("figure set")


def figures_of(kind: str) -> FigureSet:
    """The :class:`FigureSet` of scenario kind ``kind`` (:data:`NO_FIGURES` where it has none)."""
    return FIGURES.get(kind, NO_FIGURES)
