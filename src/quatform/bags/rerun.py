"""A run as a Rerun recording, headless (bags layer; optional extra ``rerun``: rerun-sdk).

:func:`write_rerun` writes the same :class:`~quatform.bags.scene.Scene` and channels as the
MCAP file to an ``.rrd`` file (``rerun FILE.rrd`` opens it) on the timeline ``time`` (the
scenario's seconds), all columns at once (``send_columns``), never a viewer:

* ``world`` (right-handed, z up: REP-103's ENU) with one entity per body
  (``world/<body>``: a :class:`rerun.Transform3D` per sample, quaternion ``(x, y, z, w)``
  as Rerun orders it, and its axes), ``world/robots`` and ``world/robots_desired`` (the
  bodies as points), ``world/edges`` and ``world/edges_desired`` (the formation's edges as
  line strips), ``world/paths`` and ``world/paths_desired`` (each body's whole path);
* ``channels/<name>``: every channel of the log as time series (one series per column,
  named by it), so the cluster variables, their references and the errors plot as in
  ``timeseries.csv``.

rerun-sdk is imported only here; without it :func:`require_rerun` raises
:class:`~quatform.errors.MissingDependencyError` naming ``pip install -e ".[rerun]"``.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..errors import InvalidInputError, MissingDependencyError
from .scene import scene_of

__all__ = ["INSTALL_HINT", "require_rerun", "write_rerun"]

#: How to install the extra (run in the quatform checkout).
INSTALL_HINT = 'pip install -e ".[rerun]"'
#: Points of each body's path (the run's samples, evenly thinned).
PATH_POINTS = 1000
_XYZW = [1, 2, 3, 0]  # quatform (w, x, y, z) -> Rerun (x, y, z, w)


def require_rerun():
    """The ``rerun`` module; a missing rerun-sdk is one line naming its ``pip install``."""
    try:
        import rerun
    except ImportError:
        raise MissingDependencyError(f"--rerun writes a Rerun recording and needs rerun-sdk: {INSTALL_HINT}") from None
    return rerun


def _world(rr, rec, root: str, scene, t: np.ndarray) -> None:
    time = [rr.TimeColumn("time", duration=t)]
    n_t = t.size
    rec.log(f"{root}world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    for i, body in enumerate(scene.bodies):
        entity = f"{root}world/{body}"
        rec.send_columns(entity, indexes=time,
                         columns=rr.Transform3D.columns(translation=scene.position[:, i],
                                                        quaternion=scene.quaternion[:, i][:, _XYZW]))
        rec.log(entity, rr.TransformAxes3D(0.3), static=True)
    n = len(scene.bodies)
    keep = np.unique(np.linspace(0, n_t - 1, min(n_t, PATH_POINTS)).round().astype(int))
    for suffix, p in (("", scene.position), ("_desired", scene.position_desired)):
        if p is None:
            continue
        rec.send_columns(f"{root}world/robots{suffix}", indexes=time,
                         columns=rr.Points3D.columns(positions=p.reshape(-1, 3)).partition([n] * n_t))
        rec.log(f"{root}world/paths{suffix}", rr.LineStrips3D([p[keep, i] for i in range(n)],
                                                              labels=list(scene.bodies)), static=True)
    for suffix, edges in (("", scene.edges), ("_desired", scene.edges_desired)):
        if edges is None:
            continue
        e = edges.shape[1] // 2
        strips = edges.reshape(n_t * e, 2, 3)
        rec.send_columns(f"{root}world/edges{suffix}", indexes=time,
                         columns=rr.LineStrips3D.columns(strips=strips).partition([e] * n_t))


def _channels(rr, rec, root: str, log) -> None:
    time = [rr.TimeColumn("time", duration=log.t)]
    for name, ch in log.channels.items():
        k = len(ch.columns)
        if k == 0:
            continue
        entity = f"{root}channels/{name}"
        rec.log(entity, rr.SeriesLines(names=list(ch.columns)), static=True)
        data = np.asarray(ch.data, dtype=float)
        rec.send_columns(entity, indexes=time, columns=rr.Scalars.columns(scalars=data.reshape(-1)).partition([k] * len(log)))


def write_rerun(logs, path, *, kind: str | None = None, name: str = "quatform") -> Path:
    """Write one or more runs as a Rerun recording.

    Parameters
    ----------
    logs : Log or mapping of str to Log
        One world each; a mapping puts run ``key`` under ``/<key>/`` (``""``: at the root), so a
        compare's runs sit side by side.
    path : path-like
        The ``.rrd`` file (written beside and moved in when complete).
    kind : str, optional
        The scenario kind (default: each log's ``meta["kind"]``).
    name : str
        The recording's application id (the scenario's name).

    Returns
    -------
    Path
    """
    rr = require_rerun()
    logs = logs if isinstance(logs, Mapping) else {"": logs}
    path = Path(path)
    if path.suffix != ".rrd":
        raise InvalidInputError(f"--rerun {path}: a Rerun recording is a .rrd file; give FILE.rrd")
    for key, log in logs.items():
        if log.batch_shape:
            raise InvalidInputError(f"run {key or name}: the log holds a batch of worlds {log.batch_shape}; a "
                                    "recording holds one: write log.world(i)")
    tmp = path.with_name(path.name + ".partial")
    rec = rr.RecordingStream(str(name))
    rec.save(tmp)
    try:
        try:
            for key, log in logs.items():
                root = f"/{key}/" if key else "/"
                _world(rr, rec, root, scene_of(log, kind), log.t)
                _channels(rr, rec, root, log)
            rec.flush()
        finally:
            rec.disconnect()
        os.replace(tmp, path)
    except BaseException:  # Ctrl-C included: no half-written recording is left behind
        tmp.unlink(missing_ok=True)
        raise
    return path
