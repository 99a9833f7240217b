"""Decentralised formations: every robot runs a local law on what its neighbours' radios deliver.

Scenarios layer. A ``kind = "network"`` file names a local law
(:data:`quatform.control.local.LOCAL_CONTROLLERS`) and its gains, the robots (a
``[[robots]]`` entry of one model), the formation's motion (the team kind's ``[shape]``,
``[path]``, ``[attitude]``, ``[headings]``: each robot's desired point over time), the
communication graph (``[graph]``, or a switching schedule ``[[switching]]``), the links'
delay, jitter, loss, rates and staleness (``[links]``) and the robots' start (``[initial]``:
random offsets, turns and antipodal signs about the desired points at ``t = 0``). The run is
:class:`~quatform.control.networked.NetworkedController` in the one loop (NumPy or JAX,
batched), and writes the consensus error against the rate λ₂ predicts, what the links
carried, and ``graph.json`` (``docs/networks.md``, "Scenarios").
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..checks import MISSING, check_keys, check_work, flag, integer, number, records, short, table, text, vector
from ..control.local import LOCAL_CONTROLLERS
from ..control.neighbour_barrier import NeighbourBarrier
from ..control.networked import NetworkedController
from ..errors import InvalidInputError, ResourceLimitError
from ..formations import TeamChart
from ..formations.geometry import mul
from ..formations.layout import POINT_KINDS
from ..network import Graph, Links
from ..network.stress import AffineExample, Stress
from ..references.team_motion import TeamMotion
from ..robots import Team
from ..sim.log import Channel, Log
from ..sim.plants import KinematicTeam
from . import KINDS
from .base import Experiment, Option, ScenarioKind, finish_worlds
from .team import check_team_work, read_motion, read_robots

__all__ = ["NetworkScenario", "NetworkKind", "GRAPH_KINDS", "network_scenario_from_dict", "graph_record",
           "averaged_graph", "measured_rate", "start_points", "network_metrics",
           "desired_at_zero", "CSV_ROBOTS", "AffineMotion", "desired", "affine_extras"]

_HINT = "see docs/networks.md, scenarios"
_TOP_KEYS = ("kind", "name", "title", "source", "duration_s", "dt_s", "metrics_from_s", "law", "gains", "robots",
             "shape", "path", "attitude", "headings", "graph", "switching", "switching_period_s", "links", "initial", "converged_below", "safety", "affine")
_GRAPH_KEYS = ("kind", "directed", "k", "radius_m", "edges", "weights")
_SWITCH_KEYS = ("start_s",) + _GRAPH_KEYS
_LINK_KEYS = ("delay_s", "jitter_s", "drop", "rate_hz", "max_age_s", "seed", "range_m")
_INITIAL_KEYS = ("position_m", "angle_rad", "antipodal", "seed", "offsets")
_SAFETY_KEYS = ("min_separation_m", "gamma", "hold_unheard")
_AFFINE_KEYS = ("leaders", "keyframes")
#: The ``[graph]`` kinds: what each builds over the robots (numbered from 1 in files).
GRAPH_KINDS = ("ring", "complete", "k-nearest", "disk", "edges")


def _law(name: str, gains: dict, where: str):
    """The local law ``name`` with the file's ``gains`` (its dataclass fields, numbers)."""
    from ..checks import nearest
    import quatform.control.local_laws  # noqa: F401  (registers the laws)

    if name not in LOCAL_CONTROLLERS:
        raise InvalidInputError(f"{where}: unknown law {name!r}{nearest(name, LOCAL_CONTROLLERS)}; choose one of "
                                f"{', '.join(sorted(LOCAL_CONTROLLERS))}")
    cls = LOCAL_CONTROLLERS[name]
    fields = tuple(f.name for f in dataclasses.fields(cls)) if dataclasses.is_dataclass(cls) else ()
    check_keys(gains, fields, where, "[gains]", f"the {name} law takes {', '.join(fields) or 'no gains'}")
    values = {k: number(gains, k, where, place="[gains]") for k in gains}
    return cls(**values)


#: Most candidate edges a network run takes (a graph's arrays and the links' schedule hold a
#: few bytes per edge and tick).
MAX_EDGES = 2_000_000


def _check_edges(count: int, what: str, where: str) -> None:
    if count > MAX_EDGES:
        raise ResourceLimitError(f"{where}: {what} gives {count:,} edges, more than {MAX_EDGES:,}; give each robot "
                                 f"fewer neighbours (kind = 'k-nearest' or 'disk')")


