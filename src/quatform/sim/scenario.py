"""Scenario files by name: the built-in TOML files and the loader that reads any of them.

Sim layer (transitional: the scenarios layer's loader, which dispatches on the file's
``kind`` through :data:`quatform.scenarios.KINDS`, replaces it). Built-in scenarios live in
``quatform/scenarios/*.toml``; a user's own file is passed by path (``docs/scenarios.md``).
"""

from __future__ import annotations

from pathlib import Path

from ..checks import text
from ..tomlio import builtin_files, read_toml

__all__ = ["load_scenario", "builtin_scenarios"]


def builtin_scenarios() -> dict[str, Path]:
    """Built-in scenario files by name."""
    return builtin_files("scenarios")


def load_scenario(name_or_file: str | Path):
    """Load a built-in scenario by name or a TOML file by path.

    Returns a :class:`~quatform.scenarios.pair.Scenario` (two 4-DOF robots, seed 000), for
    ``kind = "ugv-uav"`` a :class:`~quatform.scenarios.ugv_uav.UgvUavScenario` (seed 001), for
    ``kind = "teleop"`` a :class:`~quatform.scenarios.teleop.TeleopScenario` (seed 003).
    """
    data, p = read_toml(name_or_file, builtin_scenarios(), "scenario")
    kind = text(data, "kind", str(p), "pair", choices=("pair", "ugv-uav", "teleop"))
    if kind == "ugv-uav":
        from ..scenarios.ugv_uav import ugv_uav_scenario_from_dict  # until the one loader of scenarios/

        return ugv_uav_scenario_from_dict(data, where=str(p))
    if kind == "teleop":
        from ..scenarios.teleop import teleop_scenario_from_dict

        return teleop_scenario_from_dict(data, where=str(p))
    from ..scenarios.pair import scenario_from_dict  # the pair kind (until the scenarios loader lands)

    return scenario_from_dict(data, where=str(p))
