"""The quatform command: --help, --version, demo, run, compare, scenarios, one-line errors."""

from __future__ import annotations

import csv
import json
import subprocess
import sys

import pytest

import quatform
from quatform import cli

PNG = b"\x89PNG\r\n\x1a\n"


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
