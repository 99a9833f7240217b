"""A run stepped tick by tick, with an operator's goal and parameters (live layer, beside runs).

:class:`LiveSession` runs one team scenario (``kind = "team"`` files and seed 000's pair files,
which read into the team kind) as :func:`quatform.runs.run` would, but one tick at a time
(:class:`quatform.sim.loop.Stepper`: the loop's one pure tick driven on NumPy, one world), so
that between two ticks

* a goal pose (:meth:`set_goal`) moves the reference: from the tick it arrives, the
  reference's centroid and attitude go toward it along the pure step
  :func:`quatform.references.goal.approach_pose` (within :func:`~quatform.references.goal.goal_limits`
  of the robots, its velocity changing by at most those bounds over
  :data:`~quatform.references.goal.GOAL_RAMP_S` per second, from rest at the goal's first tick),
  stated in the scenario's chart (:meth:`~quatform.scenarios.team.TeamChartParts.pose`,
  :meth:`~quatform.scenarios.team.TeamChartParts.posed`) and mapped to the controller's
  description by its ``from_chart``; the shape and headings stay the scenario's;
* the controller's gains and the separation barrier's distance (:meth:`set_parameter`) are
  replaced, each checked by the controller's own check (:func:`quatform.control.team.check_gain`,
  the controller's construction, the barrier's) and refused in one line otherwise; a change
  takes effect from the next tick (the loop's tick rebuilt with the new controller, the carry
  kept).

A client's calls (:meth:`set_goal`, :meth:`set_parameter`, :meth:`parameters`) come from the
server's threads, the ticks from the stepping thread: they hold one lock, so a change is
checked against the state between two ticks and taken by the next one.

Without a goal or a change, each tick's reference is the experiment's own and the run is the
run :func:`quatform.runs.run` makes. :meth:`finish` writes the ticks done (all of them, or
those before a stop) as a run writes its folder (:func:`quatform.runs.write_outputs`,
atomically): the log's desired channels are the references the ticks used.
"""

from __future__ import annotations

import dataclasses
import os
import sys
import threading
from pathlib import Path

import numpy as np

from ..control import Reference, SafeController
from ..control.team import check_gain, team_gain_sizes
from ..errors import InvalidInputError
from ..references.goal import GOAL_RAMP_S, approach_pose, goal_limits
from ..runs import given_options, record_options, record_runs, write_outputs
from ..scenarios import kind_of, load_scenario
from ..scenarios.separation import separation_barrier
from ..scenarios.team import TEAM, TEAM_CHARTS, check_step_stable
from ..sim.loop import Stepper
from ..sim.metrics import min_separations
from ..sim.output import staged_dir
from ..outputs import chosen_writers, writer_choices

__all__ = ["LiveSession", "GAIN_PREFIX", "SEPARATION_PARAMETER", "PAUSED_PARAMETER", "MAX_GOAL_DISTANCE_M"]

#: Parameter names: ``gains.<key>`` for each of the controller's gains (``gains.k_x`` ...),
#: the barrier's distance, and the pause switch.
GAIN_PREFIX = "gains."
SEPARATION_PARAMETER = "min_separation_m"
PAUSED_PARAMETER = "paused"
#: The farthest a goal may be from the reference's centroid now, m (a goal farther off is
#: refused: no scenario's robots cover it, and its distance would overflow the step's arithmetic).
MAX_GOAL_DISTANCE_M = 1e6


def _plain(value):
    """A gain as a parameter value: a float or a list of floats."""
    a = np.asarray(value, dtype=float)
    return float(a) if a.ndim == 0 else [float(x) for x in a.ravel()]


