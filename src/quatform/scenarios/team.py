"""The team scenario kind: N robots of any mix in a formation that moves, turns and deforms.

Scenarios layer (above sim, below report and runs). A file with ``kind = "team"`` states the
robots (``[[robots]]`` groups: a model, a count, limits), the formation's shape (a template
times a scale, with keyframed slot changes), the path of its origin, its attitude and the
robots' headings, the gains of each controller (seed 000 Tables 1-2 for teams), the initial
offset, the safety barrier and the run (``docs/scenarios.md``). Every key is read with
:mod:`quatform.checks` (unknown keys name the nearest valid one, one line per bad value; the
run's memory and time are estimated up front).

:class:`TeamKind` builds the :class:`~quatform.scenarios.base.Experiment` of a scenario and a
controller (``quaternion``, ``dual-quaternion``, ``cluster-space``, ``robot-space``: the team
descriptions of :data:`quatform.control.TEAM_CONTROLLERS`): the kinematic plant of the team,
the controller (:func:`quatform.control.team_controller`), the reference ``Reference(c_des,
c_dot_des, r_des)`` with ``c_des, c_dot_des = formation.from_chart(e, e_dot)`` of the
motion's chart values (:class:`~quatform.references.team_motion.TeamMotion`, or a saved plan:
:class:`~quatform.references.team_motion.PlanMotion`), and ``finish`` adding the desired
robots, the chart recovered by the controller's description, the desired chart and the
singularity measure; the metrics are :func:`quatform.sim.metrics.compute_metrics`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..checks import (
    MISSING,
    check_keys,
    check_within_run,
    check_work,
    flag,
    integer,
    number,
    records,
    short,
    table,
    text,
    vector,
)
from ..control import TEAM_CONTROLLERS, Reference, team_controller
from ..control.team import check_gain, team_descriptions, team_gain_sizes
from ..control.safety import SafeController, start_floor
from ..errors import InvalidInputError
from ..formations import EuclideanTeam, RobotSpaceTeam, TeamChart
from ..formations import geometry as g
from ..formations.team_chart import ATTITUDE, CENTROID, check_template
from ..references.team_motion import (
    HEADING_MODES,
    PATH_KINDS,
    PROFILES,
    SCALE_KINDS,
    TEMPLATES,
    Attitude,
    Headings,
    Move,
    OriginPath,
    PlanMotion,
    Scale,
    TeamMotion,
    Turn,
    template_positions,
)
from ..registry import Registry, RegistryView
from ..robots import Team, file_models
from ..sim.log import Channel, Log
from ..sim.plants import KinematicTeam
from ..sim.metrics import TEAM_CHART, compute_metrics, min_separations
from . import KINDS
from .base import Experiment, Option, ScenarioKind, finish_worlds
from .separation import FILE_LABEL, safety_table, separation_barrier, with_option

__all__ = ["TeamScenario", "RobotGroupSpec", "TeamKind", "TEAM", "team_scenario_from_dict",
           "TEAM_TABLES", "TEAM_TABLE_COLUMNS", "TEAM_PHYSICS", "TEAM_BYTES_PER_ROBOT_STEP",
           "TEAM_SECONDS_PER_ROBOT_STEP", "check_team_work", "singularity_samples", "available_controllers",
           "with_plan", "TeamChartParts", "TEAM_CHARTS", "check_step_stable"]

_HINT = "see docs/scenarios.md, team scenarios"

#: Memory one logged step of one robot may take, bytes: the log's channels (state, measured,
#: command, cluster, error, the desired robots, the two charts: about 40 floats a robot), the
#: loop's lists and the CSV; about 3 times the measured peak.
TEAM_BYTES_PER_ROBOT_STEP = 2.5e3
#: Wall time one step of one robot may take, s (plus :data:`_SECONDS_PER_STEP` a step):
#: measured 3-10 us per robot-step at N = 100, 0.3-0.6 ms per step at N = 4.
TEAM_SECONDS_PER_ROBOT_STEP = 5e-5
_SECONDS_PER_STEP = 2e-3

def _tables() -> dict:
    """``{table: {controller: gains}}`` of the registered team descriptions' ``gain_tables``."""
    tables = {}
    for name, cls in team_descriptions().items():
        for key, gains in cls.gain_tables.items():
            tables.setdefault(key, {})[name] = gains
    return tables


#: Seed 000 Tables 1 and 2 for teams, by table and controller: each registered team
#: description's ``gain_tables`` (read-only; the keys each role reads are
#: ``control.TEAM_GAIN_KEYS``).
TEAM_TABLES = RegistryView(_tables, "TEAM_TABLES")

#: What moves the robots: their kinematic models, or MuJoCo physics (quadrotors and Pioneers,
#: :func:`quatform.sim.plants.mujoco_team.team_plant`).
TEAM_PHYSICS = ("kinematic", "mujoco")


def available_controllers() -> tuple[str, ...]:
    """The team controllers whose description is registered (``formations.TEAM_FORMATIONS``),
    in :data:`quatform.control.TEAM_CONTROLLERS` order: what ``--controller`` and ``compare`` offer."""
    return tuple(TEAM_CONTROLLERS)


# --------------------------------------------------------------------------- robot models

@dataclass(frozen=True)
class RobotGroupSpec:
    """One ``[[robots]]`` entry: ``count`` robots of one model with its limits."""

    model: str
    count: int
    robot: object


# --------------------------------------------------------------------------- the scenario

