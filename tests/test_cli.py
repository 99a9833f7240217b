"""The quatform command: --help, --version, demo, one-line errors."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

import quatform
from quatform import cli


def test_version_and_help(capsys):
    with pytest.raises(SystemExit) as e:
        cli.main(["--version"])
    assert e.value.code == 0
    assert capsys.readouterr().out.strip() == f"quatform {quatform.__version__}"
    for argv in (["--help"], ["demo", "--help"]):
        with pytest.raises(SystemExit) as e:
            cli.main(argv)
        assert e.value.code == 0
        assert "usage: quatform" in capsys.readouterr().out


def test_demo_writes_summary_and_plot(tmp_path, capsys):
    assert cli.main(["demo", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "Cluster frame" in out
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["cluster_frame"]["decoupled"]["distance_to_midpoint_m"] < 1e-12
    assert summary["cluster_frame"]["screw"]["distance_to_midpoint_m"] > 0.1
    rows = summary["rate_conditioning"]
    assert rows[-1]["euler_rate_gain"] == float("inf")
    assert all(abs(r["quaternion_rate_gain_max"] - 0.5) < 1e-12 for r in rows)
    assert summary["integrator_drift"]["exp"]["angle_error_rad"] < 1e-10
    png = (tmp_path / "demo.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000


def test_console_script_error_is_one_line(tmp_path):
    # a file where the output directory should go: the error is reported, not a traceback
    blocker = tmp_path / "file"
    blocker.write_text("x")
    proc = subprocess.run(
        [sys.executable, "-m", "quatform.cli", "demo", "--out", str(blocker / "sub")],
        capture_output=True, text=True,
    )
    assert proc.returncode != 0
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("quatform: error:")
