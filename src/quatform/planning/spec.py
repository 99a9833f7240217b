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

from ..tomlio import builtin_files, read_toml
from ..algebra import matrix_from_q
from ..checks import check_keys, check_work, integer, number, short, text, vector
from ..checks import table as table_
from ..errors import InvalidInputError, QuatformError
from ..registry import Registry
from .geodesic import meeting_bound, plan_from_geodesic, plan_through_meeting, solve_geodesic
from .measures import min_separation, rigid_motion, straight_line_motion
from .plan import PLAN_MAX_ABS, PLAN_MIN_STEP_S, Plan, check_plan_rates
from .rigid_formation import AIRPLANE_CASES, RIGID_SPEC_KEYS, airplanes_spec, rigid_plan_from_spec
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


_HINT = "see docs/planning.md"
#: Bytes and seconds a knot of a saved plan costs (generous: the sampled arrays, the spline or
#: projected-curve evaluation, the npz write), per robot coordinate.
_BYTES_PER_KNOT_COORD, _SECONDS_PER_KNOT_COORD = 400.0, 2e-6


def _common(data: dict, where: str) -> tuple[float, int, float]:
    """``duration_s``, ``knots`` and ``min_clearance_m`` of a spec, read with quatform.checks."""
    duration = number(data, "duration_s", where, 1.0, low=0.0, low_open=True)
    knots = integer(data, "knots", where, 201, low=2)
    clearance = number(data, "min_clearance_m", where, 0.05, low=0.0)
    _check_spacing(where, duration, knots)
    return duration, knots, clearance


def _check_spacing(where: str, duration: float, knots: int) -> None:
    """Refuse a ``duration_s`` beyond :data:`~.plan.PLAN_MAX_ABS` or one that spaces the ``knots``
    closer than :data:`~.plan.PLAN_MIN_STEP_S` (the bounds of every plan, docs/planning.md)."""
    if duration > PLAN_MAX_ABS:
        raise InvalidInputError(f"{where}: duration_s = {duration:g} s is beyond the bound {PLAN_MAX_ABS:g} s of "
                                "a plan's times (docs/planning.md); give a physical duration")
    if duration / (knots - 1) < PLAN_MIN_STEP_S:
        raise InvalidInputError(f"{where}: duration_s = {duration:g} s over knots = {knots} spaces the knots "
                                f"{duration / (knots - 1):.3g} s apart, below a plan's smallest knot spacing "
                                f"{PLAN_MIN_STEP_S:g} s (its rates divide by the spacing squared; docs/planning.md); "
                                f"give a duration_s of at least {(knots - 1) * PLAN_MIN_STEP_S:.3g} s or fewer knots")


def _check_knots(where: str, knots: int, coords: int) -> None:
    """Refuse a plan whose knots would not fit in memory or time (``coords`` = N * d)."""
    check_work(where, "knots", float(knots), bytes_per_step=_BYTES_PER_KNOT_COORD * max(coords, 1),
               seconds_per_step=_SECONDS_PER_KNOT_COORD * max(coords, 1), fix="use fewer knots (201 is plenty: "
               "Plan.sample interpolates between them)")


def _positions(data: dict, key: str, n: int, where: str) -> np.ndarray:
    """``data[key]``: a list of ``n`` positions of 2 or 3 finite numbers each, shape (n, d)."""
    if key not in data:
        raise InvalidInputError(f"{where}: missing key [robots] {key}")
    value = data[key]
    if not isinstance(value, list) or len(value) != n or not all(isinstance(p, list) for p in value):
        raise InvalidInputError(f"{where}: [robots] {key} = {short(value)} must be a list of N = {n} positions "
                                "(one per mass) of 2 or 3 numbers each")
    d = len(value[0])
    if d not in (2, 3):
        raise InvalidInputError(f"{where}: [robots] {key} positions need 2 or 3 coordinates, got {short(value[0])}")
    return np.array([vector({key: p}, key, d, where, place="[robots]") for p in value])


