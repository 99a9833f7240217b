"""A sweep's trials as Parquet shards: read whole by pandas, polars and Dask with the CSV's rows,
the summary streamed from them equal to the one of the rows in memory, resume after a kill,
the schema widened by later chunks, the tables written a row at a time, pyarrow missing."""

import csv
import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from quatform.cli import main
from quatform.errors import InvalidInputError, MissingDependencyError
from quatform.sweeps import load_sweep, run_sweep
from quatform.sim.output import remove_dead_temporaries
from quatform.sweeps.results import summarize, summarize_blocks, write_table
from quatform.sweeps.trials import Chunk

pa = pytest.importorskip("pyarrow")
pq = pytest.importorskip("pyarrow.parquet")

from test_sweep import SMALL  # noqa: E402  (the suite's small sweep spec)


def _spec(tmp_path, text=SMALL):
    p = tmp_path / "small.toml"
    p.write_text(text)
    return load_sweep(p)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """The small sweep written as CSV (rows in memory) and as both (shards, CSV from them)."""
    base = tmp_path_factory.mktemp("pq")
    spec = _spec(base)
    run_sweep(spec, base / "csv", quiet=True, plots=False)
    run_sweep(spec, base / "both", quiet=True, results="both")
    return spec, base / "csv", base / "both"


def _csv_rows(path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _text(v) -> str:
    """A value as results.csv writes it (floats by repr: exact)."""
    if v is None:
        return ""
    if isinstance(v, (bool, np.bool_)):
        return str(bool(v))
    if isinstance(v, (np.integer, int)):
        return str(int(v))
    if isinstance(v, (np.floating, float)):
        return repr(float(v))
    return str(v)


def test_shards_are_one_per_chunk_in_trial_order_with_one_schema(runs):
    spec, _, both = runs
    shards = sorted((both / "trials").glob("*.parquet"))
    assert len(shards) == 16 and not (both / "chunks").exists()
    assert shards[0].name == "part-00000-000000.parquet" and shards[1].name == "part-00000-000002.parquet"
    schemas = [pq.read_schema(p) for p in shards]
    assert all(s.equals(schemas[0]) for s in schemas)
    s = schemas[0]
    assert s.names[:8] == ["cell", "point", "controller", "noise_m", "initial_offset_rad", "latency_ticks", "trial",
                           "seed"]
    assert s.names[-4:] == ["failed", "failure", "lost", "success"]
    assert s.field("cell").type == pa.int64() and s.field("noise_m").type == pa.float64()
    assert s.field("success").type == pa.bool_() and s.field("controller").type == pa.string()
    keys = [(r["cell"], r["trial"]) for p in shards for r in pq.read_table(p, columns=["cell", "trial"]).to_pylist()]
    assert keys == sorted(keys) and len(keys) == 24


def test_both_writes_the_csv_runs_tables_byte_for_byte(runs):
    _, csv_out, both = runs
    for name in ("results.csv", "results.json", "summary.csv", "summary.json"):
        assert (both / name).read_bytes() == (csv_out / name).read_bytes(), name
    assert {"errors_max_orientation_error_rad.png", "heatmap_noise_m_initial_offset_rad.png"} <= \
        {p.name for p in (both / "figures").iterdir()}  # drawn from the shards


def _frame_rows(columns, records) -> list[dict]:
    return [{c: _text(v) for c, v in zip(columns, rec)} for rec in records]


def test_pandas_polars_and_dask_read_the_csvs_rows(runs):
    _, csv_out, both = runs
    want = _csv_rows(csv_out / "results.csv")
    folder = both / "trials"
    pd = pytest.importorskip("pandas")
    plain = pd.read_parquet(folder)  # NumPy dtypes: a null float reads as NaN
    assert list(plain.columns) == list(want[0]) and len(plain) == len(want)
    assert [repr(v) for v in plain["max_orientation_error_rad"]] == [r["max_orientation_error_rad"] for r in want]
    df = pd.read_parquet(folder, dtype_backend="pyarrow")  # null apart from NaN
    assert _frame_rows(df.columns, ([None if v is pd.NA else v for v in r] for r in df.itertuples(index=False))) \
        == want
    pl = pytest.importorskip("polars")
    lf = pl.scan_parquet(folder / "*.parquet").collect()
    assert _frame_rows(lf.columns, lf.iter_rows()) == want
    dd = pytest.importorskip("dask.dataframe")
    ddf = dd.read_parquet(str(folder), dtype_backend="pyarrow").compute()
    assert _frame_rows(ddf.columns, ([None if v is pd.NA else v for v in r] for r in ddf.itertuples(index=False))) \
        == want


def test_the_streamed_summary_equals_the_rows_in_memory(runs):
    spec, csv_out, both = runs
    parquet = both.parent / "parquet"
    summary = run_sweep(spec, parquet, quiet=True, plots=False, results="parquet")
    assert not (parquet / "results.csv").exists() and (parquet / "summary.csv").is_file()
    assert json.loads((parquet / "summary.json").read_text()) == json.loads((csv_out / "summary.json").read_text())
    rows = json.loads((csv_out / "results.json").read_text())["rows"]
    assert summary == summarize(spec, rows)


def test_the_summary_reads_a_few_columns_a_batch_at_a_time(runs, monkeypatch):
    """One row per batch (a cell split over many batches) and only the columns it needs: the
    same summary."""
    from quatform.sweeps import shards
    from quatform.sweeps.results import summarize_shards

    spec, _, both = runs
    paths = sorted((both / "trials").glob("part-*.parquet"))
    whole = summarize_shards(spec, paths)
    asked = []
    real = shards.shard_batches

    def one_row(paths, columns=None):
        asked.append(columns)
        yield from real(paths, columns)

    monkeypatch.setattr(shards, "BATCH_ROWS", 1)
    monkeypatch.setattr(shards, "shard_batches", one_row)
    assert summarize_shards(spec, paths) == whole
    assert asked == [["cell", "failed", "lost", "success", *spec.success.below]]


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 3), st.booleans(), st.booleans(),
                          st.one_of(st.none(), st.floats(allow_nan=True, allow_infinity=True, width=64),
                                    st.integers(-5, 5))), min_size=1, max_size=60),
       st.integers(1, 7))
