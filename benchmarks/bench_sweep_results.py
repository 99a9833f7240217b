"""A 10^6-trial sweep's results: results.csv against the Parquet shards, and the summary's memory.

No 10^6-trial sweep runs on this machine (``helix-noise-sweep`` costs about 0.3 CPU s a
trial), so its rows are replicated from a real one: the built-in sweep ``SWEEP`` runs with
``--sample-trials`` trials a cell (its own scenario, duration, cells and seeds), and each
cell's rows are extended to ``--rows`` / cells trials column by column from that cell's real
values:

* a value the same in every sampled trial of the cell (the scenario's constants, the choice
  and the parameters, every metric of a cell without noise or initial error, whose trials are
  identical) is that value in every trial;
* a varying float metric is drawn from the log-normal (all positive) or normal of the cell's
  sampled values (continuous: every bit of the mantissa varies, as in the real rows), rounded
  to d decimals where every sampled value is within 1e-9 of d decimals (d <= 3: the times of
  control ticks, such as ``first_lost_time_s``; the real ones may carry float noise in their
  last digits, which only makes their CSV text longer);
* a varying whole number uniformly between the cell's sampled least and most, a varying flag
  with the cell's sampled rate, a varying word (or null) from the cell's sampled ones;
* ``trial`` counts up, ``seed`` is the spec's.

The rows are then written as the sweep writes them: ``results.csv`` (``quatform.sweeps.results.
write_csv``) and the shards of ``results = "parquet"`` (``ShardStore.save``, one per chunk of
``--chunk-trials``). Printed: both sizes and their ratio, the columns by their bytes in each,
and the peak memory (resident set above the process's after its imports, each in a fresh
process) of the summary streamed from the shards against loading the whole CSV (as typed rows,
quatform's in-memory path; and ``pandas.read_csv``). Every value is exact: the shards' rows read
back equal the CSV's (checked on every ``--check-every``-th shard).

Run from the repository root::

    PYTHONPATH=src python benchmarks/bench_sweep_results.py                       # helix, ~3 min
    PYTHONPATH=src python benchmarks/bench_sweep_results.py --sweep net-delay-loss-sweep
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np
from _common import machine_description, optional_import

from quatform.sweeps import load_sweep, run_sweep
from quatform.sweeps.results import leading_columns, write_csv
from quatform.sweeps.shards import ShardStore, shard_paths
from quatform.sweeps.trials import Chunk


def _same(vals) -> bool:
    return len({repr(v) for v in vals}) == 1


def _model(vals, rng):
    """A function ``n -> list`` drawing ``n`` values like the cell's sampled ``vals``."""
    if _same(vals):
        return lambda n: [vals[0]] * n
    kinds = {type(v) for v in vals if v is not None}
    nulls = sum(v is None for v in vals) / len(vals)
    real = [v for v in vals if v is not None]
    if kinds == {float} or kinds == {int, float}:
        x = np.asarray(real, dtype=float)
        if np.all(x > 0) and np.all(np.isfinite(x)):
            mu, sd = np.log(x).mean(), max(np.log(x).std(), 1e-3)
            cont = lambda n: np.exp(rng.normal(mu, sd, n))  # noqa: E731
        else:
            cont = lambda n: rng.normal(x.mean(), max(x.std(), 1e-12), n)  # noqa: E731
        d = next((d for d in range(4) if np.all(np.abs(x - np.round(x, d)) <= 1e-9 * np.maximum(1, np.abs(x)))),
                 None)
        draw = cont if d is None else (lambda n: np.round(cont(n), d))
    elif kinds == {int}:
        lo, hi = min(real), max(real)
        draw = lambda n: rng.integers(lo, hi + 1, n)  # noqa: E731
    elif kinds == {bool}:
        p = float(np.mean(real))
        draw = lambda n: rng.random(n) < p  # noqa: E731
    else:  # words
        draw = lambda n: rng.choice(np.asarray(real, dtype=object), n)  # noqa: E731

    def values(n):
        out = draw(n).tolist() if real else [None] * n
        if nulls:
            gone = rng.random(n) < nulls
            out = [None if g else v for g, v in zip(gone, out)]
        return out
    return values


