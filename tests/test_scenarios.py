"""Seed 000's experiments, closed loop: what must be true of each controller."""

from __future__ import annotations

import numpy as np
import pytest

from quatform.errors import InvalidInputError
from quatform.scenarios.pair import run_pair
from quatform.scenarios import builtin_scenarios, load_scenario
from quatform.sim import compute_metrics

CONTROLLERS = ("cluster-space", "robot-space", "quaternion", "dual-quaternion")


@pytest.fixture(scope="module")
def spiral():
    sc = load_scenario("mas-kitts-spiral")
    return {name: run_pair(sc, name) for name in CONTROLLERS}


@pytest.fixture(scope="module")
def spiral_metrics(spiral):
    return {name: compute_metrics(run) for name, run in spiral.items()}


def test_builtin_scenarios_are_listed():
    assert {"mas-kitts-spiral", "mas-kitts-helix", "mas-kitts-yaw-step"} <= set(builtin_scenarios())


def test_spiral_cluster_space_meets_the_singularity(spiral_metrics):
    m = spiral_metrics["cluster-space"]
    assert m["singularity_detected"]
    assert 26.5 < m["first_singular_time_s"] < 28.0  # Fig. 9: t = 27.5 s
    assert m["reference_lost"] and 27.0 < m["first_lost_time_s"] < 30.0
    assert m["max_robot_position_error_m"] > 0.5 and m["max_orientation_error_rad"] > 1.0
    assert m["nonfinite_commands"] == 0


@pytest.mark.parametrize("name", ["quaternion", "dual-quaternion"])
def test_spiral_quaternion_controllers_track_everything(spiral, spiral_metrics, name):
    m = spiral_metrics[name]
    assert not m["singularity_detected"] and not m["reference_lost"]
    for key in ("max_cluster_position_error_m", "max_shape_error_m", "max_robot_position_error_m"):
        assert m[key] <= 0.02, key
    for key in ("max_orientation_error_rad", "max_robot_yaw_error_rad", "max_recovered_euclidean_error_rad"):
        assert m[key] <= 0.02, key
    run = spiral[name]
    # every variable of the description itself, after t = 5 s
    late = run.t >= 5.0
    err = np.abs(run["cluster"][late] - run["c_des"][late]).max()
    assert err <= 0.02
    assert m["nonfinite_commands"] == 0


def test_spiral_robot_space_tracks_robots_but_misreports(spiral):
    run = spiral["robot-space"]
    m = compute_metrics(run)
    assert m["max_robot_position_error_m"] <= 0.02 and not m["reference_lost"]
    # §4.1: past gamma_c = pi/2 the recovered angles read beta_c + pi and pi - gamma_c
    k = np.searchsorted(run.t, 30.0)  # gamma_des = 2 pi (30-25)/10 = pi
    wrap = lambda a: (a + np.pi) % (2 * np.pi) - np.pi  # noqa: E731
    assert abs(wrap(run["e"][k, 3] - run["e_des"][k, 3] - np.pi)) < 0.02
    assert abs(wrap(run["e"][k, 4] - (np.pi - run["e_des"][k, 4]))) < 0.02
    assert m["max_recovered_euclidean_error_rad"] > 3.0


def test_yaw_step_shapes_fig4():
    sc = load_scenario("mas-kitts-yaw-step")
    d_c = sc.path.initial[5]
    cs = compute_metrics(run_pair(sc, "cluster-space"))
    rs = compute_metrics(run_pair(sc, "robot-space"))
    assert cs["min_robot_separation_m"] > 0.95 * 2 * d_c  # Fig. 4a: turns about the centre
    assert rs["min_robot_separation_m"] < 0.1 * 2 * d_c  # Fig. 4b: the robots swap places
    for name in ("quaternion", "dual-quaternion"):
        m = compute_metrics(run_pair(sc, name))
        assert m["min_robot_separation_m"] > 0.95 * 2 * d_c, name
        assert m["max_robot_position_error_m"] < 0.01, name
        assert m["max_recovered_euclidean_error_rad"] < 0.01, name


def test_helix_cluster_space_fails_at_vertical_others_follow():
    sc = load_scenario("mas-kitts-helix")
    m = compute_metrics(run_pair(sc, "cluster-space"))
    assert m["singularity_detected"] and 29.0 < m["first_singular_time_s"] < 30.5
    assert m["reference_lost"] and m["max_robot_position_error_m"] > 0.5
    for name in ("robot-space", "quaternion", "dual-quaternion"):
        run = run_pair(sc, name)
        m = compute_metrics(run)
        assert not m["reference_lost"] and m["max_robot_position_error_m"] < 0.02, name
        assert m["nonfinite_commands"] == 0
        if name == "robot-space":
            assert m["max_recovered_euclidean_error_rad"] > 3.0  # mis-reports the formation
        else:
            assert m["max_recovered_euclidean_error_rad"] < 0.02  # recovers it


