"""The team scenario kind: motions, loader, runs, metrics, figures, CLI."""

from __future__ import annotations

import dataclasses
from pathlib import Path
import json
import math

import numpy as np
import pytest

from quatform import cli
from quatform.errors import DegenerateInputError, InvalidInputError, ShapeError
from quatform.formations import RobotLayout, TeamChart
from quatform.planning import Plan
from quatform.references.team_motion import (
    Attitude,
    Headings,
    Move,
    OriginPath,
    PlanMotion,
    Scale,
    TeamMotion,
    Turn,
    template_positions,
)
from quatform.runs import compare, run
from quatform.scenarios import KINDS, builtin_scenarios, kind_of, load_scenario
from quatform.scenarios.pair import run_pair
from quatform.scenarios.team import (
    TEAM,
    TeamScenario,
    available_controllers,
    team_scenario_from_dict,
)
from quatform.sim import compute_metrics
from quatform.tomlio import read_toml

TEAM_NAMES = sorted(n for n in builtin_scenarios() if n.startswith("team-"))


def _central(motion, t, h=1e-6):
    _, ed = motion(t)
    ep, _ = motion(t + h)
    em, _ = motion(t - h)
    return ed, (ep - em) / (2 * h)


# --------------------------------------------------------------------------- the motions

@pytest.mark.parametrize("mode", ["formation", "path", "fixed"])
def test_team_motion_rates_are_the_central_differences(mode):
    L = RobotLayout(("xyz_yaw", "xyz_yaw", "xy_yaw", "xyz", "pose", "xyz_yaw"))
    motion = TeamMotion(
        L, template_positions("ring", 6, 1.2),
        OriginPath("lemniscate", center=[0.0, 0.0, 1.0], r_x=1.0, r_y=1.5, omega=0.3),
        Attitude(0.3, 0.2, -0.1, (Turn([0, 1, 0], 2 * np.pi, 1.0, 4.0, "smooth"), Turn([0, 0, 1], 1.0, 0.5, 3.0))),
        Scale("breathing", 1.0, amplitude=0.3, period_s=3.0),
        (Move(2, [0.0, 0.0, 0.5], 1.0, 2.0),), Headings(mode, [0.1]))
    t = np.linspace(0.013, 6.0, 157)  # off the linear turn's corners
    ed, num = _central(motion, t)
    assert np.abs(ed - num).max() < 1e-7
    e, _ = motion(t)
    assert np.allclose(np.linalg.norm(e[:, 3:7], axis=1), 1.0, atol=1e-14)
    chart = TeamChart(L)
    assert np.allclose(e[:, chart.shape_index].sum(axis=1), 0.0, atol=1e-12)  # s_i about the centroid
    r, rd = chart.robots(e), chart.robot_rates(e, ed)
    rp, rm = chart.robots(motion(t + 1e-6)[0]), chart.robots(motion(t - 1e-6)[0])
    assert np.abs((rp - rm) / 2e-6 - rd).max() < 1e-6
    assert np.all(np.isfinite(r))


def test_team_motion_places_the_template_on_the_path():
    L = RobotLayout.uniform("xyz_yaw", 4)
    tmpl = template_positions("tetrahedron", 4, 1.5)
    d = np.linalg.norm(tmpl[:, None] - tmpl[None], axis=-1)[np.triu_indices(4, 1)]
    assert np.allclose(d, 1.5) and np.allclose(tmpl.mean(axis=0), 0.0, atol=1e-15)
    motion = TeamMotion(L, tmpl, OriginPath("line", center=[0, 0, 2.0], velocity=[0, 0.1, 0]),
                        Attitude(turns=(Turn([0, 1, 0], 2 * np.pi, 20.0, 40.0),)))
    e, _ = motion(np.array([0.0, 30.0]))
    P = L.positions(TeamChart(L).robots(e))
    assert np.allclose(P[0], tmpl + [0, 0, 2.0], atol=1e-12)
    # a quarter turn about y at t = 30 s: R_y(pi/2) maps (x, y, z) to (z, y, -x)
    assert np.allclose(P[1], np.stack([tmpl[:, 2], tmpl[:, 1], -tmpl[:, 0]], -1) + [0, 3.0, 2.0], atol=1e-12)


