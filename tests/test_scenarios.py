"""Seed 000's experiments, closed loop: what must be true of each controller."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from quatform.errors import InvalidInputError, ResourceLimitError
from quatform.references import EuclideanPath, Ramp, Step
from quatform.scenarios.pair import Scenario, run_pair, scenario_from_dict
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


# -- the loader: metrics window, unknown keys, one line per mistake, resource limits,
# -- the feedforward key, the path's checks, the step's stability bound ------------------

GOOD = 'duration_s = 2.0\ndt_s = 0.01\nmetrics_from_s = 0.5\n[path]\ncenter = [0, 0, 1]\nd_c = 1.0\n'


def _file(tmp_path, text, name="s.toml"):
    f = tmp_path / name
    f.write_text(text)
    return f


def _one_line_error(tmp_path, text, exc=InvalidInputError):
    with pytest.raises(exc) as info:
        load_scenario(_file(tmp_path, text))
    msg = str(info.value)
    assert "\n" not in msg and "Traceback" not in msg
    return msg


@pytest.mark.parametrize("start", ["2.0", "3.0", "1e6"])
def test_metrics_from_at_or_after_the_end_is_refused_at_load(tmp_path, start):
    text = GOOD.replace("metrics_from_s = 0.5", f"metrics_from_s = {start}")
    msg = _one_line_error(tmp_path, text)
    assert "metrics_from_s" in msg and "duration_s" in msg


def test_metrics_from_just_before_the_end_is_kept(tmp_path):
    sc = load_scenario(_file(tmp_path, GOOD.replace("metrics_from_s = 0.5", "metrics_from_s = 1.99")))
    m = compute_metrics(run_pair(sc, "quaternion"))
    assert m["metrics_from_s"] == pytest.approx(1.99)


def test_compute_metrics_refuses_a_run_with_no_sample_in_the_window(tmp_path):
    """A failed run (the cluster-space controller through gamma_c = pi/2) must not read 0."""
    sc = load_scenario("mas-kitts-spiral")
    sc = dataclasses.replace(sc, duration_s=30.0)
    run = run_pair(sc, "cluster-space")
    assert compute_metrics(run)["reference_lost"]
    bad = dataclasses.replace(run, t=run.t - 100.0)  # a log built through the API
    with pytest.raises(InvalidInputError, match="metrics_from_s"):
        compute_metrics(bad)


def test_scenario_built_through_the_api_refuses_an_empty_window():
    with pytest.raises(InvalidInputError, match="metrics_from_s"):
        Scenario(name="api", path=EuclideanPath(), duration_s=3.0)  # default metrics_from_s = 5 s
    Scenario(name="api", path=EuclideanPath(), duration_s=3.0, metrics_from_s=0.0)


def test_short_file_without_metrics_from_is_measured_from_the_start(tmp_path):
    sc = load_scenario(_file(tmp_path, GOOD.replace("metrics_from_s = 0.5\n", "")))
    assert sc.metrics_from_s == 0.0


@pytest.mark.parametrize("text, key, nearest", [
    (GOOD.replace("d_c = 1.0", 'centroid = "circle"\nraduis = 2.0\nd_c = 1.0'), "raduis", "radius"),
    (GOOD.replace("d_c = 1.0", "perid_s = 3.0\nd_c = 1.0"), "perid_s", "period_s"),
    (GOOD + "[initial_ofset]\nx_c = 0.1\n", "initial_ofset", "initial_offset"),
    ("dt = 0.01\n" + GOOD, "dt", "dt_s"),
    ("feed_forward = false\n" + GOOD, "feed_forward", "feedforward"),
    (GOOD + "[robots]\nmax_speed = 2.0\n", "max_speed", "max_speed_m_s"),
    (GOOD + "[initial_offset]\nxc = 0.1\n", "xc", "x_c"),
    (GOOD + '[[path.ramps]]\nvariable = "d_c"\nstart = 0.0\nduration_s = 1.0\nchange = 0.1\n', "start", "start_s"),
    (GOOD + '[[path.steps]]\nvariable = "d_c"\ntime = 1.0\nchange = 0.1\n', "time", "time_s"),
    (GOOD + "[gains]\n[gains.quaternion]\nkx = [1, 1, 1]\n", "kx", "k_x"),
    (GOOD + "[gains]\n[gains.quaternoin]\nk_x = [1, 1, 1]\n", "quaternoin", "quaternion"),
])
def test_unknown_key_names_it_and_the_nearest_valid_one(tmp_path, text, key, nearest):
    msg = _one_line_error(tmp_path, text)
    assert f"unknown key '{key}'" in msg and f"did you mean '{nearest}'" in msg


BAD_FILES = [
    ("initial_offset = 5\n" + GOOD, "initial_offset"),
    ("gains = 5\n" + GOOD, "gains"),
    ("robots = [1]\n" + GOOD, "robots"),
    ("duration_s = true\n" + GOOD.replace("duration_s = 2.0\n", ""), "duration_s"),
    (GOOD.replace("duration_s = 2.0", "duration_s = nan"), "duration_s"),
    (GOOD.replace("duration_s = 2.0", "duration_s = -2.0"), "duration_s"),
    (GOOD.replace("dt_s = 0.01", "dt_s = inf"), "dt_s"),
    (GOOD.replace("dt_s = 0.01", "dt_s = -0.01"), "dt_s"),
    (GOOD.replace("dt_s = 0.01", 'dt_s = "0.01"'), "dt_s"),
    (GOOD.replace("metrics_from_s = 0.5", "metrics_from_s = -1.0"), "metrics_from_s"),
    (GOOD.replace("center = [0, 0, 1]", "center = [1, 2]"), "center"),
    (GOOD.replace("center = [0, 0, 1]", "center = [0, nan, 1]"), "center"),
    (GOOD.replace("d_c = 1.0", "d_c = nan"), "d_c"),
    (GOOD.replace("d_c = 1.0", "d_c = -1.0"), "d_c"),
    (GOOD.replace("d_c = 1.0", 'd_c = 1.0\ncentroid = "circle"\nradius = inf'), "radius"),
    (GOOD.replace("d_c = 1.0", 'd_c = 1.0\ncentroid = "circle"\nperiod_s = 0.0'), "period_s"),
    (GOOD.replace("d_c = 1.0", "d_c = 1.0\nbeta_c = -inf"), "beta_c"),
    (GOOD.replace("d_c = 1.0", "d_c = 1.0\nvelocity = 0.1"), "velocity"),
    (GOOD.replace("d_c = 1.0", "d_c = 1.0\nramps = 3"), "ramps"),
    (GOOD + '[[path.ramps]]\nvariable = "d_c"\nstart_s = nan\nduration_s = 1.0\nchange = 0.1\n', "start_s"),
    (GOOD + '[[path.ramps]]\nvariable = "dc"\nstart_s = 0.0\nduration_s = 1.0\nchange = 0.1\n', "variable"),
    (GOOD + '[[path.steps]]\nvariable = "d_c"\ntime_s = 1.0\nchange = "big"\n', "change"),
    (GOOD + "[initial_offset]\nx_c = nan\n", "x_c"),
    (GOOD + '[initial_offset]\nx_c = "a"\n', "x_c"),
    (GOOD + "[robots]\nmax_speed_m_s = -1.0\n", "max_speed_m_s"),
    (GOOD + "[robots]\nmax_yaw_rate_rad_s = inf\n", "max_yaw_rate_rad_s"),
    (GOOD + '[gains]\nbase = "table3"\n', "base"),
    (GOOD + "[gains]\n[gains.quaternion]\nk_x = [1, nan, 1]\n", "k_x"),
    (GOOD + "[gains]\n[gains.quaternion]\nk_d = -20\n", "k_d"),
    (GOOD + "[gains]\n[gains.dual-quaternion]\nk_dw = [1, 1]\n", "k_dw"),
    (GOOD + "[gains]\nquaternion = 5\n", "quaternion"),
    ('seed = "abc"\n' + GOOD, "seed"),
    ("feedforward = 1\n" + GOOD, "feedforward"),
    ("name = 5\n" + GOOD, "name"),
    ("path = 5\nduration_s = 2.0\n", "path"),
    ("duration_s = 2.0\n", "path"),
    ('kind = "pairs"\n' + GOOD, "kind"),
    (GOOD + "[initial_offset]\nd_c = -1.0\n", "d_c"),
]


@pytest.mark.parametrize("text, key", BAD_FILES, ids=[f"{i}-{k}" for i, (_, k) in enumerate(BAD_FILES)])
def test_bad_file_is_one_line_naming_the_key(tmp_path, text, key):
    f = _file(tmp_path, text)
    msg = _one_line_error(tmp_path, text)
    assert key in msg and str(f) in msg, msg
    assert "contains nan at index" not in msg


def test_huge_duration_is_refused_up_front(tmp_path):
    msg = _one_line_error(tmp_path, GOOD.replace("duration_s = 2.0", "duration_s = 1e9"), ResourceLimitError)
    assert "duration_s / dt_s" in msg and ("GB" in msg or " h " in msg)
    msg = _one_line_error(tmp_path, GOOD.replace("duration_s = 2.0", "duration_s = 1e300"), InvalidInputError)
    assert "duration_s = 1e+300 is beyond" in msg


def test_tiny_dt_is_refused_up_front(tmp_path):
    msg = _one_line_error(tmp_path, GOOD.replace("dt_s = 0.01", "dt_s = 1e-300"), ResourceLimitError)
    assert "duration_s / dt_s" in msg and "dt_s" in msg


def test_scenario_built_through_the_api_is_checked_and_simulate_rechecks():
    with pytest.raises(ResourceLimitError, match="duration_s / dt_s"):
        Scenario(name="api", path=EuclideanPath(), duration_s=1e9, metrics_from_s=0.0)
    sc = Scenario(name="api", path=EuclideanPath(), duration_s=1.0, metrics_from_s=0.0)
    object.__setattr__(sc, "dt_s", 1e-300)  # bypasses __post_init__
    with pytest.raises(ResourceLimitError, match="duration_s / dt_s"):
        run_pair(sc, "quaternion")


def test_time_budget_is_read_from_the_environment(tmp_path, monkeypatch):
    monkeypatch.setenv("QUATFORM_MAX_WORK_S", "1")
    msg = _one_line_error(tmp_path, GOOD.replace("duration_s = 2.0", "duration_s = 100.0"), ResourceLimitError)
    assert "QUATFORM_MAX_WORK_S" in msg


def test_api_numbers_must_be_finite():
    for kw in ({"duration_s": float("nan")}, {"duration_s": 1.0, "dt_s": float("inf")},
               {"duration_s": 1.0, "metrics_from_s": float("nan")}, {"duration_s": True}):
        with pytest.raises(InvalidInputError):
            Scenario(name="api", path=EuclideanPath(), **{"metrics_from_s": 0.0, **kw})
    for bad in (lambda: Ramp("d_c", float("nan"), 1.0, 0.1), lambda: Step("d_c", 1.0, float("inf")),
                lambda: EuclideanPath(center=[0, float("nan"), 0]), lambda: EuclideanPath(radius=float("inf"))):
        with pytest.raises(InvalidInputError):
            bad()


def _spiral_without_feedforward(tmp_path, duration_s=10.0):
    from quatform.scenarios import builtin_scenarios

    text = builtin_scenarios()["mas-kitts-spiral"].read_text()
    text = text.replace("duration_s = 60.0\n", f"duration_s = {duration_s}\nfeedforward = false\n", 1)
    head, *ramps = text.split("[[path.ramps]]")  # keep the ramps that start in the shortened run
    keep = [r for r in ramps if float(r.split("start_s = ")[1].split()[0]) <= duration_s]
    text = "[[path.ramps]]".join([head, *keep])
    return load_scenario(_file(tmp_path, text, "spiral-noff.toml"))


def test_feedforward_key_shows_fig13_steady_state_errors(tmp_path):
    """Without feed-forward a proportional loop lags a ramp of rate v by v / k (seed 000 §4.1,
    Fig. 13: "steady state error corresponding to the lack of integral compensation"). The
    centroid moves at |v| = sqrt((2 pi 2 m / 60 s)^2 + (0.05 m/s)^2) = 0.2153 m/s; the
    quaternion loop's gain on x_c is k_x = 2 (Table 1), the dual-quaternion loop's on the
    translation is k_dw / 2 = 7.5 (the dual part is t q / 2), the cluster-space one's k = 1."""
    sc = _spiral_without_feedforward(tmp_path)
    assert sc.feedforward is False
    v = np.hypot(2 * np.pi * 2.0 / 60.0, 0.05)
    from quatform.sim import errors_from_robots

    for name, k in (("quaternion", 2.0), ("dual-quaternion", 7.5), ("cluster-space", 1.0)):
        run = run_pair(sc, name)
        m = compute_metrics(run)
        assert m["feedforward"] is False and run.meta["feedforward"] is False
        err = errors_from_robots(run)["cluster_position"][run.t >= 5.0]
        assert np.mean(err) == pytest.approx(v / k, rel=0.03), name
        assert m["max_cluster_position_error_m"] == pytest.approx(v / k, rel=0.03), name
    # the caller's word wins over the scenario's, and with feed-forward the lag is gone
    on = compute_metrics(run_pair(sc, "quaternion", feedforward=True))
    assert on["feedforward"] is True and on["max_cluster_position_error_m"] < 1e-3
    on = compute_metrics(run_pair(dataclasses.replace(sc, feedforward=True), "quaternion"))
    assert on["feedforward"] is True and on["max_cluster_position_error_m"] < 1e-3


