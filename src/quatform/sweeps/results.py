"""A sweep's results: the chunk store, the per-trial table and the per-cell summary.

Sweeps layer. Every finished chunk is stored at once, so a rerun into the same ``--out`` with
the same spec skips it: as ``DIR/chunks/<chunk>.json`` (``results = "csv"``) or as a Parquet
shard ``DIR/trials/part-<cell>-<trial>.parquet`` (``"parquet"``, ``"both"``; :mod:`.shards`),
each written atomically. The spec's identity and its store are ``DIR/sweep.json`` (another
spec, backend or store in that folder is refused). The tables (``results.csv``/``.json``: a row
per trial; ``summary.csv``/``.json``: a row per cell) are written atomically
(:func:`quatform.sim.output.atomic_file`) from the rows ordered by cell and trial, so they are the
same whatever executor ran the chunks. The summary is one reduction of the rows cell by cell
(:func:`summarize_blocks`), fed from the rows in memory or from the shards a batch at a time.
"""

from __future__ import annotations

import csv
import json
import math
import os
from pathlib import Path

import numpy as np

from ..errors import InvalidInputError
from ..sim.output import OUTPUT_MARKER, atomic_file, atomic_write_text, remove_dead_temporaries
from .spec import RESULTS

__all__ = ["ChunkStore", "summarize", "summarize_blocks", "summarize_shards", "write_table", "write_csv",
           "ordered_rows", "SPEC_FILE", "CSV_MAX_TRIALS", "results_mode", "metric_values", "shard_metric_values",
           "leading_columns"]

#: The spec's identity in the output folder.
SPEC_FILE = "sweep.json"
#: Most trials (cells x trials) a sweep writes as CSV when its spec names no ``results``;
#: above it, Parquet shards.
CSV_MAX_TRIALS = 100_000


def results_mode(spec, given: str | None = None) -> str:
    """``given`` (``--results``), else the spec's ``results``, else ``"csv"`` up to
    :data:`CSV_MAX_TRIALS` trials and ``"parquet"`` above."""
    mode = given or spec.results
    if mode is None:
        return "csv" if len(spec.cells()) * spec.trials <= CSV_MAX_TRIALS else "parquet"
    if mode not in RESULTS:
        raise InvalidInputError(f"--results {mode!r}: give one of {', '.join(RESULTS)}")
    return mode


class ChunkStore:
    """The finished chunks of one sweep: rows in ``out/chunks/*.json``, or with ``shards`` the
    Parquet shards of :class:`~quatform.sweeps.shards.ShardStore` (``out/trials/``; ``load`` then
    gives a chunk's row count, and ``shards`` is that store).

    Opening refuses a folder that holds another spec's or backend's sweep, the other store, or
    files that are not a sweep's; the folder and its ``sweep.json`` are made when the first
    chunk is saved.
    """

    def __init__(self, out, spec, backend: str, shards: bool = False):
        self.out = Path(out)
        self.folder = self.out / "chunks"
        self.shards = None
        store = "parquet" if shards else "json"
        ident = {"identity": spec.identity, "backend": backend, "name": spec.name, "spec": spec.data,
                 "store": store}
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
            if old.get("store", "json") != store:
                was = "Parquet shards (results parquet or both)" if store == "json" else "JSON chunks (results csv)"
                raise InvalidInputError(f"--out {str(out)!r} holds this sweep's trials as {was}; resume it with the "
                                        "same --results, or give a new --out")
        elif self.out.exists() and (other := sorted(n for n in os.listdir(self.out) if n != OUTPUT_MARKER)):
            raise InvalidInputError(f"--out {str(out)!r} holds files that are not a sweep's (no {SPEC_FILE}; e.g. "
                                    f"{other[0]!r}); give a new or empty folder")
        self._ident, self._meta = ident, meta  # written with the first chunk: a sweep refused before it
        # (a [success] metric it does not compute) leaves no folder that locks --out to that spec
        if shards:
            from .shards import SHARD_FOLDER, ShardStore

            self.shards = ShardStore(self.out, leading_columns(spec))
            remove_dead_temporaries(self.out / SHARD_FOLDER, "part-*.parquet")

    def path(self, chunk) -> Path:
        return self.folder / f"{chunk.key}.json"

    def load(self, chunk) -> list | int | None:
        """The rows of a finished chunk (Parquet shards: their count), or None (not run, or
        unreadable: run again)."""
        if self.shards is not None:
            return self.shards.load(chunk)
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
            self.out.mkdir(parents=True, exist_ok=True)
            atomic_write_text(self._meta, json.dumps(self._ident, indent=2, sort_keys=True, default=str) + "\n")
        if self.shards is not None:
            self.shards.save(chunk, rows)
            return
        self.folder.mkdir(parents=True, exist_ok=True)
        atomic_write_text(self.path(chunk), json.dumps({"chunk": chunk.key, "rows": rows}, default=_json) + "\n")