def test_plan_motion_has_exact_robots_and_rates():
    T = np.linspace(0.0, 1.0, 41)
    base = template_positions("triangle", 3, 1.0)[:, :2]
    ang = 0.75 * np.pi * (3 * T ** 2 - 2 * T ** 3)  # a smooth turn, rest to rest
    angd = 0.75 * np.pi * (6 * T - 6 * T ** 2)
    angdd = 0.75 * np.pi * (6 - 12 * T)
    c, s = np.cos(ang), np.sin(ang)
    grow = 1.0 + 0.2 * T  # and a deformation
    R = np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)
    pos = np.einsum("tij,nj->tni", R, base) * grow[:, None, None] + np.stack([3 * T, 0 * T], -1)[:, None]
    h = 1e-6
    num = []
    for dt in (h, -h):
        a = 0.75 * np.pi * (3 * (T + dt) ** 2 - 2 * (T + dt) ** 3)
        Rr = np.stack([np.stack([np.cos(a), -np.sin(a)], -1), np.stack([np.sin(a), np.cos(a)], -1)], -2)
        num.append(np.einsum("tij,nj->tni", Rr, base) * (1 + 0.2 * (T + dt))[:, None, None]
                   + np.stack([3 * (T + dt), 0 * T], -1)[:, None])
    vel = (num[0] - num[1]) / (2 * h)
    del angd, angdd
    plan = Plan(T, pos, vel, np.zeros_like(pos), np.ones(3), {"name": "test"})
    L = RobotLayout.uniform("xy_yaw", 3)
    m = PlanMotion(L, plan, 0.0, 10.0, 0.0)
    t = np.linspace(0.05, 9.95, 120)
    ed, numd = _central(m, t, 1e-5)
    assert np.abs(ed - numd).max() < 1e-6
    e, _ = m(t)
    chart = TeamChart(L)
    p, v = m.positions(t)
    assert np.abs(L.positions(chart.robots(e)) - p).max() < 1e-12
    assert np.abs(L.positions(chart.robot_rates(e, ed)) - v).max() < 1e-9


# --------------------------------------------------------------------------- the built-in files

def test_the_builtin_team_scenarios_load():
    assert {"team-tetrahedron-helix", "team-ring-flip", "team-triangle-over-ugv", "team-grid-100",
            "team-three-bodies"} <= set(TEAM_NAMES)
    for name in TEAM_NAMES:
        sc = load_scenario(name)
        assert isinstance(sc, TeamScenario) and kind_of(sc) is TEAM and KINDS["team"] is TEAM
        assert sc.title and sc.source
    assert load_scenario("team-grid-100").team.layout.n == 100
    assert load_scenario("team-triangle-over-ugv").team.layout.kinds == ("xy_yaw",) + ("xyz_yaw",) * 3


def _short(name, seconds=1.0):
    sc = load_scenario(name)
    return dataclasses.replace(sc, duration_s=seconds, metrics_from_s=0.0)


@pytest.mark.parametrize("name", ["team-tetrahedron-helix", "team-ring-flip", "team-triangle-over-ugv",
                                  "team-grid-100", "team-three-bodies"])
def test_a_short_run_of_each_writes_its_files(name, tmp_path):
    sc = _short(name, 1.0 if name != "team-grid-100" else 0.5)
    plots = name in ("team-tetrahedron-helix", "team-grid-100")
    for k, controller in enumerate(TEAM.compare_choices(sc, "controller")[0]):  # those that can take the team
        out = tmp_path / controller
        plots = plots and k == 0  # the figures once per scenario (the compare test draws every controller's)
        _, m = run(sc, out, controller=controller, quiet=True, plots=plots)
        assert json.loads((out / "metrics.json").read_text())["n_robots"] == sc.team.layout.n
        assert m["nonfinite_commands"] == 0 and m["max_robot_position_error_m"] < 1.0  # a transient at most
        assert m["min_robot_separation_m"] >= sc.safety["min_separation_m"]
        assert m["safety_applied"] and m["safety_active_time_s"] >= 0.0
        header = (out / "timeseries.csv").read_text().splitlines()[0].split(",")
        assert header[:3] == ["t", sc.team.layout.names[0], sc.team.layout.names[0] + "_des"]
        if plots:
            for png in ("paths_3d", "centroid", "attitude", "shape", "robot_errors", "separation", "singularity"):
                assert (out / f"{png}.png").stat().st_size > 1000


