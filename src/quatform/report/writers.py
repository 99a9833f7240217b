"""The writers of a run's files: ``timeseries.csv`` from a Log, strict ``metrics.json``.

Report layer (above scenarios, below runs and the CLI). One writer serves every scenario
kind: :func:`write_timeseries` writes any :class:`~quatform.sim.log.Log` (the channels a
kind names, in its order, with the log's own column names), :func:`write_metrics` and
:func:`write_json` any metrics dict or list of rows. A new output format (MCAP, Parquet ...)
is a new function here reading the same Log.

Every file is written to a temporary name and renamed into place
(:func:`quatform.sim.output.atomic_write_text`), so a run cut off by Ctrl-C never leaves a
truncated file under its final name. JSON is strict (:func:`strict_json`): a NaN or infinite
value is written as ``null`` and named under ``nonfinite_values``.
"""

from __future__ import annotations

import io
import json
import math
from pathlib import Path

import numpy as np

from ..sim.output import atomic_write_text

__all__ = ["write_timeseries", "write_columns", "write_metrics", "write_json", "strict_json"]


def write_columns(names, data, path) -> Path:
    """A CSV file with a header row ``names`` and the ``(T, n)`` array ``data`` (9 digits).

    Parameters
    ----------
    names : sequence of str, length n
        Header.
    data : array_like, shape (T, n)
    path : path-like

    Written atomically (a temporary file renamed into place).
    """
    buf = io.StringIO()
    np.savetxt(buf, np.asarray(data, dtype=float), delimiter=",", header=",".join(names), comments="",
               fmt="%.9g")
    return atomic_write_text(path, buf.getvalue())


def write_timeseries(log, path, channels=None) -> Path:
    """``timeseries.csv`` of one world's log: ``t``, then the columns of ``channels`` side by side.

    Parameters
    ----------
    log : quatform.sim.log.Log
        One world (``log.world(i)`` of a batched log).
    path : path-like
    channels : sequence of str, optional
        Channel names in file order (a kind's ``Experiment.csv_channels``); default all, in the
        log's order.
    """
    return write_columns(*log.table(channels), path)


# --------------------------------------------------------------------------- strict JSON

def _finite(obj, where: str, bad: dict):
    """``obj`` with numpy values made plain and every NaN/inf replaced by ``None`` (noted in ``bad``)."""
    if isinstance(obj, np.ndarray):
        obj = obj.tolist()
    elif isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float):
        if math.isfinite(obj):
            return obj
        bad[where or "value"] = "nan" if math.isnan(obj) else ("inf" if obj > 0 else "-inf")
        return None
    if isinstance(obj, dict):
        return {str(k): _finite(v, f"{where}.{k}" if where else str(k), bad) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v, f"{where}[{i}]", bad) for i, v in enumerate(obj)]
    return obj


def strict_json(obj) -> str:
    """``obj`` as strict JSON text (RFC 8259: no ``NaN``, ``Infinity``), indented, one trailing newline.

    A NaN or infinite number becomes ``null``. In a dict (a ``metrics.json``) the replaced
    values are named under the added key ``nonfinite_values``, ``{"key.sub[0]": "inf" | "-inf" |
    "nan"}``, so a ``null`` that means "did not happen" (e.g. ``first_singular_time_s``) is
    told apart from one that was not finite. In a list of dicts (``comparison.json``) each
    dict gets its own ``nonfinite_values``. NumPy scalars and arrays are written as numbers and
    lists.
    """
    def one(d):
        bad: dict = {}
        clean = _finite(d, "", bad)
        if bad and isinstance(clean, dict):
            clean["nonfinite_values"] = {**clean.get("nonfinite_values", {}), **bad}
        return clean

    clean = [one(d) for d in obj] if isinstance(obj, (list, tuple)) else one(obj)
    return json.dumps(clean, indent=2, allow_nan=False) + "\n"


def write_json(obj, path) -> Path:
    """:func:`strict_json` of ``obj`` written atomically to ``path``."""
    return atomic_write_text(path, strict_json(obj))


def write_metrics(metrics: dict, path) -> Path:
    """``metrics.json``: strict JSON (non-finite values as ``null``, see :func:`strict_json`), atomic."""
    return write_json(metrics, path)