@dataclass(frozen=True, eq=False)
class TeamScenario:
    """A team run's definition (``docs/scenarios.md``, team scenarios).

    Attributes
    ----------
    name, title, source : str
    team : Team
        The robots, robot after robot.
    groups : tuple of RobotGroupSpec
        The ``[[robots]]`` entries the team was built from.
    motion : TeamMotion or PlanMotion
        ``t -> (e, e_dot)`` in the team chart of ``team.layout``.
    duration_s, dt_s, metrics_from_s : float
    gains : dict
        Gains by controller name (:data:`TEAM_TABLES` layout).
    feedforward : bool
    initial_offset : dict
        ``position`` (3, m, every robot), ``yaw`` (rad, every heading), ``scale`` (the
        shape about the centroid): the robots start at the reference at ``t = 0`` so moved.
    safety : dict
        ``enabled`` (bool), ``min_separation_m`` (m).
    reference : dict
        How a plan given by ``--reference`` is followed: ``time_scale``, ``altitude_m``,
        ``headings``.
    """

    name: str
    team: Team
    motion: object
    duration_s: float
    dt_s: float = 0.01
    metrics_from_s: float = 0.0
    title: str = ""
    source: str = ""
    groups: tuple = ()
    gains: dict = field(default_factory=lambda: TEAM_TABLES["table1"])
    feedforward: bool = True
    initial_offset: dict = field(default_factory=dict)
    safety: dict = field(default_factory=lambda: {"enabled": True, "min_separation_m": 0.3})
    reference: dict = field(default_factory=lambda: {"time_scale": 1.0, "altitude_m": 0.0, "headings": 0.0})

    #: The chart its motion is stated in (the key of its parts in :data:`TEAM_CHARTS`).
    chart = "team"

    def __post_init__(self):
        where = f"scenario {self.name!r}"
        for key in ("duration_s", "dt_s", "metrics_from_s"):
            number({key: getattr(self, key)}, key, where)
        number({"duration_s": self.duration_s}, "duration_s", where, low=0.0, low_open=True)
        number({"dt_s": self.dt_s}, "dt_s", where, low=0.0, low_open=True, high=self.duration_s)
        if not isinstance(self.team, Team):
            raise InvalidInputError(f"{where}: team must be a robots.Team, got {type(self.team).__name__}")
        TEAM_CHARTS[self.chart].check_work(self)
        check_within_run(where, "metrics_from_s", self.metrics_from_s, self.duration_s,
                         _last_step(self.duration_s, self.dt_s) * self.dt_s,
                         "no sample is measured and every error would read 0")
        types = TEAM_CHARTS[self.chart].motion_types
        if not isinstance(self.motion, types):
            raise InvalidInputError(f"{where}: motion must be a {' or a '.join(m.__name__ for m in types)}, got "
                                    f"{type(self.motion).__name__}")
        if self.motion.layout != self.team.layout:
            raise InvalidInputError(f"{where}: the motion is of robots {self.motion.layout.kinds}, the team offers "
                                    f"{self.team.layout.kinds}; build both from one layout")

    @property
    def times(self) -> np.ndarray:
        """Sample times ``0, dt_s, ...`` up to ``duration_s`` (never past it)."""
        n = _last_step(self.duration_s, self.dt_s)
        return np.minimum(np.arange(n + 1) * self.dt_s, self.duration_s)

    @property
    def template(self) -> np.ndarray:
        """The shape at ``t = 0`` about its centroid (m), the descriptions' attitude template."""
        e, _ = self.motion(np.zeros(1))
        return e[0, TeamChart(self.team.layout).shape_index]

    def controller(self, name: str, feedforward: bool | None = None):
        """The team controller ``name`` (:data:`quatform.control.TEAM_CONTROLLERS`) with this
        scenario's gains and robots; ``feedforward`` defaults to the scenario's."""
        from ..checks import nearest

        names = available_controllers()
        if name not in names:
            raise InvalidInputError(f"unknown team controller {name!r}{nearest(name, names)}; choose one of "
                                    f"{', '.join(names)} (the team descriptions registered in "
                                    "quatform.formations.TEAM_FORMATIONS)")
        gains = self.gains.get(name, {})
        ff = self.feedforward if feedforward is None else feedforward
        try:  # the description refuses what it cannot drive, in its own words
            return team_controller(name, self.team, gains, template=self.template, feedforward=bool(ff))
        except InvalidInputError as exc:
            raise type(exc)(f"scenario {self.name!r}: {exc}") from None


_STEP_SLACK = 1e-9


def _last_step(duration_s: float, dt_s: float) -> int:
    return int(math.floor(duration_s / dt_s + _STEP_SLACK))


def check_team_work(where: str, duration_s: float, dt_s: float, n_robots: int) -> None:
    """Refuse a run of ``duration_s / dt_s`` steps of ``n_robots`` robots that cannot fit in
    memory or the time budget (:func:`quatform.checks.check_work`)."""
    with np.errstate(over="ignore"):
        steps = float(duration_s) / float(dt_s) + 1.0 if dt_s > 0 else math.inf
    check_work(where, f"duration_s / dt_s = {duration_s:g} / {dt_s:g} with {n_robots} robots", steps,
               bytes_per_step=TEAM_BYTES_PER_ROBOT_STEP * n_robots,
               seconds_per_step=_SECONDS_PER_STEP + TEAM_SECONDS_PER_ROBOT_STEP * n_robots,
               fix="shorten duration_s, raise dt_s or use fewer robots")


# --------------------------------------------------------------------------- the reader

_TOP_KEYS = ("kind", "name", "title", "source", "duration_s", "dt_s", "metrics_from_s", "feedforward", "robots",
             "shape", "path", "attitude", "headings", "gains", "initial_offset", "safety", "reference")
_ROBOT_KEYS = ("model", "count")
_SHAPE_KEYS = ("template", "spacing", "radius", "side", "edge", "rows", "positions", "scale", "moves")
_SCALE_KEYS = ("kind", "value", "to", "start_s", "duration_s", "amplitude", "period_s", "profile")
_MOVE_KEYS = ("robot", "to", "start_s", "duration_s", "profile")
_PATH_KEYS = ("kind", "center", "velocity", "radius", "period_s", "climb_m_s", "r_x", "r_y", "omega")
#: Keys of ``[path]`` that one path kind only uses (any other would ignore them).
_PATH_ONLY = {"velocity": "line", "radius": "spiral", "period_s": "spiral", "climb_m_s": "spiral",
              "r_x": "lemniscate", "r_y": "lemniscate", "omega": "lemniscate"}
_ATTITUDE_KEYS = ("yaw", "pitch", "roll", "turns")
_TURN_KEYS = ("axis", "angle", "start_s", "duration_s", "profile")
_HEADING_KEYS = ("mode", "offsets")
_OFFSET_KEYS = ("position", "yaw", "scale")
_REFERENCE_KEYS = ("time_scale", "altitude_m", "headings")