def test_compare_runs_every_registered_controller(tmp_path):
    rows = compare(_short("team-ring-flip", 0.6), tmp_path / "cmp", quiet=True)
    assert [r["controller"] for r in rows] == list(available_controllers())
    assert (tmp_path / "cmp" / "comparison.md").is_file()
    assert (tmp_path / "cmp" / "compare_errors.png").stat().st_size > 1000


def test_the_plan_following_scenario_runs_a_saved_plan(tmp_path):
    T = np.linspace(0.0, 1.0, 11)
    start = template_positions("triangle", 3, 1.0)[:, :2]
    pos = start[None] + np.stack([3 * T, 0 * T], -1)[:, None]
    vel = np.broadcast_to([3.0, 0.0], pos.shape).copy()
    Plan(T, pos, vel, np.zeros_like(pos), np.ones(3), {"name": "straight"}).save(tmp_path / "plan.npz")
    log, m = run("team-three-bodies", tmp_path / "r", controller="robot-space", reference=str(tmp_path / "plan.npz"),
                 quiet=True, plots=False)
    assert m["duration_s"] == pytest.approx(20.0) and m["scenario"] == "team-three-bodies+straight"
    assert m["max_robot_position_error_m"] < 1e-3
    assert np.allclose(log["r_des"][-1, [0, 1]], [3.0 + start[0, 0], start[0, 1]], atol=1e-12)


# --------------------------------------------------------------------------- N = 2 is the pair

_PAIR_LIKE = """
kind = "team"
name = "pair-helix"
duration_s = 35.0
dt_s = 0.01
metrics_from_s = 5.0
[[robots]]
model = "holonomic"
count = 2
max_speed_m_s = 3.0
max_yaw_rate_rad_s = 4.0
[shape]
template = "positions"
positions = [[0.5, 0.0, 0.0], [-0.5, 0.0, 0.0]]
[path]
kind = "line"
center = [0.0, 0.0, 2.0]
velocity = [0.0, 0.1, 0.0]
[[attitude.turns]]
axis = [0.0, -1.0, 0.0]
angle = 6.283185307179586
start_s = 20.0
duration_s = 40.0
[headings]
mode = "fixed"
offsets = -1.5707963267948966
[gains]
base = "table2"
[gains.robot-space]
k_p = [0.06, 0.06, 0.03]
k_theta = 0.02
[safety]
enabled = false
"""


def test_a_two_robot_team_gives_the_pair_metrics(tmp_path):
    """mas-kitts-helix (to t = 35 s, through the vertical) as a two-robot team: seed 000's
    robot-space controller on the same robots and gains, measured by both kinds' metrics."""
    f = tmp_path / "pair-helix.toml"
    f.write_text(_PAIR_LIKE)
    team_sc = load_scenario(f)
    pair_sc = dataclasses.replace(load_scenario("mas-kitts-helix"), duration_s=35.0,
                                  gains={**load_scenario("mas-kitts-helix").gains,
                                         "robot-space": {"k": [0.06, 0.06, 0.03, 0.02] * 2}})
    pair = compute_metrics(run_pair(pair_sc, "robot-space"))
    ex = TEAM.experiment(team_sc, controller="robot-space")
    log = ex.run()
    assert np.abs(log["r_des"] - run_pair(pair_sc, "robot-space")["r_des"]).max() < 1e-12
    team = ex.metrics(log)
    for key in ("max_cluster_position_error_m", "max_shape_error_m", "max_orientation_error_rad",
                "max_robot_position_error_m", "max_robot_yaw_error_rad", "min_robot_separation_m",
                "max_command_speed_m_s", "min_singularity_measure"):
        assert team[key] == pytest.approx(pair[key], abs=1e-9), key
    for key in ("reference_lost", "nonfinite_commands", "singularity_detected", "first_singular_time_s"):
        assert team[key] == pair[key], key
    assert pair["max_orientation_error_rad"] > 1e-4  # the comparison means something


