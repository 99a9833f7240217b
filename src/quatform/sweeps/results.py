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

import contextlib
import csv
import json
import math
import os
from pathlib import Path

import numpy as np

from ..errors import InvalidInputError
from ..sim.output import OUTPUT_MARKER, atomic_file, atomic_write_text, remove_dead_temporaries, writing
from .spec import RESULTS

__all__ = ["ChunkStore", "summarize", "summarize_blocks", "summarize_shards", "write_table", "write_csv",
           "ordered_rows", "typed_rows", "column_kind", "column_value", "text_value", "stored_results", "SPEC_FILE",
           "LOCK_FILE", "lock_folder", "write_exclusive", "CSV_MAX_TRIALS", "results_mode", "metric_values",
           "shard_metric_values", "leading_columns"]

#: The spec's identity in the output folder.
SPEC_FILE = "sweep.json"
#: The lock a running sweep holds on its output folder.
LOCK_FILE = ".sweep.lock"
#: Most trials (cells x trials) a sweep writes as CSV when its spec names no ``results``;
#: above it, Parquet shards.
CSV_MAX_TRIALS = 100_000


def results_mode(spec, given: str | None = None, out=None) -> str:
    """``given`` (``--results``), else the spec's ``results``, else the one ``out/sweep.json``
    records (a sweep resumed as it was started), else ``"csv"`` up to :data:`CSV_MAX_TRIALS`
    trials and ``"parquet"`` above."""
    mode = given or spec.results or (stored_results(out) if out is not None else None)
    if mode is None:
        return "csv" if len(spec.cells()) * spec.trials <= CSV_MAX_TRIALS else "parquet"
    if mode not in RESULTS:
        raise InvalidInputError(f"--results {mode!r}: give one of {', '.join(RESULTS)}")
    return mode


