"""Plan specifications: TOML files with a ``kind`` key, and the planners that read them.

Planning layer. A spec names the robots (masses, start and goal positions), the plan's
duration and sampling, and a table of options for its ``kind``. ``make_plan`` dispatches on
``kind`` through :data:`PLANNERS`: ``"shaped-geodesic"`` (seed 002) and ``"rigid-se3"``
(seed 004: a rigid formation on SE(3), from an ``[airplanes]`` table, §4, or a general
``[formation]`` table). Built-in specs live in
``quatform/plans/*.toml``; keys in ``docs/planning.md``.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._toml import builtin_files, read_toml
from ..algebra import matrix_from_q
from ..errors import InvalidInputError, QuatformError
from .geodesic import meeting_bound, plan_from_geodesic, plan_through_meeting, solve_geodesic
from .measures import min_separation, rigid_motion, straight_line_motion
from .plan import Plan
from .rigid_formation import AIRPLANE_CASES, airplanes_spec, rigid_plan_from_spec
from .shaping import check_alpha, check_masses

__all__ = ["PLANNERS", "PlanSpec", "builtin_plan_specs", "load_plan_spec", "make_plan", "plan_metrics",
           "rigid_formation_dict"]


@dataclass(frozen=True, eq=False)
class PlanSpec:
    """A planning problem (see ``docs/planning.md``).

    Attributes
    ----------
    name, title, source : str
    kind : str
        Planner name, a key of :data:`PLANNERS` (``"shaped-geodesic"``).
    masses : ndarray, shape (N,)
    start, goal : ndarray, shape (N, d)
        Robot positions at ``t = 0`` and ``t = duration_s``, m.
    duration_s : float
    knots : int
        Knots of the saved plan (its ``sample`` interpolates between them).
    min_clearance_m : float
        Robots closer than this anywhere on the plan are flagged (``robots_meet``).
    options : dict
        The ``[kind]``-specific table (``[shaping]`` for ``"shaped-geodesic"``: ``alpha``).
    """

    name: str
    kind: str
    masses: np.ndarray
    start: np.ndarray
    goal: np.ndarray
    duration_s: float = 1.0
    knots: int = 201
    min_clearance_m: float = 0.05
    title: str = ""
    source: str = ""
    options: dict = field(default_factory=dict)


#: Keys every spec may have at the top level (besides its kind's options table).
_TOP_KEYS = {"kind", "name", "title", "source", "duration_s", "knots", "min_clearance_m", "robots"}


def _input_error(exc, where, table) -> InvalidInputError:
    """The one-line error for a spec table that could not be read."""
    if isinstance(exc, KeyError):
        return InvalidInputError(f"{where}: [{table}] misses key {exc} (see docs/planning.md)")
    if isinstance(exc, QuatformError):
        return InvalidInputError(f"{where}: {exc}")
    return InvalidInputError(f"{where}: {exc} (numbers expected; see docs/planning.md)")


def _knots(v, where) -> int:
    if isinstance(v, bool) or not isinstance(v, int):
        raise InvalidInputError(f"{where}: knots must be an integer (>= 2), got {v!r}")
    return v


def builtin_plan_specs() -> dict[str, Path]:
    """Built-in plan specs by name."""
    return builtin_files("plans")


def load_plan_spec(name_or_file) -> PlanSpec:
    """A built-in spec by name, or a TOML file by path; every mistake is an InvalidInputError."""
    data, p = read_toml(name_or_file, builtin_plan_specs(), "plan spec")
    return plan_spec_from_dict(data, where=str(p))


def plan_spec_from_dict(data: dict, where: str = "plan spec") -> PlanSpec:
    """Build a :class:`PlanSpec` from parsed TOML."""
    kind = data.get("kind")
    if kind not in PLANNERS:
        raise InvalidInputError(f"{where}: kind = {kind!r}; use one of {', '.join(sorted(PLANNERS))}")
    if kind == "rigid-se3":
        return _rigid_spec_from_dict(data, where)
    rb = data.get("robots")
    if not isinstance(rb, dict):
        raise InvalidInputError(f"{where}: missing [robots] table with masses, start and goal")
    table = PLANNERS[kind][0]
    for keys, allowed, what in ((data, _TOP_KEYS | {table}, "top level"), (rb, {"masses", "start", "goal"}, "[robots]")):
        unknown = sorted(set(keys) - allowed)
        if unknown:
            raise InvalidInputError(f"{where}: unknown key(s) {unknown} at {what}; see docs/planning.md")
    try:
        masses = check_masses(rb["masses"])
        start = np.asarray(rb["start"], dtype=float)
        goal = np.asarray(rb["goal"], dtype=float)
        duration = float(data.get("duration_s", 1.0))
        knots = _knots(data.get("knots", 201), where)
        clearance = float(data.get("min_clearance_m", 0.05))
    except (KeyError, TypeError, ValueError) as exc:
        raise _input_error(exc, where, "robots") from None
    if start.ndim != 2 or start.shape != goal.shape or start.shape[0] != masses.size or start.shape[1] not in (2, 3):
        raise InvalidInputError(
            f"{where}: [robots] start and goal must be lists of N = {masses.size} positions of 2 or 3 "
            f"coordinates each (one per mass); got shapes {start.shape} and {goal.shape}"
        )
    if not (np.all(np.isfinite(start)) and np.all(np.isfinite(goal)) and np.isfinite(duration) and duration > 0
            and knots >= 2 and clearance >= 0):
        raise InvalidInputError(f"{where}: need finite positions, duration_s > 0, knots >= 2, min_clearance_m >= 0")
    options = data.get(table, {})
    if not isinstance(options, dict):
        raise InvalidInputError(f"{where}: [{table}] must be a table")
    return PlanSpec(name=str(data.get("name", Path(where).stem)), kind=kind, masses=masses, start=start,
                    goal=goal, duration_s=duration, knots=knots, min_clearance_m=clearance,
                    title=str(data.get("title", "")), source=str(data.get("source", "")), options=dict(options))


def plan_metrics(plan: Plan, spec: PlanSpec, samples: int = 1001) -> dict:
    """Separation and deviation measures of ``plan`` (JSON-ready, units in the key names).

    ``max_straight_line_deviation_m``: largest distance of a robot from its uniform straight
    line; ``max_rigid_deviation_m``: from the optimal rigid motion
    (:func:`~quatform.planning.measures.rigid_motion`; None where the ends are not a rigid
    displacement or it is not a fixed-axis rotation). ``robots_meet``: the minimum
    separation is below ``spec.min_clearance_m``.
    """
    t = np.linspace(plan.times[0], plan.times[-1], samples)
    s = (t - t[0]) / (t[-1] - t[0])
    pos, _, _ = plan.sample(t)
    dmin, k, (i, j) = min_separation(pos)
    straight = straight_line_motion(spec.start, spec.goal, s)
    rigid = rigid_motion(spec.start, spec.goal, spec.masses, s)
    return {
        "plan": spec.name,
        "kind": spec.kind,
        "n_robots": int(plan.n_robots),
        "dim": int(plan.dim),
        "duration_s": plan.duration_s,
        "min_separation_m": dmin,
        "min_separation_time_s": float(t[k]),
        "min_separation_robots": [i + 1, j + 1],
        "min_clearance_m": spec.min_clearance_m,
        "robots_meet": bool(dmin < spec.min_clearance_m),
        "max_straight_line_deviation_m": float(np.linalg.norm(pos - straight, axis=-1).max()),
        # the SE(2)-style uniform reference means nothing for seed 004's projected curves
        "max_rigid_deviation_m": None if rigid is None or spec.kind == "rigid-se3"
        else float(np.linalg.norm(pos - rigid, axis=-1).max()),
    }


def _shaped_geodesic(spec: PlanSpec):
    unknown = set(spec.options) - {"alpha"}
    if unknown:
        raise InvalidInputError(f"{spec.name}: [shaping] has unknown keys {sorted(unknown)}; only alpha")
    if "alpha" not in spec.options:
        raise InvalidInputError(f"{spec.name}: [shaping] needs alpha (0 < alpha < 1)")
    alpha = check_alpha(spec.options["alpha"])
    info = {"kind": spec.kind, "name": spec.name, "alpha": alpha, "masses": spec.masses.tolist(),
            "source": spec.source}
    known = meeting_bound(spec.start, spec.goal, spec.masses)
    if known is not None and alpha != 0.5 and alpha <= known[0]:
        # no smooth geodesic: the minimiser runs through the robots' meeting (the plan flags it)
        t0 = time.perf_counter()
        plan = plan_through_meeting(spec.start, spec.goal, spec.masses, alpha, spec.duration_s, spec.knots, info)
        extra = {"alpha": alpha, "solve_time_s": time.perf_counter() - t0, "through_meeting": True,
                 "geodesic_bound_alpha": known[0], "meeting_time_s": plan.info["meeting_time_s"]}
        return plan, extra
    sol = solve_geodesic(spec.start, spec.goal, spec.masses, alpha)
    plan = plan_from_geodesic(sol, spec.duration_s, spec.knots, info)
    extra = {"alpha": alpha, "solve_time_s": sol.solve_time_s, "endpoint_error_m": sol.endpoint_error_m,
             "energy_drift": sol.energy_drift, "collocation_nodes": int(sol.s.size),
             "continuation_alphas": [round(a, 12) for a in sol.continuation], "initial_guess": sol.guess,
             "through_meeting": False}
    return plan, extra


# --------------------------------------------------------------------------- seed 004

#: Parameters of the ``[airplanes]`` table (seed 004 §4) and their defaults.
_AIRPLANE_KEYS = {"case": "b", "m": 1.0, "a": 5.0, "h": 10.0, "X": 20.0, "Y": 20.0}


def rigid_formation_dict(spec: PlanSpec) -> dict:
    """The :func:`~quatform.planning.rigid_plan_from_spec` input of a ``"rigid-se3"`` spec."""
    opts = spec.options
    if "airplanes" in opts:
        a = {**_AIRPLANE_KEYS, **opts["airplanes"]}
        if a["case"] not in AIRPLANE_CASES:
            raise InvalidInputError(f"{spec.name}: [airplanes] case = {a['case']!r}; use one of {AIRPLANE_CASES}")
        form = airplanes_spec(a["case"], *(float(a[k]) for k in ("m", "a", "h", "X", "Y")))
    else:
        form = dict(opts["formation"])
        clash = sorted({"duration", "samples"} & set(form))
        if clash:
            raise InvalidInputError(f"{spec.name}: [formation] {', '.join(clash)} - give the plan's length and "
                                    "knots at the top level as duration_s and knots")
    form["duration"] = spec.duration_s
    form["samples"] = spec.knots
    return form


def _robot_positions(form: dict, which: str) -> np.ndarray:
    pose = form[which]
    o = np.asarray(pose["orientation"], dtype=float)
    R = matrix_from_q(o) if o.shape == (4,) else o
    return np.asarray(pose["position"], dtype=float) + np.asarray(form["body_points"], dtype=float) @ R.T


def _rigid_spec_from_dict(data: dict, where: str) -> PlanSpec:
    if ("airplanes" in data) == ("formation" in data):
        raise InvalidInputError(f"{where}: a rigid-se3 spec needs exactly one of [airplanes] (seed 004 §4) or "
                                "[formation] (masses, body_points, inertias, start, end, actuation), "
                                "not [robots]")
    unknown = sorted(set(data) - (_TOP_KEYS - {"robots"}) - {"airplanes", "formation"})
    if unknown:
        raise InvalidInputError(f"{where}: unknown key(s) {unknown} at top level; see docs/planning.md")
    table = "airplanes" if "airplanes" in data else "formation"
    if not isinstance(data[table], dict):
        raise InvalidInputError(f"{where}: [{table}] must be a table")
    if table == "airplanes":
        bad = sorted(set(data[table]) - set(_AIRPLANE_KEYS))
        if bad:
            raise InvalidInputError(f"{where}: [airplanes] unknown key(s) {bad}; allowed {sorted(_AIRPLANE_KEYS)}")
    try:
        duration = float(data.get("duration_s", 1.0))
        knots = _knots(data.get("knots", 201), where)
        clearance = float(data.get("min_clearance_m", 0.05))
        spec = PlanSpec(name=str(data.get("name", Path(where).stem)), kind="rigid-se3", masses=np.ones(1),
                        start=np.zeros((1, 3)), goal=np.zeros((1, 3)), duration_s=duration, knots=knots,
                        min_clearance_m=clearance, title=str(data.get("title", "")),
                        source=str(data.get("source", "")), options={table: dict(data[table])})
        form = rigid_formation_dict(spec)
        masses = check_masses(form["masses"])
        start, goal = _robot_positions(form, "start"), _robot_positions(form, "end")
    except (KeyError, TypeError, ValueError) as exc:
        raise _input_error(exc, where, table) from None
    if not (np.isfinite(duration) and duration > 0 and knots >= 2 and clearance >= 0):
        raise InvalidInputError(f"{where}: need duration_s > 0, knots >= 2, min_clearance_m >= 0")
    if start.shape != (masses.size, 3):
        raise InvalidInputError(f"{where}: body_points must give one 3-D point per mass, got {start.shape}")
    return dataclasses.replace(spec, masses=masses, start=start, goal=goal)


def _rigid_se3(spec: PlanSpec):
    rigid = rigid_plan_from_spec(rigid_formation_dict(spec))
    s = rigid.sample(rigid.times)
    info = {"kind": spec.kind, "name": spec.name, "source": spec.source, "masses": rigid.masses.tolist(),
            "actuation": ["airplane" if a else "full" for a in rigid.airplane]}
    if "airplanes" in spec.options:
        info["case"] = {**_AIRPLANE_KEYS, **spec.options["airplanes"]}["case"]
    plan = Plan(rigid.times, s.positions, s.velocities, s.accelerations, rigid.masses, info, s.orientations)
    extra = {key: (None if isinstance(v, float) and not np.isfinite(v) else v) for key, v in rigid.metrics().items()}
    if "case" in info:
        extra["case"] = info["case"]
    return plan, extra


#: Each spec ``kind``: ``(name of its options table, planner)``; the planner is
#: ``f(spec) -> (Plan, dict of solver metrics)``.
PLANNERS = {"shaped-geodesic": ("shaping", _shaped_geodesic), "rigid-se3": ("formation", _rigid_se3)}


def make_plan(spec: PlanSpec):
    """Solve ``spec``: returns ``(plan, metrics)`` with ``converged = True`` and the measures of
    :func:`plan_metrics`; a planner that fails raises (e.g. ConvergenceError)."""
    plan, extra = PLANNERS[spec.kind][1](spec)
    metrics = {"converged": True, **extra, **plan_metrics(plan, spec)}
    return plan, metrics