class LiveSession:
    """One team scenario run tick by tick (module docstring).

    Parameters
    ----------
    scenario : object, str or path-like
        A team scenario (a loaded one, a built-in name or a ``.toml`` file).
    options : dict
        The team kind's options (``controller`` required; ``physics`` kinematic only).

    Attributes
    ----------
    times : ndarray, shape (T,)
        The run's ticks, s.
    chart, chart_rate : ndarray, shape (T, n_e)
        The scenario's reference in its chart at every tick, and its rate.
    max_speed, max_rate : float
        The goal motion's bounds, m/s and rad/s (:func:`~quatform.references.goal.goal_limits`).
    """

    def __init__(self, scenario, options: dict):
        sc = load_scenario(scenario) if isinstance(scenario, (str, os.PathLike)) else scenario
        kind = kind_of(sc)
        if kind is not TEAM:
            raise InvalidInputError(f"quatform run --live: {sc.name} is a {kind.name} scenario; a live run steps the "
                                    "team kind (team files and seed 000's pair files), whose reference an operator's "
                                    "goal can move; run it without --live")
        given = given_options(kind, options, where=str(sc.name))
        if given.get("physics", "kinematic") != "kinematic":
            raise InvalidInputError(f"quatform run --live: {sc.name}: --physics {given['physics']} is not stepped "
                                    "live; a live run moves the kinematic models (--physics kinematic)")
        self.kind, self.options = kind, given
        self.experiment = exp = kind.experiment(sc, **given)
        self.scenario = sc = exp.scenario  # a --reference plan replaces the scenario's motion
        self.parts = TEAM_CHARTS[sc.chart]
        self.safe = isinstance(exp.controller, SafeController)
        inner = exp.controller.inner if self.safe else exp.controller
        self.controller_name = given["controller"] if isinstance(given.get("controller"), str) else inner.name
        self.feedforward = bool(inner.feedforward)
        self.inner = inner
        self.formation = inner.formation
        self.times = np.asarray(exp.times, dtype=float)
        self.chart, self.chart_rate = sc.motion(self.times)
        self.stepper = Stepper(exp.plant, exp.controller, exp.reference, self.times, exp.x0, dt=exp.dt,
                               substeps=exp.substeps, measurement=exp.measurement)
        self.dt = float(self.times[1] - self.times[0]) if self.times.size > 1 else float(exp.dt)
        self.max_speed, self.max_rate = goal_limits(sc.team.robots, self._radius())
        self.gains = self._gains(inner)
        self.min_separation = float(exp.meta["safety"]["min_separation_m"]) if self.safe else None
        self.paused = False
        self._lock = threading.RLock()
        self._pending: dict = {}
        self._goal = None  # (p (3,), q (4,)) the operator's goal
        self._pose = None  # the shaped pose (p, q) of the next tick and its velocities (v, w), once a goal came
        self._e, self._c, self._r = [], [], []  # each tick's reference: chart, description, robots
        self.goal_ticks: list = []  # the ticks at which a goal arrived
        self.changes: list = []  # (tick, parameter, value) applied

    # -- set-up ---------------------------------------------------------------------------
    def _radius(self) -> float:
        """The farthest any desired robot is from the centroid over the run (sampled), m."""
        idx = np.unique(np.linspace(0, self.times.size - 1, min(self.times.size, 200)).round().astype(int))
        e = self.chart[idx]
        r = self.parts.robots(self.scenario, e)
        p = self.scenario.team.layout.positions(r)
        centre, _ = self.parts.pose(e)
        return float(np.max(np.linalg.norm(p - centre[:, None, :], axis=-1)))

    def _gains(self, inner) -> dict:
        """The controller's gains by key (the team gain schema's keys it has)."""
        own = getattr(inner, "gains", None)
        keys = team_gain_sizes()
        if isinstance(own, dict):
            return {k: _plain(v) for k, v in own.items() if k in keys}
        return {k: _plain(getattr(inner, k)) for k in keys if hasattr(inner, k)}

    # -- what a client reads and sets (any thread) ------------------------------------------
    def parameters(self) -> dict:
        """Every parameter's current value by name."""
        with self._lock:
            out = {GAIN_PREFIX + k: v for k, v in self.gains.items()}
            if self.min_separation is not None:
                out[SEPARATION_PARAMETER] = float(self.min_separation)
            out[PAUSED_PARAMETER] = bool(self.paused)
            return out

    def set_goal(self, position, quaternion) -> None:
        """The operator's goal for the formation's centroid ``position`` (3,) m and attitude
        ``quaternion`` (4,) ``(w, x, y, z)``, from the next tick; one line for a goal that is not
        finite, a quaternion of norm 0, or a position farther than :data:`MAX_GOAL_DISTANCE_M`
        from the reference's centroid now."""
        p = np.asarray(position, dtype=float).reshape(3)
        q = np.asarray(quaternion, dtype=float).reshape(4)
        n = float(np.linalg.norm(q))
        if not (np.all(np.isfinite(p)) and np.all(np.isfinite(q)) and n > 1e-9):
            raise InvalidInputError(f"goal pose refused: position {p.tolist()} and orientation (w, x, y, z) "
                                    f"{q.tolist()} must be finite with a nonzero quaternion")
        with self._lock:
            now = self._pose[0] if self._pose is not None else self.parts.pose(self._e[-1] if self._e else
                                                                               self.chart[0])[0]
            far = float(np.max(np.abs(p - now)))  # the largest coordinate: no overflow where the norm would
            if far > MAX_GOAL_DISTANCE_M:
                raise InvalidInputError(f"goal pose refused: position {p.tolist()} is {far:.3g} m from the reference "
                                        f"now, farther than {MAX_GOAL_DISTANCE_M:g} m")
            self._pending["goal"] = (p, q / n)

    def set_parameter(self, name: str, value) -> None:
        """Check ``value`` for the parameter ``name`` and apply it from the next tick (:meth:`parameters`
        reads it at once); an unknown name or a value the controller's own checks refuse is one
        line (:class:`~quatform.errors.InvalidInputError`) and nothing changes."""
        said = f"live parameter {name} refused"
        items = value if isinstance(value, (list, tuple)) else [value]
        if any(isinstance(v, int) and not isinstance(v, bool) and abs(v) > sys.float_info.max for v in items):
            raise InvalidInputError(f"{said}: an integer beyond the range of a float is not a finite number")
        if name == PAUSED_PARAMETER:
            if not isinstance(value, bool):
                raise InvalidInputError(f"{said}: {value!r} must be true or false")
            with self._lock:
                self.paused = value
            return
        if name.startswith(GAIN_PREFIX) and name[len(GAIN_PREFIX):] in self.gains:
            key = name[len(GAIN_PREFIX):]
            k = check_gain(value, key, team_gain_sizes()[key], where=said, place="gain")
            with self._lock:
                new = _plain(k if np.ndim(value) else k[0])
                if isinstance(self.gains[key], list) and not isinstance(new, list):  # the declared type kept
                    new = [new] * len(self.gains[key])
                gains = {**self.gains, key: new}
                controller = self._controller(gains, self.min_separation, said)
                self.gains = gains
                self._pending["controller"] = controller
                self._pending.setdefault("changes", {})[name] = gains[key]
            return
        if name == SEPARATION_PARAMETER and self.min_separation is not None:
            with self._lock:  # the robots' state read between two ticks, and the change taken by the next
                d = self._check_separation(value, said)
                controller = self._controller(self.gains, d, said)
                self.min_separation = d
                self._pending["controller"] = controller
                self._pending.setdefault("changes", {})[name] = d
            return
        raise InvalidInputError(f"{said}: no such parameter; parameters: {', '.join(self.parameters())}")

    def _check_separation(self, value, said: str) -> float:
        """The barrier's distance ``value`` checked: a number > 0 (the barrier stays on: turning it
        off changes the controller's state), not broken by the reference nor by the robots now."""
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value) or value <= 0:
            raise InvalidInputError(f"{said}: {value!r} must be a finite number of m > 0 (a live run keeps its "
                                    "separation barrier on)")
        d = float(value)
        try:
            self.parts.check_barrier(self.scenario, d, SEPARATION_PARAMETER, self.chart, self.times, start=False)
        except InvalidInputError as exc:
            raise InvalidInputError(f"{said}: {exc}") from None
        x = self.stepper.carry[0]
        now = float(min_separations(self.scenario.team.layout, self.scenario.team.point(x)[None])[0])
        if now < d:
            raise InvalidInputError(f"{said}: the robots are now {now:.3g} m apart, closer than {d:g} m; give a "
                                    "distance they keep")
        return d

    def _controller(self, gains: dict, d, said: str):
        """The run's controller with ``gains`` (the scenario's controller rebuilt by name: its own
        checks, and the loop's step stability) and, where the run has it, the barrier at ``d`` m."""
        sc = self.scenario
        all_gains = {**sc.gains, self.controller_name: gains}
        try:
            check_step_stable(f"scenario {sc.name!r}", sc.dt_s, all_gains)
            inner = dataclasses.replace(sc, gains=all_gains).controller(self.controller_name, self.feedforward)
            if not self.safe:
                return inner
            return SafeController(inner, separation_barrier(d, sc.dt_s), self.experiment.controller.team)
        except InvalidInputError as exc:
            raise InvalidInputError(f"{said}: {exc}") from None

    # -- the loop (the driver's thread) -------------------------------------------------------
    @property
    def k(self) -> int:
        """Ticks done."""
        return self.stepper.k

    @property
    def done(self) -> bool:
        return self.stepper.k >= self.times.size

    def _take_pending(self) -> None:
        with self._lock:
            pending, self._pending = self._pending, {}
        if "goal" in pending:
            self._goal = pending["goal"]
            self.goal_ticks.append(self.k)
        if "controller" in pending:
            self.stepper.use(pending["controller"])
            self.changes.extend((self.k, name, value) for name, value in pending["changes"].items())

    def reference(self, k: int):
        """Tick ``k``'s reference ``(e, Reference)``: the experiment's, or, once a goal has come,
        the scenario's chart values with the shaped pose; the shaped pose advances one tick."""
        e, ed = self.chart[k], self.chart_rate[k]
        if self._goal is None:
            return e, self.experiment.reference(k)
        if self._pose is None:  # from rest where the reference is (the scenario's own rate is not carried on)
            self._pose = (*self.parts.pose(e if not self._e else self._e[-1]), np.zeros(3), np.zeros(3))
        p, q, v0, w0 = self._pose
        p_next, q_next, v, w = approach_pose(p, q, *self._goal, self.max_speed, self.max_rate, self.dt, v0, w0,
                                             self.max_speed / GOAL_RAMP_S, self.max_rate / GOAL_RAMP_S)
        e, ed = self.parts.posed(e, ed, p, q, v, w, near=self._e[-1] if self._e else None)
        self._pose = (p_next, q_next, v, w)
        c, cd = self.formation.from_chart(e[None], ed[None])
        return e, Reference(c[0], cd[0], self.parts.robots(self.scenario, e[None])[0])

    def step(self) -> None:
        """Run the next tick (the pending goal and parameter changes first), holding the session's
        lock: a client's check of the state (:meth:`set_parameter`) sees it between two ticks."""
        with self._lock:
            self._take_pending()
            e, ref = self.reference(self.k)
            self.stepper.step(ref)
            self._e.append(np.asarray(e, dtype=float))
            self._c.append(np.asarray(ref.c, dtype=float))
            self._r.append(np.asarray(ref.robots, dtype=float))

    def log(self, start: int = 0, ticks=None):
        """The finished log of ticks ``start`` to :attr:`k`, or of the increasing tick indices
        ``ticks`` when given (the kind's derived channels of the references those ticks used)."""
        exp, n = self.experiment, self.k
        ticks = np.arange(start, n) if ticks is None else np.asarray(ticks, dtype=int)
        meta = {"label": exp.label, **exp.meta}
        if n and self.times[n - 1] < meta.get("metrics_from_s", 0.0):
            meta["metrics_from_s"] = 0.0  # a run stopped before the measured window: measured from its start
        log = self.stepper.log(meta, ticks=ticks)
        e, c, r = (np.asarray([refs[i] for i in ticks.tolist()]) for refs in (self._e, self._c, self._r))
        return self.parts.finisher(self.scenario, self.inner, self.times[ticks], e, c, r, None)(log)

    def finish(self, out, *, plots: bool = True, writers: dict | None = None, stopped: bool = False,
               wall_s: float | None = None, failure: str | None = None, signal: int | None = None):
        """Write the ticks done into the folder ``out`` as a run writes it (atomically: the files
        appear when all are written; :meth:`write_into` the staged folder). Returns ``(log, metrics)``."""
        chosen = chosen_writers(writer_choices(writers=writers), out)
        with staged_dir(out) as tmp:
            return self.write_into(tmp, chosen, plots=plots, stopped=stopped, wall_s=wall_s, failure=failure,
                                   signal=signal)

    def write_into(self, folder, chosen: tuple, *, plots: bool = True, stopped: bool = False,
                   wall_s: float | None = None, failure: str | None = None, signal: int | None = None):
        """Write the ticks done into ``folder`` (a staged output folder,
        :func:`~quatform.sim.output.staged_dir`) with ``chosen``, the ``(folder writers, recordings)``
        of :func:`~quatform.outputs.chosen_writers`. ``metrics.json`` adds ``live``: ticks done of
        the run's, whether it was stopped (and the failure or the ``signal`` number that stopped
        it), the goals' ticks, the parameter changes applied (tick, name, value: the last value
        set before that tick, the one the tick ran with), the goal motion's bounds and, given the
        wall time ``wall_s`` (pauses included), ticks per second; ``safety_min_separation_m`` is
        the barrier's distance in force at the end. Returns ``(log, metrics)``."""
        if self.k == 0:
            raise InvalidInputError("quatform run --live: stopped before the first tick; nothing to write")
        folder_writers, recordings = chosen
        log = self.log()
        metrics = record_options(self.kind, self.experiment, dict(self.experiment.metrics(log)))
        metrics["live"] = {"ticks": self.k, "of_ticks": int(self.times.size), "stopped": bool(stopped),
                           "goal_ticks": list(self.goal_ticks),
                           "parameter_changes": [list(c) for c in self.changes],
                           "goal_max_speed_m_s": self.max_speed, "goal_max_rate_rad_s": self.max_rate}
        if failure is not None:
            metrics["live"]["failure"] = failure
        if signal is not None:
            metrics["live"]["signal"] = int(signal)
        applied = [c[2] for c in self.changes if c[1] == SEPARATION_PARAMETER]
        if applied:
            metrics["safety_min_separation_m"] = applied[-1]
        if wall_s is not None:
            metrics["wall_time_s"] = round(wall_s, 3)
            metrics["live"]["ticks_per_s"] = round(self.k / max(wall_s, 1e-9), 1)
        write_outputs(self.kind, self.scenario, self.experiment, log, Path(folder), metrics, plots, folder_writers)
        record_runs(recordings, {"": log}, self.kind, self.scenario)
        return log, metrics