def _replica(spec, sample: list[dict], rows: int, chunk: int, seed: int = 0):
    """``(Chunk, rows)`` of the replicated sweep, chunk by chunk in row order."""
    rng = np.random.default_rng(seed)
    by_cell: dict = {}
    for r in sample:
        by_cell.setdefault(r["cell"], []).append(r)
    cells = sorted(by_cell)
    per_cell = -(-rows // len(cells))
    columns = list(dict.fromkeys(k for r in sample for k in r))
    for cell in cells:
        rs = by_cell[cell]
        models = {c: _model([r.get(c) for r in rs], rng) for c in columns if c != "trial"}
        for start in range(0, per_cell, chunk):
            n = min(chunk, per_cell - start)
            cols = {c: (list(range(start, start + n)) if c == "trial" else models[c](n)) for c in columns}
            yield Chunk(spec, cell, start, start + n), [dict(zip(columns, vals)) for vals in zip(*cols.values())]


_MEASURE = r"""
import csv, json, sys
from pathlib import Path
import numpy as np, pyarrow, pyarrow.compute, pyarrow.parquet
from quatform.sweeps import load_sweep
from quatform.sweeps.results import summarize, summarize_shards
what, out, name, trials = sys.argv[1], Path(sys.argv[2]), sys.argv[3], int(sys.argv[4])
spec = load_sweep(name, trials=trials)
if what == "pandas":
    import pandas
def rss(key):
    for line in open("/proc/self/status"):
        if line.startswith(key):
            return int(line.split()[1]) * 1024
def typed(v):
    if v == "":
        return None
    if v in ("True", "False"):
        return v == "True"
    try:
        return int(v)
    except ValueError:
        try:
            return float(v)
        except ValueError:
            return v
open("/proc/self/clear_refs", "w").write("5")  # the peak from here on
base = rss("VmRSS:")
if what == "stream":
    s = summarize_shards(spec, out)
elif what == "rows":
    with open(out / "results.csv", newline="") as f:
        r = csv.reader(f)
        cols = next(r)
        rows = [dict(zip(cols, map(typed, line))) for line in r]
    s = summarize(spec, rows)
else:
    df = pandas.read_csv(out / "results.csv")
    s = len(df)
print(json.dumps({"peak_bytes": rss("VmHWM:") - base, "summary": s if what != "pandas" else None}, default=str))
"""


def _measure(what: str, out: Path, name: str, trials: int) -> dict:
    got = subprocess.run([sys.executable, "-c", _MEASURE, what, str(out), name, str(trials)], capture_output=True,
                         text=True, check=True)
    return json.loads(got.stdout)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sweep", default="helix-noise-sweep")
    ap.add_argument("--rows", type=int, default=1_000_000)
    ap.add_argument("--chunk-trials", type=int, default=1000, help="rows per shard (the sweep's chunk_trials)")
    ap.add_argument("--sample-trials", type=int, default=3, help="real trials a cell the replica is drawn from")
    ap.add_argument("--check-every", type=int, default=50, help="read back every k-th shard against the CSV")
    ap.add_argument("--keep", metavar="DIR", help="write into DIR (kept) instead of a temporary folder")
    args = ap.parse_args(argv)
    print("\n".join(machine_description({m: optional_import(m) is not None for m in ("pyarrow", "pandas")})))
    tmp = tempfile.TemporaryDirectory() if args.keep is None else None
    root = Path(args.keep or tmp.name)
    root.mkdir(parents=True, exist_ok=True)

    t0 = time.perf_counter()
    small = load_sweep(args.sweep, trials=args.sample_trials)
    run_sweep(small, root / "sample", quiet=True, plots=False, results="csv")
    sample = json.loads((root / "sample" / "results.json").read_text())["rows"]
    cells = len(small.cells())
    per_cell = -(-args.rows // cells)
    print(f"{args.sweep}: {cells} cells, {len(sample)} real trials sampled ({time.perf_counter() - t0:.0f} s); "
          f"replica: {cells} x {per_cell} = {cells * per_cell:,} rows, {len(sample[0])} columns, "
          f"shards of {args.chunk_trials} rows")

    spec = load_sweep(args.sweep, trials=per_cell)
    out = root / "big"
    store = ShardStore(out, leading_columns(spec))
    columns = list(dict.fromkeys(k for r in sample for k in r))
    csv_bytes = {c: 0 for c in columns}
    t0 = time.perf_counter()
    checks = []

    def rows_and_shards():
        for i, (ch, rows) in enumerate(_replica(spec, sample, cells * per_cell, args.chunk_trials)):
            store.save(ch, rows)
            if i % args.check_every == 0:
                checks.append((store.path(ch), rows))
            for r in rows:
                yield r

    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / "results.csv", columns, rows_and_shards())
    store.finish()
    print(f"written in {time.perf_counter() - t0:.0f} s")

    import pyarrow.parquet as pq

    for path, rows in checks:  # exact: the shard's rows are the CSV's
        back = pq.read_table(path).to_pylist()
        assert [[(k, repr(v)) for k, v in r.items() if v is not None] for r in back] == \
            [[(k, repr(r[k])) for k in columns if r.get(k) is not None] for r in rows], path
    with open(out / "results.csv", newline="") as f:
        rd = csv.reader(f)
        next(rd)
        for line in rd:
            for c, v in zip(columns, line):
                csv_bytes[c] += len(v) + 1
    size_csv = (out / "results.csv").stat().st_size
    shards = shard_paths(out)
    size_pq = sum(p.stat().st_size for p in shards)
    col_pq = {c: 0 for c in columns}
    footers = 0
    for p in shards:
        md = pq.read_metadata(p)
        footers += md.serialized_size
        for g in range(md.num_row_groups):
            rg = md.row_group(g)
            for j in range(rg.num_columns):
                col_pq[rg.column(j).path_in_schema] += rg.column(j).total_compressed_size
    print(f"\nresults.csv        {size_csv:>14,} B  ({size_csv / (cells * per_cell):.1f} B/row)")
    print(f"trials/*.parquet   {size_pq:>14,} B  ({size_pq / (cells * per_cell):.1f} B/row; {len(shards)} shards, "
          f"footers {footers:,} B)")
    print(f"ratio              {size_pq / size_csv:.4f}  (a tenth: 0.1)")
    print("\ncolumn                                      CSV B/row  Parquet B/row")
    for c in sorted(columns, key=lambda c: -col_pq[c])[:14]:
        print(f"  {c:40s} {csv_bytes[c] / (cells * per_cell):10.2f} {col_pq[c] / (cells * per_cell):12.3f}")

    print("\npeak memory above the process's after its imports:")
    stream = _measure("stream", out, args.sweep, per_cell)
    rows = _measure("rows", out, args.sweep, per_cell)
    print(f"  summary streamed from the shards     {stream['peak_bytes'] / 2**20:9.1f} MiB")
    print(f"  whole CSV as typed rows + summarize  {rows['peak_bytes'] / 2**20:9.1f} MiB")
    try:
        pd = _measure("pandas", out, args.sweep, per_cell)
        print(f"  whole CSV by pandas.read_csv         {pd['peak_bytes'] / 2**20:9.1f} MiB")
    except subprocess.CalledProcessError:
        pass
    same = json.dumps(stream["summary"], sort_keys=True) == json.dumps(rows["summary"], sort_keys=True)
    print(f"  the two summaries equal: {same}")
    if tmp is not None:
        tmp.cleanup()
    return 0 if same and not math.isnan(size_pq) else 1


if __name__ == "__main__":
    raise SystemExit(main())