# --------------------------------------------------------------------------- bad input

def _data(**changes):
    data, _ = read_toml("team-ring-flip", builtin_scenarios(), "scenario")
    data = json.loads(json.dumps(data))
    for path, value in changes.items():
        d = data
        keys = path.split(".")
        for k in keys[:-1]:
            d = d[int(k)] if isinstance(d, list) else d.setdefault(k, {})
        if value is None:
            del d[keys[-1]]
        else:
            d[keys[-1]] = value
    return data


@pytest.mark.parametrize("changes, exc, words", [
    ({"duraton_s": 3.0}, InvalidInputError, "did you mean 'duration_s'"),
    ({"shape.radus": 1.0}, InvalidInputError, "did you mean 'radius'"),
    ({"robots.0.model": "quadrotr"}, InvalidInputError, "did you mean 'quadrotor'"),
    ({"robots.0.count": 0}, InvalidInputError, "count = 0 must be >= 1"),
    ({"robots.0.max_v_m_s": 1.0}, InvalidInputError, "unknown key 'max_v_m_s'"),
    ({"shape.template": "tetrahedron", "shape.radius": None}, ShapeError, "tetrahedron template holds 4 robots"),
    ({"shape.template": "positions", "shape.radius": None, "shape.positions": [[0, 0, 0]] * 2}, InvalidInputError,
     "must list 10 positions"),
    ({"shape.template": "positions", "shape.radius": None,
      "shape.positions": [[0, 0, 0]] * 2 + [[k, 1.0, 0.0] for k in range(8)]}, DegenerateInputError,
     "robots 1 and 2 coincide"),
    ({"shape.radius": 0.2}, InvalidInputError, "below [safety] min_separation_m"),
    ({"shape.scale.amplitude": 1.0}, InvalidInputError, "amplitude = 1.0 must be < 1"),
    ({"path.radius": 2.0}, InvalidInputError, "applies to kind = 'spiral' only"),
    ({"dt_s": 0.2}, InvalidInputError, "would be unstable"),
    ({"gains": {"quaternion": {"k_w": -1.0}}}, InvalidInputError, "must be positive"),
    ({"attitude.turns.0.axis": [0.0, 0.0, 0.0]}, InvalidInputError, "nonzero vector"),
    ({"headings.offsets": [0.0, 1.0]}, InvalidInputError, "give one number or 10"),
    ({"duration_s": 1e9, "dt_s": 1e-6}, Exception, "steps"),
])
def test_bad_input_is_one_line(changes, exc, words):
    with pytest.raises(exc) as info:
        team_scenario_from_dict(_data(**changes), "bad.toml")
    msg = str(info.value)
    assert "\n" not in msg and words in msg and msg.startswith("bad.toml")


def test_a_path_heading_needs_a_moving_path():
    with pytest.raises(InvalidInputError, match="does not move"):
        team_scenario_from_dict(_data(**{"headings.mode": "path"}), "bad.toml")


def test_a_controller_is_required_and_checked():
    sc = _short("team-ring-flip")
    with pytest.raises(InvalidInputError, match="give a controller"):
        TEAM.experiment(sc)
    with pytest.raises(InvalidInputError, match="unknown team controller 'robot-spce'.*did you mean"):
        TEAM.experiment(sc, controller="robot-spce")


# --------------------------------------------------------------------------- the CLI

