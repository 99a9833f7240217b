"""The separation barrier's setting, shared by the scenario kinds that hold robots apart.

Scenarios layer. A scenario file's ``[safety]`` table (``enabled``, ``min_separation_m``)
and a run's ``min_separation`` option (``--min-separation X``: X m, 0 turns the barrier
off, the file's table otherwise) read the same way for every kind that holds robots apart;
each checks the setting against its own reference (seed 000's ``2 d_c``, a team's pairwise
separations), and :func:`separation_barrier` is the filter a run passes its commands through.
"""

from __future__ import annotations

import math
import numbers

from ..checks import check_keys, flag, number, short, table
from ..control.safety import SeparationBarrier
from ..errors import InvalidInputError

__all__ = ["SAFETY_KEYS", "DEFAULT_MIN_SEPARATION_M", "FILE_LABEL", "OPTION_LABEL", "safety_table", "with_option",
           "separation_barrier"]

#: The keys of a ``[safety]`` table.
SAFETY_KEYS = ("enabled", "min_separation_m")
#: ``[safety] min_separation_m`` when the table names none, m.
DEFAULT_MIN_SEPARATION_M = 0.3
#: How a refusal names the file's setting and the run option's.
FILE_LABEL, OPTION_LABEL = "[safety] min_separation_m", "min_separation"


def safety_table(data: dict, where: str, hint: str, *, enabled_without_table: bool) -> dict:
    """The ``[safety]`` table of the scenario file ``data``: ``{"enabled": bool,
    "min_separation_m": float > 0}``; a table present turns the barrier on unless it says
    ``enabled = false``, an absent one leaves it ``enabled_without_table``."""
    if "safety" not in data:
        return {"enabled": bool(enabled_without_table), "min_separation_m": DEFAULT_MIN_SEPARATION_M}
    saf = table(data, "safety", where)
    check_keys(saf, SAFETY_KEYS, where, "[safety]", hint)
    return {"enabled": flag(saf, "enabled", where, True, place="[safety]"),
            "min_separation_m": number(saf, "min_separation_m", where, DEFAULT_MIN_SEPARATION_M, place="[safety]",
                                       low=0.0, low_open=True)}


def with_option(safety: dict, min_separation, where: str) -> tuple[dict, str]:
    """The run's safety: the scenario's ``safety`` or, where ``min_separation`` is given (m,
    finite, >= 0; 0 turns the barrier off and keeps the file's minimum for the record), that;
    and the label that names the setting in a refusal (:data:`FILE_LABEL`, :data:`OPTION_LABEL`)."""
    safety = dict(safety)
    if min_separation is None:
        return safety, FILE_LABEL
    if isinstance(min_separation, bool) or not isinstance(min_separation, numbers.Real) \
            or not math.isfinite(min_separation) or min_separation < 0:
        raise InvalidInputError(f"{where}: min_separation = {short(min_separation)} must be a finite number of "
                                "m >= 0 (0 turns the separation barrier off)")
    safety.update(enabled=min_separation > 0, min_separation_m=float(min_separation or safety["min_separation_m"]))
    return safety, OPTION_LABEL


def separation_barrier(d: float, dt_s: float) -> SeparationBarrier:
    """The barrier a run of step ``dt_s`` (s) with ``min_separation_m = d`` filters its
    commands through (Wang, Ames and Egerstedt 2017; :mod:`quatform.control.safety`): its rate
    ``gamma`` at most ``1 / dt_s``, so that the sampled robots keep ``h_{k+1} >= (1 - gamma dt)
    h_k >= 0``.

    Which starts of seed 000's files need it: under the dual-quaternion law (seed 000 eq.
    (28)) a start with the robots in place and their yaws off by more than about 2 rad each
    (within +-pi) can bring them arbitrarily close (the shape ``qhat_s`` carries robot 2's yaw
    error as a rotation of the relative position, corrected along a chord;
    ``docs/derivations.md``, "The dual-quaternion pair's yaw-only starts"); the robot-space law
    drives robots straight through each other's paths (seed 000 Fig. 4b).
    """
    return SeparationBarrier(d, gamma=min(SeparationBarrier.gamma, 1.0 / dt_s), dt_s=dt_s)
