"""Seed 000's two-robot scenario files, read into the team kind in seed 000's variables.

Scenarios layer (above sim, below report and runs). A seed-000 file (no ``kind`` key, or
``kind = "pair"``) states a motion in seed 000's Euclidean cluster variables, the robots, the
gains and the run (``docs/scenarios.md``); :func:`scenario_from_dict` reads it into a
:class:`Scenario`, a :class:`~quatform.scenarios.team.TeamScenario` of two ``xyz_yaw``
holonomic robots whose motion (:class:`PairMotion`) is the Euclidean path and whose initial
offset is in Euclidean variables. Every key is read with the shared typed readers of
:mod:`quatform.checks`: an unknown key names the nearest valid one, a wrong type, NaN,
infinity or an out-of-range number is refused naming the key, and a run too long for this
machine is refused before it starts (:func:`check_scenario_work`).

:class:`~quatform.scenarios.team.TeamKind` runs it; :class:`PairChartParts` are the steps of
its run that seed 000's chart decides (registered in
:data:`~quatform.scenarios.team.TEAM_CHARTS` as ``"pair"``): the four seed-000 controllers
(:data:`~quatform.control.CONTROLLERS`, whose descriptions are the pair presets), the start
and the desired robots from the Euclidean variables, the two IRIS quadrotors of MuJoCo
physics, the derived channels (``euclid_*``), the CSV channels and the table's columns.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..checks import check_keys, check_within_run, check_work, flag, number, records, short, table, text, vector
from ..control import CONTROLLERS, TABLE1, TABLE2
from ..errors import InvalidInputError
from ..formations import EUCLIDEAN_VARIABLES, EuclideanPair, RobotSpace, segment_direction
from ..formations import geometry as g
from ..references import EuclideanPath, Ramp, Step as StepChange
from ..robots import HolonomicRobot, Team
from ..sim.log import Channel, Log
from ..sim.metrics import EUCLIDEAN_CHART
from .separation import DEFAULT_MIN_SEPARATION_M, SAFETY_KEYS, safety_table
from .team import TEAM, TeamChartParts, TeamScenario, check_step_stable

__all__ = ["Scenario", "scenario_from_dict", "check_scenario_work", "check_barrier_reference",
           "DEFAULT_MIN_SEPARATION_M", "BYTES_PER_STEP",
           "SECONDS_PER_STEP", "PairMotion", "PairChartParts", "TABLE_COLUMNS", "run_pair", "simulate_physics",
           "with_plan", "PAIR_CSV_CHANNELS", "pair_csv_channels", "PLAN_RUN_BYTES_PER_STEP",
           "PLAN_RUN_SECONDS_PER_STEP"]

_TABLES = {"table1": TABLE1, "table2": TABLE2}
_NAMES = [v.name for v in EUCLIDEAN_VARIABLES]
_HINT = "see docs/scenarios.md"

#: Memory one logged step of a two-robot run may take, bytes: the log's arrays, the loop's
#: per-step Python lists, the references and the time-series CSV. Measured peak (tracemalloc,
#: spiral, 2001 steps): 1.4-4.6 kB per step, the quaternion controller the most; 12 kB is
#: about 2.6 times that (docs/derivations.md, "Two-robot scenarios (seed 000 §4)").
BYTES_PER_STEP = 12e3
#: Wall time one step may take, s: measured 0.19-0.46 ms per step of the loop (the
#: cluster-space controller the slowest) on this project's 2-core machine; 2 ms covers the
#: metrics, the CSV and a loaded machine (about 4 times the slowest).
SECONDS_PER_STEP = 2e-3

#: Keys of each table of a two-robot scenario file.
_TOP_KEYS = ("kind", "name", "title", "source", "duration_s", "dt_s", "metrics_from_s", "gains", "feedforward",
             "robots", "path", "initial_offset", "safety")
_ROBOT_KEYS = ("max_speed_m_s", "max_yaw_rate_rad_s")
_PATH_KEYS = ("centroid", "center", "velocity", "radius", "period_s", "climb_m_s", *_NAMES[3:], "ramps", "steps")
_RAMP_KEYS = ("variable", "start_s", "duration_s", "change")
_STEP_KEYS = ("variable", "time_s", "change")
#: Gains each controller takes and their lengths (1: a scalar), seed 000 Tables 1-2.
_GAIN_KEYS = {
    "cluster-space": {"k": 8},
    "robot-space": {"k": 8},
    "quaternion": {"k_x": 3, "k_d": 1, "k_w": 3},
    "dual-quaternion": {"k_dw": 3},
}


def check_scenario_work(where: str, duration_s: float, dt_s: float) -> None:
    """Refuse a run of ``duration_s / dt_s`` steps that cannot fit in memory or the time budget.

    Raises :class:`~quatform.errors.ResourceLimitError` naming ``duration_s / dt_s`` and the
    limit (:func:`quatform.checks.check_work` with :data:`BYTES_PER_STEP` and
    :data:`SECONDS_PER_STEP`).
    """
    with np.errstate(over="ignore"):
        steps = float(duration_s) / float(dt_s) + 1.0 if dt_s > 0 else math.inf
    check_work(where, f"duration_s / dt_s = {duration_s:g} / {dt_s:g}", steps, bytes_per_step=BYTES_PER_STEP,
               seconds_per_step=SECONDS_PER_STEP, fix="shorten duration_s or raise dt_s")


def _check_window(where: str, metrics_from_s: float, duration_s: float, dt_s: float) -> None:
    """Refuse a metrics window that holds no sample (every max error would read 0, a failed
    run would look perfect): need ``0 <= metrics_from_s < duration_s`` and a sample after it."""
    number({"metrics_from_s": metrics_from_s}, "metrics_from_s", where, low=0.0)
    check_within_run(where, "metrics_from_s", metrics_from_s, duration_s,
                     _last_step(duration_s, dt_s) * dt_s,  # the last of Scenario.times
                     "no sample is measured and every error would read 0")


#: Slack, in steps, for a dt_s that divides duration_s up to rounding (0.3 / 0.1 = 2.9999...).
_STEP_SLACK = 1e-9


def _last_step(duration_s: float, dt_s: float) -> int:
    """Index of the last sample: the most whole steps of ``dt_s`` that fit in ``duration_s``
    (never past it; a ``dt_s`` that does not divide ``duration_s`` ends the run short)."""
    return int(math.floor(duration_s / dt_s + _STEP_SLACK))


@dataclass(frozen=True, eq=False, kw_only=True)
class Scenario(TeamScenario):
    """A seed-000 run's definition: a team scenario of two ``xyz_yaw`` robots whose motion is
    seed 000's Euclidean path (:class:`PairMotion`, chart ``"pair"``; ``docs/scenarios.md``).
    Its fields other than these are keywords, as :class:`~quatform.scenarios.team.TeamScenario`'s.

    Attributes
    ----------
    name : str
    path : EuclideanPath
        The desired motion in Euclidean cluster variables (any callable ``t -> (e, e_dot)``,
        e.g. a plan's :class:`~quatform.planning.PlanPairPath`).
    duration_s : float
        Length of the run, s (> 0).
    dt_s : float
        Control and integration step, s (``0 < dt_s <= duration_s`` and largest gain
        ``* dt_s < 2``, :func:`check_step_stable`).
    title, source : str
    team : Team
        The two robots.
    initial_offset : ndarray, shape (8,)
        The robots start at the reference at ``t = 0`` plus this (Euclidean variables).
    gains : dict
        Gains by controller name.
    metrics_from_s : float
        Max errors are taken from this time on (``0 <= metrics_from_s <=`` the last sample).
    feedforward : bool
        Whether the controllers feed the reference's rate forward (default of
        :meth:`controller` and :meth:`~quatform.scenarios.team.TeamKind.experiment`).
    safety : dict
        ``enabled`` (bool) and ``min_separation_m`` (m, > 0): the controller's commands pass
        through the separation barrier (:class:`~quatform.control.SeparationBarrier`), which
        holds the robots at least ``min_separation_m`` apart. Off unless the file has a
        ``[safety]`` table (the seed's runs show the robots' own paths, e.g. Fig. 4b's
        robot-space robots crossing); :func:`~quatform.scenarios.separation.separation_barrier` and ``docs/scenarios.md`` say
        which starts need it.

    Raises
    ------
    InvalidInputError
        For a non-finite or out-of-range number; :class:`~quatform.errors.ResourceLimitError`
        when ``duration_s / dt_s`` steps cannot fit in memory or the time budget.
    """

    path: EuclideanPath
    team: Team = Team()
    motion: PairMotion = field(default=None, init=False)
    initial_offset: np.ndarray = field(default_factory=lambda: np.zeros(8))
    gains: dict = field(default_factory=lambda: TABLE1)
    metrics_from_s: float = 5.0
    feedforward: bool = True
    safety: dict = field(default_factory=lambda: {"enabled": False, "min_separation_m": DEFAULT_MIN_SEPARATION_M})

    #: Seed 000's Euclidean variables (:data:`~quatform.scenarios.team.TEAM_CHARTS` ``"pair"``).
    chart = "pair"

    def __post_init__(self):
        where = f"scenario {self.name!r}"
        object.__setattr__(self, "safety", _safety(self.safety, where))
        for key in ("duration_s", "dt_s", "metrics_from_s"):  # finite real numbers (numpy scalars too)
            v = getattr(self, key)
            if isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers.Real) or not math.isfinite(v):
                raise InvalidInputError(f"{where}: {key} = {short(v)} must be a finite number")
            object.__setattr__(self, key, float(v))
        number({"duration_s": self.duration_s}, "duration_s", where, low=0.0, low_open=True)
        number({"dt_s": self.dt_s}, "dt_s", where, low=0.0, low_open=True, high=self.duration_s)
        check_scenario_work(where, self.duration_s, self.dt_s)
        _check_window(where, self.metrics_from_s, self.duration_s, self.dt_s)
        if not isinstance(self.gains, dict) or not all(isinstance(g, dict) for g in self.gains.values()):
            raise InvalidInputError(f"{where}: gains must map controller names to their gains, got {short(self.gains)}")
        check_step_stable(where, self.dt_s, self.gains)
        if not isinstance(self.feedforward, (bool, np.bool_)):
            raise InvalidInputError(f"{where}: feedforward = {short(self.feedforward)} must be True or False")
        if not callable(self.path):  # an EuclideanPath, or a plan's PlanPairPath: t -> (e, e_dot)
            raise InvalidInputError(f"{where}: path must map times to (e, e_dot), like an EuclideanPath; got "
                                    f"{type(self.path).__name__}")
        off = np.asarray(self.initial_offset, dtype=float)
        if off.shape != (8,) or not np.all(np.isfinite(off)):
            raise InvalidInputError(f"{where}: initial_offset must be 8 finite numbers, got {short(self.initial_offset)}")
        object.__setattr__(self, "initial_offset", off)
        if not isinstance(self.team, Team) or self.team.layout.kinds != ("xyz_yaw", "xyz_yaw"):
            raise InvalidInputError(f"{where}: team must be two xyz_yaw robots (a robots.Team), got {short(self.team)}")
        object.__setattr__(self, "motion", PairMotion(self.path, self.team.layout))
        super().__post_init__()

    def controller(self, name: str, feedforward: bool | None = None):
        """The controller ``name`` with this scenario's gains and robots; ``feedforward``
        defaults to the scenario's."""
        if name not in CONTROLLERS:
            raise InvalidInputError(f"unknown controller {name!r}; choose one of {', '.join(CONTROLLERS)}")
        ff = self.feedforward if feedforward is None else feedforward
        return CONTROLLERS[name](**self.gains.get(name, {}), team=self.team, feedforward=bool(ff))