def test_cli_run_help_and_a_tiny_run(tmp_path, capsys):
    with pytest.raises(SystemExit) as info:
        cli.main(["run", "team-tetrahedron-helix", "--help"])
    assert info.value.code == 0 and "--controller" in capsys.readouterr().out
    data = _data(duration_s=5.5, metrics_from_s=0.0, dt_s=0.05)
    text = "\n".join(_toml_lines(data))
    f = tmp_path / "tiny.toml"
    f.write_text(text)
    assert cli.main(["run", str(f), "--controller", "robot-space", "--out", str(tmp_path / "o"), "--no-plots"]) == 0
    out = capsys.readouterr().out
    assert "| robot-space | 10 |" in out
    assert json.loads((tmp_path / "o" / "metrics.json").read_text())["duration_s"] == pytest.approx(5.5)
    assert cli.main(["run", str(f), "--formation", "quaternion", "--out", str(tmp_path / "p")]) == 2
    assert "is a team scenario: --formation does not apply" in capsys.readouterr().err


def test_cli_min_separation_overrides_the_files_safety(tmp_path, capsys):
    """``--min-separation X`` on a team run: X m instead of ``[safety] min_separation_m`` (0.4
    in the file), 0 turns the barrier off; a bad value or one the reference breaks is one line."""
    f = tmp_path / "tiny.toml"
    f.write_text("\n".join(_toml_lines(_data(duration_s=5.5, metrics_from_s=0.0, dt_s=0.05))))
    base = ["run", str(f), "--controller", "robot-space", "--no-plots", "--no-mcap"]
    for value, on, d in (("0.45", True, 0.45), ("0", False, 0.4)):
        out = tmp_path / f"o{value}"
        assert cli.main([*base, "--out", str(out), "--min-separation", value]) == 0
        m = json.loads((out / "metrics.json").read_text())
        assert (m["safety_applied"], m["safety_min_separation_m"]) == (on, d)
        assert ("safety_active_time_s" in m) == on
    capsys.readouterr()
    for value, words in (("-1", "min_separation = -1.0 must be a finite number of m >= 0"),
                         ("nan", "min_separation = nan must be"),
                         ("50", "below min_separation = 50 m (the barrier would hold them apart)")):
        assert cli.main([*base, "--out", str(tmp_path / "bad"), f"--min-separation={value}"]) == 2
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and words in err, err
    assert not (tmp_path / "bad").exists()


def _toml_lines(data, prefix=""):
    """A tiny TOML writer for the test's tables (numbers, strings, booleans, lists, tables)."""
    def val(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, list):
            return "[" + ", ".join(val(x) for x in v) + "]"
        return repr(float(v)) if isinstance(v, float) else str(v)

    plain = {k: v for k, v in data.items() if not isinstance(v, dict) and not
             (isinstance(v, list) and v and isinstance(v[0], dict))}
    lines = [f"{k} = {val(v)}" for k, v in plain.items()]
    for k, v in data.items():
        name = f"{prefix}{k}"
        if isinstance(v, dict):
            lines += [f"[{name}]", *_toml_lines(v, name + ".")]
        elif isinstance(v, list) and v and isinstance(v[0], dict):
            for item in v:
                lines += [f"[[{name}]]", *_toml_lines(item, name + ".")]
    return lines


def test_the_motion_refuses_bad_values():
    L = RobotLayout.uniform("xyz_yaw", 3)
    with pytest.raises(ShapeError, match="template has shape"):
        TeamMotion(L, np.zeros((4, 3)))
    with pytest.raises(DegenerateInputError, match="during a move"):
        TeamMotion(L, template_positions("triangle", 3), moves=(Move(0, template_positions("triangle", 3)[1] * 1.0,
                                                                      1.0, 1.0),))
    with pytest.raises(InvalidInputError, match="nonzero vector"):
        Turn([0, 0, 0], 1.0, 0.0, 1.0)
    assert math.isfinite(Scale("ramp", 1.0, 2.0, 0.0, 1.0)(0.5)[0])


def test_a_team_flies_on_mujoco_physics(tmp_path):
    pytest.importorskip("mujoco")
    _, m = run(_short("team-tetrahedron-helix", 0.4), tmp_path / "mj", controller="robot-space", physics="mujoco",
                 quiet=True, plots=False)
    assert m["physics"] == "mujoco" and m["collisions"]["count"] == 0
    assert m["max_robot_position_error_m"] < 0.05 and m["nonfinite_commands"] == 0


