"""Checks of user input shared by every loader and runner (below every layer).

Like :mod:`quatform.errors`, this module imports nothing else of quatform, so the scenario
loaders (sim), the plan-spec loader (planning) and the CLI all refuse bad input the same way:
one line naming the file, the key, the value and the fix.

- :func:`check_keys` refuses unknown keys and names the nearest valid one;
- :func:`table`, :func:`number`, :func:`integer`, :func:`vector`, :func:`flag`, :func:`text`
  read one typed value from a parsed TOML table (NaN, infinity, magnitudes beyond
  :data:`MAX_NUMBER`, booleans or tables where numbers belong and numbers out of range are
  refused, naming the key);
- :func:`check_work` estimates the memory and time of a run up front and refuses what
  cannot finish;
- :func:`short` is the one-line, bounded ``repr`` that error messages quote values with.
"""

from __future__ import annotations

import difflib
import math
import os
from collections.abc import Iterable, Mapping

from .errors import InvalidInputError, ResourceLimitError

__all__ = [
    "MISSING",
    "MAX_NUMBER",
    "short",
    "nearest",
    "check_keys",
    "records",
    "table",
    "number",
    "integer",
    "vector",
    "flag",
    "text",
    "check_work",
    "check_within_run",
    "memory_budget_bytes",
    "time_budget_s",
]


#: Largest magnitude :func:`number` accepts. quatform's files hold SI values (m, s, rad, N, kg,
#: N/m); nothing physical in a formation, a plan or a teleoperation scenario comes near 1e12,
#: while 1e154 m overflows a squared distance and 1e300 a product of two of them.
MAX_NUMBER = 1e12


class _Missing:
    def __repr__(self) -> str:
        return "MISSING"


#: Default of the readers meaning "the key is required".
MISSING = _Missing()


def short(value, limit: int = 60) -> str:
    """``repr(value)`` on one line, at most ``limit`` characters (``...`` marks a cut)."""
    try:
        text_ = repr(value)
    except Exception:  # noqa: BLE001 - a broken __repr__ must not hide the real error
        text_ = f"<{type(value).__name__}>"
    text_ = " ".join(text_.split())
    return text_ if len(text_) <= limit else text_[: limit - 3] + "..."


def nearest(name: str, allowed: Iterable[str]) -> str:
    """`` (did you mean 'x'?)`` for the closest of ``allowed`` to ``name``, or ``""``."""
    match = difflib.get_close_matches(str(name), sorted(allowed), n=1, cutoff=0.6)
    return f" (did you mean {match[0]!r}?)" if match else ""


def check_keys(data: Mapping, allowed: Iterable[str], where: str, place: str = "top level",
               hint: str = "see docs/scenarios.md") -> None:
    """Refuse a key of ``data`` that is not in ``allowed``, naming the nearest valid one.

    Parameters
    ----------
    data : mapping
        A parsed TOML table.
    allowed : iterable of str
        The keys the table may hold.
    where : str
        The file (or scenario name) quoted at the start of the message.
    place : str
        Where in the file the table is: ``"top level"`` or ``"[gains]"``.
    hint : str
        Where the keys are documented.
    """
    allowed = set(allowed)
    for key in data:
        if key not in allowed:
            raise InvalidInputError(
                f"{where}: unknown key {short(key)} at {place}{nearest(key, allowed)}; allowed: "
                f"{', '.join(sorted(allowed))} ({hint})"
            )


def records(data: Mapping, key: str, allowed: Iterable[str], where: str, place: str,
            hint: str = "see docs/scenarios.md"):
    """``(table, where)`` of each entry of the array of tables ``[[place]]`` (``data[key]``,
    default none), each entry's keys checked against ``allowed``; ``where`` names the entry
    (``FILE [[place]] #k``)."""
    items = data.get(key, [])
    if not isinstance(items, list) or not all(isinstance(r, Mapping) for r in items):
        raise InvalidInputError(f"{where}: {place} = {short(items)} must be an array of tables ([[{place}]] "
                                f"entries; {hint})")
    for i, r in enumerate(items):
        w = f"{where} [[{place}]] #{i + 1}"
        check_keys(r, allowed, w, f"[[{place}]]", hint)
        yield r, w


