"""Trials of a sweep: one cell's scenario variant, its batch of worlds, their draws, their rows.

Sweeps layer. A cell is one choice (a controller) at one point of the varied parameters; its
trials run as ONE batch through :meth:`quatform.scenarios.Experiment.run` (B worlds per tick),
each world with its own initial error and its own :class:`~quatform.sim.trial_measurement.TickMeasurement`
noise and dropped frames. A trial's random numbers come from its own stream,
``numpy.random.SeedSequence([seed, point, trial])``: they do not depend on the batch, the
chunk, the worker or the controller (the controllers of one point face the same noise and
the same initial errors: common random numbers). Per trial the metrics are the kind's own
``Experiment.metrics`` of that world's finished log, so a trial with no noise and no offset
equals ``quatform run``.

:data:`SWEEP_KINDS` holds, per scenario kind, what the sweep may vary and how a cell's
scenario and initial states are built (a registry: the spec reader asks it).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..errors import InvalidInputError, QuatformError, ResourceLimitError
from ..formations import EUCLIDEAN_VARIABLES, EuclideanPair
from ..sim.trial_measurement import TickMeasurement
from ..registry import Registry, RegistryView
from ..tomlio import read_toml
from .spec import PARAMETERS

__all__ = ["SweepKind", "SWEEP_KINDS", "NOT_SWEEPABLE", "Chunk", "chunk_batch", "run_chunk", "trial_stream", "cell_experiment",
           "trial_offsets", "scaled_gains",
           "COINCIDENT_M", "ROW_COLUMNS", "row_metrics"]

#: Robots closer than this (m) at any sample coincide: the trial failed.
COINCIDENT_M = 1e-6



def scaled_gains(gains: dict, factor: float, only: str | None) -> dict:
    """``gains`` with each (or only the one named ``only``) times ``factor`` (numbers, lists, arrays, tuples)."""
    return {k: (v if only not in (None, k) else
                type(v)(x * factor for x in v) if isinstance(v, (list, tuple)) else
                np.asarray(v) * factor if isinstance(v, np.ndarray) else v * factor)
            for k, v in gains.items()}


def _offset_scales(variables, m: float, rad: float) -> np.ndarray:
    """Per entry, the bound of its random initial error: ``m`` for positions, ``rad`` for
    angles, 0 for lengths (a pair's ``d_c``) and quaternion components."""
    return np.array([m if v.kind == "position" else rad if v.kind == "angle" else 0.0 for v in variables])


def _noise_scales(variables, m: float, rad: float) -> np.ndarray:
    """Per measured entry, its noise standard deviation (units as :func:`_offset_scales`;
    quaternion components are read without noise)."""
    return np.array([m if v.unit == "m" else rad if v.unit == "rad" else 0.0 for v in variables])


@dataclass(frozen=True)
class SweepKind:
    """How a sweep varies the scenarios of one kind (the pair's and the team's: the robots'
    points measured by a :class:`TickMeasurement`; a kind with its own measurement or plant
    subclasses it and overrides :meth:`batch` and what else differs).

    Attributes
    ----------
    kind : str
        The scenario kind (:data:`SWEEP_KINDS` key).
    cannot : tuple of str
        Parameters that apply to every kind (``kinds`` None) which this kind's batch cannot
        read (the teleop kind has no measurement model to make noisy).
    settle_key : str or None
        The scenario field ``settle_s`` sets: where its errors are measured from (None: the
        kind's metrics have no settling time; ``settle_s`` is refused).
    success : Success or None
        What a successful trial is when the spec has no ``[success]`` (None: the default of
        :mod:`~quatform.sweeps.spec`, errors below 0.1 m / 0.1 rad, the reference not lost).
    scenario_keys : tuple of str
        Parameters without a ``data`` or ``apply`` hook that :meth:`scenario` reads into the
        cell's scenario (the ugv-uav kind's motion-capture settings).
    """

    kind: str
    cannot: tuple = ()
    settle_key: str | None = "metrics_from_s"
    success: object = None
    scenario_keys: tuple = ()

    def variant(self, choice: str, values: dict) -> tuple:
        """What makes a cell's scenario differ from another's: the choice and the values of the
        parameters that change the scenario (their ``data``/``apply`` hooks, :attr:`scenario_keys`)."""
        return (choice, *((k, v) for k, v in values.items()
                          if k in self.scenario_keys or PARAMETERS[k].data is not None or PARAMETERS[k].apply is not None))

    @property
    def parameters(self) -> tuple:
        """The keys of :data:`~quatform.sweeps.spec.PARAMETERS` it can vary (each parameter's
        ``kinds``, less :attr:`cannot`)."""
        return tuple(name for name, p in PARAMETERS.items() if p.applies_to(self.kind) and name not in self.cannot)

    def robots(self, exp) -> int:
        """How many robots one world moves (for the wall-time estimate)."""
        return exp.controller.team.layout.n

    def shorten(self, sc, duration_s: float | None, settle_s: float | None):
        """``sc`` run for its first ``duration_s`` with its errors measured from ``settle_s``
        (None: the scenario's own)."""
        short = {}
        if duration_s is not None:
            short["duration_s"] = duration_s
        if settle_s is not None:
            short[self.settle_key] = settle_s
        return dataclasses.replace(sc, **short) if short else sc

    def scenario(self, sc, values: dict):
        """The cell's scenario with the point's ``values`` of the parameters the kind reads
        into its scenario (here none: the batch reads them, :meth:`batch`)."""
        return sc

    def gains(self, sc, choice: str) -> dict:
        """The gains of the choice ``choice`` by name (what ``gain_scale`` multiplies)."""
        return dict(sc.gains.get(choice, {}))

    def with_gains(self, sc, choice: str, gains: dict):
        """``sc`` with ``gains`` (:meth:`gains`' names) for the choice ``choice``."""
        return dataclasses.replace(sc, gains={**sc.gains, choice: gains})

    def batch(self, exp, values: dict, seed: int, point: int, trials: list):
        """``(batch, delay)``: the experiment of the trials ``trials`` of one cell (its worlds'
        initial states and their :class:`TickMeasurement`, drawn from each trial's
        :func:`trial_stream`; ``finish`` the identity: each world is finished on its own) and
        the latency in control ticks."""
        T = len(exp.times)
        tick = exp.substeps * exp.dt
        out_vars = _output_variables(exp)
        off_vars = self.variables(exp)
        z, u, off = _draws(seed, point, trials, T, len(out_vars), len(off_vars))
        noise = z * _noise_scales(out_vars, values.get("noise_m", 0.0), values.get("noise_rad", 0.0))
        delay = int(round(values.get("latency_s", 0.0) / tick))
        dropped = u < values.get("dropout_rate", 0.0)
        x0 = self.initial(exp, off, values.get("initial_offset_m", 0.0), values.get("initial_offset_rad", 0.0))
        return dataclasses.replace(exp, x0=x0, measurement=TickMeasurement(noise, delay, dropped),
                                   finish=lambda log: log), delay

    def data(self, data: dict, values: dict, where: str) -> dict:
        """The scenario file's table for a cell (each varied parameter's ``data``: ``team_size``
        changes the robot count)."""
        for name, value in values.items():
            hook = PARAMETERS[name].data
            if hook is not None:
                data = hook(data, value, where)
        return data

    def variables(self, exp):
        """The entries a trial's initial error is drawn on (:class:`~quatform.formations.layout.Variable`)."""
        return exp.controller.team.layout.variables

    def initial(self, exp, unit: np.ndarray, m: float, rad: float) -> np.ndarray:
        """Initial states ``(B, n_x)``: the experiment's own moved by ``unit`` (``(B, n)``
        uniform in [-1, 1]) times the bounds ``m`` / ``rad``."""
        return np.asarray(exp.x0, dtype=float)[None] + unit * _offset_scales(self.variables(exp), m, rad)


@dataclass(frozen=True)
class PairSweep(SweepKind):
    """Seed 000's two robots: the initial error is drawn on the Euclidean cluster variables
    (centroid in m, ``beta_c, gamma_c, phi_1, phi_2`` in rad; ``d_c`` kept), seed 000 eqs. (1)-(8)."""

    def variables(self, exp):
        return EUCLIDEAN_VARIABLES

    def initial(self, exp, unit, m, rad):
        sc = exp.scenario
        e0 = np.asarray(sc.path(np.asarray(sc.times[:1]))[0])[0] + sc.initial_offset
        e = e0[None] + unit * _offset_scales(EUCLIDEAN_VARIABLES, m, rad)
        return EuclideanPair().inverse(e)  # seed 000 eqs. (1)-(8) solved for the robots


#: Sweep adapters by scenario kind, by the name its parts are registered under
#: (:meth:`~quatform.scenarios.ScenarioKind.parts_of`: the team kind's seed-000 files ``"pair"``;
#: ``SWEEP_KINDS.add(name, adapter)`` beside the adapter; a new kind's file adds its own).
SWEEP_KINDS = Registry("sweep kind")
SWEEP_KINDS.add("pair", PairSweep("pair"))
SWEEP_KINDS.add("team", SweepKind("team"))


def _not_sweepable() -> dict:
    from ..scenarios import KINDS

    return {name: k.not_sweepable for name, k in KINDS.items() if k.not_sweepable and name not in SWEEP_KINDS}


#: Why the other kinds cannot be swept yet (one line each): each kind's ``not_sweepable``.
NOT_SWEEPABLE: Mapping = RegistryView(_not_sweepable, "NOT_SWEEPABLE")


# --------------------------------------------------------------------------- one cell


@lru_cache(maxsize=8)
def _scenario_data(ref: str) -> tuple:
    from ..scenarios import builtin_scenarios

    data, p = read_toml(ref, builtin_scenarios(), "scenario")
    return data, str(p)


def cell_scenario(spec, values: dict, choice: str):
    """The scenario of one cell: the spec's overrides and the point's team size and gains."""
    data, where = _scenario_data(spec.scenario)
    kind = _kind(spec)
    adapter = SWEEP_KINDS[spec.data["kind"]]
    data = adapter.data(dict(data), values, spec.where)
    try:
        sc = kind.from_dict(data, where)
    except ResourceLimitError as exc:
        # the kind checks the scenario as its file has it; the sweep's duration_s applies after
        if spec.duration_s is None:
            raise
        raise ResourceLimitError(f"{spec.where}: the scenario is checked at its own length before the sweep's "
                                 f"duration_s = {spec.duration_s:g} s applies, and refused: {exc}") from None
    except InvalidInputError as exc:
        if "team_size" not in values:
            raise
        raise InvalidInputError(f"{spec.where}: [vary.team_size] value {values['team_size']}: {exc}") from None
    # the first duration_s of the scenario (its changes past the end do not happen), measured from settle_s
    try:
        sc = adapter.shorten(sc, spec.duration_s, spec.settle_s)
    except InvalidInputError as exc:
        raise InvalidInputError(f"{spec.where}: duration_s / settle_s: {exc}") from None
    try:
        sc = adapter.scenario(sc, values)
    except InvalidInputError as exc:
        raise InvalidInputError(f"{spec.where}: {', '.join(f'{k} = {v:g}' for k, v in values.items())}: {exc}") \
            from None
    for name, value in values.items():  # each varied parameter's change of the scenario
        hook = PARAMETERS[name].apply
        if hook is not None:
            sc = hook(sc, value, spec, choice)
    return sc


def cell_experiment(spec, values: dict, choice: str):
    """The single-world experiment of a cell (its scenario and choice, nothing drawn yet)."""
    return _kind(spec).experiment(cell_scenario(spec, values, choice), **{spec.compare_key: choice})


def _kind(spec):
    """The scenario kind of a sweep (its ``data["kind"]``: a kind's name or an alias it reads)."""
    from ..scenarios import KINDS, kind_aliases

    return KINDS[kind_aliases().get(spec.data["kind"], spec.data["kind"])]


def trial_stream(seed: int, point: int, trial: int) -> np.random.Generator:
    """The random stream of one trial: ``SeedSequence([seed, point, trial])``."""
    return np.random.default_rng(np.random.SeedSequence([int(seed), int(point), int(trial)]))


def trial_offsets(seed: int, point: int, trials, n: int) -> np.ndarray:
    """Each trial's ``n`` uniforms in [-1, 1] (its initial error), the first draws of its own
    :func:`trial_stream`: ``(B, n)`` (for a kind whose measurement draws from its own streams)."""
    return np.array([trial_stream(seed, point, i).uniform(-1.0, 1.0, n) for i in trials]).reshape(len(trials), n)


def _draws(seed, point, trials, T, k, n_off):
    """Each trial's standard normals ``(T, k)``, uniforms ``(T,)`` (dropped frames) and
    uniforms in [-1, 1] ``(n_off,)`` (initial error), in that order from its own stream:
    ``(T, B, k)``, ``(T, B)``, ``(B, n_off)``."""
    z = np.empty((T, len(trials), k))
    u = np.empty((T, len(trials)))
    off = np.empty((len(trials), n_off))
    for b, i in enumerate(trials):
        rng = trial_stream(seed, point, i)
        z[:, b] = rng.standard_normal((T, k))
        u[:, b] = rng.random(T)
        off[b] = rng.uniform(-1.0, 1.0, n_off)
    return z, u, off


@dataclass(frozen=True)
class Chunk:
    """A slice of one cell's trials, the unit of work an executor runs.

    Attributes
    ----------
    spec : SweepSpec
    cell : int
        Index into ``spec.cells()``.
    start, stop : int
        Trials ``start <= i < stop``.
    backend : str
        The compute backend (:data:`quatform.sim.backends.SIM_BACKENDS`).
    """

    spec: object
    cell: int
    start: int
    stop: int
    backend: str = "numpy"

    @property
    def key(self) -> str:
        return f"cell{self.cell:05d}-trials{self.start:06d}-{self.stop:06d}"


def chunk_batch(chunk: Chunk):
    """``(exp, batch, delay)``: the cell's single-world experiment, the batched one of the
    chunk's trials (:meth:`SweepKind.batch`; its ``finish`` is the identity: each world is
    finished on its own) and the latency in control ticks."""
    spec = chunk.spec
    point, choice, values = spec.cells()[chunk.cell]
    seed = int(values.get("seed", spec.seed))
    exp = cell_experiment(spec, values, choice)
    batch, delay = SWEEP_KINDS[spec.data["kind"]].batch(exp, values, seed, point, list(range(chunk.start, chunk.stop)))
    return exp, batch, delay


def run_chunk(chunk: Chunk) -> list[dict]:
    """Run one chunk's trials as one batch; a row per trial (its parameters, seed, metrics,
    ``failed``/``failure``, ``lost``, ``success``)."""
    spec = chunk.spec
    point, choice, values = spec.cells()[chunk.cell]
    seed = int(values.get("seed", spec.seed))
    trials = list(range(chunk.start, chunk.stop))
    exp, batch, delay = chunk_batch(chunk)
    log = batch.run(backend=chunk.backend)
    failed = np.asarray(log.meta.get("failed", np.zeros(len(trials), dtype=bool)))
    failure = dict(log.meta.get("failure", {}))
    rows = []
    for b, i in enumerate(trials):
        row = {"cell": chunk.cell, "point": point, spec.compare_key: choice, **values,
               "latency_ticks": delay, "trial": i, "seed": seed}
        reason = failure.get((b,)) if failed[b] else None
        metrics = {}
        try:
            metrics = exp.metrics(exp.finish(log.world(b)))
        except (QuatformError, ArithmeticError, ValueError) as exc:
            reason = reason or f"metrics: {' '.join(str(exc).split())}"
        sep = metrics.get("min_robot_separation_m")
        if reason is None and isinstance(sep, float) and sep < COINCIDENT_M:
            reason = f"robots coincide (separation {sep:.3g} m)"
        metrics = {k: (v.item() if isinstance(v, np.generic) else v) for k, v in metrics.items()
                   if isinstance(v, (bool, int, float, str, np.generic)) or v is None}
        row.update(metrics)
        row.update(values)  # the cell's own values (a metric of the same name, teleop's preload, says the same)
        row["failed"] = reason is not None
        row["failure"] = reason or ""
        row["lost"] = bool(metrics.get("reference_lost", False))
        row["success"] = (reason is None) and spec.success(metrics)
        rows.append(row)
    return rows


#: The columns a row holds besides the kind's metrics (and the compare key and the varied parameters).
ROW_COLUMNS = ("cell", "point", "latency_ticks", "trial", "seed", "failed", "failure", "lost", "success")


def row_metrics(spec, row: dict) -> dict:
    """The kind's metrics of one row (what :class:`~quatform.sweeps.spec.Success` is called on)."""
    own = {*ROW_COLUMNS, spec.compare_key, *(a.name for a in spec.axes)}
    return {k: v for k, v in row.items() if k not in own}


def _output_variables(exp):
    """What the measurement reads, as layout variables (their units pick the noise)."""
    layout = exp.controller.team.layout
    if tuple(exp.plant.output_columns) != tuple(layout.names):
        raise InvalidInputError(f"sweep: the {exp.label} run's plant outputs {exp.plant.output_columns[:4]}... are "
                                "not the robots' points; its measurement cannot be varied")
    if exp.measurement is not None:
        raise InvalidInputError(f"sweep: the {exp.label} run has its own measurement model "
                                f"({type(exp.measurement).__name__}); a sweep replaces it only for a perfect one")
    return layout.variables
