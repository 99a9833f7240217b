"""The scenario-kind contract: one builder file per kind of experiment, one registry.

Scenarios layer (above sim, below report and runs). mujoco_playground's and brax's one file per
environment plus a registry is the model. A scenario file is plain TOML whose ``kind`` key
names its :class:`ScenarioKind` (``pair`` when absent: seed 000's two robots). A kind

* reads its files strictly (:meth:`ScenarioKind.from_dict`: unknown keys name the nearest
  valid one, non-finite numbers are refused with the key named, the run's memory and time
  are estimated up front);
* declares the choices a run takes (:attr:`ScenarioKind.options`: the controller, the
  formation description, the physics, ...), read by the CLI from this registry instead of
  re-typed lists;
* builds an :class:`Experiment` for a scenario and a choice: the plant, the controller, the
  reference, the measurement model, the initial state and the times that
  :func:`quatform.sim.simulate` runs, and what to compute from the resulting log (derived
  channels and metrics).

A subclass registers one instance of itself in :data:`KINDS` when it is defined, and says
whether a sweep can batch it (:attr:`ScenarioKind.not_sweepable`). Its figures and its bag
scene are registered beside their functions (:data:`quatform.report.FIGURES`,
:data:`quatform.bags.scene.SCENES`; a kind in one file adds both there). The generic run and
compare of :mod:`quatform.runs` know nothing else about a kind.
"""

from __future__ import annotations

from abc import ABC, abstractmethod, update_abstractmethods
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from ..sim.log import Channel, Log
from ..sim.backends import simulator
from ..registry import Registry

__all__ = ["Option", "Experiment", "ScenarioKind", "finish_worlds", "world_meta"]


@dataclass(frozen=True)
class Option:
    """A choice a run of a kind takes (a CLI option and a keyword of :meth:`ScenarioKind.experiment`).

    Attributes
    ----------
    name : str
        Keyword (``controller``, ``formation``, ``physics`` ...); the CLI flag is
        ``--`` + ``name`` with ``_`` as ``-``.
    help : str
    choices : tuple of str, optional
        Allowed values (the keys of a registry), or None for a typed value.
    default : object
        Value when not given (``None``: the scenario's own).
    type : type
        ``str``, ``float`` or ``bool`` (a flag).
    """

    name: str
    help: str
    choices: tuple | None = None
    default: Any = None
    type: type = str

    @property
    def flag(self) -> str:
        return "--" + self.name.replace("_", "-")


@dataclass(frozen=True)
class Experiment:
    """Everything one run of one scenario with one choice needs.

    Attributes
    ----------
    scenario : object
        The scenario value it was built from.
    label : str
        The choice in words (``quaternion``, ``euler-parameters, preload on`` ...), for
        messages and compare folders.
    plant, controller, reference, measurement, times, x0, dt, substeps
        The arguments of :func:`quatform.sim.simulate`.
    finish : callable ``Log -> Log``
        Adds the derived channels (desired values, chart variables, singularity measure ...).
    metrics : callable ``Log -> dict``
        The run's ``metrics.json`` (without ``wall_time_s``, which the runner adds).
    csv_channels : tuple of str, optional
        Channels written to ``timeseries.csv`` in order (default: all).
    meta : dict
        Stored in the log's ``meta``.
    """

    scenario: Any
    label: str
    plant: Any
    controller: Any
    reference: Callable
    times: Any
    x0: Any
    dt: float
    substeps: int = 1
    measurement: Any = None
    finish: Callable[[Log], Log] = lambda log: log
    metrics: Callable[[Log], dict] = lambda log: {}
    csv_channels: tuple | None = None
    meta: dict = field(default_factory=dict)

    def run(self, progress: Callable | None = None, backend: str = "numpy") -> Log:
        """Simulate (on the compute ``backend`` of :data:`quatform.sim.backends.SIM_BACKENDS`)
        and finish: the run's complete log."""
        log = simulator(backend)(self.plant, self.controller, self.reference, self.times, self.x0, dt=self.dt,
                                 substeps=self.substeps, measurement=self.measurement, progress=progress,
                                 meta={"label": self.label, **self.meta})
        return self.finish(log)