def _one_graph(g: dict, where: str, place: str, n: int, positions: np.ndarray) -> Graph:
    kind = text(g, "kind", where, "ring", place=place, choices=GRAPH_KINDS)
    only = {"directed": ("ring", "edges"), "k": ("k-nearest",), "radius_m": ("disk",), "edges": ("edges",),
            "weights": ("edges",)}
    for key, owners in only.items():
        if key in g and kind not in owners:
            raise InvalidInputError(f"{where}: {place} {key} is for kind = {' or '.join(map(repr, owners))}, not "
                                    f"{kind!r}; remove it")
    if kind == "ring":
        return Graph.ring(n, directed=flag(g, "directed", where, True, place=place))
    if kind == "complete":
        _check_edges(n * (n - 1), f"{place} kind = 'complete' of {n} robots", where)
        return Graph.complete(n)
    if kind == "k-nearest":
        k = integer(g, "k", where, place=place, low=1, high=n - 1)
        _check_edges(n * k, f"{place} k = {k} of {n} robots", where)
        return Graph.k_nearest(positions, k)
    if kind == "disk":
        return Graph.disk(positions, number(g, "radius_m", where, place=place, low=0.0, low_open=True))
    edges = g.get("edges", MISSING)
    if not isinstance(edges, list) or not edges or not all(isinstance(e, list) and len(e) == 2 for e in edges):
        raise InvalidInputError(f"{where}: {place} edges must be a list of [receiver, sender] robot numbers "
                                f"(1..{n}), e.g. [[1, 2], [2, 3]]; got {short(edges)}")
    pairs = []
    for e in edges:
        if not all(isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= n for v in e):
            raise InvalidInputError(f"{where}: {place} edge {short(e)} must be two robot numbers in 1..{n} "
                                    f"([receiver, sender])")
        pairs.append((e[0] - 1, e[1] - 1))
    weights = None
    if "weights" in g:
        weights = vector(g, "weights", len(pairs), where, place=place)
    return Graph.from_edges(n, pairs, weights=weights, directed=flag(g, "directed", where, True, place=place))


def averaged_graph(pattern, period: float) -> Graph:
    """The time average over one period of a repeated switching schedule ``[(start_s, Graph),
    ...]``: the union of the edges, each weighted by its weight times the fraction of the
    period its graph holds (its Laplacian is the average of the intervals' Laplacians)."""
    n = pattern[0][1].n
    ends = [s for s, _ in pattern[1:]] + [period]
    acc: dict = {}
    for (start, g), end in zip(pattern, ends):
        for (i, j), w in zip(g.edges.tolist(), g.weights.tolist()):
            acc[(i, j)] = acc.get((i, j), 0.0) + w * (end - start) / period
    return Graph(n, list(acc), weights=list(acc.values()))


def graph_record(links: Links, scenario=None, lambda2=None, extra=None) -> dict:
    """``graph.json``'s content: the robots (numbered from 1), every graph's edges ``[receiver,
    sender]`` with their weights, and the switching schedule (``start_s`` of each graph; a
    repeated one as one period's intervals and ``switching_period_s``); the radio range; the
    λ₂ the run reports; an affine maneuver's leaders and stress weights."""
    graphs = [(None, links.graph)] if isinstance(links.graph, Graph) else list(links.graph)
    out = {}
    if scenario is not None and scenario.switching is not None:
        graphs, out["switching_period_s"] = list(scenario.switching[0]), float(scenario.switching[1])
    if scenario is not None:
        out["range_m"] = scenario.range_m
    if lambda2 is not None:
        out["graph_lambda2"] = float(lambda2)
    if extra and "stress" in extra:
        w = extra["stress"]
        i, j = np.nonzero(w)
        out["affine"] = {"leaders": [int(k) + 1 for k in np.flatnonzero(extra["leader"][:, 0])],
                         "stress": [[int(a) + 1, int(b) + 1, float(w[a, b])] for a, b in zip(i, j)]}
    return {"robots": list(range(1, links.n + 1)), **out,
            "convention": "edge [i, j]: robot i receives robot j's messages (robots numbered from 1)",
            "graphs": [{"start_s": None if s is None else float(s),
                        "edges": (g.edges + 1).tolist(), "weights": g.weights.tolist(),
                        "lambda2": float(g.lambda2())} for s, g in graphs],
            "links": {"delay_s": links.delay_s.tolist(), "jitter_s": links.jitter_s.tolist(),
                      "drop": links.drop.tolist(),
                      "rate_hz": None if links.rate_hz is None else links.rate_hz.tolist(),
                      "max_age_s": links.max_age_s, "seed": links.seed,
                      "candidate_edges": (links.edges + 1).tolist()}}


# --------------------------------------------------------------------------- the scenario

