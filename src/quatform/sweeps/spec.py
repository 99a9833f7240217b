"""The sweep spec: a plain TOML file naming a scenario, the choices to compare, the parameters to vary.

Sweeps layer (top, beside :mod:`quatform.runs`). :func:`load_sweep` reads a built-in sweep by
name or a ``.toml`` file by path strictly (:mod:`quatform.checks`: an unknown key or parameter
names the nearest valid one, an empty range or an out-of-range value is refused naming the
key) into a :class:`SweepSpec`. The keys are documented in ``docs/sweeps.md``.

* :data:`PARAMETERS` - what a sweep may vary, with units and bounds (a registry: the reader,
  the docs' table and the error messages read it);
* :class:`Axis` - one varied parameter and its values (a grid, or random draws from the
  spec's seed);
* :class:`SweepSpec` - the whole spec, its cells (:meth:`SweepSpec.points`) and its identity.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..checks import check_keys, integer, nearest, number, short, table, text
from ..errors import InvalidInputError, ResourceLimitError
from ..registry import Registry
from ..tomlio import builtin_files, read_toml

__all__ = ["Parameter", "PARAMETERS", "sweep_parameter", "Axis", "Success", "SweepSpec", "load_sweep", "sweep_from_dict",
           "builtin_sweeps", "DEFAULT_SUCCESS_BELOW", "DEFAULT_SUCCESS_FALSE", "MAX_TRIALS", "SLURM_KEYS",
           "SLURM_COUNTS", "check_slurm", "RESULTS"]

_HINT = "see docs/sweeps.md"


@dataclass(frozen=True)
class Parameter:
    """One parameter a sweep may vary.

    Attributes
    ----------
    name : str
        Key of ``[vary]``.
    unit : str
    help : str
    low, high : float or None
        Bounds of a value (inclusive; ``high_open``: the upper one excluded).
    integer : bool
        Whole values only.
    kinds : tuple of str or None
        Scenario kinds that can vary it (None: every sweepable kind).
    data : callable ``(table, value, where) -> table`` or None
        How a value changes the scenario file's table before its kind reads it (``team_size``:
        the robot count).
    apply : callable ``(scenario, value, spec, choice) -> scenario`` or None
        How a value changes the scenario of a cell (``gain_scale``: the choice's gains; a new
        parameter of a scenario field: ``dataclasses.replace``). A parameter with neither is
        read by the batch itself (:func:`quatform.sweeps.trials.chunk_batch`: the measurement's
        noise, latency and lost frames, the initial errors, the trials' seed).
    """

    name: str
    unit: str
    help: str
    low: float | None = 0.0
    high: float | None = None
    integer: bool = False
    kinds: tuple | None = None
    high_open: bool = False
    data: Callable | None = None
    apply: Callable | None = None

    def applies_to(self, kind: str) -> bool:
        """Whether a scenario of kind ``kind`` can vary it."""
        return self.kinds is None or kind in self.kinds


#: What ``[vary]`` may hold, by name (filled by :func:`sweep_parameter`).
PARAMETERS = Registry("sweep parameter")


def sweep_parameter(p: Parameter) -> Parameter:
    """Register ``p`` in :data:`PARAMETERS` (under ``p.name``) and return it: a new parameter is
    one call beside its definition, and ``[vary]``, the CLI's help and the rows read it."""
    return PARAMETERS.add(p.name, p)


def _team_size_data(data: dict, value, where: str) -> dict:
    """The scenario table with its one ``[[robots]]`` group ``value`` robots strong (a grid
    template's rows: the largest divisor of N up to sqrt(N); a prime N: a line)."""
    n = int(value)
    groups = data.get("robots")
    if not isinstance(groups, list) or len(groups) != 1:
        raise InvalidInputError(f"{where}: [vary.team_size] needs a scenario with one [[robots]] group (it sets "
                                "its count); this one has " + str(len(groups) if isinstance(groups, list) else 0))
    out = {**data, "robots": [{**groups[0], "count": n}]}
    shape = dict(data.get("shape", {}))
    if shape.get("template") == "grid":
        shape["rows"] = max(r for r in range(1, math.isqrt(n) + 1) if n % r == 0)
        out["shape"] = shape
    return out


def _gain_scale(sc, scale, spec, choice: str):
    """``sc`` with the gains of the choice ``choice`` (or the axis' one ``gain``) times
    ``scale``; the kind's sweep adapter says where its gains live
    (:meth:`~quatform.sweeps.trials.SweepKind.gains`, ``with_gains``)."""
    from .trials import SWEEP_KINDS, scaled_gains

    if scale == 1.0:
        return sc
    axis = spec.axis("gain_scale")
    adapter = SWEEP_KINDS[spec.data["kind"]]
    own = adapter.gains(sc, choice)
    if axis.gain is not None and axis.gain not in own:
        raise InvalidInputError(f"{spec.where}: [vary.gain_scale] gain = {axis.gain!r} is not a gain of the "
                                f"{choice} controller{nearest(axis.gain, own)}; it has {', '.join(own) or 'none'}")
    try:
        return adapter.with_gains(sc, choice, scaled_gains(own, float(scale), axis.gain))
    except InvalidInputError as exc:
        raise InvalidInputError(f"{spec.where}: gain_scale = {scale:g}: {exc}") from None


sweep_parameter(Parameter("noise_m", "m", "standard deviation of the motion capture's position noise, each "
                          "coordinate"))
sweep_parameter(Parameter("noise_rad", "rad", "standard deviation of the motion capture's noise on every yaw angle"))
sweep_parameter(Parameter("latency_s", "s", "age of the measurement the controller reads (rounded to whole "
                          "control ticks)"))
sweep_parameter(Parameter("dropout_rate", "1", "probability that a control tick's frame is lost (the last one is "
                          "held)", high=1.0, high_open=True))
sweep_parameter(Parameter("gain_scale", "1", "factor on every gain of the controller (or on the one named by the "
                          "axis' gain key)", low=1e-9, apply=_gain_scale))
sweep_parameter(Parameter("initial_offset_m", "m", "bound of the random initial position error: each trial draws "
                          "every coordinate uniformly in [-a, a]"))
sweep_parameter(Parameter("initial_offset_rad", "rad", "bound of the random initial angle error: each trial draws "
                          "every angle uniformly in [-a, a]"))
sweep_parameter(Parameter("team_size", "robots", "number of robots of the team's one [[robots]] group", low=2,
                          high=10_000, integer=True, kinds=("team",), data=_team_size_data))
sweep_parameter(Parameter("seed", "1", "the seed the trials' random numbers are derived from (replaces the spec's "
                          "seed)", low=0, high=2**63 - 1, integer=True))

#: Default success: after the settling time (the scenario's metrics_from_s), the centroid,
#: attitude and robot tracking errors stay below 0.1 m / 0.1 rad (seed 000's plots read the
#: errors on that scale) and the reference is not lost.
DEFAULT_SUCCESS_BELOW = {"max_cluster_position_error_m": 0.1, "max_orientation_error_rad": 0.1,
                         "max_robot_position_error_m": 0.1}
DEFAULT_SUCCESS_FALSE = ("reference_lost",)

#: Most trials a cell may ask for (the time and memory checks refuse far less in practice).
MAX_TRIALS = 1_000_000
#: Most cells a sweep may have (choices x the product of the axes' lengths).
MAX_CELLS = 100_000
#: Most values one axis may hold.
MAX_AXIS_VALUES = 10_000

#: Keys of ``[slurm]`` (keyword arguments of dask_jobqueue.SLURMCluster).
SLURM_KEYS = ("queue", "account", "cores", "memory", "walltime", "processes", "job_extra_directives",
              "job_script_prologue", "interface", "local_directory", "log_directory", "jobs")

_TOP_KEYS = ("name", "title", "source", "scenario", "trials", "seed", "duration_s", "settle_s", "chunk_trials",
             "vary", "success", "slurm", "results")
#: What ``results`` may name: ``results.csv``/``.json`` (the rows in memory, the chunks in
#: ``chunks/*.json``), Parquet shards (``trials/``, the summary streamed from them) or both.
RESULTS = ("csv", "parquet", "both")
_AXIS_KEYS = ("values", "start", "stop", "count", "random", "draws", "gain")
_SUCCESS_KEYS = ("below", "false", "true")


def builtin_sweeps() -> dict[str, Path]:
    """Built-in sweep specs by name (``quatform/sweeps/builtin/*.toml``)."""
    return builtin_files("sweeps/builtin")


@dataclass(frozen=True)
class Axis:
    """One varied parameter.

    Attributes
    ----------
    name : str
        A key of :data:`PARAMETERS`.
    values : tuple of float (int for whole parameters)
        Its values, in the order of the cells.
    gain : str or None
        For ``gain_scale``: the one gain scaled (None: all of the controller's).
    how : str
        ``grid`` or ``random`` (drawn from the spec's seed).
    """

    name: str
    values: tuple
    gain: str | None = None
    how: str = "grid"

    @property
    def label(self) -> str:
        p = PARAMETERS[self.name]
        stem = f"gain_scale[{self.gain}]" if self.gain else self.name
        return f"{stem} ({p.unit})" if p.unit not in ("1", "") else stem


@dataclass(frozen=True)
class Success:
    """What a successful trial is: not failed, each metric of ``below`` under its threshold,
    each flag of ``false`` false and each flag of ``true`` true."""

    below: dict = field(default_factory=lambda: dict(DEFAULT_SUCCESS_BELOW))
    false: tuple = DEFAULT_SUCCESS_FALSE
    true: tuple = ()

    def __call__(self, metrics: dict) -> bool:
        for key, limit in self.below.items():
            v = metrics.get(key)
            if v is None or not (isinstance(v, (int, float)) and math.isfinite(v) and v < limit):
                return False
        return not any(bool(metrics.get(key, True)) for key in self.false) and all(
            metrics.get(key) is True for key in self.true)

    def check_metrics(self, metrics: dict, where: str) -> None:
        """Refuse criteria naming metrics the kind does not compute (one line, nearest name)."""
        for key in (*self.below, *self.false, *self.true):
            if key not in metrics:
                raise InvalidInputError(f"{where}: [success] names the metric {key!r}, which this scenario's runs do "
                                        f"not compute{nearest(key, metrics)}; metrics: {', '.join(sorted(metrics))}")
        flags = sorted(k for k, v in metrics.items() if isinstance(v, bool))
        for key in self.below:  # a flag or a word has no threshold: every trial would read as failed
            if isinstance(metrics[key], (bool, str)):
                raise InvalidInputError(f"{where}: [success] below = {{{key} = ...}}: {key} is not a number "
                                        f"({short(metrics[key])}); list flags in false = [...] instead")
        for name, keys in (("false", self.false), ("true", self.true)):  # a number is no flag: refused
            for key in keys:
                if not isinstance(metrics[key], bool):
                    raise InvalidInputError(f"{where}: [success] {name} = [{key!r}]: {key} is not a flag "
                                            f"({short(metrics[key])}); put numbers in below = {{...}}; flags: "
                                            f"{', '.join(flags)}")


@dataclass(frozen=True)
class SweepSpec:
    """A parsed sweep spec (see ``docs/sweeps.md``).

    Attributes
    ----------
    name, title, source : str
    scenario : str
        A built-in scenario name or the path of a scenario file (made absolute).
    compare_key : str
        The kind's compare option (``controller``, ``formation``).
    choices : tuple of str
        The values of ``compare_key`` compared.
    axes : tuple of Axis
    trials : int
        Trials per cell.
    seed : int
    duration_s, settle_s : float or None
        Overrides of the scenario's ``duration_s`` and ``metrics_from_s``.
    chunk_trials : int or None
        Trials per chunk (None: a cell's trials in one batch).
    success : Success
    slurm : dict
        The ``[slurm]`` table.
    results : str or None
        ``csv``, ``parquet`` or ``both``: how the trials are written (None: by the sweep's size,
        :func:`quatform.sweeps.results.results_mode`); not part of the identity.
    where : str
        The file, for messages.
    data : dict
        The parsed file with the overrides applied (its identity).
    """

    name: str
    scenario: str
    compare_key: str
    choices: tuple
    axes: tuple
    trials: int
    seed: int = 0
    title: str = ""
    source: str = ""
    duration_s: float | None = None
    settle_s: float | None = None
    chunk_trials: int | None = None
    success: Success = field(default_factory=Success)
    slurm: dict = field(default_factory=dict)
    results: str | None = None
    where: str = "sweep"
    data: dict = field(default_factory=dict)

    def points(self) -> list[dict]:
        """Every combination of the axes' values (the first axis slowest), ``[{}]`` without axes."""
        names = [a.name for a in self.axes]
        return [dict(zip(names, combo)) for combo in itertools.product(*(a.values for a in self.axes))]

    def cells(self) -> list[tuple[int, str, dict]]:
        """``(point index, choice, parameter values)`` of every cell: each point for each choice."""
        return [(p, c, vals) for p, vals in enumerate(self.points()) for c in self.choices]

    def axis(self, name: str) -> Axis | None:
        return next((a for a in self.axes if a.name == name), None)

    @property
    def identity(self) -> str:
        """A hash of the effective spec (what a resumed run must match; ``results``, how the
        rows are written, left out)."""
        blob = json.dumps({k: v for k, v in self.data.items() if k != "results"}, sort_keys=True,
                          default=str).encode()
        return hashlib.sha256(blob).hexdigest()[:16]


def load_sweep(name_or_file, trials: int | None = None) -> SweepSpec:
    """The sweep spec of a built-in name or a ``.toml`` path; ``trials`` overrides its
    ``trials`` (a quick look)."""
    data, p = read_toml(name_or_file, builtin_sweeps(), "sweep")
    if trials is not None:
        data = {**data, "trials": trials}
    return sweep_from_dict(data, str(p), base=p.parent)


def _scenario_ref(data: dict, where: str, base: Path | None) -> str:
    from ..scenarios import builtin_scenarios

    ref = text(data, "scenario", where)
    if ref in builtin_scenarios():
        return ref
    path = Path(ref)
    if not path.is_absolute() and base is not None:
        path = base / path
    if path.suffix != ".toml" or not path.is_file():
        raise InvalidInputError(f"{where}: scenario = {ref!r} is neither a built-in scenario{nearest(ref, builtin_scenarios())} "
                                "nor a .toml file (relative paths are read from the spec's folder); see "
                                "'quatform scenarios'")
    return str(path.resolve())


def _axis(name: str, d, where: str, seed: int, index: int) -> Axis:
    place = f"[vary.{name}]"
    if name not in PARAMETERS:
        raise InvalidInputError(f"{where}: unknown parameter [vary.{name}]{nearest(name, PARAMETERS)}; a sweep varies "
                                f"{', '.join(PARAMETERS)} ({_HINT})")
    p = PARAMETERS[name]
    if not isinstance(d, dict):
        raise InvalidInputError(f"{where}: {place} = {short(d)} must be a table (values = [...], start/stop/count "
                                "or random = {low, high} with draws)")
    check_keys(d, _AXIS_KEYS, where, place, _HINT)
    gain = None
    if "gain" in d:
        if name != "gain_scale":
            raise InvalidInputError(f"{where}: {place} gain applies to [vary.gain_scale] only; remove it")
        gain = text(d, "gain", where, place=place)
    forms = [k for k in (("values",), ("start", "stop", "count"), ("random", "draws")) if any(x in d for x in k)]
    if len(forms) != 1:
        raise InvalidInputError(f"{where}: {place} needs exactly one of values = [...], start/stop/count or "
                                f"random = {{low, high}} with draws; got {', '.join(sorted(d)) or 'nothing'}")
    form = forms[0]
    bounds = {"low": p.low, "high": p.high, "high_open": p.high_open}
    read = (lambda t, k, pl=place: integer(t, k, where, place=pl, low=None if p.low is None else int(p.low),
                                           high=None if p.high is None else int(p.high))) if p.integer else \
        (lambda t, k, pl=place: number(t, k, where, place=pl, **bounds))
    how = "grid"
    if form == ("values",):
        vals = d["values"]
        if not isinstance(vals, list):
            raise InvalidInputError(f"{where}: {place} values = {short(vals)} must be a list of numbers")
        if not vals:
            raise InvalidInputError(f"{where}: {place} values = [] is an empty range; give at least one value")
        values = tuple(read({"values": v}, "values") for v in vals)
        twice = next((v for i, v in enumerate(values) if v in values[:i]), None)
        if twice is not None:  # two cells with the same parameters and label: a typo, most likely
            raise InvalidInputError(f"{where}: {place} values = {short(vals)} lists {twice:g} twice; list each value "
                                    "once (for more trials of it, raise trials)")
    elif form == ("start", "stop", "count"):
        for k in form:
            if k not in d:
                raise InvalidInputError(f"{where}: {place} needs start, stop and count (missing {k})")
        start, stop = read(d, "start"), read(d, "stop")
        count = integer(d, "count", where, place=place, low=1, high=MAX_AXIS_VALUES)
        if count > 1 and start == stop:
            raise InvalidInputError(f"{where}: {place} start = stop = {start:g} with count = {count} is an empty "
                                    "range; give stop != start or count = 1")
        grid = np.linspace(start, stop, count)
        values = tuple(int(round(v)) for v in grid) if p.integer else tuple(float(v) for v in grid)
        if p.integer and len(set(values)) != len(values):
            raise InvalidInputError(f"{where}: {place} {count} whole values between {start} and {stop} repeat; "
                                    "lower count or list values = [...]")
    else:
        if "random" not in d or "draws" not in d:
            raise InvalidInputError(f"{where}: {place} random draws need random = {{low, high}} and draws")
        r = table(d, "random", where, place)
        check_keys(r, ("low", "high"), where, f"{place} random", _HINT)
        low, high = read(r, "low", f"{place} random"), read(r, "high", f"{place} random")
        if not high > low:
            raise InvalidInputError(f"{where}: {place} random = {{low = {low:g}, high = {high:g}}} is an empty range; "
                                    "give high > low")
        draws = integer(d, "draws", where, place=place, low=1, high=MAX_AXIS_VALUES)
        # seed 0 of the axis' own stream: the spec's seed and the axis' position (file order)
        rng = np.random.default_rng(np.random.SeedSequence([seed, 1_000_003, index]))
        if p.integer:
            values = tuple(int(v) for v in rng.integers(int(low), int(high), draws, endpoint=True))
        else:
            values = tuple(float(v) for v in rng.uniform(low, high, draws))
        how = "random"
    if len(values) > MAX_AXIS_VALUES:
        raise InvalidInputError(f"{where}: {place} holds {len(values)} values, more than {MAX_AXIS_VALUES}")
    return Axis(name, values, gain, how)


def _success(data: dict, where: str, default: Success | None = None) -> Success:
    """``[success]``; what it leaves out is ``default``'s (None: :data:`DEFAULT_SUCCESS_BELOW`
    and :data:`DEFAULT_SUCCESS_FALSE`)."""
    s = table(data, "success", where, default={})
    check_keys(s, _SUCCESS_KEYS, where, "[success]", _HINT)
    default = default or Success()
    below = dict(default.below)
    if "below" in s:
        b = table(s, "below", where, "[success]")
        below = {k: number(b, k, where, place="[success.below]") for k in b}
    flags = {"false": tuple(default.false), "true": tuple(default.true)}
    for name in flags:
        if name in s:
            f = s[name]
            if not isinstance(f, list) or not all(isinstance(x, str) for x in f):
                raise InvalidInputError(f"{where}: [success] {name} = {short(f)} must be a list of metric names")
            flags[name] = tuple(f)
    return Success(below, flags["false"], flags["true"])


def sweep_from_dict(data: dict, where: str = "sweep", base: Path | None = None) -> SweepSpec:
    """Build a :class:`SweepSpec` from parsed TOML (``base``: the folder relative scenario
    paths are read from); every mistake is one line naming the key."""
    from ..scenarios import KINDS, kind_of, load_scenario
    from .trials import NOT_SWEEPABLE, SWEEP_KINDS

    if not isinstance(data, dict):
        raise InvalidInputError(f"{where}: a sweep spec is a TOML table")
    scenario = _scenario_ref(data, where, base)
    try:
        sc = load_scenario(scenario)
    except ResourceLimitError as exc:  # its kind checks it at its file's length; duration_s applies after
        if "duration_s" not in data:
            raise
        raise ResourceLimitError(f"{where}: the scenario is checked at its own length before the sweep's "
                                 f"duration_s = {short(data['duration_s'])} s applies, and refused: {exc}") from None
    kind = kind_of(sc)
    kind_name = kind.parts_of(sc)  # its sweep adapter's key: the kind's name, or the name of its parts ("pair")
    if kind_name not in SWEEP_KINDS:
        sweepable = ", ".join(k for k in KINDS if k in SWEEP_KINDS)
        raise InvalidInputError(f"{where}: scenario {Path(scenario).stem!r} is of kind {kind_name!r}, which a sweep "
                                f"cannot batch yet ({NOT_SWEEPABLE.get(kind_name, 'no sweep adapter')}); sweepable "
                                f"kinds: {sweepable}")
    key = kind.compare_over
    plural = key + "s"
    check_keys(data, (*_TOP_KEYS, plural), where, hint=_HINT)
    runnable, skipped = kind.compare_choices(sc, key)
    allowed = tuple({o.name: o for o in kind.options}[key].choices)
    if plural in data:
        given = data[plural]
        if not isinstance(given, list) or not given or not all(isinstance(c, str) for c in given):
            raise InvalidInputError(f"{where}: {plural} = {short(given)} must be a non-empty list of names, e.g. "
                                    f"{list(allowed[:2])}")
        for c in given:
            if c not in allowed:
                raise InvalidInputError(f"{where}: unknown {key} {c!r} in {plural}{nearest(c, allowed)}; the "
                                        f"{kind_name} kind offers {', '.join(allowed)}")
            if c not in runnable:
                raise InvalidInputError(f"{where}: {key} {c!r} cannot run this scenario: {skipped.get(c, '')}")
        if len(set(given)) != len(given):
            raise InvalidInputError(f"{where}: {plural} = {short(given)} names one twice")
        choices = tuple(given)
    else:
        choices = tuple(runnable)
    trials = integer(data, "trials", where, low=1, high=MAX_TRIALS)
    seed = integer(data, "seed", where, 0, low=0, high=2**63 - 1)
    vary = table(data, "vary", where, default={})
    axes = tuple(_axis(name, d, where, seed, i) for i, (name, d) in enumerate(vary.items()))
    n_cells = len(choices) * math.prod(len(a.values) for a in axes)
    if n_cells > MAX_CELLS:
        raise ResourceLimitError(f"{where}: {len(choices)} {plural} x [vary] grid of "
                                 f"{' x '.join(str(len(a.values)) for a in axes)} = {n_cells:,} cells, more than "
                                 f"{MAX_CELLS:,}; coarsen [vary] (fewer values or draws)")
    adapter = SWEEP_KINDS[kind_name]
    can = adapter.parameters
    for a in axes:
        if a.name not in can:
            raise InvalidInputError(f"{where}: [vary.{a.name}]: a {kind_name} scenario cannot vary {a.name}; it can "
                                    f"vary {', '.join(p for p in PARAMETERS if p in can)}")
    duration = number(data, "duration_s", where, None, low=0.0, low_open=True)
    settle = number(data, "settle_s", where, None, low=0.0)
    _check_times(sc, duration, settle, axes, where, adapter.settle_key)
    chunk = integer(data, "chunk_trials", where, None, low=1, high=MAX_TRIALS)
    slurm = table(data, "slurm", where, default={})
    check_keys(slurm, SLURM_KEYS, where, "[slurm]", _HINT)
    check_slurm(slurm, f"{where}: [slurm]")
    results = text(data, "results", where, None, choices=RESULTS)
    return SweepSpec(name=text(data, "name", where, Path(where).stem), title=text(data, "title", where, ""),
                     source=text(data, "source", where, ""), scenario=scenario, compare_key=key, choices=choices,
                     axes=axes, trials=trials, seed=seed, duration_s=duration, settle_s=settle, chunk_trials=chunk,
                     success=_success(data, where, adapter.success), slurm=slurm, results=results, where=where,
                     data={**data, "scenario": scenario, "kind": kind_name,
                           "scenario_sha256": _file_hash(scenario)})


#: The [slurm] options that count (jobs, cores, worker processes per job): whole numbers >= 1.
SLURM_COUNTS = ("cores", "processes", "jobs")


def check_slurm(options: dict, where: str) -> None:
    """Refuse a count of ``[slurm]`` / ``--slurm`` that is not a whole number >= 1 (one line)."""
    for key in SLURM_COUNTS:
        v = options.get(key)
        if v is not None and (isinstance(v, bool) or not isinstance(v, int) or v < 1):
            raise InvalidInputError(f"{where}: {key} = {short(v)} must be a whole number >= 1 (e.g. {key} = 4)")


def _check_times(sc, duration, settle, axes, where: str, settle_key: str | None = "metrics_from_s") -> None:
    """The run's length against the scenario's and the varied latency (one line each);
    ``settle_key``: the scenario field ``settle_s`` replaces (None: the kind has none)."""
    own = float(sc.duration_s)
    if duration is not None and duration > own:
        raise InvalidInputError(f"{where}: duration_s = {duration:g} s is longer than the scenario's own {own:g} s; a "
                                f"sweep runs the first duration_s of it: give at most {own:g} (or lengthen the "
                                "scenario file's duration_s)")
    run = own if duration is None else duration
    if run < 2 * float(sc.dt_s):
        raise InvalidInputError(f"{where}: duration_s = {run:g} s is shorter than two of the scenario's control "
                                f"ticks (dt_s = {sc.dt_s:g} s); give a longer duration_s")
    if settle_key is None:
        if settle is not None:
            raise InvalidInputError(f"{where}: settle_s: a {type(sc).__name__} has no settling time (its metrics "
                                    "read the whole run and its holds); remove settle_s")
        start = 0.0
    else:
        start = float(getattr(sc, settle_key)) if settle is None else settle
    if start >= run:
        what = f"settle_s = {settle:g}" if settle is not None else \
            f"the scenario's {settle_key} = {start:g} s (settle_s not given)"
        raise InvalidInputError(f"{where}: {what} is not before the end of the run (duration_s = {run:g} s): no "
                                "sample would be measured; set settle_s below duration_s")
    lat = next((a for a in axes if a.name == "latency_s"), None)
    if lat is not None and max(lat.values) >= run:
        raise InvalidInputError(f"{where}: [vary.latency_s] value {max(lat.values):g} s is not shorter than the run "
                                f"(duration_s = {run:g} s): the controller would never read a measurement; give "
                                "latencies below duration_s")


def _file_hash(ref: str) -> str:
    """The hash of a scenario file's bytes ("" for a built-in name): a resumed sweep must read
    the same scenario."""
    p = Path(ref)
    return hashlib.sha256(p.read_bytes()).hexdigest()[:16] if p.is_file() else ""
