"""``quatform plan`` and ``quatform run --reference``: files, metrics, warnings, one-line errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from quatform import cli
from quatform.planning import load_plan

PNG = b"\x89PNG\r\n\x1a\n"
METRIC_KEYS = ("converged", "solve_time_s", "min_separation_m", "max_straight_line_deviation_m",
               "max_rigid_deviation_m", "robots_meet", "alpha")


def test_help_of_the_new_commands(capsys):
    for argv in (["plan", "--help"], ["plans", "--help"], ["run", "--help"]):
        with pytest.raises(SystemExit) as e:
            cli.main(argv)
        assert e.value.code == 0
        text = capsys.readouterr().out
        assert "usage: quatform" in text
    assert "--reference" in text
    assert cli.main(["plans"]) == 0
    out = capsys.readouterr().out
    for name in ("belta-kumar-2002-two-bodies", "belta-kumar-2002-three-bodies", "vertical-pass-two-bodies"):
        assert name in out


def test_plan_writes_plan_metrics_and_plots(tmp_path, capsys):
    out = tmp_path / "three"
    assert cli.main(["plan", "belta-kumar-2002-three-bodies", "--out", str(out), "--alpha", "0.99"]) == 0
    m = json.loads((out / "metrics.json").read_text())
    for key in METRIC_KEYS:
        assert key in m, key
    assert m["converged"] and m["alpha"] == 0.99 and not m["robots_meet"]
    assert m["max_rigid_deviation_m"] < 0.01 * 3.0  # within 1 % of the travel (Fig. 4, alpha = 0.99)
    plan = load_plan(out / "plan.npz")
    assert plan.positions.shape == (201, 3, 2) and plan.info["alpha"] == 0.99
    for f in ("plan_paths.png", "plan_separation.png"):
        assert (out / f).read_bytes()[:8] == PNG
    assert "converged = True" in capsys.readouterr().out


def test_seed_panels_and_alpha_below_the_geodesic_bound(tmp_path, capsys):
    """alpha = 0.2 (seed Fig. 3): no smooth geodesic (bound 0.36); the plan is the minimiser
    through the robots' meeting, and the user is told they meet."""
    out = tmp_path / "fig3"
    rc = cli.main(["plan", "belta-kumar-2002-two-bodies", "--out", str(out), "--alpha", "0.5",
                   "--alpha", "0.2", "--no-plots"])
    captured = capsys.readouterr()
    assert rc == 0
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("quatform: warning: robots 1 and 2 come within 0 m")
    ok = json.loads((out / "alpha-0.5" / "metrics.json").read_text())
    low = json.loads((out / "alpha-0.2" / "metrics.json").read_text())
    assert ok["converged"] and ok["max_straight_line_deviation_m"] < 1e-9 and not ok["through_meeting"]
    assert low["through_meeting"] and low["robots_meet"] and low["min_separation_m"] < 1e-9
    assert low["geodesic_bound_alpha"] == pytest.approx(0.36)
    plan = load_plan(out / "alpha-0.2" / "plan.npz")
    np.testing.assert_allclose(plan.positions[[0, -1]], [[[1.0, 0.0], [-0.5, 0.0]], [
        [2.2928932188134525, -0.7071067811865476], [3.3535533905932737, 0.3535533905932738]]], atol=1e-12)


def test_close_robots_are_flagged(tmp_path, capsys):
    spec = tmp_path / "close.toml"
    spec.write_text(
        'kind = "shaped-geodesic"\nname = "close"\nmin_clearance_m = 0.3\n'
        "[robots]\nmasses = [1.0, 2.0]\nstart = [[1.0, 0.0], [-0.5, 0.0]]\n"
        "goal = [[2.2928932188134525, -0.7071067811865476], [3.3535533905932737, 0.3535533905932738]]\n"
        "[shaping]\nalpha = 0.4\n")
    assert cli.main(["plan", str(spec), "--out", str(tmp_path / "o"), "--no-plots"]) == 0
    m = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert m["robots_meet"] and m["min_separation_m"] < 0.3
    assert "warning: robots 1 and 2 come within" in capsys.readouterr().err