def test_compare_leaves_out_a_description_that_cannot_take_the_team(tmp_path):
    text = (Path(__file__).parents[1] / "src/quatform/scenarios/team-triangle-over-ugv.toml").read_text()
    text = text.replace('model = "pioneer"\ncount = 1', 'model = "pioneer"\ncount = 2')
    text = text.replace("[[0.0, 0.0, 0.0],", "[[0.0, 0.0, 0.0], [-1.5, 0.0, 0.0],")
    text = text.replace("start_s = 60.0", "start_s = 0.1").replace("duration_s = 15.0", "duration_s = 0.2")
    text = text.replace("metrics_from_s = 5.0", "metrics_from_s = 0.0").replace("robot = 2", "robot = 3")
    (tmp_path / "two-ugvs.toml").write_text(text.replace("duration_s = 120.0", "duration_s = 0.4"))
    sc = load_scenario(tmp_path / "two-ugvs.toml")  # two Pioneers (planar) and three 4-DOF UAVs
    values, skipped = TEAM.compare_choices(sc, "controller")
    assert "cluster-space" in skipped and "cluster-space" not in values and "quaternion" in values
    assert "mixes 2 planar" in skipped["cluster-space"] and "\n" not in skipped["cluster-space"]
    rows = compare(sc, tmp_path / "cmp", quiet=True, plots=False)
    assert [r["controller"] for r in rows] == list(values)
    assert "Not run: cluster-space" in (tmp_path / "cmp" / "comparison.md").read_text()


def test_the_singular_threshold_is_the_pairs_for_two_robots_and_scales_with_the_team():
    """A flat ring of 10 read 0.0135 under the Euclidean team away from any singular pose, below
    the pair's 0.02, so every run would read 'singular from t = 0' with the pair's threshold."""
    from quatform.sim.metrics import SINGULAR_THRESHOLD, singular_threshold

    assert singular_threshold(2) == SINGULAR_THRESHOLD
    assert singular_threshold(10) < 0.0135 and singular_threshold(100) < singular_threshold(10)


def test_the_seed_000_comparison_holds_for_the_tetrahedron():
    """Seed 000 §4's story for four robots, 34 s of the tetrahedron helix (the pitch passes the
    vertical at 30 s): the Euclidean baseline meets its singular pose and loses the formation,
    robot space tracks the robots but reads the formation folded, the quaternion and
    dual-quaternion teams track every variable and read it continuously."""
    sc = dataclasses.replace(load_scenario("team-tetrahedron-helix"), duration_s=34.0)
    m = {}
    for c in ("cluster-space", "robot-space", "quaternion", "dual-quaternion"):
        experiment = TEAM.experiment(sc, controller=c)
        m[c] = experiment.metrics(experiment.run())
    assert m["cluster-space"]["singularity_detected"] and m["cluster-space"]["reference_lost"]
    assert 28.0 <= m["cluster-space"]["first_singular_time_s"] <= 30.5
    rs = m["robot-space"]
    assert not rs["reference_lost"] and rs["max_robot_position_error_m"] < 0.01
    assert rs["max_reading_error_rad"] > 3.0 and rs["reading_folded_time_s"] > 3.0  # folded past 30 s
    for c in ("quaternion", "dual-quaternion"):
        assert not m[c]["singularity_detected"] and not m[c]["reference_lost"]
        assert m[c]["max_reading_error_rad"] < 0.01 and m[c]["reading_folded_time_s"] == 0.0


def test_min_separation_at_a_shapes_exact_edge_is_kept():
    """A barrier minimum equal to the shape's shortest edge (the tetrahedron's 1.5 m, its points
    built by trigonometry a few ulps short of it) is kept, as the barrier keeps such a start;
    one a centimetre above the edge is refused in one line naming the robots."""
    kind = KINDS["team"]
    sc = load_scenario("team-tetrahedron-helix")
    assert kind.experiment(sc, "quaternion", min_separation=1.5) is not None
    with pytest.raises(InvalidInputError, match="below min_separation = 1.51 m"):
        kind.experiment(sc, "quaternion", min_separation=1.51)


