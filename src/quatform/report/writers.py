"""The writers of a run's files: ``timeseries.csv`` from a Log, strict ``metrics.json``.

Report layer (above scenarios, below runs and the CLI). One writer serves every scenario
kind: :func:`write_timeseries` writes any :class:`~quatform.sim.log.Log` (the channels a
kind names, in its order, with the log's own column names), :func:`write_metrics` and
:func:`write_json` any metrics dict or list of rows. A run writes them through the writer
registry (:data:`quatform.outputs.WRITERS`); a new output format (Parquet ...) is one
:class:`quatform.outputs.Writer` subclass reading the same Log.

Every file is written to a temporary name and renamed into place
(:func:`quatform.sim.output.atomic_write_text`), so a run cut off by Ctrl-C never leaves a
truncated file under its final name. JSON is strict (:func:`strict_json`): a NaN or infinite
value is written as ``null`` and named under ``nonfinite_values``.

Times in CSV files (:data:`TIME_COLUMNS`) are written exactly, so a bag's nanosecond stamps
survive: a time held as integer nanoseconds (``quatform replay``'s ``commands.csv``: the
bag's stamps) as its decimal seconds with nine decimals (``1700000000.010000000``), a float
time (a simulation's ``timeseries.csv``) as the shortest decimal that reads back as the same
float64 (``repr``; ``round(t * 1e9)`` is then the stamp ``run.mcap`` holds). Other columns
have 9 significant digits. (At an epoch time of 1.7e9 s, 9 digits would resolve 1 s and a
float64 238 ns.)
"""

from __future__ import annotations

import io
import json
import math
from pathlib import Path

import numpy as np

from ..errors import InvalidInputError
from ..sim.output import atomic_write_text

__all__ = ["write_timeseries", "timeseries_table", "write_columns", "write_metrics", "write_json", "strict_json",
           "TIME_COLUMNS", "ns_text"]

#: Columns written exactly (see the module docstring): the time and a replay's reference time, s.
TIME_COLUMNS = ("t", "reference_time")


def ns_text(ns) -> list[str]:
    """Decimal seconds, nine decimals, of integer nanoseconds ``ns`` (T,): exact (``1700000000.010000000``)."""
    out = []
    for v in np.asarray(ns, dtype=np.int64).tolist():
        sec, frac = divmod(abs(v), 1_000_000_000)
        out.append(f"{'-' if v < 0 else ''}{sec}.{frac:09d}")
    return out


def write_columns(names, data, path, *, ns=None) -> Path:
    """A CSV file with a header row ``names`` and the ``(T, n)`` array ``data``.

    :data:`TIME_COLUMNS` are written exactly (float times as their shortest round-trip
    decimal, ``repr``), every other column with 9 significant digits.

    Parameters
    ----------
    names : sequence of str, length n
        Header.
    data : array_like, shape (T, n)
    path : path-like
    ns : dict, optional
        ``{column name: (T,) integer nanoseconds}``: those columns' text comes from the integers
        (:func:`ns_text`, exact to the nanosecond) rather than from ``data``'s floats.

    Written atomically (a temporary file renamed into place).
    """
    names = list(names)
    data = np.asarray(data, dtype=float)
    ns = dict(ns or {})
    unknown = sorted(set(ns) - set(names))
    if unknown:
        raise InvalidInputError(f"write_columns: ns names columns {unknown} that the header {names} lacks")
    exact = [j for j, n in enumerate(names) if n in ns or n in TIME_COLUMNS]
    if not exact or data.ndim != 2 or data.shape[1] != len(names) or data.shape[0] == 0:
        buf = io.StringIO()
        np.savetxt(buf, data, delimiter=",", header=",".join(names), comments="", fmt="%.9g")
        return atomic_write_text(path, buf.getvalue())
    texts = {j: ns_text(ns[names[j]]) if names[j] in ns else [repr(v) for v in data[:, j].tolist()] for j in exact}
    rest = [j for j in range(len(names)) if j not in texts]
    buf = io.StringIO()
    if rest:
        np.savetxt(buf, data[:, rest], delimiter=",", fmt="%.9g")
    rest_lines = buf.getvalue().splitlines() if rest else [""] * data.shape[0]
    lines = [",".join(names)]
    if exact == list(range(len(exact))):  # the exact columns lead (t first): a prefix of each row
        heads = [",".join(row) for row in zip(*(texts[j] for j in exact))]
        lines += [f"{h},{line}" for h, line in zip(heads, rest_lines)] if rest else heads
    else:
        for k, line in enumerate(rest_lines):  # the exact columns put back in their places, row by row
            cells = line.split(",") if rest else []
            for j in exact:
                cells.insert(j, texts[j][k])
            lines.append(",".join(cells))
    return atomic_write_text(path, "\n".join(lines) + "\n")


def timeseries_table(log, channels=None) -> tuple[list[str], np.ndarray]:
    """Column names (``t`` first) and the ``(T, n)`` array of one world's log, for a CSV file.

    Parameters
    ----------
    log : quatform.sim.log.Log
        One world (``log.world(i)`` of a batched log).
    channels : sequence, optional
        File order (a kind's ``Experiment.csv_channels``): each item a channel name (its
        columns as they are) or a tuple of channel names of equal width, whose columns are
        interleaved (``("state", "r_des")`` -> ``x1, x1_des, y1, y1_des, ...``: each value
        beside its desired one). Default: every channel, in the log's order.
    """
    if channels is None:
        return log.table()
    names, cols = ["t"], [log.t[:, None]]
    for item in channels:
        group = (item,) if isinstance(item, str) else tuple(item)
        widths = {len(log.columns(name)) for name in group}
        if len(widths) != 1:
            raise InvalidInputError(f"timeseries: interleaved channels {group} have different widths "
                                    f"{[len(log.columns(n)) for n in group]}; interleave channels of one width")
        for i in range(widths.pop()):
            for name in group:
                names.append(log.columns(name)[i])
                cols.append(np.asarray(log[name], dtype=float)[:, i:i + 1])
    return names, np.hstack(cols)


def write_timeseries(log, path, channels=None) -> Path:
    """``timeseries.csv`` of one world's log: the columns of :func:`timeseries_table` (``t``
    exactly, then ``channels`` in order, 9 digits), written atomically."""
    return write_columns(*timeseries_table(log, channels), path)


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