def test_feedforward_defaults_to_true_and_is_recorded(tmp_path):
    sc = load_scenario(_file(tmp_path, GOOD))
    assert sc.feedforward is True and sc.controller("dual-quaternion").feedforward is True
    assert sc.controller("dual-quaternion", feedforward=False).feedforward is False
    m = compute_metrics(run_pair(sc, "robot-space"))
    assert m["feedforward"] is True
    json.dumps(m)


@pytest.mark.parametrize("text", [BAD_FILES[0][0], BAD_FILES[22][0], GOOD.replace("duration_s = 2.0", "duration_s = 1e9"),
                                  GOOD.replace("metrics_from_s = 0.5", "metrics_from_s = 2.0")])
def test_cli_prints_one_line_and_no_traceback(tmp_path, capsys, text):
    from quatform import cli

    f = _file(tmp_path, text)
    assert cli.main(["run", str(f), "--controller", "quaternion", "--out", str(tmp_path / "o"), "--no-plots"]) != 0
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err and str(f) in err, err


_DATA = {"path": {"center": [0, 0, 1]}}


@settings(max_examples=200, deadline=None)
@given(duration=st.floats(0.05, 50.0), steps=st.integers(1, 400), frac=st.floats(0.0, 1.5))
def test_an_accepted_metrics_window_always_holds_a_sample(duration, steps, frac):
    dt = duration / steps * _jitter(steps)
    m = frac * duration
    try:
        sc = scenario_from_dict({**_DATA, "duration_s": duration, "dt_s": dt, "metrics_from_s": m}, "h")
    except InvalidInputError as exc:
        assert "metrics_from_s" in str(exc) or "dt_s" in str(exc)
        # or dt_s too long for Table 1's largest gain, 20 1/s (k dt_s < 2, check_step_stable)
        assert m >= duration or m > _last_sample(duration, dt) or dt > duration or 20.0 * dt >= 2.0
        return
    assert m < duration and np.any(sc.times >= m)


