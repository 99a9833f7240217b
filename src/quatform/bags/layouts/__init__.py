"""The Foxglove layout shipped with quatform (bags layer): ``foxglove-layout.json`` beside this file.

Import it in Foxglove (Layouts > Import from file) after opening a run's ``run.mcap``: a 3-D
panel following the ``world`` frame with the robots' TF frames, the formation frame, the
formation's edges (``/formation/edges``) and the robots' paths (``/<body>/path``,
``/<body>/path_desired``); plots of the formation frame's position and attitude against the
reference (``/formation/pose``, ``/formation/pose_desired``), of their difference
(``/formation/error``) and of the singularity measure (``/quatform/singularity``): topics
every pair, UGV-UAV and team run has, whatever its controller.
"""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

from ...sim.output import atomic_write_text

__all__ = ["FOXGLOVE_LAYOUT_FILE", "foxglove_layout", "write_foxglove_layout"]

#: The layout's file name (in this package and, written next to a run, in its folder).
FOXGLOVE_LAYOUT_FILE = "foxglove-layout.json"


def foxglove_layout() -> dict:
    """The shipped Foxglove layout (parsed JSON)."""
    return json.loads(resources.files(__package__).joinpath(FOXGLOVE_LAYOUT_FILE).read_text(encoding="utf-8"))


def write_foxglove_layout(folder) -> Path:
    """Write the layout into ``folder`` as :data:`FOXGLOVE_LAYOUT_FILE`; returns its path."""
    path = Path(folder) / FOXGLOVE_LAYOUT_FILE
    atomic_write_text(path, json.dumps(foxglove_layout(), indent=2) + "\n")
    return path