def read_robots(data: dict, where: str):
    """``(groups, team)`` of a file's ``[[robots]]`` entries (one line naming a bad key)."""
    items = data.get("robots", MISSING)
    if items is MISSING:
        raise InvalidInputError(f"{where}: missing [[robots]] (e.g. [[robots]] model = 'quadrotor', count = 4)")
    groups = []
    for r, w in records(data, "robots", _all_robot_keys(), where, "robots", _HINT):
        models = file_models()
        model = text(r, "model", w, choices=tuple(models))
        cls = models[model]
        limits = tuple(cls.limit_keys)
        check_keys(r, _ROBOT_KEYS + limits, w, "[[robots]]", f"a {model} takes {', '.join(limits)}; {_HINT}")
        count = integer(r, "count", w, 1, low=1, high=100_000)
        groups.append(RobotGroupSpec(model, count, cls.from_file(r, w, "[[robots]]", model)))
    n = sum(gr.count for gr in groups)
    if n < 2:
        raise InvalidInputError(f"{where}: [[robots]] give {n} robot; a formation needs at least 2 (raise count)")
    return tuple(groups), Team(tuple(gr.robot for gr in groups for _ in range(gr.count)))


def _all_robot_keys():
    return _ROBOT_KEYS + tuple(dict.fromkeys(k for cls in file_models().values() for k in cls.limit_keys))


def _shape(data: dict, where: str, n: int, duration: float):
    s = table(data, "shape", where, default={"template": "ring"})
    check_keys(s, _SHAPE_KEYS, where, "[shape]", _HINT)
    at = {"place": "[shape]"}
    name = text(s, "template", where, "ring", **at, choices=tuple(TEMPLATES))
    size_key = TEMPLATES[name]
    for key in ("spacing", "radius", "side", "edge", "rows", "positions"):
        if key in s and key != size_key and not (name == "grid" and key == "rows") \
                and not (name == "positions" and key == "positions"):
            raise InvalidInputError(f"{where}: [shape] {key} does not apply to template = {name!r}"
                                    + (f" (its size is {size_key})" if size_key else "") + "; remove it")
    size = number(s, size_key, where, 1.0, **at, low=0.0, low_open=True) if size_key else None
    rows = integer(s, "rows", where, None, **at, low=1) if name == "grid" else None
    positions = None
    if name == "positions":
        if "positions" not in s:
            raise InvalidInputError(f"{where}: [shape] template = 'positions' needs positions = [[x, y, z], ...] "
                                    f"({n} of them, m)")
        pos = s["positions"]
        if not isinstance(pos, list) or len(pos) != n:
            raise InvalidInputError(f"{where}: [shape] positions must list {n} positions (one per robot), got "
                                    f"{short(pos)}")
        positions = [vector({"positions": p}, "positions", 3, where, place=f"[shape] positions #{i + 1}")
                     for i, p in enumerate(pos)]
    template = template_positions(name, n, size, rows, positions)
    sc = table(s, "scale", where, "[shape]", default={})
    check_keys(sc, _SCALE_KEYS, where, "[shape.scale]", _HINT)
    p = "[shape.scale]"
    scale = Scale(kind=text(sc, "kind", where, "constant", place=p, choices=SCALE_KINDS),
                  value=number(sc, "value", where, 1.0, place=p, low=0.0, low_open=True),
                  to=number(sc, "to", where, 1.0, place=p, low=0.0, low_open=True),
                  start_s=number(sc, "start_s", where, 0.0, place=p, low=0.0, high=duration),
                  duration_s=number(sc, "duration_s", where, 1.0, place=p, low=0.0, low_open=True),
                  amplitude=number(sc, "amplitude", where, 0.0, place=p, low=0.0, high=1.0, high_open=True),
                  period_s=number(sc, "period_s", where, 1.0, place=p, low=0.0, low_open=True),
                  profile=text(sc, "profile", where, "linear", place=p, choices=PROFILES))
    moves = []
    for m, w in records(s, "moves", _MOVE_KEYS, where, "shape.moves", _HINT):
        moves.append(Move(robot=integer(m, "robot", w, low=1, high=n) - 1, to=vector(m, "to", 3, w),
                          start_s=number(m, "start_s", w, low=0.0, high=duration),
                          duration_s=number(m, "duration_s", w, low=0.0, low_open=True),
                          profile=text(m, "profile", w, "smooth", choices=PROFILES)))
    return template, scale, tuple(moves)


def _path(data: dict, where: str) -> OriginPath:
    p = table(data, "path", where, default={})
    check_keys(p, _PATH_KEYS, where, "[path]", _HINT)
    at = {"place": "[path]"}
    kind = text(p, "kind", where, "fixed", **at, choices=PATH_KINDS)
    for key, owner in _PATH_ONLY.items():
        if key in p and kind != owner:
            raise InvalidInputError(f"{where}: [path] {key} applies to kind = {owner!r} only, not {kind!r}: remove "
                                    f"it or set kind = {owner!r}")
    kw = {}
    if kind == "spiral":
        for key in ("radius", "period_s"):
            kw[key] = number(p, key, where, MISSING, **at, low=0.0, low_open=True)
        kw["climb_m_s"] = number(p, "climb_m_s", where, 0.0, **at)
    if kind == "lemniscate":
        kw.update(r_x=number(p, "r_x", where, 1.0, **at, low=0.0, low_open=True),
                  r_y=number(p, "r_y", where, 1.0, **at, low=0.0, low_open=True),
                  omega=number(p, "omega", where, 0.1, **at))
        if kw["omega"] == 0.0:
            raise InvalidInputError(f"{where}: [path] omega = 0.0 must be nonzero (rad/s; the path would stand still)")
    return OriginPath(kind=kind, center=vector(p, "center", 3, where, (0.0, 0.0, 0.0), **at),
                      velocity=vector(p, "velocity", 3, where, (0.0, 0.0, 0.0), **at), **kw)