def test_summary_blocks_equal_the_in_memory_quantiles(trials, block):
    """Cut into blocks of any size, the cells' counts and quantiles are NumPy's of each cell's
    finite values over its trials that did not fail, bit for bit."""
    class Spec:
        compare_key = "controller"
        success = type("S", (), {"below": {"m": 1.0}})()

        @staticmethod
        def cells():
            return [(c, "q", {"noise_m": 0.1 * c}) for c in range(4)]

    rows = sorted(({"cell": c, "failed": f, "lost": f and s, "success": s and not f, "m": v}
                   for c, f, s, v in trials), key=lambda r: r["cell"])
    cut = [rows[i:i + block] for i in range(0, len(rows), block)]
    blocks = [{"cell": np.array([r["cell"] for r in b]), "failed": np.array([r["failed"] for r in b]),
               "lost": np.array([r["lost"] for r in b]), "success": np.array([r["success"] for r in b]),
               "m": np.array([float(r["m"]) if isinstance(r["m"], (int, float)) else np.nan for r in b])}
              for b in cut]
    got = summarize_blocks(Spec, blocks)
    for s in got:
        rs = [r for r in rows if r["cell"] == s["cell"]]
        v = np.asarray([r["m"] for r in rs if not r["failed"] and isinstance(r["m"], (int, float))
                        and math.isfinite(r["m"])], dtype=float)
        assert (s["trials"], s["failed"], s["lost"]) == (len(rs), sum(r["failed"] for r in rs),
                                                         sum(r["lost"] for r in rs))
        assert s["success_rate"] == sum(r["success"] for r in rs) / len(rs)
        for q, key in ((0.5, "median_m"), (0.9, "p90_m")):
            want = float(np.quantile(v, q)) if v.size else None
            assert (s[key] is None and want is None) or s[key].hex() == want.hex()
    assert [s["cell"] for s in got] == sorted({r["cell"] for r in rows})


def _rows_text(folder) -> list:
    """Every stored row, every value by repr (exact), read from the shards."""
    return [[(k, repr(v)) for k, v in r.items()] for p in sorted((folder / "trials").glob("*.parquet"))
            for r in pq.read_table(p).to_pylist()]