def stored_results(out) -> str | None:
    """The ``results`` of the sweep stored in ``out`` (None: none there, or unreadable)."""
    try:
        old = json.loads((Path(out) / SPEC_FILE).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(old, dict):
        return None
    mode = old.get("results", {"json": "csv", "parquet": "parquet"}.get(old.get("store", "json")))
    return mode if mode in RESULTS else None


class ChunkStore:
    """The finished chunks of one sweep: rows in ``out/chunks/*.json`` (``results = "csv"``), or
    the Parquet shards of :class:`~quatform.sweeps.shards.ShardStore` (``out/trials/``; ``load`` then
    gives a chunk's row count, and ``shards`` is that store).

    A context manager: entering it locks the folder for the sweep's duration (an exclusive
    ``flock`` on ``out/.sweep.lock``; a second sweep into the same ``--out`` is refused in one
    line naming the first one's pid), removes the temporaries of the sweep's files left by a
    killed run, and refuses a folder that holds another spec's or backend's sweep, the other
    store, or files that are not a sweep's. ``sweep.json`` is made (exclusively) when the first
    chunk is saved; a sweep that stored none leaves no folder it made.
    """

    def __init__(self, out, spec, backend: str, results: str = "csv"):
        self.out = Path(out)
        self.folder = self.out / "chunks"
        self.shards = None
        self.rows: list[dict] = []  # the JSON chunks' rows, loaded or saved (results = "csv")
        self.store = "json" if results == "csv" else "parquet"
        self._spec, self._backend = spec, backend
        self._ident = {"identity": spec.identity, "backend": backend, "name": spec.name, "spec": spec.data,
                       "store": self.store, "results": results}
        self._meta = self.out / SPEC_FILE
        self._lock = None
        self._made = False

    def __enter__(self):
        out = self.out
        if out.exists() and not out.is_dir():
            raise InvalidInputError(f"--out {str(out)!r} is a file; give a folder")
        self._made = not out.exists()
        out.mkdir(parents=True, exist_ok=True)
        try:
            self._lock = lock_folder(out)
            self._check()
        except BaseException:
            self.__exit__(None, None, None)
            raise
        if self.store == "parquet":
            from .shards import ShardStore

            self.shards = ShardStore(out, leading_columns(self._spec))
        return self

    def __exit__(self, *exc) -> None:
        if self._lock is not None and not self._meta.exists():  # nothing stored: no lock file left,
            with contextlib.suppress(OSError):  # and the folder this sweep made goes
                (self.out / LOCK_FILE).unlink()
        if self._made and not self._meta.exists():
            remove_dead_temporaries(self.out)
            for folder in (self.out / "chunks", self.out / "trials", self.out):  # each only if empty
                with contextlib.suppress(OSError):
                    folder.rmdir()
        if self._lock is not None:
            self._lock.close()  # releases the flock
            self._lock = None

    def _check(self) -> None:
        """Refuse a folder that is not this sweep's (under the lock); remove dead temporaries."""
        out, meta = self.out, self._meta
        remove_dead_temporaries(out, SPEC_FILE)  # a run killed writing sweep.json
        if meta.is_file():
            try:
                old = json.loads(meta.read_text(encoding="utf-8"))
            except (OSError, ValueError):
                old = None
            if not isinstance(old, dict):
                raise InvalidInputError(f"--out {str(out)!r}: its {SPEC_FILE} is unreadable, so its chunks cannot be told "
                                        "to be this spec's; give a new --out")
            spec, backend = self._spec, self._backend
            if (old.get("identity"), old.get("backend")) != (spec.identity, backend):
                raise InvalidInputError(
                    f"--out {str(out)!r} holds the sweep {old.get('name')!r} of another spec or backend "
                    f"({old.get('identity')}, {old.get('backend')}; this is {spec.identity}, {backend}); give a new "
                    "--out, or rerun the same spec to resume it")
            if old.get("store", "json") != self.store:
                was = ("Parquet shards (results parquet or both)" if self.store == "json"
                       else "JSON chunks (results csv)")
                raise InvalidInputError(f"--out {str(out)!r} holds this sweep's trials as {was}; resume it with the "
                                        "same --results, or give a new --out")
        elif other := sorted(n for n in os.listdir(out) if n not in (OUTPUT_MARKER, LOCK_FILE)):
            raise InvalidInputError(f"--out {str(out)!r} holds files that are not a sweep's (no {SPEC_FILE}; e.g. "
                                    f"{other[0]!r}); give a new or empty folder")
        for folder in (out, out / "chunks", out / "trials", out / "figures"):  # every atomic output's
            remove_dead_temporaries(folder)

    def path(self, chunk) -> Path:
        return self.folder / f"{chunk.key}.json"

    def load(self, chunk) -> int | None:
        """The number of rows of a finished chunk (JSON chunks: kept in :attr:`rows`), or None
        (not run, or unreadable: run again)."""
        if self.shards is not None:
            return self.shards.load(chunk)
        p = self.path(chunk)
        if not p.is_file():
            return None
        try:
            rows = json.loads(p.read_text(encoding="utf-8"))["rows"]
        except (OSError, ValueError, KeyError, TypeError):
            return None
        if not isinstance(rows, list) or len(rows) != chunk.stop - chunk.start:
            return None
        self.rows.extend(rows)
        return len(rows)

    def first_row(self) -> dict:
        """The first stored row (of the chunks loaded)."""
        return self.rows[0] if self.shards is None else self.shards.first_row()

    def save(self, chunk, rows: list) -> None:
        """Store a finished chunk (JSON chunks: its rows kept in :attr:`rows` too)."""
        if not self._meta.is_file():
            write_exclusive(self._meta, json.dumps(self._ident, indent=2, sort_keys=True, default=str) + "\n")
        if self.shards is not None:
            self.shards.save(chunk, rows)
            return
        self.folder.mkdir(parents=True, exist_ok=True)
        atomic_write_text(self.path(chunk), json.dumps({"chunk": chunk.key, "rows": rows}, default=_json) + "\n")
        self.rows.extend(rows)


def lock_folder(out):
    """An exclusive ``flock`` on ``out/.sweep.lock`` (the open file: closing it releases the
    lock), holding this process' pid; one line naming the holder's pid when another sweep has it.
    Where the system has no ``flock`` (not POSIX) the file is made but not locked."""
    try:
        import fcntl
    except ImportError:
        fcntl = None
    path = Path(out) / LOCK_FILE
    while True:
        f = open(path, "a+", encoding="utf-8")
        try:
            if fcntl is not None:
                fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            f.seek(0)
            pid = f.read().strip() or "?"
            f.close()
            raise InvalidInputError(f"another sweep is writing into {str(out)!r} (pid {pid}); wait or choose another "
                                    "--out") from None
        try:
            same = os.stat(path).st_ino == os.fstat(f.fileno()).st_ino
        except FileNotFoundError:  # unlinked by the sweep that held it: lock the new one
            same = False
        if same:
            f.seek(0)
            f.truncate()
            f.write(f"{os.getpid()}\n")
            f.flush()
            return f
        f.close()


def write_exclusive(path, text: str) -> Path:
    """Write ``text`` to ``path`` through a temporary file linked into place: whole or absent,
    and refused in one line if ``path`` exists (another sweep made it). On a file system
    without hard links the file is moved into place instead, where ``path`` does not exist
    (the sweep holds the folder's lock, :func:`lock_folder`)."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        with writing(path), open(tmp, "w", encoding="utf-8", newline="") as f:
            f.write(text)
        try:
            os.link(tmp, path)
        except FileExistsError:
            raise
        except OSError:  # no hard links here (FAT, exFAT, SMB, FUSE): under the folder's lock, moved in
            if path.exists():
                raise FileExistsError(path) from None
            os.replace(tmp, path)
    except FileExistsError:
        raise InvalidInputError(f"--out {str(path.parent)!r}: another sweep made its {path.name} meanwhile; "
                                "give a new --out") from None
    finally:
        with contextlib.suppress(OSError):
            tmp.unlink()
    return path


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


def text_value(v) -> str:
    """A value as the tables' CSV writes it: a float by its ``repr`` (exact), None empty, any
    other by ``str`` (``True``, ``3``, a word)."""
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(v)
    return str(v)


def column_kind(kinds) -> str:
    """A column's kind from the Python types of its non-null values (every trial's, in both
    stores): ``"null"`` (none yet), ``"bool"``, ``"int"``, ``"float"`` (floats, or whole
    numbers and floats: the whole ones stored as floats) or ``"text"`` (words, or values of
    two kinds, such as a flag and a number: each stored as :func:`text_value` writes it)."""
    kinds = set(kinds)
    if not kinds:
        return "null"
    if kinds == {bool}:
        return "bool"
    if kinds == {int}:
        return "int"
    if kinds <= {int, float}:
        return "float"
    return "text"


def column_value(v, kind: str):
    """``v`` as a column of ``kind`` (:func:`column_kind`) holds it."""
    if v is None:
        return None
    if kind == "float":
        return float(v)
    if kind == "text":
        return v if isinstance(v, str) else text_value(v)
    return v


def typed_rows(rows: list[dict]) -> list[dict]:
    """``rows`` with each column's values as its kind over all the rows holds them (the rule the
    Parquet shards follow, so ``results = "csv"`` and ``"both"`` write the same tables)."""
    kinds: dict = {}
    for r in rows:
        for k, v in r.items():
            seen = kinds.setdefault(k, set())
            if v is not None:
                seen.add(type(v))
    mixed = {k: column_kind(t) for k, t in kinds.items() if len(t) > 1}
    if not mixed:
        return rows
    return [{k: column_value(v, mixed[k]) if k in mixed else v for k, v in r.items()} for r in rows]


def write_csv(path, columns: list[str], rows) -> Path:
    """``rows`` (an iterable of row dicts) as CSV with ``columns`` at ``path``, atomically, a row
    at a time (a float by its ``repr``: exact; None: empty)."""
    with atomic_file(path, "w") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(columns)
        for r in rows:
            w.writerow([text_value(r.get(c)) for c in columns])
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


def summarize_shards(spec, paths) -> list[dict]:
    """:func:`summarize` of the sweep's Parquet shards ``paths`` (in row order), read a batch at
    a time (the columns it needs only)."""
    from .shards import float_column, shard_batches

    base = ("cell", "failed", "lost", "success")
    metrics = tuple(spec.success.below)
    return summarize_blocks(spec, ({**{k: b.column(k).to_numpy(zero_copy_only=False) for k in base},
                                    **{k: float_column(b, k) for k in metrics}}
                                   for b in shard_batches(paths, [*base, *metrics])))


def metric_values(spec, rows: list[dict]):
    """``values(metric) -> {choice: floats}``: a success metric over each choice's trials that
    did not fail (NaN: not a number), for the figures."""
    def values(metric):
        return {c: np.array([_number(r.get(metric)) for r in rows if r[spec.compare_key] == c and not r["failed"]],
                            dtype=float) for c in spec.choices}
    return values


def shard_metric_values(spec, paths):
    """:func:`metric_values` read from the shards: one metric's column (and the choice and
    ``failed``) at a time."""
    from .shards import float_column, shard_batches

    key = spec.compare_key

    def values(metric):
        parts: dict = {c: [] for c in spec.choices}
        for b in shard_batches(paths, [key, "failed", metric]):
            choice = b.column(key).to_numpy(zero_copy_only=False)
            ok = ~b.column("failed").to_numpy(zero_copy_only=False)
            v = float_column(b, metric)
            for c in spec.choices:
                parts[c].append(v[ok & (choice == c)])
        return {c: np.concatenate(p) if p else np.empty(0) for c, p in parts.items()}
    return values
