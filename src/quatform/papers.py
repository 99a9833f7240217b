"""The five research documents quatform implements, one registry (below every layer).

Code and docs cite them as "seed 000" ... "seed 004"; users read them by name. Scenario and
plan files name them in ``source`` either way ("Mas & Kitts 2017 (seed 000) §4.1" or
"seed 002 §5"); :func:`cited` finds them there, :func:`with_names` rewrites a source for a
figure's title. Like :mod:`quatform.errors`, this module imports nothing of quatform.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

__all__ = ["Paper", "PAPERS", "cited", "with_names"]


@dataclass(frozen=True)
class Paper:
    """One seed document: its number (``"000"``), short name and full citation."""

    seed: str
    short: str
    citation: str

    @property
    def tag(self) -> str:
        """``"seed 000"``, as code comments and docs cite it."""
        return f"seed {self.seed}"


#: The seed documents by number.
PAPERS = {p.seed: p for p in (
    Paper("000", "Mas & Kitts 2017", 'I. Mas, C. Kitts, 2017, "Quaternions and Dual Quaternions: Singularity-Free '
          'Multirobot Formation Control", J. Intell. Robot. Syst.'),
    Paper("001", "Marciano 2021", 'H. N. Marciano, 2021, "Using Quaternions to Avoid Singularities in UAV-UGV Multi '
          'Robot Systems", MSc thesis, UFES'),
    Paper("002", "Belta & Kumar 2002", 'C. Belta, V. Kumar, 2002, "Trajectory design for formations of robots by '
          'kinetic energy shaping", ICRA 2002'),
    Paper("003", "Jansen et al. 1990", 'J. F. Jansen, R. L. Kress, S. M. Babcock, W. R. Hamel, 1990, "Controller '
          'design for a teleoperator system with dissimilar kinematics and force feedback", ORNL CONF-910223-4'),
    Paper("004", "Belta & Kumar 2001", 'C. Belta, V. Kumar, 2001, "Motion generation for formations of robots: a '
          'geometric approach", ICRA 2001'),
)}


def cited(source: str) -> list[Paper]:
    """The papers a ``source`` text names, by seed tag or short name, in order of mention."""
    text = str(source)
    found = {}
    for p in PAPERS.values():
        hits = [m.start() for m in re.finditer(re.escape(p.tag), text)] + \
               [m.start() for m in re.finditer(re.escape(p.short), text)]
        if hits:
            found[p.seed] = min(hits)
    return [PAPERS[s] for s in sorted(found, key=found.get)]


def with_names(source: str) -> str:
    """``source`` with each seed tag replaced by the paper's short name (dropped, with its
    brackets, where the name is already there: "Mas & Kitts 2017 (seed 000)" stays one name)."""
    out = str(source)
    for p in PAPERS.values():
        out = out.replace(f" ({p.tag})", "") if p.short in out else out.replace(p.tag, p.short)
    return out
