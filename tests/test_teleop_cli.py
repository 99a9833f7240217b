"""``quatform teleop``: files, metrics keys, options and one-line errors."""

from __future__ import annotations

import json

import pytest

from quatform.cli import main

REQUIRED = ("final_position_error_m", "final_orientation_error_rad", "peak_orientation_error_rad",
            "contact_force_error_pct", "reversal_hysteresis_m", "wall_penetration_m", "nonfinite_torques")

SHORT = """
kind = "teleop"
name = "short"
duration_s = 0.6
dt_s = 0.002
holds_s = [0.3, 0.6]

[wall]
point = [0.48, 0.0, 0.5]
normal = [-1.0, 0.0, 0.0]

[push]
keys = [{ t_s = 0.0, move = [0.0, 0.0, 0.0] }, { t_s = 0.2, move = [0.0, 0.02, 0.0] },
        { t_s = 0.4, move = [0.0, -0.02, 0.0] }]

[[virtual_walls]]
normal = [0.0, 0.0, -1.0]
offset = -0.25

[hand]
keys = [{ t_s = 0.0 }, { t_s = 0.5, move = [0.03, 0.0, -0.02] }]

[controller]
orientation_error = "rpy"
k_for = 0.01
"""


def test_teleop_writes_metrics_timeseries_and_every_plot(tmp_path, capsys):
    f = tmp_path / "short.toml"
    f.write_text(SHORT)
    out = tmp_path / "run"
    assert main(["teleop", str(f), "--out", str(out), "--orientation-error", "euler-parameters",
                 "--preload", "on"]) == 0
    m = json.loads((out / "metrics.json").read_text())
    for key in REQUIRED:
        assert key in m
    assert m["orientation_error"] == "euler-parameters" and m["preload"] is True  # the options override the file
    assert m["nonfinite_torques"] == 0
    header = (out / "timeseries.csv").read_text().splitlines()[0].split(",")
    assert header[0] == "t" and "F_s_x" in header and "tau_s7" in header
    for png in ("tracking.png", "torques.png", "orientation_rpy.png", "contact.png", "hysteresis.png",
                "virtual_wall.png"):
        assert (out / png).stat().st_size > 10_000
    assert "| euler-parameters | True |" in capsys.readouterr().out


def test_teleop_help_and_errors(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["teleop", "--help"])
    assert exc.value.code == 0
    assert "--orientation-error" in capsys.readouterr().out
    assert main(["teleop", "mas-kitts-spiral", "--out", str(tmp_path)]) == 2
    assert "not a teleoperation scenario" in capsys.readouterr().err
    assert main(["run", "teleop-preload", "--out", str(tmp_path), "--controller", "quaternion"]) == 2
    err = capsys.readouterr().err
    assert "teleop-preload is a teleop scenario: --controller does not apply to it" in err and "--preload" in err
    bad = tmp_path / "bad.toml"
    bad.write_text('kind = "teleop"\nduration_s = 1.0\n[master]\nq0 = [0, 1]\n')
    assert main(["teleop", str(bad), "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "[master] q0 = [0, 1] must be a list of 6 numbers" in err[0]


def test_run_runs_a_teleop_scenario_as_the_teleop_alias_does(tmp_path, capsys):
    """'quatform run' runs every kind; 'quatform teleop' is the same run."""
    f = tmp_path / "short.toml"
    f.write_text(SHORT)
    runs = {}
    for command in ("run", "teleop"):
        out = tmp_path / command
        assert main([command, str(f), "--out", str(out), "--orientation-error", "rpy", "--preload", "off",
                     "--no-plots"]) == 0
        runs[command] = json.loads((out / "metrics.json").read_text())
        assert (out / "timeseries.csv").read_text() == (tmp_path / "run" / "timeseries.csv").read_text()
    a, b = ({k: v for k, v in m.items() if k != "wall_time_s"} for m in runs.values())
    assert a == b and a["orientation_error"] == "rpy" and a["preload"] is False
    with pytest.raises(SystemExit) as exc:  # the alias takes the teleop kind's options only
        main(["teleop", str(f), "--controller", "quaternion", "--out", str(tmp_path / "x")])
    assert exc.value.code == 2 and "unrecognized arguments: --controller" in capsys.readouterr().err


# -- bad files: one line ------------------------------------------------------

@pytest.mark.parametrize("body, names", [
    ("virtual_walls = [5]\n", "virtual_walls"),
    ("[wall]\npoint = [0.49, 0.0, 0.5]\nnormal = [-1.0, 0.0, 0.0]\nstiffness = 1e10\n", "[wall] stiffness"),
    ("dt_s = 1e-300\n", "duration_s / dt_s"),
    ("[controller]\ngains_master = { kp_pos = nan }\n", "kp_pos = nan"),
])
def test_the_cli_answers_bad_teleop_files_with_one_line(tmp_path, capsys, body, names):
    from quatform.cli import main

    f = tmp_path / "bad.toml"
    f.write_text('kind = "teleop"\nduration_s = 1.0\n' + body)
    assert main(["teleop", str(f), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and names in err[0] and "Traceback" not in err[0]
