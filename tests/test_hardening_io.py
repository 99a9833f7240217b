"""CLI and run outputs: strict JSON, staged (atomic) run folders, Ctrl-C, one-line
errors, the TOML reader, --no-feedforward, the paper citations, the help texts, pytest-xdist."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from quatform import cli
from quatform.tomlio import read_toml
from quatform.algebra import validate
from quatform.errors import InvalidInputError, NonFiniteError
from quatform.report import writers
from quatform.report.writers import strict_json, write_columns
from quatform.scenarios import Experiment
from quatform.sim import output
from quatform.sim.output import OUTPUT_MARKER, atomic_write_text, staged_dir

ROOT = Path(__file__).resolve().parents[1]


def _strict_loads(text):
    """json.loads that refuses NaN / Infinity (what a strict JSON reader does)."""
    def refuse(name):
        raise ValueError(f"non-standard JSON constant {name}")
    return json.loads(text, parse_constant=refuse)


def _lines(text):
    return [ln for ln in text.splitlines() if ln.strip()]


def _leftovers(folder: Path):
    return sorted(p.name for p in folder.iterdir() if ".partial-" in p.name or ".old-" in p.name
                  or ".tmp-" in p.name)


# --------------------------------------------------------------------------- A: xdist

def test_the_test_extra_has_pytest_xdist():
    text = (ROOT / "pyproject.toml").read_text()
    test_extra = text.split("test = [", 1)[1].split("]", 1)[0]
    assert "pytest-xdist" in test_extra


# --------------------------------------------------------------------------- B: strict JSON

def test_metrics_json_is_strict_json_with_nonfinite_values_named(tmp_path):
    m = {"max_shape_error_m": float("inf"), "first_singular_time_s": None, "x": np.float64("nan"),
         "n": np.int64(3), "flag": np.bool_(True), "sub": {"v": [1.0, -np.inf]}, "arr": np.array([1.0, 2.0])}
    f = writers.write_metrics(m, tmp_path / "metrics.json")
    back = _strict_loads(f.read_text())
    assert back["max_shape_error_m"] is None and back["x"] is None and back["first_singular_time_s"] is None
    assert back["sub"]["v"] == [1.0, None] and back["n"] == 3 and back["flag"] is True and back["arr"] == [1.0, 2.0]
    assert back["nonfinite_values"] == {"max_shape_error_m": "inf", "x": "nan", "sub.v[1]": "-inf"}
    rows = _strict_loads(strict_json([{"a": 1.0}, {"a": float("nan")}]))
    assert rows == [{"a": 1.0}, {"a": None, "nonfinite_values": {"a": "nan"}}]


# --------------------------------------------------------------------------- C: atomic files, staged folders

def test_a_csv_cut_off_while_written_leaves_no_file(tmp_path, monkeypatch):
    real = np.savetxt

    def half_then_ctrl_c(target, *a, **k):
        real(target, np.zeros((2, 2)), delimiter=",")  # part of the output, then Ctrl-C
        raise KeyboardInterrupt

    monkeypatch.setattr(writers.np, "savetxt", half_then_ctrl_c)
    with pytest.raises(KeyboardInterrupt):
        write_columns(["t", "x"], np.ones((5, 2)), tmp_path / "timeseries.csv")
    assert list(tmp_path.iterdir()) == []


def test_an_atomic_write_keeps_the_old_file_when_cut_off(tmp_path, monkeypatch):
    f = tmp_path / "metrics.json"
    f.write_text("old")

    def ctrl_c(*a):
        raise KeyboardInterrupt

    monkeypatch.setattr(output.os, "replace", ctrl_c)
    with pytest.raises(KeyboardInterrupt):
        atomic_write_text(f, "new")
    assert f.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["metrics.json"]


def _interrupt_at(monkeypatch, n_ok: int):
    """``Experiment.run`` (every kind's simulation) that runs ``n_ok`` times, then raises
    KeyboardInterrupt; returns the list of the runs' ``feedforward`` (from their meta)."""
    real, calls = Experiment.run, []

    def sim(self, progress=None):
        calls.append(self.meta.get("feedforward"))
        if len(calls) > n_ok:
            raise KeyboardInterrupt
        return real(self, progress)

    monkeypatch.setattr(Experiment, "run", sim)
    return calls


def test_ctrl_c_during_compare_leaves_nothing_and_exits_130(tmp_path, monkeypatch, capsys):
    _interrupt_at(monkeypatch, 1)  # the first controller's folder is complete, the second is cut off
    out = tmp_path / "new" / "cmp"
    assert cli.main(["compare", "mas-kitts-yaw-step", "--out", str(out)]) == 130
    err = [ln for ln in _lines(capsys.readouterr().err) if "quatform:" in ln]  # (and progress lines)
    assert len(err) == 1 and err[0].startswith("quatform: interrupted") and "Traceback" not in err[0]
    assert not (tmp_path / "new").exists()  # the parent made for the run is gone too
    assert list(tmp_path.iterdir()) == []


def test_ctrl_c_during_a_rerun_keeps_the_previous_run(tmp_path, monkeypatch, capsys):
    out = tmp_path / "run"
    assert cli.main(["run", "mas-kitts-yaw-step", "--controller", "quaternion", "--out", str(out), "--no-plots"]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    _interrupt_at(monkeypatch, 0)
    assert cli.main(["run", "mas-kitts-yaw-step", "--controller", "robot-space", "--out", str(out)]) == 130
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert _leftovers(tmp_path) == []


def test_a_failed_run_leaves_no_folder(tmp_path, monkeypatch, capsys):
    def fails(*a, **k):
        raise InvalidInputError("bad reference")

    monkeypatch.setattr(Experiment, "run", fails)
    out = tmp_path / "a" / "b"
    assert cli.main(["run", "mas-kitts-yaw-step", "--controller", "quaternion", "--out", str(out)]) == 2
    assert list(tmp_path.iterdir()) == []


def test_a_rerun_replaces_the_old_plots_and_keeps_user_files_safe(tmp_path, capsys):
    out = tmp_path / "run"
    argv = ["run", "mas-kitts-yaw-step", "--controller", "quaternion", "--out", str(out)]
    assert cli.main(argv) == 0
    assert list(out.glob("*.png"))
    assert cli.main(argv + ["--no-plots"]) == 0
    assert sorted(p.name for p in out.iterdir()) == sorted([OUTPUT_MARKER, "metrics.json", "timeseries.csv",
                                                            "run.mcap", "foxglove-layout.json"])
    # a file the user put there: the folder is no longer quatform's alone, so it is not replaced
    (out / "notes.txt").write_text("mine")
    capsys.readouterr()
    assert cli.main(argv) == 2
    err = _lines(capsys.readouterr().err)
    assert len(err) == 1 and "notes.txt" in err[0] and "did not write" in err[0]
    assert (out / "notes.txt").read_text() == "mine"
    # a folder of the user's (not made by quatform, not empty) is refused before any work
    user = tmp_path / "mine"
    user.mkdir()
    (user / "data.csv").write_text("1,2\n")
    assert cli.main(argv[:-1] + [str(user)]) == 2
    assert [p.name for p in user.iterdir()] == ["data.csv"] and _leftovers(tmp_path) == []


def test_out_dot_and_a_file_are_refused(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    for out, needle in ((".", "current folder"), (str(tmp_path), "current folder")):
        assert cli.main(["run", "mas-kitts-yaw-step", "--controller", "quaternion", "--out", out]) == 2
        assert needle in capsys.readouterr().err
    (tmp_path / "f").write_text("x")
    assert cli.main(["run", "mas-kitts-yaw-step", "--controller", "quaternion", "--out", "f"]) == 2
    assert "is a file" in capsys.readouterr().err
    assert cli.main(["run", "mas-kitts-yaw-step", "--controller", "quaternion", "--out", "a\x00b"]) == 2
    assert "NUL" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f"]


def test_an_empty_folder_is_used_and_stale_partials_of_dead_runs_are_removed(tmp_path):
    out = tmp_path / "o"
    out.mkdir()
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    stale = tmp_path / f".o.partial-{int(dead.stdout)}"
    stale.mkdir()
    (stale / "timeseries.csv").write_text("cut")
    with staged_dir(out) as tmp:
        assert tmp.parent == tmp_path and not stale.exists()
        (tmp / "a.txt").write_text("a")
    assert sorted(p.name for p in out.iterdir()) == [OUTPUT_MARKER, "a.txt"]
    assert json.loads((out / OUTPUT_MARKER).read_text())["entries"] == ["a.txt"]


def test_plan_and_teleop_write_through_the_staged_folder(tmp_path, monkeypatch, capsys):
    import quatform.plan_runs as plan_runs

    def ctrl_c(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(plan_runs, "make_plan", ctrl_c)
    assert cli.main(["plan", "belta-kumar-2002-two-bodies", "--out", str(tmp_path / "p"), "--alpha", "0.5",
                     "--alpha", "0.9"]) == 130
    monkeypatch.setattr(Experiment, "run", ctrl_c)
    assert cli.main(["teleop", "teleop-preload", "--out", str(tmp_path / "t")]) == 130
    assert list(tmp_path.iterdir()) == []


def test_sigint_to_a_real_run_exits_130_with_one_line_and_no_files(tmp_path):
    """Ctrl-C (SIGINT) sent to a real `quatform run` while it works: one line, status 130, no folder."""
    out = tmp_path / "run"
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    proc = subprocess.Popen([sys.executable, "-m", "quatform.cli", "run", "mas-kitts-spiral", "--controller",
                             "dual-quaternion", "--out", str(out)], cwd=tmp_path, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    while not any(".partial-" in p.name for p in tmp_path.iterdir()):  # the run has started writing
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.005)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    err = _lines(err)
    assert len(err) == 1 and err[0].startswith("quatform: interrupted") and "left as it was" in err[0]
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------- D: no traceback

@pytest.mark.parametrize("exc, code, needle", [
    (KeyboardInterrupt(), 130, "interrupted"),
    (MemoryError(), 2, "out of memory running run mas-kitts-yaw-step"),
    (RecursionError(), 2, "nested too deeply"),
    (PermissionError(13, "Permission denied", "/x/y"), 1, "Permission denied: /x/y"),
    (ZeroDivisionError("float division by zero"), 3, "internal error: ZeroDivisionError"),
])
def test_every_exception_is_one_line_with_its_status(tmp_path, monkeypatch, capsys, exc, code, needle):
    def raises(*a, **k):
        raise exc

    monkeypatch.setattr(Experiment, "run", raises)
    assert cli.main(["run", "mas-kitts-yaw-step", "--controller", "quaternion", "--out", str(tmp_path / "o")]) == code
    err = _lines(capsys.readouterr().err)
    assert len(err) == 1 and needle in err[0]
    assert list(tmp_path.iterdir()) == []


def test_usage_errors_are_one_line(capsys):
    for argv in (["run", "mas-kitts-yaw-step"], ["plan"], ["frobnicate"], ["scenarios", "extra"],
                 ["plan", "x", "--out", "o", "--alpha", "abc"]):
        with pytest.raises(SystemExit) as e:
            cli.main(argv)
        assert e.value.code == 2
        err = _lines(capsys.readouterr().err)
        assert len(err) == 1 and ": error:" in err[0] and "--help" in err[0], argv


_TOKENS = ["mas-kitts-yaw-step", "marciano-circle", "teleop-preload", "belta-kumar-2002-two-bodies", "nope", "",
           "\x00", "x" * 3000, "--controller", "quaternion", "--formation", "spherical", "--alpha", "nan", "-1",
           "1e309", "0.5", "--case", "a", "--physics", "mujoco", "--mocap-noise-m", "--mocap-latency-s",
           "--no-feedforward", "--no-plots", "--preload", "on", "--reference", "--out", "."]


@settings(max_examples=150, deadline=None)
@given(command=st.sampled_from(["run", "compare", "plan", "teleop", "demo", "scenarios", "plans"]),
       rest=st.lists(st.sampled_from(_TOKENS), max_size=7), out=st.sampled_from(["o", ".", "\x00", "x" * 3000, ""]))
def test_fuzzed_command_lines_never_show_a_traceback(tmp_path_factory, command, rest, out):
    """Random command lines (the simulators replaced by a stub that raises): every outcome is one
    line on stderr with status 0, 1, 2 or 130, or the stub's own 'internal error' (status 3)."""
    import contextlib
    import io

    import quatform.plan_runs as plan_runs

    class Reached(Exception):
        pass

    def reached(*a, **k):
        raise Reached("stub")

    from quatform.scenarios import KINDS

    folder = tmp_path_factory.mktemp("fuzz")
    # every kind's experiment (its plant built, MuJoCo's included) and every simulation
    stubbed = [(Experiment, "run"), (plan_runs, "make_plan")] + [(type(k), "experiment") for k in KINDS.values()]
    saved = [getattr(m, n) for m, n in stubbed]
    for m, n in stubbed:
        setattr(m, n, reached)
    err = io.StringIO()
    cwd = os.getcwd()
    try:
        os.chdir(folder)
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            try:
                code = cli.main([command, *rest, "--out", out] if command not in ("scenarios", "plans") or rest
                                else [command])
            except SystemExit as e:
                code = e.code
    finally:
        os.chdir(cwd)
        for (m, n), f in zip(stubbed, saved):
            setattr(m, n, f)
    lines = _lines(err.getvalue())
    assert code in (0, 1, 2, 3, 130) and len(lines) <= 1, (code, lines)
    assert code != 3 or "Reached" in lines[0], lines
    assert all(len(ln) <= 700 and "Traceback" not in ln for ln in lines)
    assert [p.name for p in folder.iterdir()] == []  # nothing half-written


# --------------------------------------------------------------------------- E: one-line, cheap messages

def test_a_huge_vector_where_three_belong_is_one_short_line(tmp_path, capsys):
    f = tmp_path / "big.toml"
    f.write_text('name = "big"\nduration_s = 1.0\n[path]\ncentroid = "fixed"\ncenter = ['
                 + ", ".join(["1"] * 200_000) + "]\nd_c = 1.0\n")
    t0 = time.perf_counter()
    assert cli.main(["run", str(f), "--controller", "quaternion", "--out", str(tmp_path / "o")]) == 2
    assert time.perf_counter() - t0 < 30.0
    err = _lines(capsys.readouterr().err)
    assert len(err) == 1 and len(err[0]) <= 520 and "center" in err[0]


def test_validator_messages_are_cheap_to_build():
    """A NaN in a 4e6-entry array: the message names the first bad entry without allocating
    index lists or copies of the bad entries (argwhere and a[bad] would take 3x the array)."""
    a = np.full((1_000_000, 4), np.nan)
    a[0] = 1.0
    tracemalloc.start()
    try:
        with pytest.raises(NonFiniteError, match=r"contains nan at index \(1, 0\)"):
            validate.as_array(a, "q", 4)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 0.5 * a.nbytes
    q = np.ones((3, 5, 4))
    with pytest.raises(InvalidInputError, match=r"has norm 2 at index \(0, 0\)"):
        validate.as_unit_quaternion(q)
    with pytest.raises(InvalidInputError, match=r"primary \. dual = 1 \(tolerance"):
        validate.as_unit_dual_quaternion(np.r_[1.0, 0, 0, 0, 1.0, 0, 0, 0])


# --------------------------------------------------------------------------- F: the TOML reader

@pytest.mark.parametrize("make, needle", [
    (lambda p: p.write_bytes(b'name = "\xff\xfe"\n'), "not UTF-8 text (byte 0xff on line 1); save the file as UTF-8"),
    (lambda p: p.write_text("a = " + "[" * 100_000 + "]" * 100_000), "nested too deeply"),
    (lambda p: p.mkdir(), "is a folder, not a file"),
    (lambda p: p.write_text("# " + "x" * 1_100_000), "too large for a scenario file"),
    (lambda p: None, "no such file"),
])
def test_unreadable_toml_files_are_one_line_naming_the_file(tmp_path, make, needle):
    p = tmp_path / "s.toml"
    make(p)
    with pytest.raises(InvalidInputError) as e:
        read_toml(p, {}, "scenario")
    msg = str(e.value)
    assert str(p) in msg and needle in msg and "\n" not in msg


def test_a_device_and_an_unreadable_file_are_one_line(tmp_path, monkeypatch):
    with pytest.raises(InvalidInputError, match="not a regular file"):
        read_toml("/dev/null", {}, "scenario")
    p = tmp_path / "s.toml"
    p.write_text("x = 1\n")
    import quatform.tomlio as toml_module

    def denied(*a, **k):
        raise PermissionError(13, "Permission denied", str(p))

    monkeypatch.setattr(toml_module, "open", denied, raising=False)
    with pytest.raises(InvalidInputError, match="cannot read it .Permission denied.; check its permissions"):
        read_toml(p, {}, "plan spec")


def test_bad_toml_through_the_cli_is_one_line(tmp_path, capsys):
    p = tmp_path / "s.toml"
    p.write_bytes(b"\x80\x81")
    assert cli.main(["plan", str(p), "--out", str(tmp_path / "o")]) == 2
    err = _lines(capsys.readouterr().err)
    assert len(err) == 1 and "not UTF-8" in err[0]


# --------------------------------------------------------------------------- G: --no-feedforward

def test_no_feedforward_gives_seed_000_fig13_steady_state_errors(tmp_path, capsys):
    """Seed 000 Fig. 13 (no feedforward): steady-state cluster position errors about 0.236 m
    (robot space), 0.108 m (quaternion), 0.029 m (dual quaternion)."""
    fig13 = {"robot-space": 0.236, "quaternion": 0.108, "dual-quaternion": 0.029}
    for c, expected in fig13.items():
        out = tmp_path / c
        assert cli.main(["run", "mas-kitts-spiral", "--controller", c, "--no-feedforward", "--no-plots",
                         "--out", str(out)]) == 0
        m = json.loads((out / "metrics.json").read_text())
        assert m["feedforward"] is False
        assert m["max_cluster_position_error_m"] == pytest.approx(expected, rel=0.05)
    assert "feedforward: off" in capsys.readouterr().out


def test_compare_passes_no_feedforward_and_ugv_uav_refuses_it(tmp_path, monkeypatch, capsys):
    calls = _interrupt_at(monkeypatch, 0)
    assert cli.main(["compare", "mas-kitts-yaw-step", "--no-feedforward", "--out", str(tmp_path / "c")]) == 130
    assert calls == [False]
    for argv in (["compare", "marciano-circle"], ["run", "marciano-circle"]):
        assert cli.main([*argv, "--no-feedforward", "--out", str(tmp_path / "u")]) == 2
        err = capsys.readouterr().err
        assert "marciano-circle is a ugv-uav scenario: --no-feedforward does not apply to it" in err


# --------------------------------------------------------------------------- H, I: listings and help

def test_scenarios_and_plans_name_the_papers(capsys):
    assert cli.main(["scenarios"]) == 0
    text = capsys.readouterr().out
    for needle in ('I. Mas, C. Kitts, 2017, "Quaternions and Dual Quaternions: Singularity-Free Multirobot',
                   'H. N. Marciano, 2021, "Using Quaternions to Avoid Singularities',
                   'J. F. Jansen, R. L. Kress, S. M. Babcock, W. R. Hamel, 1990, "Controller design'):
        assert needle in text
    assert cli.main(["plans"]) == 0
    text = capsys.readouterr().out
    assert 'C. Belta, V. Kumar, 2002, "Trajectory design for formations of robots by kinetic energy shaping"' in text
    assert 'C. Belta, V. Kumar, 2001, "Motion generation for formations of robots: a geometric approach"' in text


def test_every_command_has_help_and_the_mujoco_hint_is_the_editable_install(capsys):
    parser = cli._build_parser()
    commands = next(a for a in parser._actions if a.dest == "command").choices
    assert set(commands) == {"demo", "run", "plan", "plans", "compare", "teleop", "scenarios", "sweep", "sweeps",
                             "ros2", "replay"}
    for name in commands:
        with pytest.raises(SystemExit) as e:
            cli.main([name, "--help"])
        assert e.value.code == 0
        text = " ".join(capsys.readouterr().out.split())
        assert text.startswith(f"usage: quatform {name}")
        if name in ("run", "compare"):
            assert 'pip install -e ".[mujoco]"' in text and "quatform[mujoco]" not in text
            assert "--no-feedforward" in text


@pytest.mark.parametrize("kind,line,key", [
    ("pair", "d_c = 1e200", "d_c"),
    ("ugv-uav", "r_x = 1e160", "r_x"),
    ("teleop", "duration_s = 1e300", "duration_s"),
    ("plan", "X = 1e300", "X"),
])
def test_huge_finite_numbers_are_refused_at_load_naming_the_key(tmp_path, kind, line, key):
    """A huge finite number in any file kind is refused by the reader, naming the key (not late,
    from an internal array, nor by overflowing into warnings)."""
    from quatform.checks import MAX_NUMBER, number
    from quatform.errors import InvalidInputError

    with pytest.raises(InvalidInputError, match=rf"f.toml: {key} = .* is beyond \+-1e\+12"):
        number({key: float(line.split("=")[1])}, key, "f.toml")
    assert number({key: MAX_NUMBER}, key, "f.toml") == MAX_NUMBER


def test_a_second_ctrl_c_while_reporting_the_first_is_ignored(tmp_path, monkeypatch):
    """Review: a second Ctrl-C while the first was being reported ended the process by the
    signal (exit -2); SIGINT is ignored while the one line is written, restored after."""
    import signal

    seen = []
    monkeypatch.setattr(cli, "_say", lambda text: seen.append((text, signal.getsignal(signal.SIGINT))))
    _interrupt_at(monkeypatch, 0)
    before = signal.getsignal(signal.SIGINT)
    assert cli.main(["run", "mas-kitts-yaw-step", "--controller", "quaternion", "--out", str(tmp_path / "r")]) == 130
    assert seen and seen[-1][0].startswith("interrupted") and seen[-1][1] is signal.SIG_IGN
    assert signal.getsignal(signal.SIGINT) is before


def test_an_out_holding_an_input_is_refused_before_any_work(tmp_path, monkeypatch, capsys):
    """Review finding 2: ``--out`` set to the folder of its own input would delete the input."""
    from quatform.planning import builtin_plan_specs
    from quatform.scenarios import builtin_scenarios

    def no_work(*a, **k):
        raise AssertionError("work started")

    monkeypatch.setattr(Experiment, "run", no_work)
    prev = tmp_path / "prev"
    prev.mkdir()
    files = {"plan.npz": b"npz", "run.mcap": b"mcap", "robots.toml": b"",
             "spec.toml": builtin_plan_specs()["belta-kumar-2002-two-bodies"].read_bytes(),
             "sc.toml": builtin_scenarios()["mas-kitts-helix"].read_bytes(), "sweep.toml": b""}
    for name, data in files.items():
        (prev / name).write_bytes(data)
    (prev / OUTPUT_MARKER).write_text(json.dumps({"written_by": "quatform", "entries": sorted(files)}))
    monkeypatch.chdir(tmp_path)
    commands = [
        (["run", "team-three-bodies", "--reference", "prev/plan.npz", "--out", "prev"], "prev/plan.npz"),
        (["compare", "team-three-bodies", "--reference", "prev/plan.npz", "--out", "prev"], "prev/plan.npz"),
        (["run", "prev/sc.toml", "--controller", "quaternion", "--out", "prev"], "prev/sc.toml"),
        (["compare", "prev/sc.toml", "--out", "./prev/"], "prev/sc.toml"),
        (["plan", "prev/spec.toml", "--out", "prev"], "prev/spec.toml"),
        (["plan", "prev/spec.toml", "--case", "a", "--out", "prev"], "prev/spec.toml"),
        (["plan", "prev/spec.toml", "--alpha", "0.5", "--alpha", "0.9", "--out", "prev"], "prev/spec.toml"),
        (["replay", "prev/run.mcap", "--scenario", "mas-kitts-helix", "--controller", "quaternion", "--robots",
          "prev/robots.toml", "--out", "prev"], "prev/run.mcap"),
        (["replay", "prev", "--scenario", "mas-kitts-helix", "--controller", "quaternion", "--robots",
          "prev/robots.toml", "--out", str(prev)], "'prev'"),
        (["sweep", "prev/sweep.toml", "--out", "prev"], "prev/sweep.toml"),
    ]
    for argv, named in commands:
        assert cli.main(argv) == 2, argv
        err = _lines(capsys.readouterr().err)
        assert len(err) == 1 and "inside the output folder" in err[0] and named in err[0], (argv, err)
        assert "--out" in err[0] and "outside it" in err[0]
    assert sorted(p.name for p in prev.iterdir()) == sorted([*files, OUTPUT_MARKER])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["prev"]


def test_check_inputs_outside_follows_links_and_skips_names(tmp_path):
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "bag.mcap").write_text("x")
    (tmp_path / "link").symlink_to(tmp_path / "out")
    with pytest.raises(InvalidInputError, match="bag.mcap"):
        output.check_inputs_outside(tmp_path / "link", tmp_path / "out" / "bag.mcap")
    with pytest.raises(InvalidInputError, match="inside the output folder"):
        with staged_dir(tmp_path / "out", inputs=[str(tmp_path / "link" / "bag.mcap")]):
            raise AssertionError("entered")
    output.check_inputs_outside(tmp_path / "out", None, "mas-kitts-helix", tmp_path / "bag.mcap", object())
    output.check_inputs_outside(tmp_path / "out2", tmp_path / "out" / "bag.mcap")
    assert (tmp_path / "out" / "bag.mcap").read_text() == "x"


@pytest.mark.parametrize("name", ["QUATFORM_MAX_MEMORY_BYTES", "QUATFORM_MAX_WORK_S"])
@pytest.mark.parametrize("value", ["abc", "-5", "0", "nan", "inf"])
def test_a_budget_that_is_no_positive_number_is_one_line(monkeypatch, name, value):
    from quatform.checks import memory_budget_bytes, time_budget_s
    from quatform.errors import InvalidInputError

    monkeypatch.setenv(name, value)
    budget = memory_budget_bytes if "MEMORY" in name else time_budget_s
    with pytest.raises(InvalidInputError, match=name) as exc:
        budget()
    assert "\n" not in str(exc.value) and repr(value) in str(exc.value)
    monkeypatch.setenv(name, " 2.5e3 ")
    assert budget() == 2500.0


def test_a_toml_file_with_a_byte_order_mark_reads(tmp_path):
    """Some editors start a UTF-8 file with a byte-order mark: the scenario reads as without it."""
    from quatform.scenarios import builtin_scenarios, load_scenario

    text = builtin_scenarios()["mas-kitts-spiral"].read_text(encoding="utf-8")
    f = tmp_path / "bom.toml"
    f.write_bytes(b"\xef\xbb\xbf" + text.encode("utf-8"))
    assert repr(load_scenario(f)) == repr(load_scenario("mas-kitts-spiral"))