@dataclass(frozen=True, eq=False)
class NetworkScenario:
    """A decentralised run's definition (module docstring).

    Attributes
    ----------
    name, title, source : str
    team : Team
        One model for every robot.
    motion : TeamMotion or AffineMotion
        The desired points over time.
    law : object
        The :class:`~quatform.control.local.LocalController` every robot runs.
    links : Links
        The graph (or switching schedule) and the radio.
    duration_s, dt_s, metrics_from_s : float
    initial : dict
        ``position_m`` (m, each robot's random offset, normal per axis), ``angle_rad`` (each
        pose robot turned by this angle about a random axis; a yaw robot's yaw by a uniform
        draw in ``+-angle_rad``), ``antipodal`` (robot indices whose quaternion starts as -q),
        ``seed``.
    converged_below : float
        The consensus error at the end at or under which the run counts as converged.
    switching : (tuple of (float, Graph), float) or None
        A repeated switching schedule: one period's ``(start_s, Graph)`` intervals and the
        period, s (``links`` holds them repeated over the run).
    range_m : float or None
        The radio's range, m (``[links] range_m``): a message from a sender farther away is
        not used (:class:`~quatform.control.networked.NetworkedController`).
    safety : dict or None
        ``[safety]``: ``min_separation_m`` (m), ``gamma`` (1/s), ``hold_unheard``: each robot's
        separation filter (:class:`~quatform.control.neighbour_barrier.NeighbourBarrier`, its
        speed bound the robots' ``max_speed``); None: no filter.
    """

    name: str
    team: Team
    motion: object
    law: object
    links: Links
    duration_s: float
    dt_s: float = 0.02
    metrics_from_s: float = 0.0
    title: str = ""
    source: str = ""
    groups: tuple = ()
    initial: dict = field(default_factory=dict)
    converged_below: float = 1e-3
    switching: tuple | None = None
    range_m: float | None = None
    safety: dict | None = None

    @property
    def times(self) -> np.ndarray:
        n = int(math.floor(self.duration_s / self.dt_s + 1e-9))
        return np.minimum(np.arange(n + 1) * self.dt_s, self.duration_s)

    def controller(self) -> NetworkedController:
        barrier, hold = None, False
        if self.safety is not None:
            barrier = NeighbourBarrier(self.safety["min_separation_m"], getattr(self.team.robots[0], "max_speed", 0.0)
                                       or 1.0, gamma=self.safety["gamma"], dt_s=self.dt_s)
            hold = self.safety["hold_unheard"]
        return NetworkedController(self.law, self.team, self.links, self.dt_s, range_m=self.range_m, safety=barrier,
                                   hold_unheard=hold, run_ticks=len(self.times))


@dataclass(frozen=True, eq=False)
class AffineMotion:
    """The robots' desired positions as an affine image of a nominal configuration: ``p*_i(t) =
    A(t) p̄_i + b(t)`` in the plane of ``x, y`` (each robot's ``z`` and heading its nominal one),
    ``A`` and ``b`` moving between keyframes (:class:`~quatform.network.stress.AffineExample`'s
    quintic; Zhao 2018's maneuvers).

    Attributes
    ----------
    layout : RobotLayout
    nominal : ndarray, shape (N, 3)
        ``p̄``, m (the file's ``[shape]`` positions).
    keyframes : ndarray, shape (K, 7)
        ``(t_s, θ_rad, s_x, s_y, h, b_x_m, b_y_m)``: ``A = R(θ) [[s_x, h], [0, s_y]]``.
    leaders : tuple of int
        0-based indices of the leaders (the robots that track their targets).
    """

    layout: object
    nominal: np.ndarray
    keyframes: np.ndarray
    leaders: tuple

    def example(self) -> AffineExample:
        return AffineExample(self.nominal[:, :2], np.zeros((0, 2), dtype=int), self.leaders, self.nominal[:, :2],
                             self.keyframes)

    def robots(self, t) -> tuple:
        """The desired robot points and their rates at times ``t`` (``(T,)``): ``(T, layout.size)``
        each (each robot's ``z`` its nominal one, its heading 0)."""
        p, v = self.example().targets(np.asarray(t, dtype=float))          # (T, N, 2) each
        z = np.broadcast_to(self.nominal[:, 2], p.shape[:-1])[..., None]
        out = []
        for xyz in (np.concatenate([p, z], axis=-1), np.concatenate([v, np.zeros_like(z)], axis=-1)):
            padded = np.zeros((len(xyz), self.layout.size + 1))  # a planar robot's z: the column dropped
            padded[:, self.layout.position_index] = xyz
            out.append(padded[:, :-1])
        return tuple(out)


def desired(motion, layout, t) -> tuple:
    """``(r, r_dot)`` ``(T, layout.size)``: the desired robot points of a :class:`TeamMotion` (its
    chart's robots) or an :class:`AffineMotion` at times ``t``."""
    if isinstance(motion, AffineMotion):
        return motion.robots(t)
    e, ed = motion(np.asarray(t, dtype=float))
    chart = TeamChart(layout)
    return chart.robots(e), chart.robot_rates(e, ed)