def _name(key: str, place: str) -> str:
    return key if place in ("", "top level") else f"{place} {key}"


def _absent(data: Mapping, key: str, where: str, default, place: str) -> bool:
    """True where ``data`` lacks ``key`` and ``default`` stands in; refuses a missing required key."""
    if key in data:
        return False
    if default is MISSING:
        raise InvalidInputError(f"{where}: missing key {_name(key, place)}")
    return True


def table(data: Mapping, key: str, where: str, place: str = "top level", default=MISSING) -> dict:
    """The sub-table ``data[key]``; a number or list there is refused, naming the key."""
    if key not in data:
        if default is MISSING:
            raise InvalidInputError(f"{where}: missing table [{key}]")
        return dict(default)
    value = data[key]
    if not isinstance(value, Mapping):
        raise InvalidInputError(
            f"{where}: {_name(key, place)} must be a table ([{key}] with keys), got {short(value)}"
        )
    return dict(value)


def number(data: Mapping, key: str, where: str, default=MISSING, *, place: str = "top level",
           low: float | None = None, high: float | None = None, low_open: bool = False,
           high_open: bool = False) -> float:
    """The finite real number ``data[key]`` (an int or float, not a bool), within bounds.

    ``low``/``high`` bound it, inclusively unless ``low_open``/``high_open``. A missing key
    gives ``default`` (refused when ``default`` is :data:`MISSING`).
    """
    if _absent(data, key, where, default, place):
        return default
    value = data[key]
    label = _name(key, place)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InvalidInputError(f"{where}: {label} = {short(value)} must be a number")
    v = float(value) if abs(value) < 1e308 or isinstance(value, float) else math.inf
    if not math.isfinite(v):
        raise InvalidInputError(f"{where}: {label} = {short(value)} must be finite")
    if abs(v) > MAX_NUMBER:
        raise InvalidInputError(f"{where}: {label} = {short(value)} is beyond +-{MAX_NUMBER:g}; the files hold SI "
                                "values (m, s, rad, N, kg): give a physical one")
    if low is not None and (v <= low if low_open else v < low):
        raise InvalidInputError(f"{where}: {label} = {short(value)} must be {'>' if low_open else '>='} {low:g}")
    if high is not None and (v >= high if high_open else v > high):
        raise InvalidInputError(f"{where}: {label} = {short(value)} must be {'<' if high_open else '<='} {high:g}")
    return v


def integer(data: Mapping, key: str, where: str, default=MISSING, *, place: str = "top level",
            low: int | None = None, high: int | None = None) -> int:
    """The integer ``data[key]`` (a TOML integer, not a bool or float), within ``[low, high]``."""
    if _absent(data, key, where, default, place):
        return default
    value = data[key]
    label = _name(key, place)
    if isinstance(value, bool) or not isinstance(value, int):
        raise InvalidInputError(f"{where}: {label} = {short(value)} must be an integer")
    if (low is not None and value < low) or (high is not None and value > high):
        lo = "" if low is None else f">= {low}"
        hi = "" if high is None else f"<= {high}"
        raise InvalidInputError(f"{where}: {label} = {short(value)} must be {' and '.join(s for s in (lo, hi) if s)}")
    return value


def vector(data: Mapping, key: str, n: int, where: str, default=MISSING, *,
           place: str = "top level") -> tuple[float, ...]:
    """The list of ``n`` finite numbers ``data[key]``, as a tuple of floats."""
    if _absent(data, key, where, default, place):
        return tuple(default)
    value = data[key]
    label = _name(key, place)
    if not isinstance(value, (list, tuple)) or len(value) != n:
        raise InvalidInputError(f"{where}: {label} = {short(value)} must be a list of {n} numbers")
    return tuple(number({key: v}, key, where, place=place) for v in value)


def flag(data: Mapping, key: str, where: str, default=MISSING, *, place: str = "top level") -> bool:
    """The boolean ``data[key]`` (``true``/``false``; numbers and strings are refused)."""
    if _absent(data, key, where, default, place):
        return default
    value = data[key]
    if not isinstance(value, bool):
        raise InvalidInputError(f"{where}: {_name(key, place)} = {short(value)} must be true or false")
    return value