def scenario_from_dict(data: dict, where: str = "scenario") -> Scenario:
    """Build a :class:`Scenario` from parsed TOML; every mistake is one InvalidInputError line
    naming the key (see ``docs/scenarios.md``)."""
    check_keys(data, _TOP_KEYS, where, hint=_HINT)
    text(data, "kind", where, "pair", choices=("pair",))
    duration = number(data, "duration_s", where, low=0.0, low_open=True)
    dt = number(data, "dt_s", where, 0.01, low=0.0, low_open=True, high=duration)
    check_scenario_work(where, duration, dt)  # before anything is sampled
    # default 5 s (seed 000's transient); a run of 5 s or less is measured from its start
    metrics_from = number(data, "metrics_from_s", where, 5.0 if duration > 5.0 else 0.0, low=0.0)
    _check_window(where, metrics_from, duration, dt)
    try:
        path = _path(table(data, "path", where), where, duration)
        robots = table(data, "robots", where, default={})
        check_keys(robots, _ROBOT_KEYS, where, "[robots]", _HINT)
        robot = HolonomicRobot(
            max_speed=number(robots, "max_speed_m_s", where, 2.5, place="[robots]", low=0.0, low_open=True),
            max_yaw_rate=number(robots, "max_yaw_rate_rad_s", where, 3.0, place="[robots]", low=0.0,
                                low_open=True))
        off = table(data, "initial_offset", where, default={})
        check_keys(off, _NAMES, where, "[initial_offset]", _HINT)
        offset = np.array([number(off, n, where, 0.0, place="[initial_offset]") for n in _NAMES])
        gains = _gains(data, where)
        check_step_stable(where, dt, gains)
        safety = safety_table(data, where, _HINT, enabled_without_table=False)  # off without a [safety] table
        sc = Scenario(
            name=text(data, "name", where, Path(where).stem),
            title=text(data, "title", where, ""),
            source=text(data, "source", where, ""),
            path=path,
            duration_s=duration,
            dt_s=dt,
            team=Team((robot, robot)),
            initial_offset=offset,
            gains=gains,
            metrics_from_s=metrics_from,
            feedforward=flag(data, "feedforward", where, True),
            safety=safety,
        )
        d0 = float(path(0.0)[0][5] + offset[5])
        if not d0 > 0:
            raise InvalidInputError(f"{where}: [path] d_c + [initial_offset] d_c = {d0:g} m at t = 0; the robots "
                                    "would start on top of each other: make it > 0")
        if safety["enabled"]:
            check_barrier_reference(sc, safety["min_separation_m"], where, "[safety] min_separation_m")
        for name in CONTROLLERS:  # the gains must make a controller
            sc.controller(name)
    except InvalidInputError as exc:
        msg = str(exc)
        raise type(exc)(msg if msg.startswith(where) else f"{where}: {msg}") from None
    return sc