def desired_at_zero(team: Team, motion) -> np.ndarray:
    """The desired robot points at ``t = 0``, ``(layout.size,)``."""
    return desired(motion, team.layout, np.zeros(1))[0][0]


def _check_graphs(graph, where: str) -> None:
    """Refuse a graph (of a switching schedule: the union over its intervals) in which no robot's
    messages reach every robot: no law reaches consensus there (one line naming the robots;
    :meth:`Graph.check_spanning_tree`)."""
    if isinstance(graph, Graph):
        g, what = graph, "[graph]"
    else:
        pattern = graph
        n = pattern[0][1].n
        edges = sorted({tuple(e) for _, gr in pattern for e in gr.edges.tolist()})
        g, what = Graph(n, edges), "the union of the [[switching]] graphs"
    try:
        g.check_spanning_tree()
    except InvalidInputError as exc:
        raise type(exc)(f"{what}: {exc}") from None


def _check_links(links: Links, dt: float, duration: float, n: int, where: str) -> None:
    """Refuse links over which no message is ever used, and a run too large for the machine."""
    E = len(links.edges)
    if np.all(links.drop >= 1.0):
        raise InvalidInputError(f"{where}: [links] drop = 1 loses every message; give a probability below 1")
    first = np.ceil(links.delay_s / dt - 1e-9)  # ticks to the earliest arrival
    horizon = math.floor(links.max_age_s / dt + 1e-9)
    if np.all(first > horizon):
        raise InvalidInputError(f"{where}: [links] delay_s = {float(np.min(links.delay_s)):g} s reaches past max_age_s "
                                f"= {links.max_age_s:g} s at a {dt:g} s tick: every message arrives stale; raise "
                                f"max_age_s above the delay")
    steps = duration / dt + 1.0
    ring = min(horizon, steps) + 1
    check_work(where, f"duration_s / dt_s = {duration:g} / {dt:g} with {n} robots and {E} candidate edges", steps,
               bytes_per_step=3.0 * E + 8.0 * n * 40.0 + 48.0 * n * ring / steps,
               seconds_per_step=2e-3 + 2e-7 * E + 2e-6 * n,
               fix="shorten duration_s, raise dt_s, use fewer robots or fewer neighbours")


def _affine_motion(data: dict, where: str, team: Team, motion: TeamMotion, duration: float) -> AffineMotion:
    """``[affine]``: the leaders (robot numbers) and the keyframes of ``A(t), b(t)`` over the
    ``[shape]`` template as the nominal configuration."""
    af = table(data, "affine", where)
    check_keys(af, _AFFINE_KEYS, where, "[affine]", _HINT)
    n = team.layout.n
    leaders = af.get("leaders", MISSING)
    if not isinstance(leaders, list) or not leaders or not all(
            isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= n for v in leaders):
        raise InvalidInputError(f"{where}: [affine] leaders must list robot numbers in 1..{n} (the robots that track "
                                f"their targets; at least 3 in the plane), got {short(leaders)}")
    kf = af.get("keyframes", MISSING)
    try:
        kf = np.asarray(kf, dtype=float)
    except (TypeError, ValueError):
        kf = np.zeros((0,))
    if kf.ndim != 2 or kf.shape[1] != 7 or len(kf) < 2 or not np.all(np.isfinite(kf)):
        raise InvalidInputError(f"{where}: [affine] keyframes must be at least two rows [t_s, theta_rad, s_x, s_y, h, "
                                f"b_x_m, b_y_m] of finite numbers (A = R(theta) [[s_x, h], [0, s_y]], b = (b_x, b_y))")
    if kf[0, 0] != 0.0 or np.any(np.diff(kf[:, 0]) <= 0.0):
        raise InvalidInputError(f"{where}: [affine] keyframes' times must start at 0 s and increase, got "
                                f"{', '.join(f'{v:g}' for v in kf[:, 0])}")
    if any(k == "pose" for k in team.layout.kinds):
        raise InvalidInputError(f"{where}: [affine] moves points in the plane; the {team.robots[0].name} robots' "
                                f"orientations have no affine image: give holonomic or planar robots")
    nominal = np.asarray(motion.template, dtype=float) + motion.path(np.zeros(1))[0][0]
    kf.setflags(write=False)
    return AffineMotion(team.layout, nominal, kf, tuple(sorted(v - 1 for v in leaders)))