def leading_columns(spec) -> tuple:
    """The columns a row starts with: ``cell``, ``point``, the choice, the varied parameters,
    ``latency_ticks``, ``trial``, ``seed``."""
    return ("cell", "point", spec.compare_key, *(a.name for a in spec.axes), "latency_ticks", "trial", "seed")


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


def write_csv(path, columns: list[str], rows) -> Path:
    """``rows`` (an iterable of row dicts) as CSV with ``columns`` at ``path``, atomically, a row
    at a time (a float by its ``repr``: exact; None: empty)."""
    with atomic_file(path, "w") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(columns)
        for r in rows:
            w.writerow([_cell(r.get(c)) for c in columns])
    return Path(path)


def write_table(folder, stem: str, rows, columns: list[str] | None = None) -> list[Path]:
    """``stem.csv`` and ``stem.json`` of ``rows`` in ``folder`` (atomic writes, a row at a time).

    ``rows`` is a list of row dicts (the columns: every key, first seen first), or a function
    returning a new iterator of them (called once per file) with ``columns`` given.
    """
    if not callable(rows):
        columns, listed = _columns(rows), rows
        rows = lambda: listed  # noqa: E731
    folder = Path(folder)
    write_csv(folder / f"{stem}.csv", columns, rows())
    # the bytes of json.dumps({"columns": ..., "rows": ...}, indent=1), a row at a time
    with atomic_file(folder / f"{stem}.json", "w") as f:
        f.write('{\n "columns": ' + json.dumps(columns, indent=1).replace("\n", "\n ") + ',\n "rows": [')
        sep = "\n  "
        for r in rows():
            f.write(sep + json.dumps(r, indent=1, default=_json).replace("\n", "\n  "))
            sep = ",\n  "
        f.write("]\n}\n" if sep == "\n  " else "\n ]\n}\n")
    return [folder / f"{stem}.csv", folder / f"{stem}.json"]


def _number(v) -> float:
    """A metric's value as a float (NaN: not a number, so not counted)."""
    return float(v) if isinstance(v, (int, float)) else math.nan


class _Tally:
    """One cell's counts and its success metrics' finite values over the trials that did not fail."""

    def __init__(self, cell: int, metrics):
        self.cell, self.n, self.failed, self.lost, self.success = cell, 0, 0, 0, 0
        self.values = {k: [] for k in metrics}

    def add(self, block: dict) -> None:
        failed = np.asarray(block["failed"], dtype=bool)
        self.n += len(failed)
        self.failed += int(failed.sum())
        self.lost += int(np.asarray(block["lost"], dtype=bool).sum())
        self.success += int(np.asarray(block["success"], dtype=bool).sum())
        for k, vals in self.values.items():
            v = np.asarray(block[k], dtype=float)[~failed]
            vals.append(v[np.isfinite(v)])

    def row(self, spec) -> dict:
        point, choice, values = spec.cells()[self.cell]
        row = {"cell": self.cell, "point": point, spec.compare_key: choice, **values, "trials": self.n,
               "failed": self.failed, "lost": self.lost, "success_rate": self.success / self.n}
        for key, parts in self.values.items():
            v = np.concatenate(parts)
            row[f"median_{key}"] = float(np.quantile(v, 0.5)) if v.size else None
            row[f"p90_{key}"] = float(np.quantile(v, 0.9)) if v.size else None
        return row