def test_a_sweep_killed_mid_run_resumes_to_identical_rows(tmp_path):
    """SIGKILL (no clean-up at all) after the first shard: no partial shard is left, and the
    rerun stores exactly the rows, schema and tables of an uninterrupted run."""
    text = SMALL.replace("trials = 3\nchunk_trials = 2", "trials = 4\nchunk_trials = 1").replace(
        "duration_s = 1.0", "duration_s = 3.0")
    spec = tmp_path / "s.toml"
    spec.write_text(text)
    out, ref = tmp_path / "o", tmp_path / "ref"
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1] / "src"))
    cmd = [sys.executable, "-m", "quatform.cli", "sweep", str(spec), "--no-plots", "--results", "parquet"]
    proc = subprocess.Popen([*cmd, "--out", str(out)], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 120
    while not list((out / "trials").glob("part-*.parquet")):  # no folder yet: no files
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.005)
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=60)
    if proc.returncode == 0:
        pytest.skip("the sweep finished before the kill arrived")
    stored = sorted((out / "trials").glob("part-*.parquet"))
    for p in stored:  # every shard left is whole
        assert pq.read_metadata(p).num_rows == 1
    assert len(stored) < 32 and not (out / "summary.csv").exists()
    again = subprocess.run([*cmd, "--out", str(out)], env=env, capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr
    assert f"resuming, {len(stored)}/32 trials already stored" in again.stderr
    whole = subprocess.run([*cmd, "--out", str(ref), "--quiet"], env=env, capture_output=True, text=True,
                           timeout=300)
    assert whole.returncode == 0, whole.stderr
    assert _rows_text(out) == _rows_text(ref)
    assert pq.read_schema(sorted((out / "trials").glob("*.parquet"))[-1]).equals(
        pq.read_schema(sorted((ref / "trials").glob("*.parquet"))[-1]))
    assert (out / "summary.json").read_bytes() == (ref / "summary.json").read_bytes()
    assert not list((out / "trials").glob(".*"))  # no temporary file left


def test_a_write_cut_off_leaves_no_shard_and_the_chunk_runs_again(tmp_path, monkeypatch):
    from quatform.sweeps import shards

    spec = _spec(tmp_path)
    out = tmp_path / "o"
    real = pq.write_table

    def cut(table, where, **kw):
        where.write(b"PAR1 half a shard")
        raise KeyboardInterrupt

    store = shards.ShardStore(out, ("cell",))
    ch = Chunk(spec, 0, 0, 2)
    rows = [{"cell": 0, "trial": 0, "m": 1.5, "failed": False}, {"cell": 0, "trial": 1, "m": None, "failed": False}]
    monkeypatch.setattr(pq, "write_table", cut)
    with pytest.raises(KeyboardInterrupt):
        store.save(ch, rows)
    assert list((out / "trials").iterdir()) == [] and store.load(ch) is None
    monkeypatch.setattr(pq, "write_table", real)
    (out / "trials" / "part-00000-000000.parquet").write_bytes(b"PAR1 truncated")  # a damaged file: run again
    assert shards.ShardStore(out, ("cell",)).load(ch) is None
    store.save(ch, rows)
    assert shards.ShardStore(out, ("cell",)).load(ch) == 2
    dead, alive = (out / "trials" / f".part-00001-000000.parquet.tmp-{pid}" for pid in (2**22 + 12345, os.getppid()))
    dead.write_bytes(b"PAR1")
    alive.write_bytes(b"PAR1")
    remove_dead_temporaries(out / "trials", "part-*.parquet")  # what a rerun's store does first
    assert not dead.exists() and alive.exists()


def test_a_later_chunk_widens_the_stored_shards(tmp_path):
    """A column null in the first chunk and words in a later one, whole numbers then floats,
    a flag then a number: every shard ends with the same widened schema, its values unchanged
    (two kinds in one column: each value as text, as results.csv writes it)."""
    from quatform.sweeps.shards import ShardStore

    spec = _spec(tmp_path)
    out = tmp_path / "o"
    store = ShardStore(out, ("cell", "trial"))
    first = [{"cell": 0, "trial": 0, "reason": None, "count": 3, "failed": False}]
    second = [{"cell": 0, "trial": 1, "reason": "stopped", "count": 2.5, "extra": True, "failed": True}]
    store.save(Chunk(spec, 0, 0, 1), first)
    store.save(Chunk(spec, 0, 1, 2), second)
    paths = sorted((out / "trials").glob("*.parquet"))
    schemas = [pq.read_schema(p) for p in paths]
    assert schemas[0].equals(schemas[1])
    assert schemas[0].names == ["cell", "trial", "reason", "count", "extra", "failed"]
    assert schemas[0].field("reason").type == pa.string() and schemas[0].field("count").type == pa.float64()
    assert pq.read_table(paths[0]).to_pylist() == [{"cell": 0, "trial": 0, "reason": None, "count": 3.0,
                                                    "extra": None, "failed": False}]
    store.save(Chunk(spec, 0, 2, 3), [{"cell": 0, "trial": 2, "reason": 1.5, "extra": 2, "failed": False}])
    tables = [pq.read_table(p) for p in sorted((out / "trials").glob("*.parquet"))]
    assert all(t.schema.equals(tables[0].schema) for t in tables)
    assert [r["reason"] for t in tables for r in t.to_pylist()] == [None, "stopped", "1.5"]  # two kinds: text
    assert [r["extra"] for t in tables for r in t.to_pylist()] == [None, "True", "2"]


def test_tables_written_a_row_at_a_time_are_json_dumps_bytes(tmp_path):
    rows = [{"a": 1, "b": 0.1, "c": None, "d": "x\ny", "e": True}, {"a": 2, "b": float("nan"), "e": False}]
    write_table(tmp_path, "t", rows)
    assert (tmp_path / "t.json").read_text() == json.dumps({"columns": list("abcde"), "rows": rows}, indent=1) + "\n"
    write_table(tmp_path, "u", [])
    assert (tmp_path / "u.json").read_text() == json.dumps({"columns": [], "rows": []}, indent=1) + "\n"


def test_results_option_and_the_store_it_chose(runs, tmp_path, capsys):
    spec, csv_out, _ = runs
    with pytest.raises(InvalidInputError, match="JSON chunks"):
        run_sweep(spec, csv_out, quiet=True, plots=False, results="parquet")
    assert main(["sweep", str(tmp_path / "x.toml"), "--out", str(tmp_path / "o")]) == 2  # no such spec
    capsys.readouterr()
    p = tmp_path / "bad.toml"
    p.write_text(SMALL.replace('name = "small"', 'name = "small"\nresults = "parquett"'))
    with pytest.raises(InvalidInputError, match="parquet"):
        load_sweep(p)
    p.write_text(SMALL.replace('name = "small"', 'name = "small"\nresults = "parquet"'))
    spec2 = load_sweep(p)
    assert spec2.results == "parquet" and spec2.identity == _spec(tmp_path).identity


def test_without_pyarrow_small_sweeps_write_csv_and_a_large_one_is_one_line(tmp_path, monkeypatch, capsys):
    from quatform.sweeps import results

    monkeypatch.setitem(sys.modules, "pyarrow", None)
    spec = _spec(tmp_path)
    out = tmp_path / "o"
    run_sweep(spec, out, quiet=True, plots=False)
    assert (out / "results.csv").is_file() and not (out / "trials").exists()
    monkeypatch.setattr(results, "CSV_MAX_TRIALS", 10)
    monkeypatch.setattr("quatform.sweeps.runner.CSV_MAX_TRIALS", 10)
    with pytest.raises(MissingDependencyError, match=r'pip install -e "\.\[dask\]"') as exc:
        run_sweep(spec, tmp_path / "big", quiet=True, plots=False)
    assert "\n" not in str(exc.value) and "the default above 10 trials" in str(exc.value)
    assert not (tmp_path / "big").exists()
    assert main(["sweep", str(tmp_path / "small.toml"), "--out", str(tmp_path / "b2"), "--results", "both"]) == 2
    assert 'pip install -e ".[dask]"' in capsys.readouterr().err


def _sweep_cmd(tmp_path, out, *extra):
    spec = tmp_path / "small.toml"
    if not spec.exists():
        spec.write_text(SMALL)
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1] / "src"))
    return [sys.executable, "-m", "quatform.cli", "sweep", str(spec), "--no-plots", "--quiet", "--out", str(out),
            *extra], env


