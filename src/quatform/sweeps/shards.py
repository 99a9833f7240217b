"""A sweep's trials as Parquet shards: a file per chunk, one schema, read back a batch at a time.

Sweeps layer. With ``results = "parquet"`` or ``"both"`` (``docs/sweeps.md``) each finished chunk
is written as ``DIR/trials/part-<cell>-<first trial>.parquet`` (zero-padded, so the files' lexical
order is the rows' order: by cell, then trial) through a hidden temporary file renamed into place
(:func:`quatform.sim.output.atomic_file`): a chunk cut off mid-write leaves no shard, and the
shards are the resume store of such a sweep. Every shard has the same columns and types, so
``pandas.read_parquet(DIR / "trials")``, ``polars.scan_parquet(DIR / "trials/*.parquet")`` and
``dask.dataframe.read_parquet(DIR / "trials")`` read them as one table.

The columns: ``cell``, ``point``, the choice, each varied parameter, ``latency_ticks``, ``trial``,
``seed``, the kind's metrics, ``failed``, ``failure``, ``lost``, ``success``; a column's type is that
of its values over every trial, by the rule the CSV path follows too
(:func:`~quatform.sweeps.results.column_kind`: bool, int64, float64 for floats or whole numbers
and floats, string for words or values of two other kinds, as text; a column null in every
trial so far is float64 nulls). A chunk whose values widen a column rewrites the stored shards
to the widened schema, so the schema at the end depends on the trials' values only, not on
which chunk finished first. Every page carries a CRC-32 checksum, verified on every read; the
sweep reads the shards of its planned chunks only. Values are exact:
each column chunk is encoded by what its values are (few distinct values: a dictionary of
run-length-coded indices; whole numbers: delta; floats: byte-stream split; booleans:
run-length), then compressed with zstd (level 19 for the split floats, 3 for the rest).

pyarrow is optional (``pip install -e ".[dask]"``), imported only here.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InvalidInputError, MissingDependencyError
from ..sim.output import atomic_file

__all__ = ["SHARD_FOLDER", "INSTALL_HINT", "require_pyarrow", "ShardStore", "read_shard", "shard_batches",
           "shard_rows", "shard_columns", "float_column", "write_shard", "ZSTD_LEVEL", "FLOAT_ZSTD_LEVEL",
           "DICTIONARY_FRACTION", "TRAILING"]

#: The shards' folder in the sweep's output.
SHARD_FOLDER = "trials"
INSTALL_HINT = 'pip install -e ".[dask]"'
#: zstd level of the shards' columns (3: the library's default trade of time for size) ...
ZSTD_LEVEL = 3
#: ... and of their byte-stream-split floats, whose noisy low bytes level 19 packs 3-5 % tighter
#: (measured on the ugv-uav sweep's 10^6-row replica: 51.0 -> 49.3 B a row, for 2.5 CPU s more).
FLOAT_ZSTD_LEVEL = 19
#: A numeric column chunk is dictionary-encoded when its distinct values are at most this
#: fraction of its rows (the parameters, the constant metrics, the clean cells' repeated
#: values); otherwise floats are byte-stream split and whole numbers delta-coded.
DICTIONARY_FRACTION = 0.25
#: The columns every row ends with (after the metrics).
TRAILING = ("failed", "failure", "lost", "success")
#: Rows per batch read back from a shard (one row group at most).
BATCH_ROWS = 65_536


def require_pyarrow(what: str = 'results = "parquet"'):
    """``(pyarrow, pyarrow.parquet, pyarrow.compute)``, or one line naming the install."""
    try:
        import pyarrow as pa
        import pyarrow.compute as pc
        import pyarrow.parquet as pq
    except ImportError:
        raise MissingDependencyError(f"{what} writes Parquet shards and needs pyarrow, which is not installed here: "
                                     f'{INSTALL_HINT} (or results = "csv")') from None
    return pa, pq, pc


def _arrow_type(pa, kind: str):
    """The Arrow type of a column of ``kind`` (:func:`~quatform.sweeps.results.column_kind`); a
    column null so far is float64 (the metrics' usual type), so that shards written while a
    metric is null everywhere read together with the later ones."""
    return {"bool": pa.bool_(), "int": pa.int64(), "text": pa.string()}.get(kind, pa.float64())


def _kinds(column) -> set:
    """The Python types of a stored column's non-null values (none: all null)."""
    pa, _, _ = require_pyarrow()
    if column.null_count == len(column):
        return set()
    t = column.type
    return {bool} if pa.types.is_boolean(t) else {int} if pa.types.is_integer(t) else \
        {float} if pa.types.is_floating(t) else {str}


def _column(values: list, kind: str):
    """Python values as an Arrow array of ``kind``, each converted as the CSV path does."""
    from .results import column_value

    pa, _, _ = require_pyarrow()
    return pa.array([column_value(v, kind) for v in values], type=_arrow_type(pa, kind))


def _encoding(pa, pc, column) -> str | None:
    """How one column chunk is encoded: ``"dictionary"``, a Parquet encoding, or None (plain)."""
    t = column.type
    if pa.types.is_boolean(t):
        return "RLE"
    if pa.types.is_string(t):
        return "dictionary"
    if pa.types.is_integer(t) or pa.types.is_floating(t):
        few = pc.count_distinct(column, mode="all").as_py() <= max(1, DICTIONARY_FRACTION * len(column))
        return "dictionary" if few else ("DELTA_BINARY_PACKED" if pa.types.is_integer(t) else "BYTE_STREAM_SPLIT")
    return None


def write_shard(path, table, statistics=()) -> Path:
    """Write ``table`` to ``path`` atomically, each column encoded by its values (:func:`_encoding`),
    zstd-compressed; min/max statistics for the columns ``statistics`` only (a reader's filters
    on the cell, the parameters and the outcome skip shards by them; a metric's would cost a
    shard about 40 B a column). Every page carries a CRC-32 of its bytes, checked whenever a
    shard is read (:func:`read_shard`, :func:`shard_batches`). The Parquet schema alone describes the columns (no Arrow
    schema copy in the footer: the types read back are the same)."""
    pa, pq, pc = require_pyarrow()
    how = {f.name: _encoding(pa, pc, c) for f, c in zip(table.schema, table.columns)}
    with atomic_file(path) as f:
        pq.write_table(table, f, compression="zstd", data_page_version="2.0",
                       compression_level={k: FLOAT_ZSTD_LEVEL if v == "BYTE_STREAM_SPLIT" else ZSTD_LEVEL
                                          for k, v in how.items()},
                       use_dictionary=[k for k, v in how.items() if v == "dictionary"],
                       column_encoding={k: v for k, v in how.items() if v not in (None, "dictionary")},
                       store_schema=False, write_page_checksum=True,
                       write_statistics=[n for n in table.column_names if n in statistics])
    return Path(path)


def _damaged(path, exc) -> InvalidInputError:
    return InvalidInputError(f"sweep results: the shard {str(path)!r} is damaged ({' '.join(str(exc).split())[:160]}); "
                             "delete it and rerun the sweep to run its chunk again")


def read_shard(path, columns=None):
    """The whole shard at ``path`` as an Arrow table, every page's checksum verified."""
    pa, pq, _ = require_pyarrow()
    try:
        return pq.read_table(path, columns=columns, page_checksum_verification=True)
    except (OSError, pa.ArrowException) as exc:
        raise _damaged(path, exc) from None


def shard_batches(paths, columns=None):
    """The rows of the shards ``paths`` (in row order) as Arrow record batches, ``columns`` only
    (None: all), at most :data:`BATCH_ROWS` rows each: memory for one batch at a time; one line
    naming a damaged shard."""
    pa, pq, _ = require_pyarrow()
    for p in paths:
        try:
            yield from pq.ParquetFile(p, page_checksum_verification=True).iter_batches(batch_size=BATCH_ROWS,
                                                                                      columns=columns)
        except (OSError, pa.ArrowException) as exc:
            raise _damaged(p, exc) from None


def shard_rows(paths):
    """The rows of the shards ``paths`` as dicts, one batch in memory at a time."""
    for b in shard_batches(paths):
        yield from b.to_pylist()


def shard_columns(paths) -> list[str]:
    """The shards' column names (of the first shard; every shard has the same)."""
    _, pq, _ = require_pyarrow()
    return list(pq.read_schema(paths[0]).names) if paths else []


class ShardStore:
    """The finished chunks of one sweep as Parquet shards in ``out/trials/`` (see the module).

    Parameters
    ----------
    out : path
        The sweep's output folder.
    leading : sequence of str
        The columns every row starts with (``cell``, ``point``, the choice, the varied
        parameters, ``latency_ticks``, ``trial``, ``seed``); the metrics follow, then :data:`TRAILING`.
    """

    def __init__(self, out, leading):
        require_pyarrow()
        self.folder = Path(out) / SHARD_FOLDER
        self.leading = tuple(leading)
        self.schema = None
        self.kinds: dict[str, set] = {}  # each column's Python types of its non-null values, first seen first
        self._stored: dict[Path, object] = {}  # each stored shard's schema

    def path(self, chunk) -> Path:
        return self.folder / f"part-{chunk.cell:05d}-{chunk.start:06d}.parquet"

    def load(self, chunk) -> int | None:
        """The number of rows of a finished chunk's shard, or None (not run, unreadable, damaged
        (a page whose checksum fails: the shard is read whole) or of another length: run again)."""
        p = self.path(chunk)
        if not p.is_file():
            return None
        try:
            table = read_shard(p)
        except InvalidInputError:
            return None
        if table.num_rows != chunk.stop - chunk.start:
            return None
        for name, column in zip(table.column_names, table.columns):
            self.kinds.setdefault(name, set()).update(_kinds(column))
        self.schema = self._schema()
        self._stored[p] = table.schema
        return table.num_rows

    def first_row(self) -> dict:
        """The first stored row."""
        _, pq, _ = require_pyarrow()
        p = min(self._stored)
        return pq.ParquetFile(p).read_row_group(0).slice(0, 1).to_pylist()[0]

    def save(self, chunk, rows: list[dict]) -> None:
        """Write the chunk's shard in the sweep's schema (widened by its values; the stored
        shards rewritten to a widened one)."""
        pa, _, _ = require_pyarrow()
        for r in rows:
            for k, v in r.items():
                seen = self.kinds.setdefault(k, set())
                if v is not None:
                    seen.add(type(v))
        schema = self._schema()
        self.folder.mkdir(parents=True, exist_ok=True)
        widened = self.schema is not None and not schema.equals(self.schema)
        self.schema = schema
        if widened:
            self.finish()  # the stored shards to the widened schema
        p = self.path(chunk)
        table = pa.Table.from_arrays([_column([r.get(f.name) for r in rows], self._kind(f.name)) for f in schema],
                                     schema=schema)
        write_shard(p, table, (*self.leading, *TRAILING))
        self._stored[p] = schema

    def finish(self) -> list[Path]:
        """Rewrite each stored shard whose schema is not the sweep's (widened since it was
        written; or a run killed during such a rewrite); return the stored shards in row order
        (the planned chunks' only: another file in the folder is never read)."""
        pa, _, _ = require_pyarrow()
        for p, schema in sorted(self._stored.items()):
            if not schema.equals(self.schema):
                table = read_shard(p)
                have = dict(zip(table.column_names, table.columns))
                cols = [have[f.name] if f.name in have and have[f.name].type == f.type else
                        _column(have[f.name].to_pylist() if f.name in have else [None] * table.num_rows,
                                self._kind(f.name)) for f in self.schema]
                write_shard(p, pa.Table.from_arrays(cols, schema=self.schema), (*self.leading, *TRAILING))
                self._stored[p] = self.schema
        return sorted(self._stored)

    def _kind(self, name: str) -> str:
        from .results import column_kind

        return column_kind(self.kinds.get(name, ()))

    def _schema(self):
        """The sweep's schema: each column's type by the kinds of all its values stored so far,
        the columns ordered leading, metrics (first seen first), trailing."""
        pa, _, _ = require_pyarrow()
        names = list(self.kinds)
        order = [n for n in self.leading if n in names] + \
            [n for n in names if n not in self.leading and n not in TRAILING] + [n for n in TRAILING if n in names]
        return pa.schema([pa.field(n, _arrow_type(pa, self._kind(n))) for n in order])


def float_column(batch, name: str) -> np.ndarray:
    """A column of a record batch as float64 (null, and every value of a text column: NaN, as
    :func:`~quatform.sweeps.results._number` reads a word)."""
    pa, _, pc = require_pyarrow()
    column = batch.column(name)
    if pa.types.is_string(column.type):
        return np.full(len(column), np.nan)
    return pc.cast(column, pa.float64()).to_numpy(zero_copy_only=False)
