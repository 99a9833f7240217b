"""The quatform command: --help, --version, demo, run, compare, scenarios, one-line errors."""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
from hypothesis import given, settings, strategies as st

import quatform
from quatform import cli
from quatform.scenarios import Experiment

PNG = b"\x89PNG\r\n\x1a\n"
ROOT = Path(__file__).resolve().parents[1]


def _lines(text):
    return [ln for ln in text.splitlines() if ln.strip()]


def test_version_and_help(capsys):
    with pytest.raises(SystemExit) as e:
        cli.main(["--version"])
    assert e.value.code == 0
    assert capsys.readouterr().out.strip() == f"quatform {quatform.__version__}"
    for argv in (["--help"], ["demo", "--help"], ["run", "--help"], ["compare", "--help"],
                 ["scenarios", "--help"]):
        with pytest.raises(SystemExit) as e:
            cli.main(argv)
        assert e.value.code == 0
        assert "usage: quatform" in capsys.readouterr().out


def test_demo_compares_the_four_controllers_on_the_spiral(tmp_path, capsys):
    out = tmp_path / "demo"
    assert cli.main(["demo", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    rows = {r["controller"]: r for r in json.loads((out / "comparison.json").read_text())}
    assert set(rows) == {"cluster-space", "robot-space", "quaternion", "dual-quaternion"}
    assert rows["cluster-space"]["singularity_detected"] and rows["cluster-space"]["reference_lost"]
    assert not rows["quaternion"]["reference_lost"] and not rows["dual-quaternion"]["reference_lost"]
    assert "| cluster-space |" in text and (out / "compare_errors.png").exists()


def test_scenarios_lists_builtins(capsys):
    assert cli.main(["scenarios"]) == 0
    out = capsys.readouterr().out
    assert "mas-kitts-spiral" in out and "seed 000" in out


def test_run_writes_metrics_timeseries_and_plots(tmp_path, capsys):
    out = tmp_path / "run"
    assert cli.main(["run", "mas-kitts-yaw-step", "--controller", "quaternion", "--out", str(out)]) == 0
    m = json.loads((out / "metrics.json").read_text())
    for key in ("controller", "scenario", "singularity_detected", "first_singular_time_s",
                "max_cluster_position_error_m", "max_shape_error_m", "max_orientation_error_rad",
                "max_robot_position_error_m", "min_robot_separation_m",
                "max_recovered_euclidean_error_rad", "nonfinite_commands"):
        assert key in m, key
    assert m["controller"] == "quaternion" and m["scenario"] == "mas-kitts-yaw-step"
    with open(out / "timeseries.csv") as f:
        header = next(csv.reader(f))
        rows = list(csv.reader(f))
    for col in ("t", "x1", "x1_des", "q_c_w", "q_c_w_des", "q_c1_z", "d_c", "d_c_des",
                "euclid_beta_c", "euclid_beta_c_des", "u_x1", "singularity_measure"):
        assert col in header, col
    assert len(rows) == 1001 and all(len(r) == len(header) for r in rows)
    pngs = sorted(p.name for p in out.glob("*.png"))
    assert pngs and all((out / p).read_bytes()[:8] == PNG for p in pngs)
    assert "quaternion" in capsys.readouterr().out


def test_compare_writes_table_and_fig13(tmp_path, capsys):
    out = tmp_path / "cmp"
    assert cli.main(["compare", "mas-kitts-yaw-step", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    for name in ("cluster-space", "robot-space", "quaternion", "dual-quaternion"):
        assert name in text
        assert (out / name / "metrics.json").exists()
    rows = json.loads((out / "comparison.json").read_text())
    assert [r["controller"] for r in rows] == ["cluster-space", "robot-space", "quaternion", "dual-quaternion"]
    assert (out / "compare_errors.png").read_bytes()[:8] == PNG
    assert "| controller |" in (out / "comparison.md").read_text()


@pytest.mark.parametrize("argv, msg", [
    (["run", "no-such", "--controller", "quaternion", "--out", "x"], "unknown scenario"),
])
def test_errors_are_one_line(tmp_path, argv, msg):
    proc = subprocess.run([sys.executable, "-m", "quatform.cli", *argv], capture_output=True, text=True,
                          cwd=tmp_path)
    assert proc.returncode == 2
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("quatform: error:") and msg in lines[0]


def test_file_system_error_is_one_line(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    proc = subprocess.run(
        [sys.executable, "-m", "quatform.cli", "run", "mas-kitts-yaw-step", "--controller", "quaternion",
         "--out", str(blocker / "sub")], capture_output=True, text=True,
    )
    assert proc.returncode == 1
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip() and not ln.startswith("\r")]
    assert lines[-1].startswith("quatform: error:")
    assert all(ln.startswith("quatform: error:") or "%" in ln for ln in lines)


def test_ugv_uav_run_and_compare(tmp_path, capsys):
    out = tmp_path / "uu"
    assert cli.main(["run", "marciano-front-to-over", "--formation", "quaternion", "--out", str(out),
                     "--mocap-noise-m", "0.002", "--mocap-latency-s", "0.005"]) == 0
    m = json.loads((out / "metrics.json").read_text())
    for key in ("max_ugv_position_error_m", "max_uav_position_error_m", "max_uav_yaw_error_rad",
                "unreachable_reference", "singularity_detected", "nonfinite_commands"):
        assert key in m, key
    header = (out / "timeseries.csv").read_text().splitlines()[0].split(",")
    assert {"x_b", "x_b_des", "q_c_w", "q_c_w_des", "u_v_p", "euclid_alpha_c"} <= set(header)
    assert (out / "paths_3d.png").read_bytes()[:8] == PNG
    cmp_dir = tmp_path / "cmp"
    assert cli.main(["compare", "marciano-front-to-over", "--out", str(cmp_dir)]) == 0
    text = capsys.readouterr().out
    rows = json.loads((cmp_dir / "comparison.json").read_text())
    assert [r["formation"] for r in rows] == ["spherical", "restricted", "quaternion"]
    assert rows[1]["unreachable_reference"] and not rows[2]["unreachable_reference"]
    assert "| restricted | 60.0 |" in text and (cmp_dir / "compare_formations.png").exists()  # unreachable ref. (s)
    # a two-robot scenario needs --controller
    assert cli.main(["run", "mas-kitts-yaw-step", "--out", str(tmp_path / "x")]) == 2


def test_compare_no_plots_writes_the_table_and_no_figure(tmp_path, capsys):
    """``compare`` had no --no-plots (``run`` and ``teleop`` had); it draws nothing with it."""
    toml = tmp_path / "short.toml"
    toml.write_text('name = "short"\nduration_s = 0.5\nmetrics_from_s = 0.0\n[path]\ncentroid = "fixed"\n'
                    'center = [0.0, 0.0, 1.0]\nd_c = 1.0\n')
    out = tmp_path / "cmp"
    assert cli.main(["compare", str(toml), "--no-plots", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert (out / "comparison.json").exists() and not list(out.rglob("*.png"))
    assert (out / "quaternion" / "metrics.json").exists() and "compare plots" not in text


# -- no traceback: every outcome is one line; listings and help name the papers ----------------------

def test_the_test_extra_has_pytest_xdist():
    text = (ROOT / "pyproject.toml").read_text()
    test_extra = text.split("test = [", 1)[1].split("]", 1)[0]
    assert "pytest-xdist" in test_extra


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


def test_a_huge_vector_where_three_belong_is_one_short_line(tmp_path, capsys):
    f = tmp_path / "big.toml"
    f.write_text('name = "big"\nduration_s = 1.0\n[path]\ncentroid = "fixed"\ncenter = ['
                 + ", ".join(["1"] * 200_000) + "]\nd_c = 1.0\n")
    t0 = time.perf_counter()
    assert cli.main(["run", str(f), "--controller", "quaternion", "--out", str(tmp_path / "o")]) == 2
    assert time.perf_counter() - t0 < 30.0
    err = _lines(capsys.readouterr().err)
    assert len(err) == 1 and len(err[0]) <= 520 and "center" in err[0]


def test_bad_toml_through_the_cli_is_one_line(tmp_path, capsys):
    p = tmp_path / "s.toml"
    p.write_bytes(b"\x80\x81")
    assert cli.main(["plan", str(p), "--out", str(tmp_path / "o")]) == 2
    err = _lines(capsys.readouterr().err)
    assert len(err) == 1 and "not UTF-8" in err[0]


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


def test_python_dash_m_runs_the_command_line():
    """Guards against: ``python -m quatform`` failing for want of a ``__main__`` module."""
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-m", "quatform", "--help"], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0 and "COMMAND" in out.stdout
