"""Scenarios layer: the built-in TOML scenarios, one builder per kind, and the kind registry.

Above :mod:`quatform.sim`, below :mod:`quatform.report` and :mod:`quatform.runs`. See
:mod:`.base` for the contract; each kind module registers itself in :data:`KINDS`.
"""

from .base import Experiment, Option, ScenarioKind

#: Scenario kinds by their TOML ``kind`` value (filled by the kind modules).
KINDS: dict[str, ScenarioKind] = {}

__all__ = ["Experiment", "Option", "ScenarioKind", "KINDS"]