def _attitude(data: dict, where: str, duration: float) -> Attitude:
    a = table(data, "attitude", where, default={})
    check_keys(a, _ATTITUDE_KEYS, where, "[attitude]", _HINT)
    at = {"place": "[attitude]"}
    turns = []
    for r, w in records(a, "turns", _TURN_KEYS, where, "attitude.turns", _HINT):
        axis = vector(r, "axis", 3, w)
        if not any(axis):
            raise InvalidInputError(f"{w}: axis = {list(axis)} must be a nonzero vector (the world axis to turn about)")
        turns.append(Turn(axis, number(r, "angle", w), number(r, "start_s", w, low=0.0, high=duration),
                          number(r, "duration_s", w, low=0.0, low_open=True),
                          text(r, "profile", w, "linear", choices=PROFILES)))
    return Attitude(number(a, "yaw", where, 0.0, **at), number(a, "pitch", where, 0.0, **at),
                    number(a, "roll", where, 0.0, **at), tuple(turns))


def _headings(data: dict, where: str, n: int) -> Headings:
    h = table(data, "headings", where, default={})
    check_keys(h, _HEADING_KEYS, where, "[headings]", _HINT)
    mode = text(h, "mode", where, "formation", place="[headings]", choices=HEADING_MODES)
    off = h.get("offsets", 0.0)
    if isinstance(off, list):
        if len(off) not in (1, n):
            raise InvalidInputError(f"{where}: [headings] offsets lists {len(off)} angles for {n} robots; give one "
                                    f"number or {n}")
        vals = vector(h, "offsets", len(off), where, place="[headings]")
    else:
        vals = (number(h, "offsets", where, 0.0, place="[headings]"),)
    return Headings(mode, np.array(vals))


def _largest_gain(where: str, gains: dict) -> float:
    """Largest gain, 1/s, over every controller's gains in ``gains`` (scalars or lists)."""
    try:
        vals = [float(x) for g in gains.values() for v in g.values() for x in np.ravel(v)]
    except (TypeError, ValueError):
        raise InvalidInputError(f"{where}: gains = {short(gains)} must hold numbers (seed 000 Tables 1-2)") from None
    return max(vals, default=0.0)


def check_step_stable(where: str, dt_s: float, gains: dict) -> None:
    """Refuse a ``dt_s`` at which the explicit Euler loop of a proportional law diverges.

    Every controller here commands ``c_dot = -k (c - c_des)`` (seed 000 Fig. 2; eqs. (20),
    (28) with ``k`` on the quaternion error's vector part); one Euler step multiplies the error
    by ``1 - k dt_s``, which shrinks it only while ``k dt_s < 2``. The bound is taken on the
    largest gain of any controller the scenario can run, seed 000's files and team files alike
    (``docs/derivations.md``, "The two-robot scenario loader (seed 000)")."""
    k = _largest_gain(where, gains)
    if k * dt_s >= 2.0:
        raise InvalidInputError(
            f"{where}: dt_s = {dt_s:g} s with a largest gain of {k:g} 1/s gives gain x dt_s = {k * dt_s:.3g} "
            f">= 2: the discrete control loop would be unstable; use dt_s < {2.0 / k:.3g} s (smaller gains "
            "allow a larger step)")


def _gains(data: dict, where: str, dt: float) -> dict:
    g = data.get("gains", "table1")
    if isinstance(g, str):
        base, own = text(data, "gains", where, "table1", choices=tuple(TEAM_TABLES)), {}
    elif isinstance(g, dict):
        check_keys(g, ("base", *TEAM_CONTROLLERS), where, "[gains]", _HINT)
        base = text(g, "base", where, "table1", place="[gains]", choices=tuple(TEAM_TABLES))
        own = g
    else:
        raise InvalidInputError(f"{where}: gains = {short(g)} must be 'table1', 'table2' or a [gains] table")
    gains, sizes, tables = {}, team_gain_sizes(), TEAM_TABLES[base]
    for name in TEAM_CONTROLLERS:
        place = f"[gains.{name}]"
        mine = table(own, name, where, "[gains]", default={})
        check_keys(mine, sizes, where, place, _HINT)
        gains[name] = dict(tables.get(name, {}))
        for key, size in sizes.items():
            if key in mine:
                k = check_gain(mine[key], key, size, where=where, place=place)
                gains[name][key] = k.tolist() if isinstance(mine[key], list) else float(k[0])
    check_step_stable(where, dt, gains)
    return gains


def read_motion(data: dict, where: str, team: Team, duration: float) -> TeamMotion:
    """The :class:`TeamMotion` of a file's ``[shape]``, ``[path]``, ``[attitude]`` and
    ``[headings]`` for the robots of ``team`` over ``duration`` s (one line naming a bad key)."""
    n = team.layout.n
    template, scale, moves = _shape(data, where, n, duration)
    return TeamMotion(team.layout, template, _path(data, where), _attitude(data, where, duration), scale, moves,
                      _headings(data, where, n))


def team_scenario_from_dict(data: dict, where: str = "scenario") -> TeamScenario:
    """Build a :class:`TeamScenario` from parsed TOML; every mistake is one line naming the key."""
    check_keys(data, _TOP_KEYS, where, hint=_HINT)
    text(data, "kind", where, choices=("team",))
    try:
        duration = number(data, "duration_s", where, low=0.0, low_open=True)
        dt = number(data, "dt_s", where, 0.01, low=0.0, low_open=True, high=duration)
        groups, team = read_robots(data, where)
        n = team.layout.n
        check_team_work(where, duration, dt, n)  # before anything is sampled
        metrics_from = number(data, "metrics_from_s", where, 5.0 if duration > 5.0 else 0.0, low=0.0)
        motion = read_motion(data, where, team, duration)
        off = table(data, "initial_offset", where, default={})
        check_keys(off, _OFFSET_KEYS, where, "[initial_offset]", _HINT)
        offset = {"position": vector(off, "position", 3, where, (0.0, 0.0, 0.0), place="[initial_offset]"),
                  "yaw": number(off, "yaw", where, 0.0, place="[initial_offset]"),
                  "scale": number(off, "scale", where, 1.0, place="[initial_offset]", low=0.0, low_open=True)}
        safety = safety_table(data, where, _HINT, enabled_without_table=True)  # on by default for teams
        ref = table(data, "reference", where, default={})
        check_keys(ref, _REFERENCE_KEYS, where, "[reference]", _HINT)
        reference = {"time_scale": number(ref, "time_scale", where, 1.0, place="[reference]", low=0.0,
                                          low_open=True),
                     "altitude_m": number(ref, "altitude_m", where, 0.0, place="[reference]"),
                     "headings": number(ref, "headings", where, 0.0, place="[reference]")}
        sc = TeamScenario(name=text(data, "name", where, Path(where).stem), title=text(data, "title", where, ""),
                          source=text(data, "source", where, ""), team=team, groups=groups, motion=motion,
                          duration_s=duration, dt_s=dt, metrics_from_s=metrics_from,
                          gains=_gains(data, where, dt), feedforward=flag(data, "feedforward", where, True),
                          initial_offset=offset, safety=safety, reference=reference)
        _check_start(sc, where)
    except InvalidInputError as exc:
        msg = str(exc)
        raise type(exc)(msg if msg.startswith(where) else f"{where}: {msg}") from None
    return sc


