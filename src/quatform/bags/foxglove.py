"""A run's Foxglove layout (bags layer): ``foxglove-layout.json`` beside its ``run.mcap``.

Import it in Foxglove (Layouts > Import from file) after opening the run's ``run.mcap``: a 3-D
panel following the ``world`` frame with the TF frames (``/tf``, ``/tf_static``), the
formation's edges (``/formation/edges``) and each body's actual and desired path
(``/<body>/path``, ``/<body>/path_desired``; ``/robots/poses`` for a team too large for
topics per body), each only where the run's bag has it, and the plot panels the run's kind
registers with its scene (:data:`~quatform.bags.scene.SCENES`, ``SceneKind.plots``): the
formation frame against the reference, its error and the singularity measure for a pair, a
UGV-UAV run and a team; the hands, the task error, the joint torques and the wrist wrench for
a teleoperation run.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..sim.output import atomic_write_text
from .mcap import PER_BODY_TOPICS_UP_TO
from .scene import Scene, scene_kind

__all__ = ["FOXGLOVE_LAYOUT_FILE", "foxglove_layout", "write_foxglove_layout", "layout_topics"]

#: The layout's file name in a run's folder.
FOXGLOVE_LAYOUT_FILE = "foxglove-layout.json"

#: Id of the 3-D panel.
THREE_D = "3D!quatform"
#: Share (%) of the window's width the 3-D panel takes; the plots share the rest, stacked.
THREE_D_PERCENT = 55

_ACTUAL = {"visible": True, "type": "line", "lineWidth": 0.02, "gradient": ["#3366ffff", "#3366ffff"]}
_DESIRED = {"visible": True, "type": "line", "lineWidth": 0.015, "gradient": ["#22cc55aa", "#22cc55aa"]}
_POSES = {"visible": True, "type": "axis", "axisScale": 0.3}
_PLOT_STYLE = {"showLegend": True, "legendDisplay": "floating", "showXAxisLabels": True, "showYAxisLabels": True,
               "isSynced": True, "xAxisVal": "timestamp"}


def _three_d_topics(scene: Scene) -> dict:
    """The 3-D panel's topic settings: the topics of ``scene`` that :func:`~quatform.bags.write_mcap`
    writes and the panel draws (its TF, edges, paths or pose arrays)."""
    topics = {"/tf": {"visible": True}}
    if scene.static:
        topics["/tf_static"] = {"visible": True}
    if scene.edges is not None or scene.edges_desired is not None:
        topics["/formation/edges"] = {"visible": True}
    desired = scene.position_desired is not None
    if len(scene.bodies) <= PER_BODY_TOPICS_UP_TO:
        for body in scene.bodies:
            topics[f"/{body}/path"] = dict(_ACTUAL)
            if desired:
                topics[f"/{body}/path_desired"] = dict(_DESIRED)
    else:
        topics["/robots/poses"] = dict(_POSES)
        if desired:
            topics["/robots/poses_desired"] = dict(_POSES)
    return topics


def _camera_distance(scene: Scene) -> float:
    """A camera distance (m) that shows every body: 2.5 times the farthest finite position from
    the world origin, at least 1 m (12 m for a formation a few metres wide; about 2 m for arms)."""
    p = np.asarray(scene.position, dtype=float)
    r = np.linalg.norm(p[np.all(np.isfinite(p), axis=-1)], axis=-1)
    return float(max(1.0, 2.5 * r.max())) if r.size else 12.0


def _three_d(scene: Scene) -> dict:
    distance = round(_camera_distance(scene), 3)
    return {
        "cameraState": {"perspective": True, "distance": distance, "phi": 60, "thetaOffset": 45,
                        "target": [0, 0, 0], "targetOffset": [0, 0, 0], "targetOrientation": [0, 0, 0, 1],
                        "fovy": 45, "near": 0.01, "far": 5000},
        "followMode": "follow-none",
        "followTf": "world",
        "scene": {"transforms": {"showLabel": True, "axisScale": round(distance / 30.0, 3)}},
        "transforms": {},
        "topics": _three_d_topics(scene),
        "layers": {"grid": {"visible": True, "layerId": "foxglove.Grid", "instanceId": "grid", "frameId": "world",
                            "size": 10, "divisions": 10, "lineWidth": 1, "color": "#248eff",
                            "position": [0, 0, 0], "rotation": [0, 0, 0]}},
    }


def _stack(ids: list) -> str | dict:
    """Foxglove's split tree stacking the panels ``ids`` top to bottom in equal heights."""
    if len(ids) == 1:
        return ids[0]
    return {"direction": "column", "first": ids[0], "second": _stack(ids[1:]),
            "splitPercentage": round(100.0 / len(ids), 3)}


def layout_topics(layout: dict) -> set:
    """Every topic ``layout`` references: its 3-D panels' topics and its plots' series' topics."""
    out = set()
    for key, config in layout["configById"].items():
        if key.startswith("3D!"):
            out.update(config.get("topics", {}))
        for series in config.get("paths", []):
            out.add(series["value"].split(".", 1)[0])
    return out


def foxglove_layout(kind: str, scene: Scene) -> dict:
    """The Foxglove layout of one run of scenario kind ``kind`` whose scene is ``scene``.

    Parameters
    ----------
    kind : str
        The scenario kind (a key of :data:`~quatform.bags.scene.SCENES`): its ``plots``.
    scene : Scene
        The run's scene (:func:`~quatform.bags.scene.scene_of`), which its ``run.mcap`` was
        written from.

    Returns
    -------
    dict
        The layout (Foxglove's JSON: ``configById``, ``layout`` ...): the 3-D panel and the
        kind's plots, each panel's title under ``foxglovePanelTitle``.
    """
    config = {THREE_D: _three_d(scene)}
    for plot in scene_kind(kind).plots(scene):
        config[f"Plot!{plot.key}"] = {
            "foxglovePanelTitle": plot.title,
            "paths": [{"value": value, "enabled": True, "timestampMethod": "receiveTime", "label": label}
                      for value, label in plot.series],
            **_PLOT_STYLE}
    plots = [k for k in config if k != THREE_D]
    tree = THREE_D if not plots else {"direction": "row", "first": THREE_D, "splitPercentage": THREE_D_PERCENT,
                                      "second": _stack(plots)}
    return {"configById": config, "globalVariables": {}, "userNodes": {}, "playbackConfig": {"speed": 1},
            "layout": tree}


def write_foxglove_layout(folder, kind: str, scene: Scene) -> Path:
    """Write :func:`foxglove_layout` of ``kind`` and ``scene`` into ``folder`` as
    :data:`FOXGLOVE_LAYOUT_FILE` (atomically); returns its path."""
    path = Path(folder) / FOXGLOVE_LAYOUT_FILE
    atomic_write_text(path, json.dumps(foxglove_layout(kind, scene), indent=2) + "\n")
    return path
