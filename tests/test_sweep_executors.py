"""Sweep executors: identical tables in process, on 2 local processes and on Dask; bad schedulers; Ctrl-C."""

import json
import time
from concurrent.futures.process import BrokenProcessPool

import pytest

from quatform.errors import InvalidInputError, MissingDependencyError, UnreachableError
from quatform.sweeps import load_sweep, run_sweep
from quatform.sweeps.executors import executor

SPEC = """
name = "tiny"
scenario = "mas-kitts-helix"
controllers = ["robot-space", "quaternion"]
trials = 2
chunk_trials = 1
seed = 3
duration_s = 1.0
settle_s = 0.2

[vary.noise_m]
values = [0.0, 0.02]

[vary.dropout_rate]
values = [0.3]
"""


@pytest.fixture(scope="module")
def spec(tmp_path_factory):
    p = tmp_path_factory.mktemp("spec") / "tiny.toml"
    p.write_text(SPEC)
    return load_sweep(p)


def _table(out):
    return (out / "results.csv").read_text(), json.loads((out / "summary.json").read_text())


@pytest.fixture(scope="module")
def in_process(spec, tmp_path_factory):
    out = tmp_path_factory.mktemp("one") / "out"
    run_sweep(spec, out, plots=False, quiet=True)
    return _table(out)


def test_two_processes_give_the_same_table(spec, in_process, tmp_path):
    run_sweep(spec, tmp_path / "two", workers=2, plots=False, quiet=True)
    assert _table(tmp_path / "two") == in_process


def test_dask_local_cluster_gives_the_same_table(spec, in_process, tmp_path):
    pytest.importorskip("distributed")
    run_sweep(spec, tmp_path / "dask", workers=2, scheduler="local", plots=False, quiet=True)
    assert _table(tmp_path / "dask") == in_process


def test_unreachable_scheduler_is_one_line_and_quick():
    pytest.importorskip("distributed")
    t0 = time.perf_counter()
    with pytest.raises(UnreachableError, match="tcp://127.0.0.1:9") as exc:
        with executor(1, "tcp://127.0.0.1:9", timeout_s=1.0):
            pass
    assert "\n" not in str(exc.value)
    assert time.perf_counter() - t0 < 30.0


def test_a_server_that_is_no_scheduler_is_one_line():
    """An address where another server answers (a web server's bytes read as a Dask frame
    length ask for exabytes): one line saying it is not a scheduler, not 'out of memory'."""
    pytest.importorskip("distributed")
    import socket
    import threading

    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(4)
    port = server.getsockname()[1]

    def answer():
        while True:
            try:
                conn, _ = server.accept()
            except OSError:
                return
            with conn:
                conn.sendall(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n" * 8)

    threading.Thread(target=answer, daemon=True).start()
    try:
        with pytest.raises(UnreachableError, match="not a Dask scheduler") as exc:
            with executor(1, f"tcp://127.0.0.1:{port}", timeout_s=2.0):
                pass
    finally:
        server.close()
    assert "\n" not in str(exc.value) and f"127.0.0.1:{port}" in str(exc.value)


def test_unknown_scheduler_names_the_nearest():
    with pytest.raises(InvalidInputError, match="local"):
        with executor(1, "locl"):
            pass


def test_slurm_job_script():
    pytest.importorskip("dask_jobqueue")
    from quatform.sweeps.executors import slurm_job_script

    script = slurm_job_script({"queue": "normal", "account": "lab", "cores": 2, "memory": "8GB",
                               "walltime": "01:00:00"})
    assert script.startswith("#!/")
    for line in ("#SBATCH -p normal", "#SBATCH -A lab", "#SBATCH --cpus-per-task=2", "#SBATCH -t 01:00:00"):
        assert line in script


def test_slurm_job_script_from_the_cli(spec, tmp_path, capsys):
    pytest.importorskip("dask_jobqueue")
    from quatform.cli import main

    p = tmp_path / "s.toml"
    p.write_text(SPEC + '\n[slurm]\nqueue = "gpu"\ncores = 1\n')
    assert main(["sweep", str(p), "--out", str(tmp_path / "o"), "--scheduler", "slurm", "--slurm",
                 "walltime=00:30:00", "--print-job-script"]) == 0
    out = capsys.readouterr().out
    assert "#SBATCH -p gpu" in out and "#SBATCH -t 00:30:00" in out
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("scheduler, missing, names", [
    ("local", "distributed", "Dask"), ("tcp://127.0.0.1:9", "distributed", "Dask"),
    ("slurm", "dask_jobqueue", "dask-jobqueue")])
def test_dask_missing_is_one_line_before_any_experiment_is_built(spec, monkeypatch, capsys, tmp_path, scheduler,
                                                                 missing, names):
    """Without Dask, ``--scheduler`` is refused up front: no spec loaded, no experiment built."""
    import sys

    from quatform import cli
    from quatform.sweeps import runner, spec as spec_module

    monkeypatch.setitem(sys.modules, missing, None)  # import raises ImportError

    def built(*args, **kwargs):
        raise AssertionError("experiments built before the scheduler was checked")

    monkeypatch.setattr(spec_module, "load_sweep", built)
    monkeypatch.setattr(runner, "estimate", built)
    assert cli.main(["sweep", "team-size-sweep", "--out", str(tmp_path / "o"), "--scheduler", scheduler]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"--scheduler {scheduler} needs {names}" in err
    assert 'pip install -e ".[dask]"' in err
    with pytest.raises(MissingDependencyError, match=r'pip install -e "\.\[dask\]"'):  # the library's entry too
        run_sweep(spec, tmp_path / "p", scheduler=scheduler)


def test_ctrl_c_stops_the_local_workers():
    """An interrupt inside the pool stops its workers instead of waiting for their chunks (the
    exit hung for good when a second Ctrl-C came during that wait)."""
    with pytest.raises(KeyboardInterrupt):
        with executor(2) as ex:
            fut = ex.submit(time.sleep, 20)
            time.sleep(1.0)  # the worker has started it
            raise KeyboardInterrupt
    assert isinstance(fut.exception(timeout=30), BrokenProcessPool)


def test_local_workers_leave_ctrl_c_to_the_sweep():
    """A terminal's Ctrl-C reaches every process of the group: the workers ignore it (no
    tracebacks from them) and the sweep's process stops them."""
    import signal

    with executor(2) as ex:
        assert ex.submit(signal.getsignal, signal.SIGINT).result(timeout=60) == signal.SIG_IGN