@pytest.mark.parametrize("results", ["csv", "parquet"])
def test_a_second_sweep_into_a_locked_folder_is_one_line(runs, tmp_path, results):
    """Guards against: two sweeps into one empty --out writing over each other, both exiting 0.
    The lock is another process' (this one); a sweep started meanwhile is refused, and two
    sweeps started together give the one sweep's tables (the second refused or resuming)."""
    from quatform.sweeps.results import lock_folder

    out = tmp_path / "o"
    out.mkdir()
    cmd, env = _sweep_cmd(tmp_path, out, "--results", results)
    with lock_folder(out):
        got = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300)
    assert got.returncode == 2
    assert got.stderr.strip().splitlines() == [f"quatform: error: another sweep is writing into {str(out)!r} "
                                               f"(pid {os.getpid()}); wait or choose another --out"]
    assert sorted(os.listdir(out)) == [".sweep.lock"]
    both = tmp_path / "both"
    cmd, env = _sweep_cmd(tmp_path, both, "--results", results)
    procs = [subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
             for _ in range(2)]
    codes = sorted(p.wait(timeout=300) for p in procs)
    errs = [p.stderr.read() for p in procs]
    assert codes in ([0, 0], [0, 2]), errs
    assert (both / "summary.json").read_bytes() == (runs[1] / "summary.json").read_bytes()