def builtin_plan_specs() -> dict[str, Path]:
    """Built-in plan specs by name."""
    return builtin_files("plans")


def load_plan_spec(name_or_file) -> PlanSpec:
    """A built-in spec by name, or a TOML file by path; every mistake is an InvalidInputError."""
    data, p = read_toml(name_or_file, builtin_plan_specs(), "plan spec")
    return plan_spec_from_dict(data, where=str(p))


def plan_spec_from_dict(data: dict, where: str = "plan spec") -> PlanSpec:
    """Build a :class:`PlanSpec` from parsed TOML (every value read with :mod:`quatform.checks`)."""
    kind = text(data, "kind", where, choices=sorted(PLANNERS))
    if kind == "rigid-se3":
        return _rigid_spec_from_dict(data, where)
    table = PLANNERS[kind][0]
    check_keys(data, _TOP_KEYS | {table}, where, hint=_HINT)
    rb = table_(data, "robots", where)
    check_keys(rb, {"masses", "start", "goal"}, where, "[robots]", _HINT)
    if "masses" not in rb:
        raise InvalidInputError(f"{where}: missing key [robots] masses")
    masses = rb["masses"]
    if not isinstance(masses, list) or not masses:
        raise InvalidInputError(f"{where}: [robots] masses = {short(masses)} must be a list of N >= 2 numbers")
    masses = check_masses(vector(rb, "masses", len(masses), where, place="[robots]"), f"{where}: [robots] masses")
    start = _positions(rb, "start", masses.size, where)
    goal = _positions(rb, "goal", masses.size, where)
    if goal.shape != start.shape:
        raise InvalidInputError(f"{where}: [robots] start and goal must have the same number of coordinates; "
                                f"got shapes {start.shape} and {goal.shape}")
    duration, knots, clearance = _common(data, where)
    _check_knots(where, knots, start.size)
    options = table_(data, table, where, default={})
    return PlanSpec(name=text(data, "name", where, Path(where).stem), kind=kind, masses=masses, start=start,
                    goal=goal, duration_s=duration, knots=knots, min_clearance_m=clearance,
                    title=text(data, "title", where, ""), source=text(data, "source", where, ""),
                    options=dict(options))


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
    check_keys(spec.options, {"alpha"}, spec.name, "[shaping]", _HINT)
    alpha = check_alpha(number(spec.options, "alpha", spec.name, place="[shaping]", low=0.0, high=1.0,
                               low_open=True, high_open=True))
    info = {"kind": spec.kind, "name": spec.name, "alpha": alpha, "masses": spec.masses.tolist(),
            "source": spec.source}
    known = meeting_bound(spec.start, spec.goal, spec.masses)
    if known is not None and alpha != 0.5 and alpha <= known[0]:
        # no smooth geodesic: the minimiser runs through the robots' meeting (the plan flags it)
        t0 = time.perf_counter()
        plan = plan_through_meeting(spec.start, spec.goal, spec.masses, alpha, spec.duration_s, spec.knots, info)
        extra = {"alpha": alpha, "solve_time_s": time.perf_counter() - t0, "through_meeting": True,
                 "geodesic_bound_alpha": known[0], "meeting_time_s": plan.info["meeting_time_s"],
                 # info["energy"] is the constant integrand q̇^T M_alpha q̇; its integral over [0, T]
                 "energy": plan.info["energy"] * spec.duration_s}
        return plan, extra
    sol = solve_geodesic(spec.start, spec.goal, spec.masses, alpha)
    plan = plan_from_geodesic(sol, spec.duration_s, spec.knots, info)
    extra = {"alpha": alpha, "solve_time_s": sol.solve_time_s, "endpoint_error_m": sol.endpoint_error_m,
             "energy_drift": sol.energy_drift, "collocation_nodes": int(sol.s.size),
             "continuation_alphas": [round(a, 12) for a in sol.continuation], "initial_guess": sol.guess,
             "through_meeting": False,
             # int_0^T q̇^T M_alpha q̇ dt with q̇ = q' / T (seed 002 eq. (12)): the s-energy over T
             "energy": sol.energy / spec.duration_s,
             "second_variation": sol.second_variation,
             "rejected_geodesics": [{"initial_guess": g, "energy": e / spec.duration_s} for g, e in sol.alternatives]}
    return plan, extra