def summarize_blocks(spec, blocks) -> list[dict]:
    """A row per cell from ``blocks``: dicts of equal-length arrays ``cell``, ``failed``,
    ``lost``, ``success`` and each success metric (float, NaN where not a number), in the rows'
    order (a cell's rows together). Counts add up block by block; the median and 90th
    percentile (NumPy's linear interpolation, exact) are of the cell's finite values of its
    trials that did not fail, the only values held, one cell at a time."""
    out = []
    tally = None
    for block in blocks:
        cells = np.asarray(block["cell"])
        if not cells.size:
            continue
        starts = np.flatnonzero(np.r_[True, cells[1:] != cells[:-1]])
        for a, b in zip(starts, np.r_[starts[1:], cells.size]):
            cell = int(cells[a])
            if tally is None or tally.cell != cell:
                if tally is not None:
                    out.append(tally.row(spec))
                tally = _Tally(cell, spec.success.below)
            tally.add({k: v[a:b] for k, v in block.items()})
    if tally is not None:
        out.append(tally.row(spec))
    return out


def _row_blocks(spec, rows: list[dict]):
    """The rows (by cell, then trial) as one block of :func:`summarize_blocks`."""
    block = {k: np.array([r[k] for r in rows]) for k in ("cell", "failed", "lost", "success")}
    block.update({k: np.array([_number(r.get(k)) for r in rows], dtype=float) for k in spec.success.below})
    return [block] if rows else []


def summarize(spec, rows: list[dict]) -> list[dict]:
    """A row per cell: its choice and parameters, trials, failed, lost, success rate and the
    median and 90th percentile of each success metric (over the trials that did not fail)."""
    return summarize_blocks(spec, _row_blocks(spec, ordered_rows(rows)))


def summarize_shards(spec, out) -> list[dict]:
    """:func:`summarize` of the sweep's Parquet shards, read a batch at a time (the columns it
    needs only)."""
    from .shards import float_column, shard_batches

    base = ("cell", "failed", "lost", "success")
    metrics = tuple(spec.success.below)
    return summarize_blocks(spec, ({**{k: b.column(k).to_numpy(zero_copy_only=False) for k in base},
                                    **{k: float_column(b, k) for k in metrics}}
                                   for b in shard_batches(out, [*base, *metrics])))


def metric_values(spec, rows: list[dict]):
    """``values(metric) -> {choice: floats}``: a success metric over each choice's trials that
    did not fail (NaN: not a number), for the figures."""
    def values(metric):
        return {c: np.array([_number(r.get(metric)) for r in rows if r[spec.compare_key] == c and not r["failed"]],
                            dtype=float) for c in spec.choices}
    return values


def shard_metric_values(spec, out):
    """:func:`metric_values` read from the shards: one metric's column (and the choice and
    ``failed``) at a time."""
    from .shards import float_column, shard_batches

    key = spec.compare_key

    def values(metric):
        parts: dict = {c: [] for c in spec.choices}
        for b in shard_batches(out, [key, "failed", metric]):
            choice = np.asarray(b.column(key).to_pylist(), dtype=object)
            ok = ~b.column("failed").to_numpy(zero_copy_only=False)
            v = float_column(b, metric)
            for c in spec.choices:
                parts[c].append(v[ok & (choice == c)])
        return {c: np.concatenate(p) if p else np.empty(0) for c, p in parts.items()}
    return values