def finish_worlds(log: Log, finish: Callable[[Log], Log]) -> Log:
    """``finish`` of a one-world log applied to every world of a batched ``log``
    (:meth:`Log.world`), its added channels stacked back on the batch axes ``(T, *batch, k)``
    and each meta entry it adds or changes kept per world: an object array of the batch shape
    (read one world's with :func:`world_meta`). A one-world ``log`` is ``finish(log)``.

    Each world's channels are the one-world finish's own numbers, so a world of a finished
    batch equals the finished run of that world alone wherever the simulated worlds do."""
    batch = log.batch_shape
    if not batch:
        return finish(log)
    worlds = {idx: finish(log.world(idx)) for idx in np.ndindex(*batch)}
    first = worlds[next(iter(worlds))]
    added = [name for name in first.channels if name not in log.channels]
    chans = []
    for name in added:
        ch = first.channels[name]
        data = np.empty((len(log.t),) + batch + ch.data.shape[1:], dtype=ch.data.dtype)
        for idx, w in worlds.items():
            data[(slice(None),) + idx] = w[name]
        chans.append(Channel(name, ch.columns, data))
    meta = {}
    for key, value in first.meta.items():
        if key == "world" or (key in log.meta and log.meta[key] is value):
            continue
        per = np.empty(batch, dtype=object)
        for idx, w in worlds.items():
            per[idx] = w.meta[key]
        meta[key] = per
    return log.with_channels(*chans, **meta)


def world_meta(log: Log, key: str, default=None):
    """``log.meta[key]`` of a one-world log: of a world of a batch finished by
    :func:`finish_worlds` (its ``meta["world"]``), that world's entry."""
    value = log.meta.get(key, default)
    world = log.meta.get("world")
    if world is not None and isinstance(value, np.ndarray) and value.dtype == object and value.ndim == len(world):
        return value[world]
    return value


#: Scenario kinds by their TOML ``kind`` value: one instance of every :class:`ScenarioKind`
#: subclass that sets a ``name``, registered when the class is defined.
KINDS = Registry("scenario kind")


class ScenarioKind(ABC):
    """One kind of scenario file (see the module docstring).

    A subclass that sets :attr:`name` registers one instance of itself in :data:`KINDS`
    when it is defined (``class MyKind(ScenarioKind, register=False)`` does not: a kind a
    test registers for its own duration).
    """

    #: Value of the TOML ``kind`` key.
    name: str = ""
    #: Why a sweep cannot batch this kind's runs (None: ``quatform.sweeps`` says whether it can).
    not_sweepable: str | None = None

    def __init_subclass__(cls, register: bool = True, **kwargs):
        super().__init_subclass__(**kwargs)
        if register and cls.__dict__.get("name"):
            update_abstractmethods(cls)  # ABCMeta sets them after this hook; instantiating needs them now
            KINDS.add(cls.name, cls())
    #: The Python type of its scenarios (the registry maps a scenario back to its kind).
    scenario_type: type = object
    #: Choices a run takes.
    options: tuple = ()
    #: The option ``compare`` runs every choice of (None: the kind has no compare).
    compare_over: str | None = None
    #: Columns of the comparison table: (metrics key, header, format).
    table_columns: tuple = ()
    #: Other values of the TOML ``kind`` key whose files this kind reads.
    aliases: tuple = ()

    def parts_of(self, scenario) -> str:
        """The name ``scenario``'s figures (:data:`quatform.report.FIGURES`), bag scene
        (:data:`quatform.bags.scene.SCENES`) and sweep adapter
        (:data:`quatform.sweeps.trials.SWEEP_KINDS`) are registered under: the kind's own name
        (the team kind's seed-000 files: ``"pair"``)."""
        return self.name

    def columns_of(self, scenario) -> tuple:
        """The comparison table's columns of ``scenario`` (default :attr:`table_columns`)."""
        return self.table_columns

    @abstractmethod
    def from_dict(self, data: dict, where: str):
        """The scenario of parsed TOML ``data`` (``where``: the file or name, for messages)."""

    @abstractmethod
    def experiment(self, scenario, **options) -> Experiment:
        """The run of ``scenario`` with the given :attr:`options` (missing ones: their default)."""

    def compare_choices(self, scenario, axis: str) -> tuple[tuple, dict]:
        """The values of the option ``axis`` a compare of ``scenario`` runs, and the ones it
        leaves out with the reason (``{value: one line}``): by default every choice, none left
        out (a kind whose scenarios cannot take some choice, e.g. a team description that
        cannot represent the team's mix of robots, says so here)."""
        own = {o.name: o for o in self.options}
        return tuple(own[axis].choices), {}