# --------------------------------------------------------------------------- seed 004

#: Parameters of the ``[airplanes]`` table (seed 004 §4) and their defaults.
_AIRPLANE_KEYS = {"case": "b", "m": 1.0, "a": 5.0, "h": 10.0, "X": 20.0, "Y": 20.0}


def rigid_formation_dict(spec: PlanSpec) -> dict:
    """The :func:`~quatform.planning.rigid_plan_from_spec` input of a ``"rigid-se3"`` spec."""
    opts = spec.options
    if "airplanes" in opts:
        a = opts["airplanes"]
        check_keys(a, _AIRPLANE_KEYS, spec.name, "[airplanes]", _HINT)
        case = text(a, "case", spec.name, _AIRPLANE_KEYS["case"], place="[airplanes]", choices=AIRPLANE_CASES)
        form = airplanes_spec(case, *(number(a, k, spec.name, _AIRPLANE_KEYS[k], place="[airplanes]", low=0.0,
                                             low_open=k in ("m", "a", "h")) for k in ("m", "a", "h", "X", "Y")))
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
    check_keys(data, (_TOP_KEYS - {"robots"}) | {"airplanes", "formation"}, where, hint=_HINT)
    table = "airplanes" if "airplanes" in data else "formation"
    options = table_(data, table, where)
    if table == "formation":
        clash = sorted({"duration", "samples"} & set(options))
        if clash:
            raise InvalidInputError(f"{where}: [formation] {', '.join(clash)} - give the plan's length and "
                                    "knots at the top level as duration_s and knots")
        check_keys(options, set(RIGID_SPEC_KEYS) - {"duration", "samples"}, where, "[formation]", _HINT)
    duration, knots, clearance = _common(data, where)
    spec = PlanSpec(name=text(data, "name", where, Path(where).stem), kind="rigid-se3", masses=np.ones(1),
                    start=np.zeros((1, 3)), goal=np.zeros((1, 3)), duration_s=duration, knots=knots,
                    min_clearance_m=clearance, title=text(data, "title", where, ""),
                    source=text(data, "source", where, ""), options={table: options})
    try:
        form = rigid_formation_dict(spec)
        masses = check_masses(form["masses"])
        start, goal = _robot_positions(form, "start"), _robot_positions(form, "end")
    except (KeyError, TypeError, ValueError) as exc:
        raise _input_error(exc, where, table) from None
    _check_knots(where, knots, 3 * masses.size)
    if start.shape != (masses.size, 3):
        raise InvalidInputError(f"{where}: body_points must give one 3-D point per mass, got {start.shape}")
    return dataclasses.replace(spec, masses=masses, start=start, goal=goal)


def _rigid_se3(spec: PlanSpec):
    rigid = rigid_plan_from_spec(rigid_formation_dict(spec))
    s = rigid.sample(rigid.times)
    check_plan_rates(spec.duration_s, s.velocities * spec.duration_s, s.accelerations * spec.duration_s ** 2, spec.name)
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
PLANNERS = Registry("planner")
PLANNERS.add("shaped-geodesic", ("shaping", _shaped_geodesic))
PLANNERS.add("rigid-se3", ("formation", _rigid_se3))


def make_plan(spec: PlanSpec):
    """Solve ``spec``: returns ``(plan, metrics)`` with ``converged = True`` and the measures of
    :func:`plan_metrics`; a planner that fails raises (e.g. ConvergenceError)."""
    _check_spacing(spec.name, spec.duration_s, spec.knots)
    plan, extra = PLANNERS[spec.kind][1](spec)
    metrics = {"converged": True, **extra, **plan_metrics(plan, spec)}
    return plan, metrics
