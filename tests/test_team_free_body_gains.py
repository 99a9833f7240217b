"""A free-body team under the robot-space controller: seed 000's robot-space gains (K_RS of
Tables 1 and 2) give no orientation gain, so the choice is refused before the run, naming the
controller, the robots and the reason, unless [gains.robot-space] gives k_w."""

from __future__ import annotations

import pytest

from quatform import cli
from quatform.errors import InvalidInputError
from quatform.scenarios.team import team_scenario_from_dict


def _free_team(gains):
    return {"kind": "team", "name": "free-team", "duration_s": 2.0, "dt_s": 0.02, "metrics_from_s": 0.0,
            "gains": gains, "robots": [{"model": "planar", "count": 1}, {"model": "free-body", "count": 2}],
            "shape": {"template": "triangle", "side": 1.0},
            "path": {"kind": "line", "center": [0.0, 0.0, 0.0], "velocity": [0.15, 0.0, 0.0]}}


def _toml(tmp_path, gains: str) -> str:
    f = tmp_path / "free-team.toml"
    f.write_text(f'kind = "team"\nname = "free-team"\nduration_s = 2.0\ndt_s = 0.02\nmetrics_from_s = 0.0\n'
                 f'gains = "{gains}"\n[[robots]]\nmodel = "planar"\ncount = 1\n[[robots]]\nmodel = "free-body"\n'
                 'count = 2\n[shape]\ntemplate = "triangle"\nside = 1.0\n[path]\nkind = "line"\n'
                 'center = [0.0, 0.0, 0.0]\nvelocity = [0.15, 0.0, 0.0]\n')
    return str(f)


@pytest.mark.parametrize("table", ["table1", "table2"])
def test_cli_run_of_a_free_body_team_under_robot_space_is_refused_in_one_line(tmp_path, capsys, table):
    """Guards against: "team controller: the orientation law needs gains['k_w']; given ['k_p', 'k_theta']"."""
    out = tmp_path / "r"
    rc = cli.main(["run", _toml(tmp_path, table), "--controller", "robot-space", "--out", str(out), "--no-plots",
                   "--no-mcap"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and "Traceback" not in err
    assert "--controller robot-space cannot drive robots 2-3 (free bodies)" in err
    assert "K_RS of Tables 1 and 2" in err and "[gains.robot-space]" in err
    assert not out.exists()


def test_the_refusal_lifts_when_the_orientation_gain_is_given():
    sc = team_scenario_from_dict(_free_team("table1"), "t.toml")
    with pytest.raises(InvalidInputError, match="robots 2-3 .free bodies.*give no gain"):
        sc.controller("robot-space")
    sc.controller("quaternion")  # the other team controllers keep their gains
    given = team_scenario_from_dict({**_free_team("table1"), "gains": {"robot-space": {"k_w": 6.0}}}, "t.toml")
    assert given.controller("robot-space").gains["k_w"] == 6.0


def test_the_robot_space_description_refuses_free_bodies_without_k_w_itself():
    """The refusal is the description's (RobotSpaceTeam.check_gains, called by the team
    controller), not the scenario layer's: team_controller gives the same words."""
    from quatform.control import team_controller
    from quatform.formations import TEAM_FORMATIONS

    sc = team_scenario_from_dict(_free_team("table1"), "t.toml")
    gains = TEAM_FORMATIONS["robot-space-team"].gain_tables["table1"]
    with pytest.raises(InvalidInputError) as info:
        team_controller("robot-space", sc.team, gains)
    msg = str(info.value)
    assert msg.startswith("--controller robot-space cannot drive robots 2-3 (free bodies): seed 000's robot-space")
    assert msg.endswith("in [gains.robot-space]") and "\n" not in msg
    with pytest.raises(InvalidInputError) as scenario_info:
        sc.controller("robot-space")
    assert str(scenario_info.value) == f"scenario 'free-team': {msg}"
    assert team_controller("robot-space", sc.team, {**gains, "k_w": 6.0}).gains["k_w"] == 6.0