def _safety(value, where: str) -> dict:
    """A :attr:`Scenario.safety` checked: ``{"enabled": bool, "min_separation_m": float > 0}``."""
    if not isinstance(value, dict):
        raise InvalidInputError(f"{where}: safety must be a dict with keys enabled and min_separation_m, got "
                                f"{short(value)}")
    check_keys(value, SAFETY_KEYS, where, "safety", _HINT)
    enabled = value.get("enabled", False)
    if not isinstance(enabled, (bool, np.bool_)):
        raise InvalidInputError(f"{where}: safety enabled = {short(enabled)} must be True or False")
    d = number(value, "min_separation_m", where, DEFAULT_MIN_SEPARATION_M, place="safety", low=0.0, low_open=True)
    return {"enabled": bool(enabled), "min_separation_m": d}


#: Samples of the reference the barrier's reference check reads (at most; evenly spaced).
_BARRIER_CHECK_SAMPLES = 2000


def check_barrier_reference(sc: Scenario, d: float, where: str, label: str, e_des=None, t=None,
                            start: bool = True) -> None:
    """Refuse a barrier of ``d`` m the run cannot keep: the robots start closer than ``d``
    (``start``: the scenario's own start, the reference at ``t = 0`` plus ``initial_offset``),
    or the reference brings them closer (``2 d_c < d``: the barrier would hold them apart and
    the formation could not be tracked). ``e_des`` (sampled at ``t``) if the caller has it,
    else the scenario's path at most every 1/2000 of the run; ``label`` names the setting."""
    if t is None:
        t = sc.times
        t = t[::max(1, len(t) // _BARRIER_CHECK_SAMPLES)]
        e_des = sc.path(t)[0]
    d0 = 2.0 * float(e_des[0][5] + sc.initial_offset[5])  # seed 000 eq. (6): the robots 2 d_c apart
    if start and d0 < d:
        raise InvalidInputError(f"{where}: the robots start {d0:.4g} m apart (2 x ([path] d_c + [initial_offset] "
                                f"d_c)), closer than {label} = {d:g} m; start them farther apart or lower it")
    sep = 2.0 * np.asarray(e_des)[..., 5]
    k = int(np.argmin(sep))
    if sep[k] < d:
        raise InvalidInputError(f"{where}: the reference brings the robots to {sep[k]:.4g} m at t = {t[k]:g} s, below "
                                f"{label} = {d:g} m (the barrier would hold them apart); raise d_c or lower it")


#: Keys of ``[path]`` that only one centroid kind uses (seed 000 §4: the circle of §4.1, the
#: line of §4.2); the other kinds would silently ignore them.
_CENTROID_ONLY = {"radius": "circle", "period_s": "circle", "climb_m_s": "circle", "velocity": "line"}


def _path(p: dict, where: str, duration: float) -> EuclideanPath:
    """The ``[path]`` table of the file ``where``, for a run of ``duration`` s."""
    check_keys(p, _PATH_KEYS, where, "[path]", _HINT)
    at = {"place": "[path]"}
    centroid = text(p, "centroid", where, "fixed", **at, choices=("circle", "line", "fixed"))
    for key, kind in _CENTROID_ONLY.items():
        if key in p and centroid != kind:
            raise InvalidInputError(f"{where}: [path] {key} applies to centroid = {kind!r} only, not {centroid!r}: "
                                    f"remove it or set centroid = {kind!r}")
    initial = np.zeros(8)
    for i, n in enumerate(_NAMES[3:], start=3):
        kw = {"low": 0.0, "low_open": True} if n == "d_c" else {}
        initial[i] = number(p, n, where, 1.0 if n == "d_c" else 0.0, **at, **kw)
    circle = {}
    if centroid == "circle":  # seed 000 §4.1: the centroid on a circle of radius r, one lap per period
        for key in ("radius", "period_s"):  # both checked before a missing one is named
            circle[key] = number(p, key, where, None, **at, low=0.0, low_open=True)
        for key, what in (("radius", "the circle's radius, m"), ("period_s", "the time of one lap, s")):
            if circle[key] is None:
                raise InvalidInputError(f"{where}: [path] centroid = 'circle' needs {key} ({what}, > 0); add it "
                                        "to [path] or use centroid = 'fixed'")
    ramps = tuple(Ramp(text(r, "variable", w, choices=_NAMES), _time(r, "start_s", w, duration),
                       number(r, "duration_s", w, low=0.0, low_open=True), number(r, "change", w))
                  for r, w in records(p, "ramps", _RAMP_KEYS, where, "path.ramps", _HINT))
    steps = tuple(StepChange(text(s, "variable", w, choices=_NAMES), _time(s, "time_s", w, duration),
                       number(s, "change", w))
                  for s, w in records(p, "steps", _STEP_KEYS, where, "path.steps", _HINT))
    path = EuclideanPath(
        initial=initial,
        centroid=centroid,
        center=vector(p, "center", 3, where, (0.0, 0.0, 0.0), **at),
        velocity=vector(p, "velocity", 3, where, (0.0, 0.0, 0.0), **at),
        radius=circle.get("radius", 0.0),
        period_s=circle.get("period_s", 1.0),
        climb_m_s=number(p, "climb_m_s", where, 0.0, **at),
        ramps=ramps,
        steps=steps,
    )
    _check_separation(path, where, duration)
    return path


def _time(r: dict, key: str, where: str, duration: float) -> float:
    """A ramp's start or a step's time ``r[key]``, within the run ``[0, duration]`` s (a ramp
    may run past the end: the run shows the part of it that falls inside)."""
    t = number(r, key, where)
    if not 0.0 <= t <= duration:
        raise InvalidInputError(f"{where}: {key} = {short(r[key])} s is outside the run [0, duration_s = "
                                f"{duration:g} s]; the change would not happen in it: move it into the run or "
                                "lengthen duration_s")
    return t


def _check_separation(path: EuclideanPath, where: str, duration: float) -> None:
    """Refuse a path whose ``d_c`` reaches 0 in ``[0, duration]``, naming the ramp or step that
    brings it there. ``d_c`` (entry 5) is ``[path] d_c`` plus the d_c ramps and steps, piecewise
    linear in t, so its least value lies at 0, ``duration`` or a ramp's or step's time."""
    changes = [(f"[[path.ramps]] #{i + 1}", r) for i, r in enumerate(path.ramps)] + \
              [(f"[[path.steps]] #{i + 1}", s) for i, s in enumerate(path.steps)]
    changes = [(name, c) for name, c in changes if c.variable == "d_c"]
    if not changes:
        return
    times = {0.0, duration}
    for _, c in changes:
        times.update((c.start_s, min(c.start_s + c.duration_s, duration)) if isinstance(c, Ramp) else (c.time_s,))
    times = np.array(sorted(times))
    ramps = path.initial[5] + sum(c.value_rate(times)[0] for _, c in changes if isinstance(c, Ramp))
    steps = [c for _, c in changes if isinstance(c, StepChange)]
    right = ramps + sum(np.where(times >= c.time_s, c.change, 0.0) for c in steps)  # d_c(t)
    left = ramps + sum(np.where(times > c.time_s, c.change, 0.0) for c in steps)  # d_c(t-), before a step
    bad = np.flatnonzero(np.minimum(left, right) <= 0.0)
    if bad.size == 0:
        return
    k = bad[0]
    t, by_step = float(times[k]), bool(left[k] > 0.0)  # reached 0 by a jump at t, else by a ramp up to t
    for name, c in changes:  # the step at t, else the ramp running up to t, that lowers d_c
        if by_step and isinstance(c, StepChange) and c.time_s == t and c.change < 0:
            label = f"{name} (d_c at {t:g} s, change = {c.change:g})"
            break
        if not by_step and isinstance(c, Ramp) and c.start_s < t <= c.start_s + c.duration_s and c.change < 0:
            label = f"{name} (d_c from {c.start_s:g} s for {c.duration_s:g} s, change = {c.change:g})"
            break
    else:  # pragma: no cover - d_c > 0 at t = 0, so some change lowered it
        label = "the d_c ramps and steps"
    d = float(min(left[k], right[k]))
    raise InvalidInputError(
        f"{where}: {label} makes d_c <= 0 ({d:.3g} m at t = {t:g} s): the robots would meet; "
        f"make the change smaller in size or raise [path] d_c = {path.initial[5]:g} m")


def _gains(data: dict, where: str) -> dict:
    """``gains = "table1" | "table2"`` or a ``[gains]`` table (``base`` and per-controller tables)."""
    g = data.get("gains", "table1")
    if isinstance(g, str):
        return _TABLES[text(data, "gains", where, "table1", choices=tuple(_TABLES))]
    if not isinstance(g, dict):
        raise InvalidInputError(f"{where}: gains = {short(g)} must be 'table1', 'table2' or a [gains] table")
    check_keys(g, ("base", *CONTROLLERS), where, "[gains]", _HINT)
    base = _TABLES[text(g, "base", where, "table1", place="[gains]", choices=tuple(_TABLES))]
    gains = {}
    for name, shapes in _GAIN_KEYS.items():
        place = f"[gains.{name}]"
        own = table(g, name, where, "[gains]", default={})
        check_keys(own, shapes, where, place, _HINT)
        gains[name] = dict(base.get(name, {}))
        for key, n in shapes.items():
            if key in own:
                gains[name][key] = _gain(own, key, n, where, place)
    return gains


def _gain(d: dict, key: str, n: int, where: str, place: str):
    """A positive gain: a number, or for ``n > 1`` also a list of ``n`` numbers."""
    v = d[key]
    if n > 1 and isinstance(v, list):
        vals = list(vector(d, key, n, where, place=place))
    else:
        if isinstance(v, list):
            raise InvalidInputError(f"{where}: {place} {key} = {short(v)} must be one number")
        vals = [number(d, key, where, place=place)]
    for x in vals:
        if not x > 0:
            raise InvalidInputError(f"{where}: {place} {key} = {short(v)} must be positive (seed 000 Tables 1-2)")
    return vals if n > 1 and isinstance(v, list) else vals[0]


# --------------------------------------------------------------------------- the chart

#: Columns of the comparison table: (metrics key, header, format).
TABLE_COLUMNS = (
    ("controller", "controller", "{}"),
    ("first_singular_time_s", "singular at (s)", "{:.2f}"),
    ("reference_lost", "lost", "{}"),
    ("max_cluster_position_error_m", "cluster pos (m)", "{:.4f}"),
    ("max_shape_error_m", "shape (m)", "{:.4f}"),
    ("max_orientation_error_rad", "orient (rad)", "{:.4f}"),
    ("max_robot_position_error_m", "robot pos (m)", "{:.4f}"),
    ("max_recovered_euclidean_error_rad", "recovered (rad)", "{:.3f}"),
    ("min_robot_separation_m", "min sep (m)", "{:.3f}"),
    ("nonfinite_commands", "NaN cmds", "{}"),
)

#: Channels of ``timeseries.csv`` in file order; a tuple's channels are interleaved, each value
#: beside its desired one (``x1, x1_des, y1, ...``: the recorded header): the robots, the
#: controller's own cluster variables, the Euclidean ones recovered by its description, then
#: the commands and the singularity measure.
PAIR_CSV_CHANNELS = (("state", "r_des"), ("cluster", "c_des"), ("e", "e_des"), "command", "singularity")


def pair_csv_channels(formation) -> tuple:
    """:data:`PAIR_CSV_CHANNELS` of a run of ``formation`` (a description): one whose cluster
    state is the robot state (:attr:`~quatform.formations.Formation.cluster_is_robot_state`,
    robot space) leaves its cluster variables out."""
    return tuple(c for c in PAIR_CSV_CHANNELS
                 if not (formation.cluster_is_robot_state and c == ("cluster", "c_des")))


#: Generous cost of one step of a run that follows a plan (time series kept, controller and
#: simulator), checked before the plan's path is built: seed 000's helix runs 8000 steps in
#: 0.8 s (docs/performance.md).
PLAN_RUN_BYTES_PER_STEP, PLAN_RUN_SECONDS_PER_STEP = 1024.0, 2e-4


def with_plan(sc: Scenario, plan_file, yaws=(0.0, 0.0)) -> Scenario:
    """Scenario ``sc`` with its path replaced by the saved two-robot spatial plan ``plan_file``.

    The plan's robot positions become the Euclidean cluster reference
    (:class:`~quatform.planning.PlanPairPath`, constant yaws ``yaws``, seed 002 §4); the run
    lasts the plan's duration; ``metrics_from_s`` is kept if it lies inside it, else 0.
    """
    from ..planning import PlanPairPath, load_plan

    plan = load_plan(plan_file)
    T = plan.duration_s
    # the run steps the plan's whole duration at the scenario's dt_s: estimate it before the
    # reference path is built (a plan lasting 1e9 s would otherwise run for days)
    check_work(str(plan_file), f"the plan's duration ({T:.6g} s) / the scenario's dt_s ({sc.dt_s:g} s)",
               T / sc.dt_s, bytes_per_step=PLAN_RUN_BYTES_PER_STEP, seconds_per_step=PLAN_RUN_SECONDS_PER_STEP,
               fix="plan a shorter motion (duration_s of the plan spec)")
    return dataclasses.replace(sc, path=PlanPairPath(plan, yaws), duration_s=T,
                               name=f"{sc.name}+{plan.info.get('name', 'plan')}",
                               metrics_from_s=sc.metrics_from_s if sc.metrics_from_s < T else 0.0)


@dataclass(frozen=True)
class PairMotion:
    """Seed 000's motion of two robots: ``t -> (e, e_dot)`` in the Euclidean cluster variables
    ``(x_c, y_c, z_c, beta_c, gamma_c, d_c, phi_1, phi_2)`` (seed 000 eqs. (1)-(8)).

    Attributes
    ----------
    path : callable
        An :class:`~quatform.references.EuclideanPath`, or a plan's
        :class:`~quatform.planning.PlanPairPath`.
    layout : RobotLayout
        The two ``xyz_yaw`` robots.
    """

    path: object
    layout: object

    def __call__(self, t):
        return self.path(t)


_EX, _EZ = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])