def _jitter(steps):
    return 1.0 + 0.37 / (steps + 1)  # dt_s not dividing duration_s: the last sample falls short


def _last_sample(duration, dt):
    return int(np.floor(duration / dt + 1e-9)) * dt  # Scenario.times: never past duration_s


def _with_path(extra, base=GOOD):
    return base.replace("d_c = 1.0", f"{extra}\nd_c = 1.0")


@pytest.mark.parametrize("extra, key", [
    ('centroid = "circle"', "radius"),
    ('centroid = "circle"\nradius = 2.0', "period_s"),
    ('centroid = "circle"\nperiod_s = 10.0', "radius"),
])
def test_circle_without_radius_or_period_is_refused_naming_the_missing_key(tmp_path, extra, key):
    """Guards against: radius 0 and period_s 1 by default, a 'circle' that is a fixed point, exit 0."""
    msg = _one_line_error(tmp_path, _with_path(extra))
    assert f"needs {key}" in msg and "centroid = 'circle'" in msg and "s.toml" in msg


def test_circle_of_radius_zero_is_refused(tmp_path):
    msg = _one_line_error(tmp_path, _with_path('centroid = "circle"\nradius = 0.0\nperiod_s = 10.0'))
    assert "radius = 0.0 must be > 0" in msg
    with pytest.raises(InvalidInputError, match="radius must be > 0"):
        EuclideanPath(centroid="circle", period_s=10.0)  # through the API too
    sc = load_scenario(_file(tmp_path, _with_path('centroid = "circle"\nradius = 2.0\nperiod_s = 10.0')))
    assert sc.path.radius == 2.0 and sc.path.period_s == 10.0


