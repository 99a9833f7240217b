"""quatform sweep: the spec reader, the trials' seeds and batches, outputs, resumability, bad input, Ctrl-C."""

import dataclasses
import errno
import json
import os
import re
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from quatform.cli import main
from quatform.errors import InvalidInputError, ResourceLimitError
from quatform.scenarios import KINDS, load_scenario
from quatform.sweeps import (
    PARAMETERS,
    builtin_sweeps,
    estimate,
    load_sweep,
    plan_chunks,
    run_sweep,
)
from quatform.sweeps.spec import sweep_from_dict
from quatform.sweeps.trials import NOT_SWEEPABLE, SWEEP_KINDS, Chunk, run_chunk

SMALL = """
name = "small"
scenario = "mas-kitts-helix"
controllers = ["robot-space", "quaternion"]
trials = 3
chunk_trials = 2
seed = 7
duration_s = 1.0
settle_s = 0.5

[vary.noise_m]
values = [0.0, 0.01]

[vary.initial_offset_rad]
values = [0.0, 0.2]
"""


def _spec(tmp_path, text=SMALL, name="small.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    return load_sweep(_spec(tmp_path_factory.mktemp("spec")))


@pytest.fixture(scope="module")
def swept(small, tmp_path_factory):
    out = tmp_path_factory.mktemp("run") / "out"
    summary = run_sweep(small, out, quiet=True)
    return out, summary


def test_builtins_load_and_fit():
    names = set(builtin_sweeps())
    assert {"helix-noise-sweep", "spiral-start-sweep", "team-size-sweep", "ugv-uav-mocap-sweep",
            "teleop-preload-sweep"} <= names
    for name in names:
        spec = load_sweep(name)
        assert spec.choices and spec.trials >= 1
        est = estimate(spec, workers=2)
        assert est.seconds < 600  # the documented estimate of a built-in stays minutes
    helix = load_sweep("helix-noise-sweep")
    assert helix.choices == tuple(KINDS["team"].compare_choices(load_scenario("mas-kitts-helix"), "controller")[0])
    assert max(helix.axis("noise_m").values) == pytest.approx(0.02)
    assert max(helix.axis("latency_s").values) == pytest.approx(0.05)
    assert max(load_sweep("team-size-sweep").axis("team_size").values) == 100
    assert max(load_sweep("spiral-start-sweep").axis("initial_offset_rad").values) == pytest.approx(np.pi)


def test_cells_and_chunks(small):
    assert len(small.points()) == 4 and len(small.cells()) == 8
    chunks = plan_chunks(small)
    assert [(c.start, c.stop) for c in chunks[:2]] == [(0, 2), (2, 3)]
    assert len(chunks) == 16


def test_outputs(swept, small):
    out, summary = swept
    for name in ("results.csv", "results.json", "summary.csv", "summary.json", "sweep.json"):
        assert (out / name).is_file()
    rows = json.loads((out / "results.json").read_text())["rows"]
    assert len(rows) == 8 * 3
    assert [(r["cell"], r["trial"]) for r in rows] == sorted((r["cell"], r["trial"]) for r in rows)
    for key in ("controller", "noise_m", "initial_offset_rad", "seed", "failed", "failure", "lost", "success",
                "max_cluster_position_error_m", "reference_lost"):
        assert key in rows[0]
    assert len(summary) == 8 and all(0.0 <= s["success_rate"] <= 1.0 for s in summary)
    assert {"median_max_orientation_error_rad", "p90_max_orientation_error_rad"} <= set(summary[0])
    figs = {p.name for p in (out / "figures").iterdir()}
    assert {"success_vs_noise_m.png", "success_vs_initial_offset_rad.png",
            "heatmap_noise_m_initial_offset_rad.png", "errors_max_orientation_error_rad.png"} <= figs
    assert len(list((out / "chunks").iterdir())) == 16
    # the noise shows: trials at 10 mm differ from each other, at 0 mm with no offset they are equal
    clean = [r for r in rows if r["noise_m"] == 0.0 and r["initial_offset_rad"] == 0.0 and r["cell"] == 0]
    noisy = [r for r in rows if r["noise_m"] == 0.01 and r["initial_offset_rad"] == 0.0 and r["cell"] == 4]
    assert len({r["max_robot_position_error_m"] for r in clean}) == 1
    assert len({r["max_robot_position_error_m"] for r in noisy}) == 3


def test_a_clean_trial_equals_the_single_run(swept, small):
    out, _ = swept
    rows = json.loads((out / "results.json").read_text())["rows"]
    sc = dataclasses.replace(load_scenario("mas-kitts-helix"), duration_s=1.0, metrics_from_s=0.5)
    for choice in small.choices:
        exp = KINDS["team"].experiment(sc, controller=choice)
        ref = exp.metrics(exp.run())
        row = next(r for r in rows if r["controller"] == choice and r["noise_m"] == 0.0
                   and r["initial_offset_rad"] == 0.0)
        for key, v in ref.items():
            if isinstance(v, float):
                assert row[key] == pytest.approx(v, abs=1e-9), key
            elif v is not None:
                assert row[key] == v, key


def test_a_trial_does_not_depend_on_its_batch(small):
    cell = 6  # noise 10 mm, offsets 0.2 rad, robot-space
    whole = run_chunk(Chunk(small, cell, 0, 3))
    apart = run_chunk(Chunk(small, cell, 0, 1)) + run_chunk(Chunk(small, cell, 1, 3))
    for a, b in zip(whole, apart):
        for key, v in a.items():
            if isinstance(v, float):
                assert b[key] == pytest.approx(v, abs=1e-9), key
            else:
                assert b[key] == v, key


def test_controllers_of_one_point_see_the_same_draws(small):
    a = run_chunk(Chunk(small, 6, 0, 1))[0]
    b = run_chunk(Chunk(small, 7, 0, 1))[0]
    assert (a["point"], a["trial"]) == (b["point"], b["trial"]) and a["controller"] != b["controller"]


def test_resume_skips_stored_chunks_and_refuses_another_spec(swept, small, tmp_path, capsys):
    out, _ = swept
    stored = sorted((out / "chunks").iterdir())
    stamps = [p.stat().st_mtime_ns for p in stored]
    stored[0].unlink()  # one chunk lost: only it runs again
    run_sweep(small, out)
    err = capsys.readouterr().err
    assert "resuming, 22/24 trials already stored" in err
    assert "24/24 trials" in err and "trials/s" in err and "left" in err
    assert [p.stat().st_mtime_ns for p in stored[1:]] == stamps[1:]
    other = load_sweep(_spec(tmp_path, SMALL.replace("seed = 7", "seed = 8")))
    with pytest.raises(InvalidInputError, match="another spec"):
        run_sweep(other, out, quiet=True)


def test_cli(tmp_path, capsys):
    spec = _spec(tmp_path, SMALL.replace('controllers = ["robot-space", "quaternion"]', 'controllers = ["quaternion"]'))
    assert main(["sweep", str(spec), "--out", str(tmp_path / "o"), "--trials", "1", "--no-plots", "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "quaternion" in out and "success" in out
    assert main(["sweeps"]) == 0
    assert "helix-noise-sweep" in capsys.readouterr().out
    assert main(["sweep", str(spec), "--out", str(tmp_path / "j"), "--backend", "nojax"]) == 2
    assert "backend" in capsys.readouterr().err
    from quatform.sim.backends import SIM_BACKENDS

    if "jax" not in SIM_BACKENDS:
        assert main(["sweep", str(spec), "--out", str(tmp_path / "j"), "--backend", "jax"]) == 2
        err = capsys.readouterr().err
        assert "jax" in err and "pip install" in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("edit, match", [
    (("trials = 3", "trials = 3\ntrails = 2"), "unknown key 'trails'.*trials"),
    (("[vary.noise_m]", "[vary.noise_mm]"), "unknown parameter.*noise_m"),
    (("values = [0.0, 0.01]", "values = []"), "empty range"),
    (("values = [0.0, 0.01]", "start = 0.01\nstop = 0.01\ncount = 3"), "empty range"),
    (("values = [0.0, 0.01]", "random = {low = 0.02, high = 0.01}\ndraws = 3"), "empty range"),
    (("values = [0.0, 0.01]", "values = [-0.01]"), "must be >= 0"),
    (("[vary.noise_m]\nvalues = [0.0, 0.01]", "[vary.team_size]\nvalues = [3]"), "cannot vary team_size"),
    (('"robot-space", "quaternion"', '"robot-spac"'), "unknown controller.*robot-space"),
    (("trials = 3", "trials = 0"), "trials"),
    (('scenario = "mas-kitts-helix"', 'scenario = "mas-kitts-helx"'), "mas-kitts-helix"),
])
def test_bad_specs_are_one_line(tmp_path, edit, match):
    text = SMALL.replace(*edit)
    with pytest.raises(InvalidInputError, match=match) as exc:
        load_sweep(_spec(tmp_path, text))
    assert "\n" not in str(exc.value)


def test_too_much_work_is_refused_with_the_numbers(tmp_path, monkeypatch):
    monkeypatch.setenv("QUATFORM_MAX_MEMORY_BYTES", "1e8")
    monkeypatch.setenv("QUATFORM_MAX_WORK_S", "60")
    spec = load_sweep(_spec(tmp_path, SMALL.replace("trials = 3\nchunk_trials = 2", "trials = 100000")))
    with pytest.raises(ResourceLimitError, match=r"GB.*chunk_trials") as exc:
        estimate(spec)
    assert "\n" not in str(exc.value)
    spec = load_sweep(_spec(tmp_path, SMALL.replace("trials = 3\nchunk_trials = 2", "trials = 100000\nchunk_trials = 10")))
    with pytest.raises(ResourceLimitError, match=r"robot-steps.*h .*lower trials"):
        estimate(spec)
    assert estimate(load_sweep(_spec(tmp_path))).seconds < 60  # the small one fits


def test_random_draws_come_from_the_seed(tmp_path):
    text = SMALL.replace("values = [0.0, 0.01]", "random = {low = 0.0, high = 0.02}\ndraws = 4")
    a, b = load_sweep(_spec(tmp_path, text)), load_sweep(_spec(tmp_path, text, "b.toml"))
    assert a.axis("noise_m").values == b.axis("noise_m").values
    assert len(set(a.axis("noise_m").values)) == 4 and all(0 <= v <= 0.02 for v in a.axis("noise_m").values)
    c = load_sweep(_spec(tmp_path, text.replace("seed = 7", "seed = 8"), "c.toml"))
    assert c.axis("noise_m").values != a.axis("noise_m").values


def test_gain_scale_names_a_gain(tmp_path):
    text = SMALL.replace("[vary.noise_m]\nvalues = [0.0, 0.01]", '[vary.gain_scale]\nvalues = [2.0]\ngain = "k_z"')
    spec = load_sweep(_spec(tmp_path, text))
    with pytest.raises(InvalidInputError, match="k_z"):
        run_chunk(Chunk(spec, 1, 0, 1))  # quaternion: k_x, k_d, k_w


def test_team_size_sets_the_robot_count(tmp_path):
    text = """
name = "teams"
scenario = "team-grid-100"
controllers = ["robot-space"]
trials = 1
duration_s = 6.0
settle_s = 1.0
[vary.team_size]
values = [2, 6]
"""
    spec = load_sweep(_spec(tmp_path, text))
    rows = [run_chunk(c)[0] for c in plan_chunks(spec)]
    assert [r["n_robots"] for r in rows] == [2, 6]
    assert all(not r["failed"] for r in rows)


def test_parameters_are_documented():
    from pathlib import Path

    doc = (Path(__file__).resolve().parents[1] / "docs" / "sweeps.md").read_text()
    for name in PARAMETERS:
        assert f"`{name}`" in doc


def test_sweep_from_dict_needs_a_table():
    with pytest.raises(InvalidInputError):
        sweep_from_dict({"scenario": "mas-kitts-helix"}, "x")  # no trials


def _measured_minus_true(tmp_path, vary):
    from quatform.sweeps.trials import chunk_batch

    text = f"""
name = "m"
scenario = "mas-kitts-helix"
controllers = ["robot-space"]
trials = 4
duration_s = 2.0
settle_s = 0.5
{vary}
"""
    spec = load_sweep(_spec(tmp_path, text))
    _, batch, delay = chunk_batch(Chunk(spec, 0, 0, 4))
    log = batch.run()
    return log["measured"], log["state"], delay


def test_noise_has_its_scale_on_positions_only(tmp_path):
    m, x, _ = _measured_minus_true(tmp_path, "[vary.noise_m]\nvalues = [0.01]")
    d = m - x  # no latency: the noise itself
    pos = [0, 1, 2, 4, 5, 6]
    assert np.std(d[..., pos]) == pytest.approx(0.01, rel=0.05)
    assert np.all(d[..., [3, 7]] == 0.0)  # the yaws: noise_rad not varied
    assert not np.allclose(d[:, 0], d[:, 1])  # each trial its own noise


def test_latency_delays_by_whole_ticks_and_dropouts_hold(tmp_path):
    m, x, delay = _measured_minus_true(tmp_path, "[vary.latency_s]\nvalues = [0.03]\n[vary.initial_offset_m]\n"
                                                 "values = [0.1]")
    assert delay == 3
    assert np.array_equal(m[3:], x[:-3]) and np.array_equal(m[:3], np.broadcast_to(x[0], m[:3].shape))
    m, x, _ = _measured_minus_true(tmp_path, "[vary.dropout_rate]\nvalues = [0.5]\n[vary.initial_offset_m]\n"
                                             "values = [0.1]")
    held = np.all(m[1:] == m[:-1], axis=-1)
    fresh = np.all(m == x, axis=-1)
    assert 0.3 < held.mean() < 0.7  # about half the frames lost (200 ticks x 4 trials)
    assert np.all(held | fresh[1:])  # a frame is the plant's output or the last one held



@settings(max_examples=40, deadline=None)
@given(start=st.floats(0.0, 1.0), span=st.floats(1e-3, 1.0), count=st.integers(1, 50),
       low=st.floats(0.0, 1.0), width=st.floats(1e-6, 1.0), draws=st.integers(1, 30), seed=st.integers(0, 2**32))
def test_axes_hold_what_they_say(start, span, count, low, width, draws, seed):
    data = {"scenario": "mas-kitts-helix", "trials": 1, "seed": seed,
            "vary": {"noise_m": {"start": start, "stop": start + span, "count": count},
                     "latency_s": {"random": {"low": low, "high": low + width}, "draws": draws}}}
    spec = sweep_from_dict(data, "p")
    grid, rnd = spec.axis("noise_m"), spec.axis("latency_s")
    assert len(grid.values) == count and grid.values[0] == pytest.approx(start)
    assert all(start - 1e-12 <= v <= start + span + 1e-12 for v in grid.values)
    assert len(rnd.values) == draws and all(low <= v <= low + width for v in rnd.values)
    assert rnd == sweep_from_dict(data, "p").axis("latency_s")
    assert len(spec.cells()) == len(spec.choices) * count * draws


# -- hostile use: Ctrl-C, non-sweepable kinds, bad specs and flags, locked outputs --------------

TINY = """
name = "tiny"
scenario = "mas-kitts-helix"
controllers = ["quaternion"]
trials = 1
duration_s = 1.0
settle_s = 0.2
"""


def _tiny(tmp_path, text=TINY, name="tiny.toml"):
    return _spec(tmp_path, text, name)


def _one_line(capsys):
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


def test_ctrl_c_says_the_chunks_are_kept(tmp_path, capsys, monkeypatch):
    import quatform.sweeps.runner as runner

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(runner, "run_sweep", interrupted)
    assert main(["sweep", str(_tiny(tmp_path)), "--out", str(tmp_path / "o")]) == 130
    err = _one_line(capsys)
    assert "chunks" in err and "rerun the same command to resume" in err and "no partial" not in err


def test_every_kind_is_sweepable_or_says_why():
    assert set(KINDS) <= set(SWEEP_KINDS) | set(NOT_SWEEPABLE), set(KINDS) - set(SWEEP_KINDS) - set(NOT_SWEEPABLE)


@pytest.mark.parametrize("success, match", [
    ("below = {max_cluster_position_eror_m = 0.1}", "did you mean 'max_cluster_position_error_m'"),
    ('false = ["max_cluster_position_error_m"]', "is not a flag.*reference_lost"),
    ("below = {reference_lost = 0.5}", "is not a number.*false"),
    ('false = ["failed"]', "names the metric 'failed'"),  # a row's column, not a metric Success reads
])
def test_a_bad_success_leaves_out_free_for_the_fixed_spec(tmp_path, capsys, success, match):
    out = tmp_path / "o"
    bad = _tiny(tmp_path, TINY + "[success]\n" + success + "\n")
    assert main(["sweep", str(bad), "--out", str(out), "--no-plots", "--quiet"]) == 2
    assert re.search(match, _one_line(capsys))
    assert not out.exists()  # no sweep.json that would lock --out to the bad spec
    assert main(["sweep", str(_tiny(tmp_path)), "--out", str(out), "--no-plots", "--quiet"]) == 0
    assert (out / "results.csv").is_file()


def test_huge_workers_neither_start_nor_shrink_the_estimate(tmp_path, capsys):
    from quatform.sim.jax_devices import usable_cores
    from quatform.sweeps import estimate, plan_chunks
    from quatform.sweeps.executors import LOCAL_WORKERS_PER_CORE, parallel_workers

    spec = load_sweep(_tiny(tmp_path, TINY.replace("trials = 1", "trials = 3\nchunk_trials = 1")))
    n = len(plan_chunks(spec))
    assert n == 3
    # no more chunks at once than there are: 10^6 workers do not make the time budget check pass
    assert estimate(spec, 10**6).seconds == pytest.approx(estimate(spec, n).seconds, rel=1e-12)
    assert estimate(spec, 1).seconds == pytest.approx(n * estimate(spec, n).seconds, rel=1e-12)
    assert parallel_workers(10**6, None) == parallel_workers(10**6, "local") == usable_cores()
    assert parallel_workers(10**6, "tcp://h:1") == 10**6  # a cluster's workers are its own
    too_many = LOCAL_WORKERS_PER_CORE * usable_cores() + 1
    for extra in ([], ["--scheduler", "local"]):
        assert main(["sweep", str(_tiny(tmp_path)), "--out", str(tmp_path / "o"), "--workers", str(too_many),
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
        load_sweep(_tiny(tmp_path, TINY.replace(*edit)))
    assert "\n" not in str(exc.value)


def test_an_empty_out_or_an_unreadable_sweep_json_is_one_line(tmp_path, capsys):
    spec = str(_tiny(tmp_path))
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
        load_sweep(_tiny(tmp_path, TINY + "[slurm]\n" + slurm + "\n"))


def test_slurm_flag_counts_are_whole_numbers(tmp_path, capsys):
    assert main(["sweep", str(_tiny(tmp_path)), "--out", str(tmp_path / "o"), "--scheduler", "slurm",
                 "--slurm", "cores=abc", "--print-job-script"]) == 2
    assert "cores = 'abc' must be a whole number" in _one_line(capsys)


def test_a_team_size_the_scenario_cannot_take_names_the_axis(tmp_path):
    text = ('scenario = "team-three-bodies"\ntrials = 1\nduration_s = 1.0\nsettle_s = 0.2\n'
            'controllers = ["quaternion"]\n[vary.team_size]\nvalues = [4]\n')
    from quatform.sweeps import estimate

    with pytest.raises(InvalidInputError, match=r"\[vary.team_size\] value 4: .*triangle template holds 3") as exc:
        estimate(load_sweep(_tiny(tmp_path, text)))
    assert "\n" not in str(exc.value)


def test_a_grid_value_listed_twice_is_refused(tmp_path):
    text = TINY + "[vary.noise_m]\nvalues = [0.0, 0.01, 0.01]\n"
    with pytest.raises(InvalidInputError, match=r"\[vary.noise_m\] values = .* lists 0.01 twice; list each value once"):
        load_sweep(_tiny(tmp_path, text))


def test_a_scenario_refused_at_its_own_length_says_so(tmp_path, monkeypatch):
    """The kinds check a scenario at its file's duration_s (80 s here) before the sweep's
    duration_s applies: the line says so instead of asking to shorten a duration already short."""
    from quatform.errors import ResourceLimitError

    monkeypatch.setenv("QUATFORM_MAX_WORK_S", "1")
    with pytest.raises(ResourceLimitError, match=r"checked at its own length before the sweep's duration_s = 1.0 s") as exc:
        load_sweep(_tiny(tmp_path))
    assert "\n" not in str(exc.value)
    text = ('scenario = "team-grid-100"\ntrials = 1\nduration_s = 1.0\nsettle_s = 0.2\ncontrollers = ["quaternion"]\n'
            "[vary.team_size]\nvalues = [10000]\n")
    monkeypatch.delenv("QUATFORM_MAX_WORK_S")
    monkeypatch.setenv("QUATFORM_MAX_MEMORY_BYTES", "1e9")
    from quatform.sweeps import estimate

    with pytest.raises(ResourceLimitError, match=r"before the sweep's duration_s = 1 s applies.*10000 robots"):
        estimate(load_sweep(_tiny(tmp_path, text)))


def test_a_bad_cell_is_refused_before_any_chunk_runs(tmp_path, capsys):
    """Only the first cell of each run shape was built up front: a gain scale making the loop
    unstable was found mid-run, after the first chunks had locked --out to the spec."""
    text = TINY + "[vary.gain_scale]\nvalues = [1.0, 1e6]\n"
    out = tmp_path / "o"
    assert main(["sweep", str(_tiny(tmp_path, text)), "--out", str(out), "--no-plots", "--quiet"]) == 2
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

    text = TINY.replace("trials = 1", "trials = 4\nchunk_trials = 1").replace("duration_s = 1.0", "duration_s = 3.0")
    spec = _tiny(tmp_path, text)
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
    assert main(["sweep", str(_tiny(tmp_path)), "--out", str(out), "--no-plots", "--quiet"]) == 2
    assert "not a sweep's (no sweep.json; e.g. 'metrics.json')" in _one_line(capsys)
    assert sorted(p.name for p in out.iterdir()) == ["metrics.json"]


@pytest.mark.parametrize("code", [errno.EPERM, errno.EOPNOTSUPP])
def test_sweep_json_is_written_where_the_file_system_has_no_hard_links(tmp_path, monkeypatch, code):
    """FAT, exFAT, SMB and FUSE mounts refuse link(): the sweep's identity is moved into place instead."""
    from quatform.sweeps import results

    def no_links(src, dst, **kw):
        raise OSError(code, os.strerror(code), str(src))

    monkeypatch.setattr(results.os, "link", no_links)
    path = results.write_exclusive(tmp_path / "sweep.json", "{}\n")
    assert path.read_text() == "{}\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sweep.json"]  # no temporary left
    with pytest.raises(InvalidInputError, match="another sweep made its sweep.json"):
        results.write_exclusive(tmp_path / "sweep.json", "{}\n")
