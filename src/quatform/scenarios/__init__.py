"""Scenarios layer: the built-in TOML scenarios, one builder per kind, the kind registry, the loader.

Above :mod:`quatform.sim`, below :mod:`quatform.report` and :mod:`quatform.runs`. See
:mod:`.base` for the contract. A :class:`ScenarioKind` subclass registers itself in
:data:`KINDS` when it is defined; this package imports every module in it, so
``import quatform.scenarios`` fills the registry. A new kind is one module here (or one
module anywhere, imported before its files are loaded).

* :func:`load_scenario` - the one loader: a built-in name or a ``.toml`` path, dispatched on
  the file's ``kind`` key (``pair`` when absent) to that kind's strict reader;
* :func:`builtin_scenarios` - the shipped files by name;
* :func:`kind_of` - the kind of a loaded scenario (by its type, a registry lookup).
"""

from __future__ import annotations

from pathlib import Path

from ..checks import text
from ..errors import InvalidInputError
from ..tomlio import builtin_files, read_toml
from ..registry import import_package_modules
from .base import KINDS, Experiment, Option, ScenarioKind

#: The ``kind`` of a scenario file without a ``kind`` key: seed 000's two robots, an alias the
#: team kind reads (:attr:`ScenarioKind.aliases`).
DEFAULT_KIND = "pair"

__all__ = ["Experiment", "Option", "ScenarioKind", "KINDS", "DEFAULT_KIND", "load_scenario", "builtin_scenarios",
           "kind_of", "kind_aliases"]


def builtin_scenarios() -> dict[str, Path]:
    """Built-in scenario files by name (the ``*.toml`` files shipped in ``quatform/scenarios``)."""
    return builtin_files("scenarios")


def load_scenario(name_or_file):
    """Load a built-in scenario by name or a TOML file by path.

    Parameters
    ----------
    name_or_file : str or path-like
        A name of :func:`builtin_scenarios` or the path of a ``.toml`` file.

    Returns
    -------
    object
        The scenario value of the file's kind (``KINDS[kind].scenario_type``): the ``kind``
        key selects the kind (``pair`` when absent, an alias of the team kind:
        :func:`kind_aliases`), whose strict reader refuses unknown keys and bad values with
        one line naming the key.
    """
    data, p = read_toml(name_or_file, builtin_scenarios(), "scenario")
    where = str(p)
    aliases = kind_aliases()
    name = text(data, "kind", where, DEFAULT_KIND, choices=(*KINDS, *aliases))
    return KINDS[aliases.get(name, name)].from_dict(data, where)


def kind_aliases() -> dict[str, str]:
    """``{alias: kind name}``: the other ``kind`` values each registered kind reads
    (:attr:`ScenarioKind.aliases`)."""
    return {alias: name for name, kind in KINDS.items() for alias in kind.aliases}


def kind_of(scenario) -> ScenarioKind:
    """The registered kind whose ``scenario_type`` ``scenario`` is (its exact type, else a subclass)."""
    for kind in KINDS.values():
        if type(scenario) is kind.scenario_type:
            return kind
    for kind in KINDS.values():
        if isinstance(scenario, kind.scenario_type) and kind.scenario_type is not object:
            return kind
    raise InvalidInputError(f"{type(scenario).__name__} is not the scenario of a registered kind "
                            f"({', '.join(KINDS) or 'none registered'}); load it with quatform.scenarios.load_scenario")


# The kind modules register their kinds in KINDS when their classes are defined.
import_package_modules(__name__, __path__, skip=("base",))