def _check_start(sc: TeamScenario, where: str) -> None:
    """Refuse robots that start on each other (the reference at t = 0 with the offset) and,
    with the barrier on, a reference that brings two robots closer than its minimum (the
    barrier would hold them apart and the formation could not be tracked): sampled at most
    every 1/2000 of the run."""
    L = sc.team.layout
    r0 = _start_points(sc, sc.motion)
    check_template(L.positions(r0)[None], L.n, "the robots at t = 0 (the reference with [initial_offset])",
                   min_separation=1e-6)
    if sc.safety["enabled"]:
        _check_barrier_reference(sc, sc.safety["min_separation_m"], where, FILE_LABEL)


def _check_barrier_reference(sc: TeamScenario, d: float, where: str, label: str) -> None:
    """Refuse a barrier of ``d`` m (the setting ``label``) that the reference breaks: two robots
    closer than ``d`` at some time (sampled at most every 1/2000 of the run), beyond the
    rounding of their points (:func:`~quatform.control.safety.start_floor`: a shape whose edge
    is exactly ``d`` keeps it)."""
    L = sc.team.layout
    t = sc.times
    t = t[::max(1, len(t) // 2000)]
    r = TeamChart(L).robots(sc.motion(t)[0])
    sep = min_separations(L, r)
    floor = start_floor(L.positions(r), d)[..., 0]  # d less the rounding of points built by trigonometry
    k = int(np.argmin(sep - floor))
    if sep[k] < floor[k]:
        i, j = L.pairs
        a = int(np.argmin(L.separations(r[k])))
        raise InvalidInputError(
            f"{where}: the reference brings robots {L.display_names[i[a]]} and {L.display_names[j[a]]} to "
            f"{sep[k]:.3g} m at t = {t[k]:g} s, below {label} = {d:g} m (the barrier would hold them apart); "
            f"enlarge the shape or lower {label}")


def _start_points(sc: TeamScenario, motion) -> np.ndarray:
    """The robots' points at t = 0: the reference moved by the initial offset."""
    e, _ = motion(np.zeros(1))
    e = e[0].copy()
    chart = TeamChart(sc.team.layout)
    off = sc.initial_offset
    e[0:3] += np.asarray(off.get("position", (0.0, 0.0, 0.0)))
    e[chart.shape_index] *= off.get("scale", 1.0)
    e[chart.yaw_index] += off.get("yaw", 0.0)
    return chart.robots(e)


def with_plan(sc: TeamScenario, plan_file) -> TeamScenario:
    """``sc`` following the saved N-robot plan ``plan_file`` (:class:`PlanMotion` with the
    scenario's ``[reference]`` settings); the run lasts the plan (times ``time_scale``)."""
    from ..planning import load_plan

    plan = load_plan(plan_file)
    ref = sc.reference
    motion = PlanMotion(sc.team.layout, plan, ref["altitude_m"], ref["time_scale"], ref["headings"])
    T = motion.duration_s
    check_team_work(str(plan_file), T, sc.dt_s, sc.team.layout.n)
    return dataclasses.replace(sc, motion=motion, duration_s=T, name=f"{sc.name}+{plan.info.get('name', 'plan')}",
                               metrics_from_s=sc.metrics_from_s if sc.metrics_from_s < T else 0.0)


# --------------------------------------------------------------------------- the kind

#: Columns of the comparison table.
TEAM_TABLE_COLUMNS = (
    ("controller", "controller", "{}"),
    ("n_robots", "N", "{}"),
    ("first_singular_time_s", "singular at (s)", "{:.2f}"),
    ("reference_lost", "lost", "{}"),
    ("max_cluster_position_error_m", "centroid (m)", "{:.4f}"),
    ("max_shape_error_m", "shape (m)", "{:.4f}"),
    ("max_orientation_error_rad", "attitude (rad)", "{:.4f}"),
    ("max_robot_position_error_m", "robot pos (m)", "{:.4f}"),
    ("max_recovered_attitude_error_rad", "recovered (rad)", "{:.3f}"),
    ("max_reading_error_rad", "Euler reading (rad)", "{:.3f}"),
    ("reading_folded_time_s", "folded (s)", "{:.1f}"),
    ("min_robot_separation_m", "min sep (m)", "{:.3f}"),
    ("nonfinite_commands", "NaN cmds", "{}"),
)

#: Most samples of the singularity measure a run computes, as ``budget / n_c^3`` (at least
#: :data:`_MIN_SINGULAR_SAMPLES`): the measure is the SVD of the dense ``(n_r, n_c)`` inverse
#: Jacobian, O(n_c^3) a sample (0.3 s at n_c = 400 on this project's 2-core machine), so a
#: 100-robot team measures it on a subsample of times (12 of them); a team of 10 at every sample.
_SINGULAR_BUDGET = 6e8
_MIN_SINGULAR_SAMPLES = 12


def singularity_samples(n_times: int, n_c: int) -> np.ndarray:
    """Indices of the samples whose singularity measure a run computes: every sample for a
    small team, else about ``6e8 / n_c^3`` evenly spaced ones (at least 12, the first and last
    kept)."""
    k = int(max(_MIN_SINGULAR_SAMPLES, _SINGULAR_BUDGET / max(n_c, 1) ** 3))
    if n_times <= k:
        return np.arange(n_times)
    return np.unique(np.linspace(0, n_times - 1, k).round().astype(int))


#: The parts of a team run that depend on its scenario's chart, by :attr:`TeamScenario.chart`:
#: one instance of each :class:`TeamChartParts` subclass that sets a ``name``, registered when
#: the class is defined (the team chart here, seed 000's variables of two robots in
#: :mod:`quatform.scenarios.pair`).
TEAM_CHARTS = Registry("team chart")


class TeamChartParts:
    """What a team run reads from the chart its motion is stated in: here the team chart
    (centroid, attitude, shape, headings; :class:`~quatform.formations.TeamChart`).

    :meth:`TeamKind.experiment` is one flow for every team scenario; the steps that depend on
    the scenario's chart (:attr:`TeamScenario.chart`) are this object's methods, and
    :data:`TEAM_CHARTS` holds one per chart (seed 000's Euclidean variables of two robots:
    :class:`quatform.scenarios.pair.PairChartParts`). Its :attr:`name` is the key the run's
    figures (:data:`quatform.report.FIGURES`), bag scene (:data:`quatform.bags.scene.SCENES`)
    and sweep adapter (:data:`quatform.sweeps.trials.SWEEP_KINDS`) are registered under and
    the log's ``meta["kind"]``.
    """

    name = "team"
    #: Columns of the comparison table: (metrics key, header, format).
    table_columns = TEAM_TABLE_COLUMNS

    def __init_subclass__(cls, register: bool = True, **kwargs):
        super().__init_subclass__(**kwargs)
        if register and cls.__dict__.get("name"):
            TEAM_CHARTS.add(cls.name, cls())

    #: The motions a scenario of this chart follows (``t -> (e, e_dot)`` in the chart).
    motion_types = (TeamMotion, PlanMotion)

    def controllers(self) -> tuple:
        """The controller names a compare runs, in its order."""
        return available_controllers()

    def physics_options(self, sc, physics: str, options: dict | None) -> dict:
        """The options of the physics (none for the team chart: one given is refused)."""
        if options:
            raise InvalidInputError(f"scenario {sc.name!r}: physics options {sorted(options)} apply to seed 000's "
                                    "two-robot scenarios only")
        return {}

    def with_plan(self, sc, plan_file):
        """``sc`` following the saved plan ``plan_file`` (the ``reference`` option)."""
        return with_plan(sc, plan_file)

    def check_work(self, sc) -> None:
        """Refuse a run that cannot fit in memory or the time budget (before anything is sampled)."""
        check_team_work(f"scenario {sc.name!r}", sc.duration_s, sc.dt_s, sc.team.layout.n)

    def check_barrier(self, sc, d: float, label: str, e_des, t, start: bool) -> None:
        """Refuse a barrier of ``d`` m (the setting ``label``) that the reference breaks; the
        file's own value was checked when the file was read."""
        if label != FILE_LABEL:
            _check_barrier_reference(sc, d, f"scenario {sc.name!r}", label)

    def start(self, sc, e_des) -> np.ndarray:
        """The robots' state at ``t = 0``: the reference moved by the initial offset (every
        team model's state is its point)."""
        return _start_points(sc, sc.motion)

    def robots(self, sc, e_des) -> np.ndarray:
        """The desired robots of the chart values ``e_des``."""
        return TeamChart(sc.team.layout).robots(e_des)

    def pose(self, e) -> tuple:
        """The formation's pose in the chart values ``e`` (``(..., n_e)``): its centroid ``x_c``
        ``(..., 3)`` m and attitude ``q_c`` ``(..., 4)`` (unit), what an operator's goal moves
        (:func:`quatform.references.goal.approach_pose`)."""
        e = np.asarray(e, dtype=float)
        q = e[..., ATTITUDE]
        return e[..., CENTROID], q / np.linalg.norm(q, axis=-1, keepdims=True)

    def posed(self, e, e_dot, p, q, v, w, near=None) -> tuple:
        """``(e, e_dot)`` with the formation's pose replaced by ``(p, q)`` moving at the velocity
        ``v`` (m/s) and the world angular velocity ``w`` (rad/s), the shape and headings kept:
        ``x_c = p``, ``q_c = q``, ``x_c' = v``, ``q_c' = (0, w) q / 2`` (:meth:`TeamChart.robot_rates`
        reads ``w = 2 (q_c' q_c*)_vec`` back). ``near`` (the previous chart values) is unused here."""
        e, ed = np.array(e, dtype=float), np.array(e_dot, dtype=float)
        e[..., CENTROID], e[..., ATTITUDE], ed[..., CENTROID] = p, q, v
        ed[..., ATTITUDE] = 0.5 * g.mul(np.concatenate([np.zeros(np.shape(w)[:-1] + (1,)), w], axis=-1), q)
        return e, ed

    def plant(self, sc, controller, feedforward, physics: str, x0, options: dict):
        """``(controller, plant, record, physics_metrics)``: the controller ``controller`` (a
        name or an object) and what moves the robots; ``record(log, ctrl) -> dict`` adds the
        physics record to the log's meta, ``physics_metrics(log) -> dict`` to the metrics."""
        ctrl = sc.controller(controller, feedforward) if isinstance(controller, str) else controller
        if physics != "mujoco":
            return ctrl, KinematicTeam(ctrl.team), None, None
        from ..sim.plants import mujoco as mjp  # MuJoCo only when asked for
        from ..sim.plants.mujoco_team import team_plant

        plant = team_plant(ctrl.team, x0, dt=sc.dt_s)
        return (ctrl, plant, lambda log, c: {"physics_record": mjp.physics_record(plant, log,
                                                                                  f"{sc.name}: {c.name} controller")},
                lambda log: mjp.physics_metrics(plant))

    def meta(self, sc, ctrl, safety: dict) -> dict:
        """The chart's entries of the log's meta."""
        team = ctrl.team
        return {"n_robots": team.layout.n, "layout": team.layout, "team": team, "safety": safety,
                "chart_variables": TeamChart(team.layout).variables, "chart": TEAM_CHART}

    def finisher(self, sc, ctrl, t, e_des, c_des, r_des, record):
        """``finish(log) -> log`` adding the desired robots, the chart recovered by the
        controller's description, the desired chart, the singularity measure and the Euler
        reading (:func:`_reading`) to each world's log."""
        team, F = ctrl.team, ctrl.formation
        chart = TeamChart(team.layout)
        reader = _euclidean_reader(F, team.layout, sc.template)
        reading_des = None if reader is None else reader.follow_reading(r_des)

        def finish_one(log: Log) -> Log:
            r = team.point(log["state"])
            c = log["cluster"]
            held = ~np.all(np.isfinite(c), axis=-1)  # a failed world's samples (sim.simulate: signals NaN)
            r_read, c_read = (np.where(held[..., None], b, a) if held.any() else a for a, b in ((r, r_des), (c, c_des)))
            e = F.to_chart(c_read, near_e=e_des, r=r_read)  # its held robots may coincide: read the reference there
            idx = singularity_samples(len(t), F.n_c)
            sing = np.full(len(t), np.nan)
            sing[idx] = F.singularity_measure(r_read[idx], near_c=c_des[idx])
            if held.any():
                e, sing = np.where(held[..., None], np.nan, e), np.where(held, np.nan, sing)
            names = chart.names
            chans = [Channel("points", team.layout.names, r),
                     Channel("r_des", tuple(n + "_des" for n in team.layout.names), r_des),
                     Channel("c_des", tuple(n + "_des" for n in F.names), c_des),
                     Channel("e", names, e), Channel("e_des", tuple(n + "_des" for n in names), e_des),
                     Channel("singularity", ("singularity_measure",), sing[:, None])]
            if reader is not None:
                reading = _reading(F, reader, r_read, c_read, reading_des)
                chans += [Channel("reading", reader.reading_names,
                                  np.where(held[..., None], np.nan, reading) if held.any() else reading),
                          Channel("reading_des", tuple(n + "_des" for n in reader.reading_names), reading_des)]
            extra = {} if record is None else record(log, ctrl)
            return log.with_channels(*chans, singularity_samples=int(idx.size), **extra)

        def finish(log: Log) -> Log:  # a batch of worlds: each world's own finish
            return finish_worlds(log, finish_one)

        return finish

    def csv_channels(self, sc, ctrl) -> tuple:
        """The channels of ``timeseries.csv`` before the barrier's (a tuple's channels interleaved)."""
        reader = _euclidean_reader(ctrl.formation, ctrl.team.layout, sc.template)
        return (("points", "r_des"), ("e", "e_des"), *((("reading", "reading_des"),) if reader is not None else ()),
                "command", "singularity")


TEAM_CHARTS.add(TeamChartParts.name, TeamChartParts())


class TeamKind(ScenarioKind):
    """N robots of any mix under one of the four team controllers; seed 000's two-robot files
    (no ``kind`` key, or ``kind = "pair"``) read into it with seed 000's chart."""

    name = "team"
    #: The ``kind`` values of files this kind reads besides its own (seed 000's two robots).
    aliases = ("pair",)
    scenario_type = TeamScenario
    _OTHER_OPTIONS = (
        Option("feedforward", "feed the reference's rate forward (default: the scenario's)", None, None, bool),
        Option("physics", "what moves the robots: their kinematic models or MuJoCo physics", TEAM_PHYSICS, "kinematic"),
        Option("reference", "a plan.npz (quatform plan) to follow instead of the scenario's motion: two robots for a "
               "seed-000 file, N for a team", None, None, str),
        Option("min_separation", "hold the robots at least this far apart, m, with the separation barrier "
               "(default: the scenario's [safety]; 0 turns it off)", None, None, float),
    )
    compare_over = "controller"

    @property
    def options(self) -> tuple:
        """The run's options; the controller's choices are the team descriptions registered now."""
        return (Option("controller", "team controller (seed 000 for N robots; required)", available_controllers(), None),
                *self._OTHER_OPTIONS)
    table_columns = TEAM_TABLE_COLUMNS

    def from_dict(self, data: dict, where: str) -> TeamScenario:
        """A team file (``kind = "team"``), or seed 000's two-robot file (no ``kind``, or
        ``kind = "pair"``: :func:`quatform.scenarios.pair.scenario_from_dict`)."""
        if data.get("kind", "pair") == "pair":
            from .pair import scenario_from_dict

            return scenario_from_dict(data, where)
        return team_scenario_from_dict(data, where)

    def parts_of(self, scenario) -> str:
        """The name the scenario's chart parts, figures, bag scene, sweep adapter and table are
        registered under: its chart's (:data:`TEAM_CHARTS`)."""
        return TEAM_CHARTS[scenario.chart].name if isinstance(scenario, TeamScenario) else self.name

    def columns_of(self, scenario) -> tuple:
        """The comparison table's columns of ``scenario``: its chart's."""
        return TEAM_CHARTS[scenario.chart].table_columns if isinstance(scenario, TeamScenario) else self.table_columns

    def compare_choices(self, scenario, axis: str) -> tuple[tuple, dict]:
        """The controllers whose description can represent the scenario's robots (the
        Euclidean team baseline refuses a mix of planar and spatial robots), and the others
        with the description's one-line refusal; over ``physics``, MuJoCo only where it can
        simulate every robot (a quadrotor or a Pioneer), else left out with the reason."""
        if axis == "physics" and isinstance(scenario, TeamScenario):
            run, skipped = [], {}
            for name in TEAM_PHYSICS:
                try:
                    if name == "mujoco":
                        from ..sim.plants.mujoco_team import physics_kinds
                        physics_kinds(scenario.team, f"scenario {scenario.name!r}")
                except InvalidInputError as exc:
                    skipped[name] = str(exc)
                else:
                    run.append(name)
            return tuple(run), skipped
        if axis != "controller" or not isinstance(scenario, TeamScenario):
            return super().compare_choices(scenario, axis)
        run, skipped = [], {}
        for name in TEAM_CHARTS[scenario.chart].controllers():
            try:
                scenario.controller(name)
            except InvalidInputError as exc:
                skipped[name] = str(exc)
            else:
                run.append(name)
        return tuple(run), skipped

    def experiment(self, scenario: TeamScenario, controller=None, feedforward: bool | None = None,
                   physics: str = "kinematic", reference=None, min_separation: float | None = None, r0=None,
                   physics_options: dict | None = None) -> Experiment:
        """The run of ``scenario`` with ``controller`` (a :data:`~quatform.control.TEAM_CONTROLLERS`
        name or a controller object of the scenario's team; required).

        Parameters
        ----------
        feedforward : bool, optional
            For a controller given by name: feed the reference's rate forward; default: the
            scenario's (an object keeps its own).
        physics : str
            ``"kinematic"`` (the robots' models, :class:`~quatform.sim.plants.KinematicTeam`)
            or ``"mujoco"`` (``log.meta["physics_record"]`` is the run's
            :class:`~quatform.sim.mujoco_backend.PhysicsRecord`).
        reference : str or path, optional
            A saved plan to follow (the chart's ``with_plan``).
        min_separation : float, optional
            The separation barrier's minimum, m (>= 0), instead of the scenario's ``[safety]``
            ``min_separation_m``; 0 turns the barrier off (:func:`.separation.with_option`); a
            reference that brings two robots closer is refused as the file's value is.
        r0 : array_like, shape (*batch, n_x), optional
            Initial robot state of each world (leading axes: a batch of worlds run at once,
            kinematic physics only); default the chart's start (the reference at ``t = 0``
            moved by the initial offset).
        physics_options : dict, optional
            Of seed 000's chart on ``physics="mujoco"`` (:class:`quatform.scenarios.pair.PairChartParts`).
        """
        if not isinstance(scenario, TeamScenario):
            raise InvalidInputError(f"team experiment: scenario must be a TeamScenario, got {type(scenario).__name__}")
        if controller is None:
            raise InvalidInputError(f"{scenario.name} is a team scenario: give a controller "
                                    f"(--controller {{{','.join(available_controllers())}}})")
        if physics not in TEAM_PHYSICS:
            raise InvalidInputError(f"unknown physics {physics!r} for a team scenario; choose one of "
                                    f"{', '.join(TEAM_PHYSICS)}")
        parts = TEAM_CHARTS[scenario.chart]
        where = f"scenario {scenario.name!r}"
        physics_options = parts.physics_options(scenario, physics, physics_options)
        safety, label = with_option(scenario.safety, min_separation, where)
        if reference is not None:
            scenario = parts.with_plan(scenario, reference)
        parts.check_work(scenario)
        t = scenario.times
        e_des, ed_des = scenario.motion(t)
        if safety["enabled"]:  # a given r0 is checked by SafeController's first update
            parts.check_barrier(scenario, safety["min_separation_m"], label, e_des, t, start=r0 is None)
        x0 = parts.start(scenario, e_des) if r0 is None else np.array(r0, dtype=float)
        ctrl, plant, record, physics_metrics = parts.plant(scenario, controller, feedforward, physics, x0,
                                                           physics_options)
        team, F, ff = ctrl.team, ctrl.formation, bool(ctrl.feedforward)
        if team.n_state != team.layout.size:
            raise InvalidInputError(f"{scenario.name}: a team robot's state must be its point (the models of "
                                    f"{', '.join(file_models())}); this team's state has {team.n_state} entries for "
                                    f"points of {team.layout.size}")
        if team.layout != scenario.team.layout:
            raise InvalidInputError(f"{scenario.name}: the controller's team offers {team.layout.kinds}, the "
                                    f"scenario's {scenario.team.layout.kinds}")
        c_des, cd_des = F.from_chart(e_des, ed_des)
        r_des = parts.robots(scenario, e_des)
        safety["applied"] = bool(safety["enabled"])
        meta = {"kind": parts.name, "scenario": scenario.name, "title": scenario.title, "source": scenario.source,
                "dt_s": scenario.dt_s, "metrics_from_s": scenario.metrics_from_s, "physics": physics,
                "physics_label": "kinematic" if physics != "mujoco" else _physics_label(), "formation": F.name,
                "cluster_variables": F.variables, "feedforward": ff, **parts.meta(scenario, ctrl, safety)}
        csv = parts.csv_channels(scenario, ctrl)
        finish = parts.finisher(scenario, ctrl, t, e_des, c_des, r_des, record)
        if safety["applied"]:
            ctrl = SafeController(ctrl, separation_barrier(safety["min_separation_m"], scenario.dt_s), team)
            csv = csv + ("min_separation", "safety_active")

        def reference_at(k):
            return Reference(c_des[k], cd_des[k], r_des[k])

        def metrics(log: Log) -> dict:
            return {**compute_metrics(log), **({} if physics_metrics is None else physics_metrics(log))}

        return Experiment(scenario=scenario, label=ctrl.name, plant=plant, controller=ctrl, reference=reference_at,
                          times=t, x0=x0, dt=scenario.dt_s, finish=finish, metrics=metrics, csv_channels=csv,
                          meta=meta)


def _physics_label() -> str:
    from ..sim import mujoco_backend as mj

    return mj.PHYSICS_LABEL


def _euclidean_reader(F, layout, template):
    """The Euclidean team description that reads the formation's attitude in Euler angles
    (seed 000's beta_c, gamma_c and, for N >= 3, alpha_c): ``F`` itself when it is one, else
    one of the team (None when no minimal Euclidean chart takes the team's mix)."""
    if isinstance(F, EuclideanTeam):
        return F
    try:
        return EuclideanTeam(layout=layout, template=template)
    except InvalidInputError:
        return None


def _reading(F, reader, r, c, reading_des):
    """The Euler reading ``(T, k)`` of the formation as the controller's description reports it
    (seed 000 §4's comparison): the Euclidean description its own cluster state's angles (held
    and unwrapped near its reference); robot space, which keeps no formation state, the forward
    map's own angles (seed 000 eqs. (4)-(5), ``gamma_c`` within ``+-pi/2``: it reads a formation
    past the vertical folded, ``(beta_c + pi, pi - gamma_c, alpha_c + pi)``); the quaternion
    and dual-quaternion descriptions, which follow the attitude continuously, the triple of the
    robots' frame nearest the reference's."""
    if F is reader:
        return np.asarray(c)[..., [F.names.index(n) for n in F.reading_names]]
    if isinstance(F, RobotSpaceTeam):
        return reader.reading(r)
    return reader.reading(r, near=reading_des)


#: The team kind (registered in :data:`quatform.scenarios.KINDS`).
TEAM = KINDS[TeamKind.name]