@pytest.mark.parametrize("centroid, extra, key, kind", [
    ("line", "radius = 2.0", "radius", "circle"),
    ("fixed", "radius = 2.0", "radius", "circle"),
    ("line", "period_s = 10.0", "period_s", "circle"),
    ("fixed", "period_s = 10.0", "period_s", "circle"),
    ("line", "climb_m_s = 0.1", "climb_m_s", "circle"),
    ("fixed", "velocity = [0.1, 0, 0]", "velocity", "line"),
    ("circle", "radius = 2.0\nperiod_s = 9.0\nvelocity = [0.1, 0, 0]", "velocity", "line"),
])
def test_keys_the_centroid_kind_does_not_use_are_refused(tmp_path, centroid, extra, key, kind):
    """Guards against: silently ignored, the run was not the one the file describes."""
    msg = _one_line_error(tmp_path, _with_path(f'centroid = "{centroid}"\n{extra}'))
    assert f"{key} applies to centroid = '{kind}' only" in msg and "s.toml" in msg


def test_default_centroid_is_fixed_and_refuses_a_radius(tmp_path):
    msg = _one_line_error(tmp_path, _with_path("radius = 2.0"))
    assert "radius applies to centroid = 'circle' only, not 'fixed'" in msg


_STEP = '[[path.steps]]\nvariable = "{v}"\ntime_s = {t}\nchange = {c}\n'


