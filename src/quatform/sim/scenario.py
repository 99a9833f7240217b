"""Scenarios: plain TOML files that state a motion, the robots, the gains and the run.

Sim layer. Built-in scenarios live in ``quatform/scenarios/*.toml``; a user's own file is
passed by path. See ``docs/scenarios.md`` for the keys.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._toml import builtin_files, read_toml
from ..control import CONTROLLERS, TABLE1, TABLE2
from ..errors import InvalidInputError
from ..formations import EUCLIDEAN_VARIABLES
from ..references import EuclideanPath, Ramp, Step
from ..robots import HolonomicRobot, Team

__all__ = ["Scenario", "load_scenario", "builtin_scenarios"]

_TABLES = {"table1": TABLE1, "table2": TABLE2}
_NAMES = [v.name for v in EUCLIDEAN_VARIABLES]


@dataclass(frozen=True)
class Scenario:
    """A run's definition (see ``docs/scenarios.md``)."""

    name: str
    path: EuclideanPath
    duration_s: float
    dt_s: float = 0.01
    title: str = ""
    source: str = ""
    team: Team = Team()
    initial_offset: np.ndarray = field(default_factory=lambda: np.zeros(8))
    gains: dict = field(default_factory=lambda: TABLE1)
    metrics_from_s: float = 5.0

    @property
    def times(self) -> np.ndarray:
        n = int(round(self.duration_s / self.dt_s))
        return np.arange(n + 1) * self.dt_s

    def controller(self, name: str, feedforward: bool = True):
        """The controller ``name`` with this scenario's gains and robots."""
        if name not in CONTROLLERS:
            raise InvalidInputError(f"unknown controller {name!r}; choose one of {', '.join(CONTROLLERS)}")
        return CONTROLLERS[name](**self.gains.get(name, {}), team=self.team, feedforward=feedforward)


def builtin_scenarios() -> dict[str, Path]:
    """Built-in scenario files by name."""
    return builtin_files("scenarios")


def _get(d, key, kind, where, default=None):
    if key not in d:
        if default is None:
            raise InvalidInputError(f"{where}: missing key {key!r}")
        return default
    v = d[key]
    try:
        if kind is float:
            v = float(v)
            if not np.isfinite(v):
                raise ValueError
        elif kind == "vec3":
            v = np.asarray(v, dtype=float)
            if v.shape != (3,) or not np.all(np.isfinite(v)):
                raise ValueError
    except (TypeError, ValueError):
        raise InvalidInputError(f"{where}: {key} = {d[key]!r} is not a valid {getattr(kind, '__name__', kind)}") from None
    return v


def load_scenario(name_or_file: str | Path) -> Scenario:
    """Load a built-in scenario by name or a TOML file by path.

    Returns a :class:`Scenario` (two 4-DOF robots, seed 000), for ``kind = "ugv-uav"`` a
    :class:`~quatform.sim.ugv_uav.UgvUavScenario` (seed 001), for ``kind = "teleop"`` a
    :class:`~quatform.sim.teleop.TeleopScenario` (seed 003).
    """
    data, p = read_toml(name_or_file, builtin_scenarios(), "scenario")
    if data.get("kind", "pair") == "ugv-uav":
        from .ugv_uav import ugv_uav_scenario_from_dict

        return ugv_uav_scenario_from_dict(data, where=str(p))
    if data.get("kind", "pair") == "teleop":
        from .teleop import teleop_scenario_from_dict

        return teleop_scenario_from_dict(data, where=str(p))
    if data.get("kind", "pair") != "pair":
        raise InvalidInputError(f"{p}: kind = {data['kind']!r}; use 'pair' (seed 000), 'ugv-uav' (seed 001) "
                                "or 'teleop' (seed 003)")
    return scenario_from_dict(data, where=str(p))


def scenario_from_dict(data: dict, where: str = "scenario") -> Scenario:
    """Build a :class:`Scenario` from parsed TOML; every mistake is an InvalidInputError."""
    try:
        sc = _scenario_from_dict(data, where)
        for name in CONTROLLERS:  # the gains must make a controller
            sc.controller(name)
    except KeyError as exc:
        raise InvalidInputError(f"{where}: missing key {exc} (see docs/scenarios.md)") from None
    except TypeError as exc:
        raise InvalidInputError(f"{where}: {exc} (see docs/scenarios.md for the keys)") from None
    except ValueError as exc:
        if isinstance(exc, InvalidInputError):
            raise
        raise InvalidInputError(f"{where}: {exc} (numbers expected; see docs/scenarios.md)") from None
    return sc


def _scenario_from_dict(data: dict, where: str) -> Scenario:
    pdata = data.get("path")
    if not isinstance(pdata, dict):
        raise InvalidInputError(f"{where}: missing [path] table")
    wp = f"{where} [path]"
    initial = np.zeros(8)
    for i, n in enumerate(_NAMES[3:], start=3):
        initial[i] = _get(pdata, n, float, wp, default=1.0 if n == "d_c" else 0.0)
    ramps = tuple(Ramp(r["variable"], float(r["start_s"]), float(r["duration_s"]), float(r["change"]))
                  for r in pdata.get("ramps", []))
    steps = tuple(Step(s["variable"], float(s["time_s"]), float(s["change"])) for s in pdata.get("steps", []))
    path = EuclideanPath(
        initial=initial,
        centroid=pdata.get("centroid", "fixed"),
        center=_get(pdata, "center", "vec3", wp, default=np.zeros(3)),
        velocity=_get(pdata, "velocity", "vec3", wp, default=np.zeros(3)),
        radius=_get(pdata, "radius", float, wp, default=0.0),
        period_s=_get(pdata, "period_s", float, wp, default=1.0),
        climb_m_s=_get(pdata, "climb_m_s", float, wp, default=0.0),
        ramps=ramps,
        steps=steps,
    )
    offset = np.array([float(data.get("initial_offset", {}).get(n, 0.0)) for n in _NAMES])
    rb = data.get("robots", {})
    robot = HolonomicRobot(max_speed=float(rb.get("max_speed_m_s", 2.5)),
                           max_yaw_rate=float(rb.get("max_yaw_rate_rad_s", 3.0)))
    g = data.get("gains", "table1")
    if isinstance(g, str):
        if g not in _TABLES:
            raise InvalidInputError(f"{where}: gains = {g!r}; use 'table1', 'table2' or a [gains] table")
        gains = _TABLES[g]
    else:
        if g.get("base", "table1") not in _TABLES:
            raise InvalidInputError(f"{where}: [gains] base = {g['base']!r}; use 'table1' or 'table2'")
        base = _TABLES[g.get("base", "table1")]
        gains = {k: dict(base.get(k, {}), **{kk: vv for kk, vv in g.get(k, {}).items()}) for k in CONTROLLERS}
    duration = _get(data, "duration_s", float, where)
    dt = _get(data, "dt_s", float, where, default=0.01)
    if not (duration > 0 and 0 < dt <= duration):
        raise InvalidInputError(f"{where}: need duration_s > 0 and 0 < dt_s <= duration_s")
    return Scenario(
        name=str(data.get("name", Path(where).stem)),
        title=str(data.get("title", "")),
        source=str(data.get("source", "")),
        path=path,
        duration_s=duration,
        dt_s=dt,
        team=Team((robot, robot)),
        initial_offset=offset,
        gains=gains,
        metrics_from_s=_get(data, "metrics_from_s", float, where, default=5.0),
    )