def network_scenario_from_dict(data: dict, where: str = "scenario") -> NetworkScenario:
    """A :class:`NetworkScenario` of parsed TOML; every mistake is one line naming the key."""
    check_keys(data, _TOP_KEYS, where, hint=_HINT)
    text(data, "kind", where, choices=("network",))
    try:
        duration = number(data, "duration_s", where, low=0.0, low_open=True)
        dt = number(data, "dt_s", where, 0.02, low=0.0, low_open=True, high=duration)
        groups, team = read_robots(data, where)
        if len(groups) != 1:
            raise InvalidInputError(f"{where}: a network team is one robot model; give one [[robots]] entry "
                                    f"(got {len(groups)})")
        team = Team.uniform(team.robots[0], team.layout.n, common_limit=False)
        n = team.layout.n
        check_team_work(where, duration, dt, n)
        motion = read_motion(data, where, team, duration)
        if "affine" in data:
            motion = _affine_motion(data, where, team, motion, duration)
        r0 = desired_at_zero(team, motion)
        pos0 = team.layout.positions(r0)
        law = _law(text(data, "law", where), table(data, "gains", where, default={}), where)
        if "switching" in data and "graph" in data:
            raise InvalidInputError(f"{where}: give [graph] or [[switching]], not both (a switching schedule lists "
                                    f"each interval's graph)")
        period = None
        if "switching_period_s" in data and "switching" not in data:
            raise InvalidInputError(f"{where}: switching_period_s repeats a [[switching]] schedule, and there is "
                                    f"none; remove it or give [[switching]] intervals")
        if "switching" in data:
            pattern = [(number(s, "start_s", w, low=0.0, high=duration), _one_graph(s, w, "[[switching]]", n, pos0))
                       for s, w in records(data, "switching", _SWITCH_KEYS, where, "switching", _HINT)]
            if not pattern:
                raise InvalidInputError(f"{where}: [[switching]] lists no graph; give at least one")
            graph = pattern
            if "switching_period_s" in data:
                period = number(data, "switching_period_s", where, low=0.0, low_open=True)
                if pattern[-1][0] >= period or pattern[0][0] != 0.0:
                    raise InvalidInputError(f"{where}: a repeated [[switching]] schedule starts its first interval "
                                            f"at 0 s and its last before switching_period_s = {period:g} s; got "
                                            f"starts {', '.join(f'{s:g}' for s, _ in pattern)} s")
                repeats = int(math.ceil(duration / period))
                graph = [(r * period + s, g) for r in range(repeats) for s, g in pattern]
        else:
            g = table(data, "graph", where, default={"kind": "ring"})
            check_keys(g, _GRAPH_KEYS, where, "[graph]", _HINT)
            graph = _one_graph(g, where, "[graph]", n, pos0)
        _check_graphs(graph, where)
        lk = table(data, "links", where, default={})
        check_keys(lk, _LINK_KEYS, where, "[links]", _HINT)
        at = {"place": "[links]"}
        rate = number(lk, "rate_hz", where, None, **at, low=0.0, low_open=True) if "rate_hz" in lk else None
        links = Links(graph, delay_s=number(lk, "delay_s", where, 0.0, **at, low=0.0),
                      jitter_s=number(lk, "jitter_s", where, 0.0, **at, low=0.0),
                      drop=number(lk, "drop", where, 0.0, **at, low=0.0, high=1.0), rate_hz=rate,
                      max_age_s=number(lk, "max_age_s", where, 1.0, **at, low=0.0, low_open=True),
                      seed=integer(lk, "seed", where, 0, **at, low=0))
        _check_links(links, dt, duration, n, where)
        ini = table(data, "initial", where, default={})
        check_keys(ini, _INITIAL_KEYS, where, "[initial]", _HINT)
        at = {"place": "[initial]"}
        antipodal = ini.get("antipodal", [])
        if not isinstance(antipodal, list) or not all(isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= n
                                                      for v in antipodal):
            raise InvalidInputError(f"{where}: [initial] antipodal must list robot numbers in 1..{n} (their "
                                    f"quaternions start as -q), got {short(antipodal)}")
        offsets = None
        if "offsets" in ini:
            try:
                offsets = np.asarray(ini["offsets"], dtype=float)
            except (TypeError, ValueError):
                offsets = np.zeros((0,))
            if offsets.shape != (n, 3):
                raise InvalidInputError(f"{where}: [initial] offsets must be {n} rows [dx, dy, dz] (m), one per "
                                        f"robot, got shape {offsets.shape}")
            if not np.all(np.isfinite(offsets)):
                raise InvalidInputError(f"{where}: [initial] offsets hold NaN or infinity; give finite metres")
        if antipodal and not all(team.layout.kinds[v - 1] == "pose" for v in antipodal):
            raise InvalidInputError(f"{where}: [initial] antipodal flips a robot's quaternion, and the "
                                    f"{team.robots[0].name} robots have none; remove it")
        initial = {"offsets": offsets, "position_m": number(ini, "position_m", where, 0.0, **at, low=0.0),
                   "angle_rad": number(ini, "angle_rad", where, 0.0, **at, low=0.0, high=math.pi),
                   "antipodal": tuple(v - 1 for v in antipodal), "seed": integer(ini, "seed", where, 0, **at, low=0)}
        safety = None
        if "safety" in data:
            sf = table(data, "safety", where)
            check_keys(sf, _SAFETY_KEYS, where, "[safety]", _HINT)
            at = {"place": "[safety]"}
            safety = {"min_separation_m": number(sf, "min_separation_m", where, **at, low=0.0, low_open=True),
                      "gamma": number(sf, "gamma", where, min(5.0, 1.0 / dt), **at, low=0.0, low_open=True),
                      "hold_unheard": flag(sf, "hold_unheard", where, False, **at)}
        metrics_from = number(data, "metrics_from_s", where, 0.0, low=0.0, high=duration)
        sc = NetworkScenario(name=text(data, "name", where, Path(where).stem), title=text(data, "title", where, ""),
                             source=text(data, "source", where, ""), team=team, groups=groups, motion=motion,
                             law=law, links=links, duration_s=duration, dt_s=dt, metrics_from_s=metrics_from,
                             initial=initial,
                             converged_below=number(data, "converged_below", where, 1e-3, low=0.0, low_open=True),
                             switching=None if period is None else (tuple(pattern), period),
                             range_m=number(lk, "range_m", where, None, place="[links]", low=0.0, low_open=True)
                             if "range_m" in lk else None, safety=safety)
        sc.controller()  # the law, robots and links fit together
        graphs = [links.graph] if isinstance(links.graph, Graph) else [gr for _, gr in links.graph]
        if (safety is not None or isinstance(motion, AffineMotion)) and not all(gr.undirected for gr in graphs):
            what = "[safety] needs every pair that can meet sensed by both robots" if safety is not None else \
                "[affine] needs every stress edge carried both ways"
            raise InvalidInputError(f"{where}: {what}, and the graph is directed; give an undirected graph "
                                    f"(directed = false, kind = 'disk' or 'complete')")
        if isinstance(motion, AffineMotion):
            affine_extras(sc)  # Zhao's leader condition on the nominal configuration
        if safety is not None:
            _check_start_apart(sc, where)
        if sc.switching is None and isinstance(links.graph, Graph):
            law.predicted_rate(links.graph, dt)  # a gain the discrete loop cannot take: one line here
    except InvalidInputError as exc:
        msg = str(exc)
        raise type(exc)(msg if msg.startswith(where) else f"{where}: {msg}") from None
    return sc