_RAMP = '[[path.ramps]]\nvariable = "{v}"\nstart_s = {t}\nduration_s = {d}\nchange = {c}\n'


@pytest.mark.parametrize("extra, key", [
    (_STEP.format(v="beta_c", t=5.0, c=1.0), "time_s = 5.0"),
    (_STEP.format(v="beta_c", t=2.001, c=1.0), "time_s = 2.001"),
    (_RAMP.format(v="gamma_c", t=3.0, d=1.0, c=1.0), "start_s = 3.0"),
])
def test_step_or_ramp_outside_the_run_is_refused(tmp_path, extra, key):
    """Guards against: a step at 5 s in a 2 s run was accepted and the run read perfect."""
    msg = _one_line_error(tmp_path, GOOD + extra)
    assert key in msg and "outside the run [0, duration_s = 2 s]" in msg and "[[path." in msg


def test_step_and_ramp_at_the_ends_of_the_run_are_kept(tmp_path):
    extra = _STEP.format(v="beta_c", t=2.0, c=1.0) + _RAMP.format(v="gamma_c", t=0.0, d=5.0, c=1.0)
    sc = load_scenario(_file(tmp_path, GOOD + extra))
    assert sc.path.steps[0].time_s == 2.0 and sc.path.ramps[0].duration_s == 5.0  # a ramp may run past the end


def test_d_c_step_to_zero_names_the_file_the_step_and_the_fix(tmp_path, capsys):
    """Guards against: 'quatform: error: the path makes d_c <= 0 (min 0 m): the robots would meet'."""
    text = GOOD + _STEP.format(v="beta_c", t=0.5, c=1.0) + _STEP.format(v="d_c", t=1.5, c=-1.0)
    msg = _one_line_error(tmp_path, text)
    assert msg.startswith(str(tmp_path / "s.toml") + ": [[path.steps]] #2 (d_c at 1.5 s")
    assert "d_c <= 0" in msg and "raise [path] d_c" in msg
    from quatform import cli

    f = _file(tmp_path, text, "cli.toml")
    assert cli.main(["run", str(f), "--controller", "quaternion", "--out", str(tmp_path / "o"), "--no-plots"]) != 0
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "cli.toml" in err and "[[path.steps]] #2" in err, err


def test_d_c_ramp_below_zero_names_the_ramp(tmp_path):
    text = GOOD + _RAMP.format(v="d_c", t=0.5, d=1.0, c=0.5) + _RAMP.format(v="d_c", t=1.0, d=0.5, c=-2.0)
    msg = _one_line_error(tmp_path, text)
    assert "[[path.ramps]] #2 (d_c from 1 s for 0.5 s" in msg and "t = 1.5 s" in msg and "s.toml" in msg


