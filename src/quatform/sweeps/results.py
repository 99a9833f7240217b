"""A sweep's results: the chunk store, the per-trial table and the per-cell summary.

Sweeps layer. Every finished chunk is stored as ``DIR/chunks/<chunk>.json`` (written
atomically), so a rerun into the same ``--out`` with the same spec skips it; the spec's
identity is ``DIR/sweep.json`` (a different spec in that folder is refused). The tables
(``results.csv``/``.json``: a row per trial; ``summary.csv``/``.json``: a row per cell) are
written atomically (:func:`quatform.sim.output.atomic_write_text`) from the rows ordered by
cell and trial, so they are the same whatever executor ran the chunks.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from pathlib import Path

import numpy as np

from ..errors import InvalidInputError
from ..sim.output import OUTPUT_MARKER, atomic_write_text

__all__ = ["ChunkStore", "summarize", "write_table", "ordered_rows", "SPEC_FILE"]

#: The spec's identity in the output folder.
SPEC_FILE = "sweep.json"


class ChunkStore:
    """The finished chunks of one sweep in ``out/chunks/``.

    Opening refuses a folder that holds another spec's sweep, or files that are not a sweep's;
    the folder and its ``sweep.json`` are made when the first chunk is saved.
    """

    def __init__(self, out, spec, backend: str):
        self.out = Path(out)
        self.folder = self.out / "chunks"
        ident = {"identity": spec.identity, "backend": backend, "name": spec.name, "spec": spec.data}
        meta = self.out / SPEC_FILE
        if self.out.exists() and not self.out.is_dir():
            raise InvalidInputError(f"--out {str(out)!r} is a file; give a folder")
        if meta.is_file():
            try:
                old = json.loads(meta.read_text(encoding="utf-8"))
            except (OSError, ValueError):
                old = None
            if not isinstance(old, dict):
                raise InvalidInputError(f"--out {str(out)!r}: its {SPEC_FILE} is unreadable, so its chunks cannot be told "
                                        "to be this spec's; give a new --out")
            if (old.get("identity"), old.get("backend")) != (spec.identity, backend):
                raise InvalidInputError(
                    f"--out {str(out)!r} holds the sweep {old.get('name')!r} of another spec or backend "
                    f"({old.get('identity')}, {old.get('backend')}; this is {spec.identity}, {backend}); give a new "
                    "--out, or rerun the same spec to resume it")
        elif self.out.exists() and (other := sorted(n for n in os.listdir(self.out) if n != OUTPUT_MARKER)):
            raise InvalidInputError(f"--out {str(out)!r} holds files that are not a sweep's (no {SPEC_FILE}; e.g. "
                                    f"{other[0]!r}); give a new or empty folder")
        self._ident, self._meta = ident, meta  # written with the first chunk: a sweep refused before it
        # (a [success] metric it does not compute) leaves no folder that locks --out to that spec

    def path(self, chunk) -> Path:
        return self.folder / f"{chunk.key}.json"

    def load(self, chunk) -> list | None:
        """The rows of a finished chunk, or None (not run, or unreadable: run again)."""
        p = self.path(chunk)
        if not p.is_file():
            return None
        try:
            rows = json.loads(p.read_text(encoding="utf-8"))["rows"]
        except (OSError, ValueError, KeyError, TypeError):
            return None
        return rows if isinstance(rows, list) and len(rows) == chunk.stop - chunk.start else None

    def save(self, chunk, rows: list) -> None:
        if not self._meta.is_file():
            self.folder.mkdir(parents=True, exist_ok=True)
            atomic_write_text(self._meta, json.dumps(self._ident, indent=2, sort_keys=True, default=str) + "\n")
        atomic_write_text(self.path(chunk), json.dumps({"chunk": chunk.key, "rows": rows}, default=_json) + "\n")


def _json(v):
    if isinstance(v, (np.floating, np.integer, np.bool_)):
        return v.item()
    raise TypeError(type(v).__name__)


def ordered_rows(rows) -> list[dict]:
    """Rows by cell, then trial."""
    return sorted(rows, key=lambda r: (r["cell"], r["trial"]))


def _columns(rows) -> list[str]:
    cols: list[str] = []
    seen = set()
    for r in rows:
        for k in r:
            if k not in seen:
                seen.add(k)
                cols.append(k)
    return cols


def _cell(v) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(v)
    return str(v)


def write_table(folder, stem: str, rows: list[dict]) -> list[Path]:
    """``stem.csv`` and ``stem.json`` of ``rows`` in ``folder`` (atomic writes)."""
    cols = _columns(rows)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols)
    for r in rows:
        w.writerow([_cell(r.get(c)) for c in cols])
    folder = Path(folder)
    return [atomic_write_text(folder / f"{stem}.csv", buf.getvalue()),
            atomic_write_text(folder / f"{stem}.json",
                              json.dumps({"columns": cols, "rows": rows}, indent=1, default=_json) + "\n")]


def _stat(values, q):
    v = np.asarray([x for x in values if isinstance(x, (int, float)) and math.isfinite(x)], dtype=float)
    return float(np.quantile(v, q)) if v.size else None


def summarize(spec, rows: list[dict]) -> list[dict]:
    """A row per cell: its choice and parameters, trials, failed, lost, success rate and the
    median and 90th percentile of each success metric (over the trials that did not fail)."""
    by_cell: dict[int, list] = {}
    for r in rows:
        by_cell.setdefault(r["cell"], []).append(r)
    out = []
    for cell, (point, choice, values) in enumerate(spec.cells()):
        rs = by_cell.get(cell, [])
        if not rs:
            continue
        ok = [r for r in rs if not r["failed"]]
        row = {"cell": cell, "point": point, spec.compare_key: choice, **values, "trials": len(rs),
               "failed": sum(r["failed"] for r in rs), "lost": sum(r["lost"] for r in rs),
               "success_rate": sum(r["success"] for r in rs) / len(rs)}
        for key in spec.success.below:
            vals = [r.get(key) for r in ok]
            row[f"median_{key}"] = _stat(vals, 0.5)
            row[f"p90_{key}"] = _stat(vals, 0.9)
        out.append(row)
    return out
