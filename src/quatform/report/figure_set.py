"""The figure registry's value type: what figures a scenario kind draws of one run and of a compare.

Report layer. :data:`quatform.report.FIGURES` maps a kind's name (its TOML ``kind``) to a
:class:`FigureSet`; :mod:`quatform.runs` calls it for every kind alike, so a new kind's
figures are one module in ``report/`` plus one registry entry.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

__all__ = ["FigureSet", "NO_FIGURES"]


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