def _check_start_apart(sc: NetworkScenario, where: str) -> None:
    """Refuse a start whose robots are closer than the separation filter's distance (its promise
    needs robots that start at least that far apart)."""
    from scipy.spatial import cKDTree

    d = sc.safety["min_separation_m"]
    p = sc.team.layout.positions(start_points(sc, desired_at_zero(sc.team, sc.motion)))
    dist, idx = cKDTree(p).query(p, k=2)
    i = int(np.argmin(dist[:, 1]))
    if dist[i, 1] < d:
        j = int(idx[i, 1])
        raise InvalidInputError(f"{where}: robots {min(i, j) + 1} and {max(i, j) + 1} start {dist[i, 1]:.3g} m apart, "
                                f"closer than [safety] min_separation_m = {d:g} m (the filter keeps robots apart that "
                                f"start apart); lower [initial] position_m, space the shape wider or lower "
                                f"min_separation_m")


def start_points(sc: NetworkScenario, r0: np.ndarray) -> np.ndarray:
    """The robots' points at ``t = 0``: the desired points ``r0`` with the scenario's random
    offsets and turns (``[initial]``), drawn from ``numpy.random.default_rng(seed)``."""
    ini, L = sc.initial, sc.team.layout
    rng = np.random.default_rng(ini.get("seed", 0))
    r = np.array(r0, dtype=float)
    fixed = ini.get("offsets")
    for i in range(L.n):
        step = ini.get("position_m", 0.0) * rng.normal(size=3)
        if fixed is not None:
            step = step + fixed[i]
        for axis, k in enumerate(L.position_index[i]):
            if k < L.size:  # a planar robot has no z
                r[k] += step[axis]
    ang = ini.get("angle_rad", 0.0)
    for i, o in enumerate(L.offsets):
        comps = [c[0] for c in POINT_KINDS[L.kinds[i]].components]
        if "q_w" in comps:
            q0 = o + comps.index("q_w")
            axis = rng.normal(size=3)
            axis = axis / max(np.linalg.norm(axis), 1e-300)
            turn = np.r_[math.cos(ang / 2), math.sin(ang / 2) * axis]
            q = mul(turn, r[q0:q0 + 4])
            q = q / np.linalg.norm(q)
            r[q0:q0 + 4] = -q if i in ini.get("antipodal", ()) else q
        elif "theta" in comps:
            r[o + comps.index("theta")] += rng.uniform(-ang, ang)
    return r