def text(data: Mapping, key: str, where: str, default=MISSING, *, place: str = "top level",
         choices: Iterable[str] | None = None) -> str:
    """The string ``data[key]``, one of ``choices`` when given (the nearest is named)."""
    if _absent(data, key, where, default, place):
        return default
    value = data[key]
    label = _name(key, place)
    if not isinstance(value, str):
        raise InvalidInputError(f"{where}: {label} = {short(value)} must be a string")
    if choices is not None:
        choices = tuple(choices)
        if value not in choices:
            raise InvalidInputError(
                f"{where}: {label} = {short(value)} is not one of {', '.join(choices)}{nearest(value, choices)}"
            )
    return value


def check_within_run(where: str, key: str, value: float, duration_s: float, last_sample_s: float,
                     consequence: str) -> None:
    """Refuse a time ``value`` (a metrics window's start, a designed switch) that no sample of
    the run reaches: it must be ``< duration_s`` and at most ``last_sample_s``; ``consequence``
    says what would happen otherwise (every error reading 0 or null, a switch never made)."""
    if not (value < duration_s and value <= last_sample_s):
        raise InvalidInputError(
            f"{where}: {key} = {value!r} must be < duration_s = {duration_s!r} and at most the last sample "
            f"time {last_sample_s:g} s; else {consequence}")


def _env_budget(name: str, unit: str) -> float | None:
    """The positive number the environment variable ``name`` gives (None when unset or
    empty); anything else is one line naming it."""
    env = os.environ.get(name, "").strip()
    if not env:
        return None
    try:
        value = float(env)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise InvalidInputError(f"{name}={env!r} must be a positive number of {unit}; set it so "
                                f"(e.g. {name}=8e9 or 3600) or unset it for the default")
    return value


def memory_budget_bytes() -> float:
    """Half of this machine's physical memory (``QUATFORM_MAX_MEMORY_BYTES`` overrides it)."""
    env = _env_budget("QUATFORM_MAX_MEMORY_BYTES", "bytes")
    if env is not None:
        return env
    try:
        return 0.5 * os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):  # pragma: no cover - non-POSIX
        return 4e9


def time_budget_s() -> float:
    """The longest run accepted, in wall seconds: 6 h (``QUATFORM_MAX_WORK_S`` overrides it)."""
    env = _env_budget("QUATFORM_MAX_WORK_S", "seconds")
    return 6 * 3600.0 if env is None else env


def check_work(where: str, key: str, steps: float, *, bytes_per_step: float = 0.0,
               seconds_per_step: float = 0.0, fix: str = "") -> None:
    """Refuse work whose up-front estimate exceeds this machine's memory or the time budget.

    Parameters
    ----------
    where : str
        The file or scenario quoted at the start of the message.
    key : str
        The key(s) that set the amount of work (e.g. ``"duration_s / dt_s"``).
    steps : float
        Number of steps (samples, knots, ...) the work needs; may be huge or infinite.
    bytes_per_step, seconds_per_step : float
        Memory kept and wall time spent per step (generous estimates of the hot path).
    fix : str
        What to change, appended to the message.
    """
    if not math.isfinite(steps) or steps < 0:
        raise ResourceLimitError(f"{where}: {key} gives {short(steps)} steps; choose finite, positive values")
    mem, secs = steps * bytes_per_step, steps * seconds_per_step
    mem_cap, time_cap = memory_budget_bytes(), time_budget_s()
    tail = f"; {fix}" if fix else ""
    if mem > mem_cap:
        raise ResourceLimitError(
            f"{where}: {key} needs {steps:.3g} steps, about {mem / 1e9:.3g} GB of memory, more than the "
            f"{mem_cap / 1e9:.3g} GB this machine allows (QUATFORM_MAX_MEMORY_BYTES){tail}"
        )
    if secs > time_cap:
        raise ResourceLimitError(
            f"{where}: {key} needs {steps:.3g} steps, about {secs / 3600:.3g} h of computing, more than the "
            f"{time_cap / 3600:.3g} h limit (QUATFORM_MAX_WORK_S){tail}"
        )