class PairChartParts(TeamChartParts):
    """The steps of a team run that seed 000's chart decides (:class:`~quatform.scenarios.team.TeamChartParts`)."""

    name = "pair"
    table_columns = TABLE_COLUMNS
    motion_types = (PairMotion,)

    def controllers(self) -> tuple:
        return tuple(CONTROLLERS)

    def physics_options(self, sc, physics: str, options: dict | None) -> dict:
        """``gains`` (of :func:`~quatform.sim.mujoco_backend.physics_controller`) and
        ``cascade_options`` (of :func:`~quatform.sim.plants.mujoco.pair_plant`), for
        ``physics="mujoco"`` only."""
        options = dict(options or {})
        check_keys(options, ("gains", "cascade_options"), f"scenario {sc.name!r}", "physics options",
                   "see quatform.sim.mujoco_backend.pair_plant")
        if options and physics != "mujoco":
            raise InvalidInputError(f"physics options {sorted(options)} apply to physics = 'mujoco' only")
        return options

    def with_plan(self, sc, plan_file):
        return with_plan(sc, plan_file)

    def check_work(self, sc) -> None:
        # up front, before the reference is sampled (its fields may have been swapped since)
        check_scenario_work(f"scenario {sc.name!r}", sc.duration_s, sc.dt_s)

    def check_barrier(self, sc, d: float, label: str, e_des, t, start: bool) -> None:
        check_barrier_reference(sc, d, f"scenario {sc.name!r}", label, e_des, t, start=start)

    def start(self, sc, e_des) -> np.ndarray:
        """The reference at ``t = 0`` displaced by ``initial_offset`` (Euclidean variables)."""
        return EuclideanPair().inverse(e_des[0] + sc.initial_offset)

    def robots(self, sc, e_des) -> np.ndarray:
        return RobotSpace().from_chart(e_des)

    def pose(self, e) -> tuple:
        """The pair's formation frame in seed 000's variables ``e`` (``(..., 8)``): the midpoint
        ``x_c`` and the minimal rotation from ``i`` to the segment from robot 2 to robot 1
        (eqs. (4)-(5) inverted, then eqs. (14)-(15)), the frame ``/formation/pose`` shows."""
        e = np.asarray(e, dtype=float)
        u = segment_direction(e[..., 3], e[..., 4])
        return e[..., 0:3], g.swing(np.broadcast_to(_EX, u.shape), u, _EZ)

    def posed(self, e, e_dot, p, q, v, w, near=None) -> tuple:
        """``(e, e_dot)`` with the pair's frame moved to ``(p, q)`` at ``(v, w)``: ``x_c = p``,
        ``(beta_c, gamma_c)`` the angles of the frame's x axis ``u`` (eqs. (4)-(5):
        ``(beta, asin u_z)`` or ``(beta + pi, pi - asin u_z)`` with ``beta = atan2(-u_x, u_y)``,
        whichever is nearer ``near``'s, so the reference stays continuous past the vertical)
        and their rates from ``u' = w x u``; ``d_c`` and the headings' offsets ``phi_i`` kept
        (the robots' yaws turn with ``beta_c``, as the chart states them). The twist of ``q``
        about ``u`` has no variable in this chart; at a vertical segment (``cos gamma_c = 0``,
        the chart's singular set) ``beta_c`` is held and the rates it cannot express are 0."""
        e, ed = np.array(e, dtype=float), np.array(e_dot, dtype=float)
        u = g.x_axis(q)
        ref = e if near is None else np.asarray(near, dtype=float)
        flat = u[..., 0] ** 2 + u[..., 1] ** 2 > 1e-24
        beta = np.where(flat, g.unwrap_near(np.arctan2(-u[..., 0], u[..., 1]), ref[..., 3]), ref[..., 3])
        gamma = g.unwrap_near(np.arcsin(np.clip(u[..., 2], -1.0, 1.0)), ref[..., 4])
        beta_b = g.unwrap_near(beta + np.pi, ref[..., 3])
        gamma_b = g.unwrap_near(np.pi - gamma, ref[..., 4])
        other = np.abs(beta_b - ref[..., 3]) + np.abs(gamma_b - ref[..., 4]) < \
            np.abs(beta - ref[..., 3]) + np.abs(gamma - ref[..., 4])
        beta, gamma = np.where(other & flat, beta_b, beta), np.where(other, gamma_b, gamma)
        ud = np.cross(w, u)
        cg = np.cos(gamma)
        e[..., 0:3], e[..., 3], e[..., 4] = p, beta, gamma
        ed[..., 0:3] = v
        h2 = np.where(flat, cg * cg, 1.0)
        ed[..., 3] = np.where(flat, (u[..., 0] * ud[..., 1] - u[..., 1] * ud[..., 0]) / h2, 0.0)
        ed[..., 4] = np.where(flat, ud[..., 2] / np.where(flat, cg, 1.0), 0.0)
        return e, ed

    def plant(self, sc, controller, feedforward, physics: str, x0, options: dict):
        """On ``physics="mujoco"`` two IRIS quadrotors (:func:`quatform.sim.plants.mujoco.pair_plant`),
        a controller given by name with the physics gains
        (:func:`~quatform.sim.mujoco_backend.physics_controller`)."""
        if physics != "mujoco":
            return super().plant(sc, controller, feedforward, physics, x0, options)
        from ..sim import mujoco_backend as mj  # MuJoCo only when asked for
        from ..sim.plants import mujoco as mjp

        ctrl, gains, source = mj.physics_controller(sc, controller, feedforward, options.get("gains"))
        plant = mjp.pair_plant(sc, x0, cascade_options=options.get("cascade_options"))

        def record(log: Log, c) -> dict:
            return {"physics_record": mjp.physics_record(plant, log, f"{sc.name}: {c.name} controller", gains, source)}

        def physics_metrics(log: Log) -> dict:
            return {**mjp.physics_metrics(plant), **log.meta["physics_record"].metrics()}

        return ctrl, plant, record, physics_metrics

    def meta(self, sc, ctrl, safety: dict) -> dict:
        return {"layout": ctrl.team.layout, "team": ctrl.team, "chart": EUCLIDEAN_CHART,
                **({"safety": safety} if safety["enabled"] else {})}

    def finisher(self, sc, ctrl, t, e_des, c_des, r_des, record):
        """``finish(log) -> log`` adding the desired robots and cluster variables, the Euclidean
        variables recovered by the controller's description (``euclid_*``), the desired ones and
        the singularity measure, on any leading batch axes."""
        F = ctrl.formation

        def finish(log: Log) -> Log:
            r, c = log["state"], log["cluster"]
            shape = r.shape[:-1]
            k = np.minimum(np.searchsorted(t, log.t), t.size - 1)  # the log's own ticks of the scenario's
            if not np.array_equal(t[k], log.t):
                raise InvalidInputError(f"scenario {sc.name!r}: the log's times are not the scenario's "
                                        f"ticks (dt_s = {sc.dt_s:g} s from 0 to {t[-1]:g} s)")
            ed, cd, rd = (np.broadcast_to(a[k].reshape((k.size,) + (1,) * (r.ndim - 2) + a.shape[1:]),
                                          shape + a.shape[1:]) for a in (e_des, c_des, r_des))
            held = ~np.all(np.isfinite(c), axis=-1)  # a failed world's samples (sim.simulate: signals NaN)
            if np.any(held):  # its held robots may coincide: read the reference there, then NaN
                c, r = np.where(held[..., None], cd, c), np.where(held[..., None], rd, r)
            e = F.to_chart(c, near_e=ed, r=r)
            sing = F.singularity_measure(r, near_c=cd)
            if np.any(held):
                e, sing = np.where(held[..., None], np.nan, e), np.where(held, np.nan, sing)
            names = [v.name for v in F.variables]
            euclid = ["euclid_" + v.name for v in EUCLIDEAN_VARIABLES]
            log = log.with_channels(
                Channel("r_des", tuple(n + "_des" for n in log.columns("state")), rd),
                Channel("c_des", tuple(n + "_des" for n in names), cd),
                Channel("e", tuple(euclid), e), Channel("e_des", tuple(n + "_des" for n in euclid), ed),
                Channel("singularity", ("singularity_measure",), np.asarray(sing)[..., None]))
            return log.with_channels(**({} if record is None else record(log, ctrl)))

        return finish

    def csv_channels(self, sc, ctrl) -> tuple:
        return pair_csv_channels(ctrl.formation)