def affine_extras(sc: NetworkScenario) -> dict:
    """The static reference of an affine maneuver: ``stress`` (each robot's row of the stress of
    the nominal configuration on the graph's undirected edges, :class:`Stress`, Zhao's leader
    condition checked) and ``leader`` (1 for a leader, ``(N, 1)``)."""
    graphs = [sc.links.graph] if isinstance(sc.links.graph, Graph) else [g for _, g in sc.links.graph]
    pairs = sorted({(min(i, j), max(i, j)) for g in graphs for i, j in g.edges.tolist()})
    motion = sc.motion
    stress = Stress(motion.nominal[:, :2], np.asarray(pairs, dtype=int))
    stress.check_leaders(list(motion.leaders))
    flag = np.zeros((sc.team.layout.n, 1))
    flag[list(motion.leaders)] = 1.0
    return {"stress": stress.rows(), "leader": flag}


def measured_rate(t: np.ndarray, err: np.ndarray, t_from: float = 0.0, floor: float = 1e-12):
    """The exponential decay rate of ``err`` (1/s): minus the least-squares slope of ``log err``
    over the samples from ``t_from`` on where the error has fallen to half its largest value
    there and is still above ``floor`` times that largest value (rounding's noise below); None
    with fewer than 10 such samples or no decay."""
    t, err = np.asarray(t, dtype=float), np.asarray(err, dtype=float)
    keep = (t >= t_from) & np.isfinite(err)
    if keep.sum() < 10:
        return None
    top = float(np.max(err[keep]))
    if not top > 0.0:
        return None
    start = int(np.argmax(keep & (err <= 0.5 * top)))
    use = keep & (np.arange(len(t)) >= start) & (err > floor * top) & (err > 0.0)
    if use.sum() < 10 or not np.any(keep & (err <= 0.5 * top)):
        return None
    slope = np.polyfit(t[use], np.log(err[use]), 1)[0]
    return float(-slope) if slope < 0 else None


#: Teams up to this size write every robot's columns to ``timeseries.csv`` (a larger one's are
#: in ``run.mcap``; its CSV holds the consensus error and the links' counts).
CSV_ROBOTS = 100


class NetworkKind(ScenarioKind):
    """Robots that each run a local law on their neighbours' delayed and lost messages."""

    name = "network"
    scenario_type = NetworkScenario
    compare_over = "law"

    @property
    def options(self) -> tuple:
        """The run's options; the law's choices are the local laws registered now."""
        import quatform.control.local_laws  # noqa: F401  (registers the laws)

        return (Option("law", "the local law every robot runs (default: the scenario's)",
                       tuple(sorted(LOCAL_CONTROLLERS)), None),)
    table_columns = (("law", "law", "{}"), ("graph_lambda2", "lambda2", "{:.4g}"), ("predicted_rate", "predicted 1/s", "{:.4g}"),
                     ("measured_rate", "measured 1/s", "{:.4g}"), ("converged", "converged", "{}"),
                     ("messages_dropped", "dropped", "{}"))

    def from_dict(self, data: dict, where: str) -> NetworkScenario:
        return network_scenario_from_dict(data, where)

    def compare_choices(self, scenario, axis: str) -> tuple[tuple, dict]:
        """Over ``law``: the laws that can drive the scenario's robots (with their default gains),
        and the others with their one-line refusal."""
        if axis != "law" or not isinstance(scenario, NetworkScenario):
            return super().compare_choices(scenario, axis)
        run, skipped = [], {}
        for name in self.options[0].choices:
            try:
                law = scenario.law if name == scenario.law.name else _law(name, {}, f"scenario {scenario.name!r}")
                ex = self.experiment(dataclasses.replace(scenario, law=law))
                ex.controller.reference_arrays((ex.reference(0), None))  # the law reads this scenario's reference
            except InvalidInputError as exc:
                skipped[name] = str(exc)
            else:
                run.append(name)
        return tuple(run), skipped

    def experiment(self, scenario: NetworkScenario, law=None) -> Experiment:
        if not isinstance(scenario, NetworkScenario):
            raise InvalidInputError(f"network experiment: scenario must be a NetworkScenario, got "
                                    f"{type(scenario).__name__}")
        if law is not None and law != scenario.law.name:  # another law, with its default gains
            scenario = dataclasses.replace(scenario, law=_law(law, {}, f"scenario {scenario.name!r}"))
        ctrl = scenario.controller()
        team, L = scenario.team, scenario.team.layout
        t = scenario.times
        r_des, rd_des = desired(scenario.motion, L, t)
        extra = {}
        if isinstance(scenario.motion, AffineMotion):  # the stress of the graph's edges and the leaders
            extra = affine_extras(scenario)
        x0 = start_points(scenario, r_des[0])
        plant = KinematicTeam(team)
        graphs = [scenario.links.graph] if isinstance(scenario.links.graph, Graph) else \
            [g for _, g in scenario.links.graph]
        lam = min(float(g.lambda2()) for g in graphs)
        law_obj = scenario.law
        if len(graphs) == 1:
            predicted = law_obj.predicted_rate(graphs[0], scenario.dt_s)
        elif scenario.switching is not None:
            pattern, period = scenario.switching
            lam = float(averaged_graph(pattern, period).lambda2())
            shortest = min(np.diff([st for st, _ in pattern] + [period]))
            # a message held longer than an interval carries an edge past its graph: no prediction
            predicted = law_obj.predicted_rate(list(pattern), scenario.dt_s, switching_period_s=period) \
                if scenario.links.max_age_s < shortest else None
        else:
            predicted = None
        meta = {"kind": self.name, "scenario": scenario.name, "title": scenario.title, "source": scenario.source,
                "dt_s": scenario.dt_s, "metrics_from_s": scenario.metrics_from_s, "law": law_obj.name,
                "n_robots": L.n, "layout": L, "team": team, "graph": graph_record(scenario.links, scenario, lam, extra),
                "links": scenario.links,
                "graph_lambda2": lam, "predicted_rate": predicted}

        def reference_at(k):
            return {"robots": r_des[k], "robots_rate": rd_des[k], **extra}

        own = ctrl.own_index()

        def finish_one(log: Log) -> Log:
            m = np.asarray(log["measured"], dtype=float)
            err = law_obj.consensus_error(m[..., own], r_des[..., own])
            return log.with_channels(Channel("points", L.names, team.point(np.asarray(log["state"], dtype=float))),
                                     Channel("r_des", tuple(n + "_des" for n in L.names), r_des),
                                     Channel("consensus_error", ("consensus_error",), err[..., None]))

        def finish(log: Log) -> Log:
            return finish_worlds(log.with_channels(batch=log.batch_shape), finish_one)

        def metrics(log: Log) -> dict:
            return network_metrics(log, scenario, ctrl)

        csv = ("consensus_error", "network") + (("command", ("measured", "r_des"), *(("safety",) if ctrl.safety else ()))
                                                 if L.n <= CSV_ROBOTS else ())
        return Experiment(scenario=scenario, label=law_obj.name, plant=plant, controller=ctrl,
                          reference=reference_at, times=t, x0=x0, dt=scenario.dt_s, finish=finish, metrics=metrics,
                          csv_channels=csv, meta=meta)