def test_d_c_ramp_below_zero_before_a_step_back_up_is_refused(tmp_path):
    """d_c is piecewise linear with jumps: its least value can be just before a step."""
    text = GOOD + _RAMP.format(v="d_c", t=0.0, d=2.0, c=-1.5) + _STEP.format(v="d_c", t=1.5, c=1.0)
    msg = _one_line_error(tmp_path, text)  # d_c(1.5 s-) = 1 - 1.125 < 0, d_c(1.5 s) = 0.875
    assert "[[path.ramps]] #1 (d_c from 0 s for 2 s" in msg and "t = 1.5 s" in msg


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.booleans(), st.floats(0.0, 2.0), st.floats(0.05, 3.0), st.floats(-1.5, 1.5)),
                max_size=4))
def test_an_accepted_path_keeps_d_c_positive_and_a_refused_one_names_its_change(changes):
    text = GOOD.replace("dt_s = 0.01", "dt_s = 0.05")
    for is_step, t, d, c in changes:
        text += _STEP.format(v="d_c", t=t, c=c) if is_step else _RAMP.format(v="d_c", t=t, d=d, c=c)
    try:
        sc = scenario_from_dict(__import__("tomllib").loads(text), "h.toml")
    except InvalidInputError as exc:
        assert str(exc).startswith("h.toml: [[path.") and "d_c <= 0" in str(exc)
        return
    fine = np.linspace(0.0, 2.0, 4001)
    fine = np.concatenate([fine, [c.time_s - 1e-9 for c in sc.path.steps if c.time_s > 0]])  # before each step
    assert np.all(sc.path(fine)[0][:, 5] > 0)


def test_long_dt_is_refused_as_unstable(tmp_path):
    """Guards against: dt_s = 0.7 in a 2 s run ran to t = 2.1 s with 20 1/s x 0.7 s = 14 (diverging steps)."""
    msg = _one_line_error(tmp_path, GOOD.replace("dt_s = 0.01", "dt_s = 0.7"))
    assert "dt_s = 0.7" in msg and "unstable" in msg and "dt_s < 0.1" in msg
    with pytest.raises(InvalidInputError, match="unstable"):
        Scenario(name="api", path=EuclideanPath(), duration_s=2.0, dt_s=0.7, metrics_from_s=0.0)
    # just inside the bound of Table 1's largest gain (20 1/s): kept
    assert load_scenario(_file(tmp_path, GOOD.replace("dt_s = 0.01", "dt_s = 0.099"))).dt_s == 0.099


def test_stability_bound_follows_the_scenario_gains(tmp_path):
    gains = ('gains = "table2"\n')  # largest gain 1 1/s: dt_s < 2 s
    sc = load_scenario(_file(tmp_path, gains + GOOD.replace("dt_s = 0.01", "dt_s = 0.7")))
    assert sc.times[-1] == pytest.approx(1.4) and sc.times[-1] <= sc.duration_s
    run = run_pair(sc, "quaternion")
    assert run.t[-1] <= sc.duration_s
    own = GOOD.replace("dt_s = 0.01", "dt_s = 0.7") + "[gains]\nbase = \"table2\"\n[gains.quaternion]\nk_d = 3.0\n"
    msg = _one_line_error(tmp_path, own)
    assert "largest gain of 3" in msg and "dt_s < 0.667" in msg


def test_euler_step_of_a_proportional_law_diverges_at_k_dt_2():
    """The bound itself: e <- (1 - k dt) e shrinks only for k dt < 2 (check_step_stable)."""
    for kdt, grows in ((1.9, False), (2.1, True)):
        e = 1.0
        for _ in range(200):
            e *= 1.0 - kdt
        assert (abs(e) > 1.0) is grows


@settings(max_examples=200, deadline=None)
@given(duration=st.floats(0.05, 50.0), ratio=st.floats(1.0, 400.0))
def test_sample_times_never_pass_the_duration(duration, ratio):
    dt = duration / ratio
    sc = Scenario(name="h", path=EuclideanPath(), duration_s=duration, dt_s=dt, metrics_from_s=0.0,
                  gains={"quaternion": {"k_d": 1e-3}})
    t = sc.times
    assert t[-1] <= duration and duration - t[-1] < dt * (1 + 1e-9)
    assert np.allclose(np.diff(t), dt)