def test_compare_over_physics_leaves_out_mujoco_where_it_cannot_fly_the_team():
    """A compare over physics of a team with robots MuJoCo cannot simulate (team-three-bodies'
    planar robots) runs the kinematic models and names why MuJoCo is left out, instead of
    failing after its kinematic run; a team of quadrotors runs both."""
    kind = KINDS["team"]
    run, skipped = kind.compare_choices(load_scenario("team-three-bodies"), "physics")
    assert run == ("kinematic",) and list(skipped) == ["mujoco"]
    assert "robot 1 is a PlanarHolonomicRobot" in skipped["mujoco"] and "\n" not in skipped["mujoco"]
    assert kind.compare_choices(load_scenario("team-tetrahedron-helix"), "physics") == (("kinematic", "mujoco"), {})


def test_a_batch_of_worlds_finishes_each_as_its_own_run():
    """Guards against: ``Experiment.run`` of a batch of team worlds failing in the finish (the
    chart read on one world's shapes): each world's finished channels are its run alone's."""
    sc = dataclasses.replace(load_scenario("team-three-bodies"), duration_s=2.0)
    exp = KINDS["team"].experiment(sc, controller="quaternion")
    x0 = np.stack([exp.x0, exp.x0 + 1e-3])
    batch = dataclasses.replace(exp, x0=x0).run()
    for i in range(2):
        one = dataclasses.replace(exp, x0=x0[i]).run()
        for name in ("e", "points", "singularity"):
            assert np.allclose(batch[name][:, i], one[name], rtol=0, atol=1e-9, equal_nan=True), name


@pytest.mark.parametrize("value, words", [
    ([1.0, 2.0], "must be one number or a list of 3"),
    (-2.0, "must be positive (seed 000 Tables 1-2)"),
    ([1.0, "a", 1.0], "must be numbers: a positive gain in 1/s, e.g. 2.0 (seed 000 Tables 1-2)"),
    ([1.0, math.nan, 1.0], "must be finite: a positive gain in 1/s, e.g. 2.0 (seed 000 Tables 1-2)"),
    ([1.0], "must be one number or a list of 3"),
    ([1.0, True, 1.0], "must be numbers: a positive gain in 1/s, e.g. 2.0 (seed 000 Tables 1-2)"),
    (1e13, "is beyond +-1e+12; give a physical gain (1/s)"),
])
def test_a_gain_has_one_check_in_the_file_and_the_controller(value, words):
    """The gain schema (control.TEAM_GAIN_KEYS) is checked once, by control.team.check_gain:
    a file's error names the file, the table and the key, the controller's its gain; the
    same words follow."""
    from quatform.checks import short
    from quatform.control import team_controller
    from quatform.robots import HolonomicRobot, Team

    with pytest.raises(InvalidInputError) as in_file:
        team_scenario_from_dict(_data(**{"gains": {"quaternion": {"k_x": value}}}), "bad.toml")
    assert str(in_file.value) == f"bad.toml: [gains.quaternion] k_x = {short(value)} {words}"
    gains = {"k_x": value, "k_d": 1.0, "k_w": 1.0}
    with pytest.raises(InvalidInputError) as in_code:
        team_controller("quaternion", Team.uniform(HolonomicRobot(), 3), gains)
    assert str(in_code.value) == f"team controller: gains['k_x'] = {short(value)} {words}"


def test_a_one_number_gain_is_no_list():
    """``k_d`` (the shape law's one gain, seed 000 Table 1) is one number: a list is refused."""
    with pytest.raises(InvalidInputError, match=r"^bad.toml: \[gains.quaternion\] k_d = \[20.0\] must be one number$"):
        team_scenario_from_dict(_data(**{"gains": {"quaternion": {"k_d": [20.0]}}}), "bad.toml")