def _copy(folder, tmp_path):
    import shutil

    return Path(shutil.copytree(folder, tmp_path / "copy"))


def test_files_in_trials_that_no_chunk_plans_are_never_read(runs, tmp_path):
    """Guards against: a copied shard counted twice, another sweep's shard a KeyError."""
    spec, _, both = runs
    out = _copy(both, tmp_path)
    first = sorted((out / "trials").glob("part-*.parquet"))[0]
    (out / "trials" / "part-00099-000000.parquet").write_bytes(first.read_bytes())
    pq.write_table(pa.table({"other": [1, 2]}), out / "trials" / "part-00000-000001.parquet")
    run_sweep(spec, out, quiet=True, plots=False, results="both")
    for name in ("summary.json", "results.csv", "results.json"):
        assert (out / name).read_bytes() == (both / name).read_bytes(), name


def test_a_shard_with_a_damaged_page_is_run_again(runs, tmp_path):
    """Guards against: a shard whose data pages are damaged but footer intact accepted on
    resume, every rerun then failing with a thrift error naming no file. Every page carries a
    checksum: the damaged shard's chunk runs again, and a damaged shard read is named."""
    from quatform.sweeps.shards import shard_batches

    spec, _, both = runs
    out = _copy(both, tmp_path)
    shard = sorted((out / "trials").glob("part-*.parquet"))[1]
    data = bytearray(shard.read_bytes())
    meta = pq.read_metadata(shard)
    col = meta.row_group(0).column(meta.num_columns - 5)  # a metric's column chunk
    at = col.data_page_offset + (col.total_compressed_size // 2)
    data[at] ^= 0xFF
    shard.write_bytes(bytes(data))
    assert pq.read_metadata(shard).num_rows == meta.num_rows  # the footer reads
    with pytest.raises(InvalidInputError, match=f"the shard {str(shard)!r} is damaged.*delete it and rerun"):
        list(shard_batches([shard]))
    run_sweep(spec, out, quiet=True, plots=False, results="both")
    for name in ("summary.json", "results.csv", "results.json"):
        assert (out / name).read_bytes() == (both / name).read_bytes(), name
    assert list(shard_batches([shard]))


def test_temporaries_of_a_killed_sweep_are_removed_when_it_reopens(runs, tmp_path):
    """Guards against: a kill during the first sweep.json write making every rerun refused, and
    dead temporaries of the tables and chunks piling up. A live process' stay."""
    spec, csv_out, _ = runs
    dead, alive = 2**22 + 12345, os.getppid()
    out = tmp_path / "new"
    out.mkdir()
    (out / f".sweep.json.tmp-{dead}").write_text("{")
    run_sweep(spec, out, quiet=True, plots=False)
    assert not (out / f".sweep.json.tmp-{dead}").exists()
    old = _copy(csv_out, tmp_path)
    made = [old / f".{n}.tmp-{pid}" for n in ("results.csv", "results.json", "summary.csv", "summary.json")
            for pid in (dead, alive)] + [old / "chunks" / f".c.json.tmp-{dead}"]
    for p in made:
        p.write_text("x")
    run_sweep(spec, old, quiet=True, plots=False)
    assert [p.exists() for p in made] == [False, True] * 4 + [False]
    assert (old / "summary.json").read_bytes() == (csv_out / "summary.json").read_bytes()


def test_a_resumed_sweep_keeps_the_results_it_was_started_with(runs, tmp_path):
    """Guards against: resuming a Parquet folder without --results refused though sweep.json
    records its store."""
    spec, _, both = runs
    out = _copy(both, tmp_path)
    run_sweep(spec, out, quiet=True, plots=False)  # no --results: the folder's (both)
    assert (out / "summary.json").read_bytes() == (both / "summary.json").read_bytes()
    meta = json.loads((out / "sweep.json").read_text())
    del meta["results"]  # a folder of an earlier sweep.json: its store decides
    (out / "sweep.json").write_text(json.dumps(meta))
    (out / "results.csv").unlink()
    run_sweep(spec, out, quiet=True, plots=False)
    assert not (out / "results.csv").exists() and (out / "summary.csv").is_file()


def test_the_results_help_says_the_default_above_the_csv_limit(capsys):
    with pytest.raises(SystemExit):
        main(["sweep", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "else the one --out's sweep was started with, else csv up to 100,000 trials (cells x trials) and " \
           "parquet above" in text


def test_csv_and_both_write_the_same_tables_for_columns_of_mixed_kinds(tmp_path, monkeypatch):
    """Guards against: "both" writing 3.0 where csv writes 3 (whole numbers and floats in one
    column), and a flag and a number in one column running as csv but stopping a Parquet sweep.
    One rule in both stores: whole numbers with floats are floats, two other kinds are text."""
    from quatform.sweeps import runner

    real = runner.run_chunk

    def synthetic(ch):  # three metrics more, before the trailing columns
        out = []
        for r in real(ch):
            tail = {k: r.pop(k) for k in ("failed", "failure", "lost", "success")}
            r["mixed_number"] = r["trial"] if r["trial"] % 2 == 0 else r["trial"] + 0.5
            r["flag_or_count"] = True if r["cell"] == 0 else 7
            r["late"] = None if r["cell"] < 2 else 1.25
            out.append({**r, **tail})
        return out

    monkeypatch.setattr(runner, "run_chunk", synthetic)
    spec = _spec(tmp_path)
    run_sweep(spec, tmp_path / "csv", quiet=True, plots=False, results="csv")
    run_sweep(spec, tmp_path / "both", quiet=True, plots=False, results="both")
    for name in ("results.csv", "results.json", "summary.csv", "summary.json"):
        assert (tmp_path / "csv" / name).read_bytes() == (tmp_path / "both" / name).read_bytes(), name
    rows = _csv_rows(tmp_path / "csv" / "results.csv")
    assert [r["mixed_number"] for r in rows[:3]] == ["0.0", "1.5", "2.0"]
    assert {r["flag_or_count"] for r in rows} == {"True", "7"}


def test_a_metric_null_so_far_is_stored_as_float_nulls(tmp_path):
    """Guards against: shards written while a metric is null everywhere typed null, the later
    ones float, so pandas and polars cannot read the folder mid-run. No shard is rewritten."""
    from quatform.sweeps.shards import ShardStore

    spec = _spec(tmp_path)
    out = tmp_path / "o"
    store = ShardStore(out, ("cell", "trial"))
    store.save(Chunk(spec, 0, 0, 1), [{"cell": 0, "trial": 0, "late": None, "failed": False}])
    first = sorted((out / "trials").glob("*.parquet"))[0]
    before = first.stat().st_mtime_ns, first.read_bytes()
    store.save(Chunk(spec, 0, 1, 2), [{"cell": 0, "trial": 1, "late": 0.5, "failed": False}])
    assert (first.stat().st_mtime_ns, first.read_bytes()) == before
    assert pq.read_schema(first).field("late").type == pa.float64()
    pl = pytest.importorskip("polars")
    got = pl.read_parquet(str(out / "trials" / "*.parquet"))
    assert got["late"].dtype == pl.Float64 and got["late"].to_list() == [None, 0.5]
