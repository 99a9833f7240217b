"""``quatform run / compare / teleop --compute jax``: the closed loop compiled with JAX from the
command line, its files equal to NumPy's within 1e-9."""

from __future__ import annotations

import json

import numpy as np
import pytest

from quatform import cli
from quatform.scenarios import builtin_scenarios

pytest.importorskip("jax")

TOL = 1e-9


def _metrics_equal(a: dict, b: dict) -> None:
    assert set(a) | {"compute_backend"} == set(b) | {"compute_backend"}
    for k, v in a.items():
        if k in ("wall_time_s", "compute_backend"):
            continue
        if isinstance(v, float):
            assert b[k] == pytest.approx(v, rel=TOL, abs=TOL, nan_ok=True), k
        else:
            assert b[k] == v, k


def _run(tmp_path, name, *argv):
    out = tmp_path / name
    assert cli.main([*argv, "--out", str(out), "--no-plots", "--no-mcap"]) == 0
    return out


def test_run_on_jax_writes_numpys_files(tmp_path, capsys):
    base = ("run", "mas-kitts-yaw-step", "--controller", "dual-quaternion")
    a, b = _run(tmp_path, "np", *base), _run(tmp_path, "jax", *base, "--compute", "jax")
    ma, mb = (json.loads((d / "metrics.json").read_text()) for d in (a, b))
    assert "compute_backend" not in ma and mb["compute_backend"] == "jax"
    _metrics_equal(ma, mb)
    ha, hb = ((d / "timeseries.csv").read_text().splitlines()[0] for d in (a, b))
    assert ha == hb  # the same columns
    ta, tb = (np.loadtxt(d / "timeseries.csv", delimiter=",", skiprows=1) for d in (a, b))
    np.testing.assert_allclose(tb, ta, rtol=0, atol=TOL)


def test_compare_and_teleop_take_compute(tmp_path, capsys):
    toml = tmp_path / "short.toml"  # teleop-free-motion in 0.4 s: the hand moves from 0.3 s to 0.4 s
    text = builtin_scenarios()["teleop-free-motion"].read_text(encoding="utf-8")
    short = text.replace("duration_s = 4.0", "duration_s = 0.4").replace("{ t_s = 1.8,", "{ t_s = 0.4,")
    assert short != text
    toml.write_text(short, encoding="utf-8")
    rows = {}
    for compute in ("numpy", "jax"):
        out = _run(tmp_path, f"t-{compute}", "compare", str(toml), "--compute", compute)
        rows[compute] = json.loads((out / "comparison.json").read_text())
    assert [r["orientation_error"] for r in rows["jax"]] == [r["orientation_error"] for r in rows["numpy"]]
    for ra, rb in zip(rows["numpy"], rows["jax"]):
        _metrics_equal(ra, rb)
    _run(tmp_path, "tele", "teleop", str(toml), "--compute", "jax")


def test_compute_refusals_are_one_line(tmp_path, capsys):
    pytest.importorskip("mujoco")
    code = cli.main(["run", "mas-kitts-yaw-step", "--controller", "quaternion", "--physics", "mujoco",
                     "--compute", "jax", "--out", str(tmp_path / "mj")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in err and "numpy" in err
    assert not (tmp_path / "mj").exists()
    with pytest.raises(SystemExit) as exc:
        cli.main(["run", "mas-kitts-yaw-step", "--compute", "gpu", "--out", str(tmp_path / "x")])
    assert exc.value.code == 2
    assert "--compute" in capsys.readouterr().err


@pytest.mark.parametrize("argv", [
    ["compare", "mas-kitts-yaw-step", "--over", "physics", "--controller", "quaternion"],
    ["run", "team-tetrahedron-helix", "--controller", "quaternion", "--physics", "mujoco"],
    ["run", "marciano-circle", "--physics", "mujoco"],
])
def test_mujoco_physics_on_jax_is_refused_before_any_run(argv, tmp_path, capsys):
    """MuJoCo physics runs on NumPy: ``--physics mujoco`` (or a compare over physics) with
    ``--compute jax`` is one line naming both flags, before any run starts (a compare does not
    run its kinematic choice first)."""
    code = cli.main([*argv, "--compute", "jax", "--no-plots", "--no-mcap", "--out", str(tmp_path / "o")])
    out = capsys.readouterr()
    err = out.err.strip()
    assert code == 2 and "\n" not in err, err
    assert "--physics mujoco runs on NumPy only, not on --compute jax; run it with --compute numpy" in err, err
    assert "done in" not in out.out + out.err and not (tmp_path / "o").exists()
