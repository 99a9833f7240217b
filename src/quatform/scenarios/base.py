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

from ..sim.log import Log
from ..sim.backends import simulator
from ..registry import Registry

__all__ = ["Option", "Experiment", "ScenarioKind"]


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