def network_metrics(log: Log, scenario: NetworkScenario, ctrl: NetworkedController) -> dict:
    """One world's ``metrics.json`` of a network run (``docs/networks.md``, "Scenarios")."""
    from scipy.spatial import cKDTree

    t = log.t
    err = np.asarray(log["consensus_error"], dtype=float)[:, 0]
    net = np.asarray(log["network"], dtype=float)
    u = np.asarray(log["command"], dtype=float)
    L = scenario.team.layout
    pos = L.positions(np.asarray(log["measured"], dtype=float))
    sep = np.array([cKDTree(p).query(p, k=2)[0][:, 1].min() if np.all(np.isfinite(p)) else np.nan for p in pos])
    final = float(err[-1])
    # a rate is measured against a prediction; a law with none (an affine maneuver) has no rate to compare
    rate = measured_rate(t, err, scenario.metrics_from_s) if log.meta["predicted_rate"] is not None else None
    d_min = None if scenario.safety is None else float(scenario.safety["min_separation_m"])
    return {"scenario": scenario.name, "law": scenario.law.name, "n_robots": L.n,
            "graph_edges": int(len(ctrl.links.edges)),
            "graph_lambda2": log.meta["graph_lambda2"], "predicted_rate": log.meta["predicted_rate"],
            "measured_rate": rate, "converged": bool(np.isfinite(final) and final <= scenario.converged_below),
            "consensus_error_initial": float(err[0]), "consensus_error_final": final,
            "consensus_error_threshold": scenario.converged_below,
            "messages_sent": int(net[:, 0].sum()), "messages_dropped": int(net[:, 1].sum()),
            "messages_delivered": int(net[:, 2].sum()), "max_message_age_s": float(np.nanmax(net[:, 3])),
            "min_separation_m": float(np.nanmin(sep)), "safety_distance_m": d_min,
            "separation_kept": bool(d_min is None or np.nanmin(sep) >= d_min * (1.0 - 1e-9)),
            "nonfinite_commands": int(np.sum(~np.all(np.isfinite(u), axis=-1))),
            "failed": bool(log.meta.get("failed", False) is True)}



#: The network kind (registered in :data:`quatform.scenarios.KINDS`).
NETWORK = KINDS[NetworkKind.name]