@pytest.mark.parametrize("argv,needle", [
    (["plan", "no-such-plan", "--out", "X"], "unknown plan spec"),
    (["plan", "belta-kumar-2002-two-bodies", "--out", "X", "--alpha", "1.5"], "[shaping] alpha = 1.5 must be < 1"),
    (["run", "mas-kitts-yaw-step", "--controller", "quaternion", "--reference", "REF", "--out", "X"],
     "not a readable quatform plan"),
])
def test_errors_are_one_line(tmp_path, capsys, argv, needle):
    argv = [str(tmp_path / a) if a in ("X", "REF") else a for a in argv]
    (tmp_path / "REF").write_text("junk")
    assert cli.main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("quatform: error:") and needle in err[0]


ROBOTS = "[robots]\nmasses = [1, 1]\nstart = [[0, 0], [1, 0]]\ngoal = [[0, 1], [1, 1]]\n"


@pytest.mark.parametrize("text,needle", [
    ('kind = "straight"\n' + ROBOTS, "kind = 'straight' is not one of rigid-se3, shaped-geodesic"),
    ('kind = "rigid-se3"\n' + ROBOTS, "exactly one of [airplanes]"),
    ('kind = "shaped-geodesic"\n[shaping]\nalpha = 0.7\n', "missing table [robots]"),
    ('kind = "shaped-geodesic"\nalpah = 0.7\n' + ROBOTS, "unknown key 'alpah' at top level"),
    ('kind = "shaped-geodesic"\n[shaping]\nalpha = 0.7\n' + ROBOTS.replace("[[0, 1], [1, 1]]", "[[0, 1]]"),
     "[robots] goal = [[0, 1]] must be a list of N = 2 positions"),
    ('kind = "shaped-geodesic"\n' + ROBOTS, "missing key [shaping] alpha"),
])
def test_bad_spec_is_one_line(tmp_path, capsys, text, needle):
    spec = tmp_path / "k.toml"
    spec.write_text(text)
    assert cli.main(["plan", str(spec), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0]


def test_a_planar_plan_is_refused_as_a_pair_reference(tmp_path, capsys):
    cli.main(["plan", "belta-kumar-2002-two-bodies", "--out", str(tmp_path / "p"), "--no-plots"])
    rc = cli.main(["run", "mas-kitts-yaw-step", "--controller", "quaternion", "--reference",
                   str(tmp_path / "p" / "plan.npz"), "--out", str(tmp_path / "r")])
    assert rc == 2 and "2 robots in space (d = 3)" in capsys.readouterr().err


def test_quaternion_tracks_the_vertical_pass_that_cluster_space_cannot(tmp_path, capsys):
    assert cli.main(["plan", "vertical-pass-two-bodies", "--out", str(tmp_path / "p"), "--no-plots"]) == 0
    ref = str(tmp_path / "p" / "plan.npz")
    rows = {}
    for c in ("quaternion", "dual-quaternion", "cluster-space"):
        assert cli.main(["run", "mas-kitts-yaw-step", "--controller", c, "--reference", ref,
                         "--out", str(tmp_path / c), "--no-plots"]) == 0
        rows[c] = json.loads((tmp_path / c / "metrics.json").read_text())
    for c in ("quaternion", "dual-quaternion"):
        m = rows[c]
        assert not m["reference_lost"] and not m["singularity_detected"] and m["nonfinite_commands"] == 0
        assert m["max_robot_position_error_m"] < 1e-3 and m["duration_s"] == pytest.approx(20.0)
    cs = rows["cluster-space"]
    assert cs["singularity_detected"] and cs["reference_lost"]
    assert 12.0 < cs["first_singular_time_s"] < 13.2  # as the pair nears the vertical (t = 13.2 s)
    # the run followed the plan: the reference's separation dips as planned (0.924 m at t = 10 s)
    with open(tmp_path / "quaternion" / "timeseries.csv") as f:
        names = f.readline().strip().split(",")
        data = np.loadtxt(f, delimiter=",")
    d_c = data[:, names.index("euclid_d_c_des")]
    assert d_c.min() == pytest.approx(0.5 * 0.9238795, abs=1e-4)
    gamma = data[:, names.index("euclid_gamma_c_des")]
    assert gamma.max() == pytest.approx(3 * np.pi / 4, abs=1e-6)


@pytest.mark.parametrize("case", ["holonomic", "a", "b"])
def test_airplanes_spec_writes_the_seed_004_metrics(tmp_path, capsys, case):
    """quatform plan belta-kumar-2001-airplanes --case C: distances kept, the airplanes'
    constraint met at both ends, the energy the §4 closed forms give (derivations)."""
    out = tmp_path / case
    assert cli.main(["plan", "belta-kumar-2001-airplanes", "--case", case, "--out", str(out)]) == 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["converged"] and m["kind"] == "rigid-se3" and m["case"] == case
    assert m["max_distance_change_m"] < 1e-9 and m["max_nonholonomic_violation"] < 1e-9
    assert m["energy"] == pytest.approx({"holonomic": 2105.0, "a": 2326.0, "b": 2409.3333}[case], rel=1e-3)
    plan = load_plan(out / "plan.npz")
    assert plan.orientations.shape == (201, 5, 4) and plan.info["case"] == case
    # the saved knots reproduce the constant formation at any time between them
    pos, vel, _ = plan.sample(np.linspace(0.0, 1.0, 37))
    d = np.linalg.norm(pos[:, :, None] - pos[:, None], axis=-1)
    np.testing.assert_allclose(d, np.broadcast_to(d[0], d.shape), atol=1e-6)
    q = plan.orientations_at(np.array([0.0, 1.0]))
    np.testing.assert_allclose(np.abs(np.sum(q * plan.orientations[[0, -1]], axis=-1)), 1.0, atol=1e-12)
    assert (out / "formation_3d.png").stat().st_size > 20_000
    assert "max_nonholonomic_violation" in capsys.readouterr().out


def test_case_needs_an_airplanes_spec(tmp_path, capsys):
    assert cli.main(["plan", "belta-kumar-2002-two-bodies", "--case", "a", "--out", str(tmp_path)]) == 2
    assert "[airplanes]" in capsys.readouterr().err
    bad = tmp_path / "bad.toml"
    bad.write_text('kind = "rigid-se3"\n[airplanes]\ncase = "c"\n')
    assert cli.main(["plan", str(bad), "--out", str(tmp_path / "x")]) == 2
    assert "case" in capsys.readouterr().err


def test_rigid_spec_inputs_and_plan_files_are_checked(tmp_path, capsys):
    assert cli.main(["plan", "belta-kumar-2001-airplanes", "--case", "a", "--alpha", "0.5",
                     "--out", str(tmp_path / "x")]) == 2
    assert "do not go together" in capsys.readouterr().err
    f = tmp_path / "f.toml"
    f.write_text('kind = "rigid-se3"\nknots = 2.7\n[airplanes]\ncase = "a"\n')
    assert cli.main(["plan", str(f), "--out", str(tmp_path / "y")]) == 2
    assert "knots = 2.7 must be an integer" in capsys.readouterr().err
    g = tmp_path / "g.toml"
    g.write_text('kind = "rigid-se3"\n[formation]\nmasses = [1, 1, 1]\nduration = 3.0\n'
                 'body_points = [[1, 0, 0], [-0.5, 0.8, 0], [-0.5, -0.8, 0]]\n'
                 'inertias = [[1, 1, 1], [1, 1, 1], [1, 1, 1]]\n'
                 'start = { position = [0, 0, 0], orientation = [1, 0, 0, 0] }\n'
                 'end = { position = [1, 0, 0], orientation = [1, 0, 0, 0] }\n')
    assert cli.main(["plan", str(g), "--out", str(tmp_path / "z")]) == 2
    assert "duration_s and knots" in capsys.readouterr().err
    bad = tmp_path / "truncated.npz"
    bad.write_bytes(b"PK\x03\x04 not a zip")
    with pytest.raises(cli.QuatformError):
        load_plan(bad)


def test_rigid_plan_metrics_and_orientations_between_knots(tmp_path):
    from quatform.algebra import q_angle_between
    from quatform.planning import airplanes_plan

    out = tmp_path / "b"
    assert cli.main(["plan", "belta-kumar-2001-airplanes", "--out", str(out), "--no-plots"]) == 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["max_rigid_deviation_m"] is None  # the SE(2)-style reference does not apply
    plan = load_plan(out / "plan.npz")
    t = 0.5 * (plan.times[:-1] + plan.times[1:])  # mid-knot: slerp against the exact plan
    exact = airplanes_plan("b").sample(t).orientations
    assert q_angle_between(plan.orientations_at(t), exact).max() < 1e-3