def test_monitoring_agrees_with_eqs_1_8_below_the_vertical(spiral):
    """Where |gamma_c| < pi/2 the quaternion descriptions' Euclidean variables are eqs. (1)-(8)
    of the measured robots; beyond, they differ from them by the fold."""
    from quatform.formations import EuclideanPair

    for name in ("quaternion", "dual-quaternion"):
        run = spiral[name]
        direct = EuclideanPair().forward(run["state"])
        below = np.cos(run["e_des"][:, 4]) > 0.2
        wrap = (run["e"] - direct + np.pi) % (2 * np.pi) - np.pi
        assert np.abs(wrap[below][:, [0, 1, 2, 5]]).max() < 1e-12
        assert np.abs(wrap[below][:, [3, 4, 6, 7]]).max() < 1e-9
        beyond = np.cos(run["e"][:, 4]) < -0.1
        assert beyond.any() and np.all(np.abs(np.abs(wrap[beyond][:, 3]) - np.pi) < 1e-3)


def test_reference_wound_by_2pi_is_not_a_manoeuvre(tmp_path):
    """phi_1 stepped by 2 pi: the same formation. No controller may move (the dual-quaternion
    one reads the yaws' branch from c_des itself)."""
    f = tmp_path / "wind.toml"
    f.write_text('name = "wind"\nduration_s = 3.0\nmetrics_from_s = 0.0\n[path]\nd_c = 1.0\n'
                 'center = [0, 0, 1]\n[[path.steps]]\nvariable = "phi_1"\ntime_s = 1.0\n'
                 'change = 6.283185307179586\n')
    sc = load_scenario(f)
    for name in CONTROLLERS:
        m = compute_metrics(run_pair(sc, name))
        assert m["max_robot_position_error_m"] < 1e-9 and m["max_command_speed_m_s"] < 1e-9, name


def test_scenario_file_errors(tmp_path):
    with pytest.raises(InvalidInputError, match="unknown scenario"):
        load_scenario("no-such-scenario")
    bad = tmp_path / "bad.toml"
    bad.write_text('duration_s = 10\n[path]\ncentroid = "ellipse"\n')
    with pytest.raises(InvalidInputError, match="centroid"):
        load_scenario(bad)
    bad.write_text("duration_s = [\n")
    with pytest.raises(InvalidInputError, match="TOML"):
        load_scenario(bad)
    bad.write_text('duration_s = 10\n[path]\nd_c = 1.0\n[[path.ramps]]\nvariable = "d_c"\n'
                   'start_s = 0\nduration_s = 5\nchange = -2.0\n')
    with pytest.raises(InvalidInputError, match="d_c <= 0"):
        run_pair(load_scenario(bad), "quaternion")
    for text, msg in (
        ('duration_s = 10\n[path]\n[[path.ramps]]\nvariable = "d_c"\nduration_s = 5\nchange = 1\n', "start_s"),
        ('duration_s = 10\n[path]\n[gains]\nbase = "table3"\n', "table3"),
        ('duration_s = 10\n[path]\n[initial_offset]\nx_c = "a"\n', "x_c = 'a' must be a number"),
        ('duration_s = 10\n[path]\n[gains.quaternion]\nk_q = [1, 1, 1]\n', "k_q"),
        ('duration_s = 10\n[path]\nd_c = -1.0\n', "d_c"),
    ):
        bad.write_text(text)
        with pytest.raises(InvalidInputError, match=msg):
            run_pair(load_scenario(bad), "quaternion")


def test_user_scenario_runs(tmp_path):
    f = tmp_path / "mine.toml"
    f.write_text('name = "mine"\nduration_s = 3.0\ndt_s = 0.01\nmetrics_from_s = 1.0\n'
                 '[path]\ncentroid = "line"\nvelocity = [0.2, 0, 0]\nd_c = 0.8\ngamma_c = 1.5707963267948966\n'
                 '[gains.quaternion]\nk_x = [3, 3, 3]\n')
    sc = load_scenario(f)
    assert sc.gains["quaternion"]["k_x"] == [3, 3, 3] and sc.gains["quaternion"]["k_d"] == 20
    m = compute_metrics(run_pair(sc, "quaternion"))
    assert m["max_robot_position_error_m"] < 1e-6  # starts on the reference, vertical throughout