def run_pair(scenario: Scenario, controller, feedforward: bool | None = None, r0=None,
             progress=None) -> Log:
    """The complete log of ``scenario`` run with ``controller`` on the kinematic robots
    (:meth:`~quatform.scenarios.team.TeamKind.experiment` then
    :meth:`~quatform.scenarios.base.Experiment.run`)."""
    return TEAM.experiment(scenario, controller=controller, feedforward=feedforward, r0=r0).run(progress)


def simulate_physics(scenario: Scenario, controller, feedforward: bool | None = None, progress=None,
                     cascade_options: dict | None = None, gains: dict | None = None):
    """A seed 000 scenario on two simulated IRIS quadrotors (MuJoCo): ``(log, PhysicsRecord)``.

    :meth:`~quatform.scenarios.team.TeamKind.experiment` with ``physics="mujoco"``; ``controller`` a name (its gains
    from :func:`~quatform.sim.mujoco_backend.physics_gains`, or ``gains``) or a controller
    object; ``feedforward`` ``None`` keeps the scenario's.
    """
    options = {k: v for k, v in (("cascade_options", cascade_options), ("gains", gains)) if v is not None}
    log = TEAM.experiment(scenario, controller=controller, feedforward=feedforward, physics="mujoco",
                          physics_options=options).run(progress)
    return log, log.meta["physics_record"]
