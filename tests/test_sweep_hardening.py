"""quatform sweep under hostile use: Ctrl-C, non-sweepable kinds, bad specs and flags, locked outputs."""

import re
import time
from concurrent.futures.process import BrokenProcessPool

import pytest

from quatform.cli import main
from quatform.errors import InvalidInputError
from quatform.scenarios import KINDS
from quatform.sweeps import load_sweep
from quatform.sweeps.executors import executor
from quatform.sweeps.trials import NOT_SWEEPABLE, SWEEP_KINDS

SPEC = """
name = "tiny"
scenario = "mas-kitts-helix"
controllers = ["quaternion"]
trials = 1
duration_s = 1.0
settle_s = 0.2
"""


def _spec(tmp_path, text=SPEC, name="tiny.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def _one_line(capsys):
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


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


def test_ctrl_c_says_the_chunks_are_kept(tmp_path, capsys, monkeypatch):
    import quatform.sweeps.runner as runner

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(runner, "run_sweep", interrupted)
    assert main(["sweep", str(_spec(tmp_path)), "--out", str(tmp_path / "o")]) == 130
    err = _one_line(capsys)
    assert "chunks" in err and "rerun the same command to resume" in err and "no partial" not in err


def test_every_kind_is_sweepable_or_says_why():
    assert set(KINDS) <= set(SWEEP_KINDS) | set(NOT_SWEEPABLE), set(KINDS) - set(SWEEP_KINDS) - set(NOT_SWEEPABLE)


def test_a_ugv_uav_sweep_says_why_not(tmp_path):
    with pytest.raises(InvalidInputError, match="ugv-uav.*motion capture one world at a time"):
        load_sweep(_spec(tmp_path, 'scenario = "marciano-circle"\ntrials = 1\n'))


@pytest.mark.parametrize("success, match", [
    ("below = {max_cluster_position_eror_m = 0.1}", "did you mean 'max_cluster_position_error_m'"),
    ('false = ["max_cluster_position_error_m"]', "is not a flag.*reference_lost"),
    ("below = {reference_lost = 0.5}", "is not a number.*false"),
    ('false = ["failed"]', "names the metric 'failed'"),  # a row's column, not a metric Success reads
])
def test_a_bad_success_leaves_out_free_for_the_fixed_spec(tmp_path, capsys, success, match):
    out = tmp_path / "o"
    bad = _spec(tmp_path, SPEC + "[success]\n" + success + "\n")
    assert main(["sweep", str(bad), "--out", str(out), "--no-plots", "--quiet"]) == 2
    assert re.search(match, _one_line(capsys))
    assert not out.exists()  # no sweep.json that would lock --out to the bad spec
    assert main(["sweep", str(_spec(tmp_path)), "--out", str(out), "--no-plots", "--quiet"]) == 0
    assert (out / "results.csv").is_file()


def test_huge_workers_neither_start_nor_shrink_the_estimate(tmp_path, capsys):
    from quatform.sim.jax_devices import usable_cores
    from quatform.sweeps import estimate, plan_chunks
    from quatform.sweeps.executors import LOCAL_WORKERS_PER_CORE, parallel_workers

    spec = load_sweep(_spec(tmp_path, SPEC.replace("trials = 1", "trials = 3\nchunk_trials = 1")))
    n = len(plan_chunks(spec))
    assert n == 3
    # no more chunks at once than there are: 10^6 workers do not make the time budget check pass
    assert estimate(spec, 10**6).seconds == pytest.approx(estimate(spec, n).seconds, rel=1e-12)
    assert estimate(spec, 1).seconds == pytest.approx(n * estimate(spec, n).seconds, rel=1e-12)
    assert parallel_workers(10**6, None) == parallel_workers(10**6, "local") == usable_cores()
    assert parallel_workers(10**6, "tcp://h:1") == 10**6  # a cluster's workers are its own
    too_many = LOCAL_WORKERS_PER_CORE * usable_cores() + 1
    for extra in ([], ["--scheduler", "local"]):
        assert main(["sweep", str(_spec(tmp_path)), "--out", str(tmp_path / "o"), "--workers", str(too_many),
                     *extra]) == 2
        assert f"--workers {too_many}" in _one_line(capsys)
        assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("edit, match", [
    (("duration_s = 1.0", "duration_s = 500.0"), r"duration_s = 500 s is longer than the scenario's own 80 s"),
    (("duration_s = 1.0", "duration_s = 1e-6"), r"shorter than two of the scenario's control ticks"),
    (("settle_s = 0.2", "settle_s = 1.0"), r"settle_s = 1 is not before the end of the run"),
    (("settle_s = 0.2\n", ""), r"the scenario's metrics_from_s = 5 s \(settle_s not given\)"),
    (("settle_s = 0.2", "settle_s = 0.2\n[vary.latency_s]\nvalues = [0.0, 1.0]"), r"latency_s\] value 1 s is not shorter"),
])
def test_run_length_mistakes_are_one_line(tmp_path, edit, match):
    with pytest.raises(InvalidInputError, match=match) as exc:
        load_sweep(_spec(tmp_path, SPEC.replace(*edit)))
    assert "\n" not in str(exc.value)


def test_an_empty_out_or_an_unreadable_sweep_json_is_one_line(tmp_path, capsys):
    spec = str(_spec(tmp_path))
    for out in ("", "  "):
        assert main(["sweep", spec, "--out", out]) == 2
        assert "is empty; give a folder" in _one_line(capsys)
    out = tmp_path / "o"
    assert main(["sweep", spec, "--out", str(out), "--no-plots", "--quiet"]) == 0
    capsys.readouterr()
    (out / "sweep.json").write_text('{"identity": ')  # cut off
    assert main(["sweep", spec, "--out", str(out), "--no-plots", "--quiet"]) == 2
    assert "sweep.json is unreadable" in _one_line(capsys)


@pytest.mark.parametrize("slurm", ['cores = "4"', "jobs = 0", "processes = 1.5", "cores = true"])
def test_slurm_counts_are_whole_numbers(tmp_path, slurm):
    with pytest.raises(InvalidInputError, match=r"\[slurm\]: \w+ = .* must be a whole number >= 1"):
        load_sweep(_spec(tmp_path, SPEC + "[slurm]\n" + slurm + "\n"))


def test_slurm_flag_counts_are_whole_numbers(tmp_path, capsys):
    assert main(["sweep", str(_spec(tmp_path)), "--out", str(tmp_path / "o"), "--scheduler", "slurm",
                 "--slurm", "cores=abc", "--print-job-script"]) == 2
    assert "cores = 'abc' must be a whole number" in _one_line(capsys)


def test_a_team_size_the_scenario_cannot_take_names_the_axis(tmp_path):
    text = ('scenario = "team-three-bodies"\ntrials = 1\nduration_s = 1.0\nsettle_s = 0.2\n'
            'controllers = ["quaternion"]\n[vary.team_size]\nvalues = [4]\n')
    from quatform.sweeps import estimate

    with pytest.raises(InvalidInputError, match=r"\[vary.team_size\] value 4: .*triangle template holds 3") as exc:
        estimate(load_sweep(_spec(tmp_path, text)))
    assert "\n" not in str(exc.value)


def test_a_grid_value_listed_twice_is_refused(tmp_path):
    text = SPEC + "[vary.noise_m]\nvalues = [0.0, 0.01, 0.01]\n"
    with pytest.raises(InvalidInputError, match=r"\[vary.noise_m\] values = .* lists 0.01 twice; list each value once"):
        load_sweep(_spec(tmp_path, text))


def test_a_scenario_refused_at_its_own_length_says_so(tmp_path, monkeypatch):
    """The kinds check a scenario at its file's duration_s (80 s here) before the sweep's
    duration_s applies: the line says so instead of asking to shorten a duration already short."""
    from quatform.errors import ResourceLimitError

    monkeypatch.setenv("QUATFORM_MAX_WORK_S", "1")
    with pytest.raises(ResourceLimitError, match=r"checked at its own length before the sweep's duration_s = 1.0 s") as exc:
        load_sweep(_spec(tmp_path))
    assert "\n" not in str(exc.value)
    text = ('scenario = "team-grid-100"\ntrials = 1\nduration_s = 1.0\nsettle_s = 0.2\ncontrollers = ["quaternion"]\n'
            "[vary.team_size]\nvalues = [10000]\n")
    monkeypatch.delenv("QUATFORM_MAX_WORK_S")
    monkeypatch.setenv("QUATFORM_MAX_MEMORY_BYTES", "1e9")
    from quatform.sweeps import estimate

    with pytest.raises(ResourceLimitError, match=r"before the sweep's duration_s = 1 s applies.*10000 robots"):
        estimate(load_sweep(_spec(tmp_path, text)))


def test_a_bad_cell_is_refused_before_any_chunk_runs(tmp_path, capsys):
    """Only the first cell of each run shape was built up front: a gain scale making the loop
    unstable was found mid-run, after the first chunks had locked --out to the spec."""
    text = SPEC + "[vary.gain_scale]\nvalues = [1.0, 1e6]\n"
    out = tmp_path / "o"
    assert main(["sweep", str(_spec(tmp_path, text)), "--out", str(out), "--no-plots", "--quiet"]) == 2
    assert "gain_scale = 1e+06" in _one_line(capsys)
    assert not out.exists()


def test_sigint_mid_sweep_then_rerun_gives_the_same_table(tmp_path):
    """A real Ctrl-C after the first stored chunk: status 130, one line, no table; the rerun
    resumes (skipping the stored chunks) and writes the table of an uninterrupted run."""
    import os
    import signal
    import subprocess
    import sys
    from pathlib import Path

    text = SPEC.replace("trials = 1", "trials = 4\nchunk_trials = 1").replace("duration_s = 1.0", "duration_s = 3.0")
    spec = _spec(tmp_path, text)
    out, ref = tmp_path / "o", tmp_path / "ref"
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1] / "src"))
    cmd = [sys.executable, "-m", "quatform.cli", "sweep", str(spec), "--no-plots"]
    proc = subprocess.Popen([*cmd, "--out", str(out)], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    deadline = time.monotonic() + 120
    while not (out / "chunks").is_dir() or not any((out / "chunks").glob("cell*.json")):
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.01)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    if proc.returncode == 0:
        pytest.skip("the sweep finished before the interrupt arrived")
    assert proc.returncode == 130, err
    last = err.strip().splitlines()[-1]
    assert "Traceback" not in err and "rerun the same command to resume" in last
    assert not (out / "results.csv").exists()
    stored = len(list((out / "chunks").glob("cell*.json")))
    again = subprocess.run([*cmd, "--out", str(out)], env=env, capture_output=True, text=True, timeout=120)
    assert again.returncode == 0, again.stderr
    assert f"resuming, {stored}/4 trials already stored" in again.stderr
    whole = subprocess.run([*cmd, "--out", str(ref), "--quiet"], env=env, capture_output=True, text=True, timeout=120)
    assert whole.returncode == 0, whole.stderr
    assert (out / "results.csv").read_text() == (ref / "results.csv").read_text()
    assert (out / "summary.json").read_text() == (ref / "summary.json").read_text()


def test_an_out_holding_other_files_names_one(tmp_path, capsys):
    out = tmp_path / "o"
    out.mkdir()
    (out / "metrics.json").write_text("{}")  # e.g. a quatform run's folder
    assert main(["sweep", str(_spec(tmp_path)), "--out", str(out), "--no-plots", "--quiet"]) == 2
    assert "not a sweep's (no sweep.json; e.g. 'metrics.json')" in _one_line(capsys)
    assert sorted(p.name for p in out.iterdir()) == ["metrics.json"]
