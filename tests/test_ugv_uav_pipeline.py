"""The seed 001 runs through the one pipeline: the ``ugv-uav`` scenario kind builds an
Experiment that :func:`quatform.sim.simulate` runs (plant, motion capture, controller,
reference), and the metrics, the time series and the figures read its Log."""

from __future__ import annotations

import dataclasses
import importlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from quatform.errors import InvalidInputError, ResourceLimitError
from quatform.robots import Bebop, Pioneer
from quatform.scenarios import KINDS
from quatform.scenarios.ugv_uav import (
    UGV_UAV_COLUMNS,
    UGV_UAV_FORMATIONS,
    UGV_UAV_KIND,
    UgvUavScenario,
    check_ugv_uav_scenario,
    simulate_ugv_uav,
    ugv_uav_experiment,
    ugv_uav_metrics,
    ugv_uav_scenario_from_dict,
)
from quatform.scenarios import load_scenario
from quatform.sim.log import Log
from quatform.sim.measurement import LatencyHistory, MotionCapture
from quatform.sim.plants.ugv_uav import PioneerBebopPlant

#: The timeseries.csv header of a quaternion run, as recorded.
QUATERNION_HEADER = (
    "t,x_p,x_p_des,y_p,y_p_des,z_p,z_p_des,x_b,x_b_des,y_b,y_b_des,z_b,z_b_des,psi_p,psi_b,psi_b_des,x_c,x_c_des,"
    "y_c,y_c_des,z_c,z_c_des,q_c_w,q_c_w_des,q_c_x,q_c_x_des,q_c_y,q_c_y_des,q_c_z,q_c_z_des,d_c_x,d_c_x_des,"
    "d_c_y,d_c_y_des,d_c_z,d_c_z_des,euclid_x_c,euclid_x_c_des,euclid_y_c,euclid_y_c_des,euclid_z_c,euclid_z_c_des,"
    "euclid_rho_c,euclid_rho_c_des,euclid_alpha_c,euclid_alpha_c_des,euclid_beta_c,euclid_beta_c_des,u_v_p,"
    "u_omega_p,u_u_x_b,u_u_y_b,u_u_z_b,u_u_psi_b,singularity_measure,no_frame").split(",")
#: ... and of a spherical one (its cluster variables are the chart's: written once).
SPHERICAL_HEADER = QUATERNION_HEADER[:16] + QUATERNION_HEADER[36:]


def _short(**changes) -> UgvUavScenario:
    sc = load_scenario("marciano-circle")
    return dataclasses.replace(sc, **{"duration_s": 3.0, "transient_s": 1.0, **changes})


def test_the_kind_is_registered_with_its_choices_from_the_registries():
    assert KINDS["ugv-uav"] is UGV_UAV_KIND and UGV_UAV_KIND.scenario_type is UgvUavScenario
    opts = {o.name: o for o in UGV_UAV_KIND.options}
    assert opts["formation"].choices == tuple(UGV_UAV_FORMATIONS) and opts["formation"].default == "quaternion"
    assert opts["physics"].choices == ("kinematic", "mujoco")
    assert opts["mocap_noise_m"].type is float and opts["mocap_latency_s"].type is float
    assert UGV_UAV_KIND.compare_over == "formation" and UGV_UAV_KIND.table_columns == UGV_UAV_COLUMNS


def test_marciano_circle_through_simulate_equals_todays_numbers(monkeypatch):
    """The run goes through quatform.sim.simulate (once) and gives main's metrics.json
    (values from /work/baseline_kin.json, marciano-circle/quaternion)."""
    calls = []
    loop = importlib.import_module("quatform.sim.simulate")  # the module (quatform.sim.simulate is also the function)
    real = loop.simulate  # the numpy backend of sim.backends.SIM_BACKENDS, looked up at each run
    monkeypatch.setattr(loop, "simulate", lambda *a, **k: calls.append(a[0]) or real(*a, **k))
    exp = UGV_UAV_KIND.experiment(load_scenario("marciano-circle"), formation="quaternion")
    assert isinstance(exp.plant, PioneerBebopPlant) and isinstance(exp.measurement, MotionCapture)
    log = exp.run()
    assert calls == [exp.plant] and isinstance(log, Log)
    m = exp.metrics(log)
    assert m["max_uav_position_error_m"] == pytest.approx(0.00027595341244905815, rel=1e-9)
    assert m["max_cluster_state_jump"] == pytest.approx(0.018117374489846964, rel=1e-9)
    assert m["min_robot_separation_m"] == pytest.approx(0.6708203932499369, rel=1e-9)
    assert m["max_ugv_position_error_m"] == pytest.approx(2.8736735169408336e-12, rel=1e-6)
    assert m["controller"] == "ugv-uav-quaternion" and m["uav_model_k"] == list(exp.controller.bebop.k)
    assert len(log.t) == 3001 and log["state"].shape == (3001, 11) and log["command"].shape == (3001, 6)


def test_an_experiment_runs_again_to_the_same_log():
    """The motion capture starts its random streams afresh with each run (noise and dropouts)."""
    exp = UGV_UAV_KIND.experiment(_short(duration_s=1.5, mocap_noise_m=0.002, mocap_dropout_rate=0.2))
    a, b = exp.run(), exp.run()
    assert (a["frame"][:, 0] == 1).any()
    for name in ("state", "measured", "command", "used"):
        np.testing.assert_array_equal(a[name], b[name])


def test_the_mocap_overrides_run_and_are_checked_with_the_scenarios_bounds():
    sc = _short()
    exp = UGV_UAV_KIND.experiment(sc, mocap_noise_m=0.002, mocap_latency_s=0.005)
    assert exp.scenario.mocap_noise_m == 0.002 and exp.scenario.mocap_latency_s == 0.005
    assert exp.measurement.noise_m == 0.002 and exp.measurement.latency == 0.005
    with pytest.raises(InvalidInputError, match=r"with --mocap-noise-m/--mocap-latency-s: mocap_noise_m = 2\.0"):
        UGV_UAV_KIND.experiment(sc, mocap_noise_m=2.0)
    with pytest.raises(InvalidInputError, match="unknown formation 'quaternoin'.*quaternion"):
        UGV_UAV_KIND.experiment(sc, formation="quaternoin")
    with pytest.raises(InvalidInputError, match="unknown physics 'bullet'"):
        UGV_UAV_KIND.experiment(sc, physics="bullet")


@pytest.mark.parametrize("formation, header", [("quaternion", QUATERNION_HEADER), ("spherical", SPHERICAL_HEADER)])
def test_the_csv_header_is_todays(formation, header):
    exp = UGV_UAV_KIND.experiment(_short(duration_s=0.3, transient_s=0.1), formation=formation)
    log = exp.run()
    cols, data = log.table(exp.csv_channels)
    assert cols == header and data.shape == (len(log.t), len(header))
    # the views hold the logged values: true and desired robots, commands
    np.testing.assert_array_equal(data[:, cols.index("x_b")], log["state"][:, 3])
    np.testing.assert_array_equal(data[:, cols.index("z_b_des")], log["r_des"][:, 5])
    np.testing.assert_array_equal(data[:, cols.index("u_u_psi_b"):cols.index("u_u_psi_b") + 1], log["command"][:, 5:6])


def test_a_run_that_loses_the_motion_capture_stops_with_the_reason_in_the_log():
    exp = UGV_UAV_KIND.experiment(_short(mocap_dropout_rate=0.9, duration_s=6.0))
    log = exp.run()
    state = log.meta["controller_state"]
    assert state.stopped and state.stop_reason.startswith("motion capture: no good frame")
    assert log.meta["stop_reason"] == state.stop_reason
    t_stop = log.meta["stopped_at"]
    assert t_stop is not None and 0.5 < t_stop <= 6.0
    stopped = log["stopped"][:, 0] == 1
    assert not stopped[log.t < t_stop].any() and stopped[log.t >= t_stop].all()
    m = exp.metrics(log)
    assert m["run_stopped"] and m["run_stopped_at_s"] == t_stop and m["run_stopped_reason"] == state.stop_reason
    assert m["mocap_dropped_frames"] == int((log["frame"][:, 0] == 1).sum()) > 0


def test_unreachable_reference_is_nan_and_the_robots_hold():
    exp = UGV_UAV_KIND.experiment(dataclasses.replace(load_scenario("marciano-front-to-over"), duration_s=3.0,
                                                      transient_s=1.0, uav_front_until_s=2.0), formation="restricted")
    assert np.all(np.isnan(exp.reference(0).c)) and np.all(np.isfinite(exp.reference(len(exp.times) - 1).c))
    log = exp.run()
    reachable = log["reachable"][:, 0] == 1
    assert not reachable[0] and reachable[-1] and log.meta["unreachable_at"] == 0.0
    assert "outside the restricted" in log.meta["unreachable_message"]
    np.testing.assert_array_equal(log["command"][~reachable, 0:2], 0.0)  # the UGV waits


# -- plant and measurement ------------------------------------------------------------------------


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0, allow_subnormal=False), min_size=6, max_size=6), st.floats(-0.2, 0.5))
def test_plant_batch_equals_single_and_keeps_the_floor(u, z):
    plant = PioneerBebopPlant(Pioneer(), Bebop(), floor=-0.3)
    x = np.array([0.0, 0.0, 0.3, 1.0, 0.5, z, 0.1, 0.0, 0.0, -1.0, 0.0])
    u = np.array(u)
    one = plant.step(x, u, 0.05)
    batch = plant.step(np.stack([x, x]), np.stack([u, u]), 0.05)
    np.testing.assert_allclose(batch, np.stack([one, one]), rtol=0, atol=1e-15)
    assert one[5] >= -0.3 - 1e-15
    np.testing.assert_array_equal(one[0:3], Pioneer().step(x[0:3], u[0:2], 0.05))


def test_motion_capture_latency_and_odometry_period():
    mc = MotionCapture(rate_hz=100.0, latency_s=0.02, odometry_period_s=0.2)
    times = np.arange(51) * 0.005  # one plant step of 5 ms per tick, to 0.25 s
    sched = mc.schedule(times, 0.005, 1)
    state = mc.init(np.zeros(11), (), sched)
    for k in range(51):  # the plant moves x_p = t, v_x = t every 5 ms
        state, m = mc.read(state, {key: v[k] for key, v in sched.items()})
        y = np.zeros(11)
        y[0], y[7] = (k + 1) * 0.005, (k + 1) * 0.005
        state = mc.observe(state, y, 0)
    assert m.shape == (11,)
    assert m[0] == pytest.approx(0.23, abs=1e-12)  # the frame of 0.25 s shows the pose of 0.23 s
    assert m[7] == pytest.approx(0.2, abs=1e-12)  # the odometry of 0.2 s
    two = mc.init(np.zeros((2, 11)), (2,), mc.schedule(times, 0.005, 1, (2,)))  # a batch: each world its own
    assert two["hist"].shape[0] == 2 and two["pose"].shape == (2, 7)
    with pytest.raises(InvalidInputError, match="motion capture"):
        MotionCapture(rate_hz=0.0)


def test_latency_history_keeps_its_horizon():
    h = LatencyHistory(0.1)
    for k in range(100):
        h.add(k * 0.01, k)
    assert h.at(0.985) == 98 and h.at(0.5) == h.x[0] and h.t[1] >= 0.98 - 0.1 - 1e-12


def test_controller_switches_must_be_booleans():
    with pytest.raises(InvalidInputError, match="compensation must be true or false .* got 'no'"):
        ugv_uav_experiment(_short(), compensation="no")


def test_check_refuses_a_changed_scenario():
    with pytest.raises(InvalidInputError, match="mocap_dropout_rate"):
        check_ugv_uav_scenario(dataclasses.replace(_short(), mocap_dropout_rate=1.0))


def test_the_scenarios_hold_limit_reaches_the_controller():
    """``mocap_max_hold_s`` of the scenario file is the controller's ``max_hold_s`` (it kept
    the default 0.5 s); a ``[gains]`` entry of the same name still wins."""
    import dataclasses

    from quatform.scenarios import load_scenario

    sc = dataclasses.replace(load_scenario("marciano-circle"), mocap_max_hold_s=0.12)
    assert sc.controller("quaternion").max_hold_s == 0.12
    assert sc.controller("quaternion").mocap.max_hold_s == 0.12
    assert dataclasses.replace(sc, gains={"max_hold_s": 0.3}).controller("quaternion").max_hold_s == 0.3


# -- the scenario loader -----------------------------------------------------------------------------

BASE = {"kind": "ugv-uav", "name": "t", "path": "circle", "r_x": 1.0, "r_y": 1.0, "omega": 0.2, "d_c": 1.5,
        "duration_s": 2.0, "transient_s": 1.0, "gains": {"k_psi": 3.0}}


def _load(**changes):
    data = {**BASE, **changes}
    return ugv_uav_scenario_from_dict({k: v for k, v in data.items() if v is not None}, "my.toml")


@pytest.mark.parametrize("key, value, words", [
    ("floor_below_platform_m", float("nan"), "floor_below_platform_m = nan must be finite"),
    ("uav_front_until_s", float("nan"), "uav_front_until_s = nan must be finite"),
    ("gains", 5, "gains must be a table"),
    ("d_c", {"a": 1}, "d_c = {'a': 1} must be a number"),
    ("r_x", "1.0", "r_x = '1.0' must be a number"),
    ("duration_s", -1.0, "duration_s = -1.0 must be > 0"),
    ("mocap_noise_m", -0.001, "mocap_noise_m = -0.001 must be >= 0"),
    ("center", [1, 2], "center = [1, 2] must be a list of 3 numbers"),
    ("seed", "abc", "seed = 'abc' must be an integer"),
    ("seed", 1.5, "seed = 1.5 must be an integer"),
    ("duraton_s", 3.0, "unknown key 'duraton_s' at top level (did you mean 'duration_s'?)"),
    ("path", "cirle", "path = 'cirle' is not one of circle, lemniscate (did you mean 'circle'?)"),
    ("max_fraction", 1.5, "max_fraction = 1.5 must be <= 1"),
    ("omega", 0.0, "omega = 0.0 must be nonzero"),
    ("control_period_s", 0.001, "control_period_s = 0.001 must be >= dt_s"),
    ("uav_start", [0.0, -0.6, -0.5], "uav_start z = -0.5 m is below the floor"),
    ("name", None, "missing key name"),
    ("duration_s", None, "missing key duration_s"),
    ("title", 3, "title = 3 must be a string"),
    ("mocap_dropout_rate", 1.0, "mocap_dropout_rate = 1.0 must be < 1"),
])
def test_loader_refuses_each_bad_value_naming_the_key(key, value, words):
    with pytest.raises(InvalidInputError, match=None) as info:
        _load(**{key: value})
    msg = str(info.value)
    assert msg.startswith("my.toml: ") and words in msg and "\n" not in msg


@pytest.mark.parametrize("gains, words", [
    ({"k_x": "big"}, "[gains] k_x = 'big' must be a number"),
    ({"k_x": [1.0, 2.0]}, "[gains] k_x = [1.0, 2.0] must be a list of 3 numbers"),
    ({"k_w": [1.0, -1.0, 1.0]}, "[gains] k_w = -1.0 must be > 0"),
    ({"k_psi": float("inf")}, "[gains] k_psi = inf must be finite"),
    ({"l_d": {"x": 1}}, "[gains] l_d = {'x': 1} must be a number"),
    ({"compensation": 1}, "[gains] compensation = 1 must be true or false"),
    ({"k_pis": 3.0}, "unknown key 'k_pis' at [gains] (did you mean 'k_psi'?)"),
    ({"arena": 1.0}, "unknown key 'arena' at [gains]"),
])
def test_loader_refuses_bad_gains(gains, words):
    with pytest.raises(InvalidInputError) as info:
        _load(gains=gains)
    assert words in str(info.value)


def test_loader_reads_good_values_and_lists():
    sc = _load(center=[0.5, -0.5, 0.2], gains={"k_x": [1.0, 2.0, 3.0], "l_d": 2.0, "compensation": False})
    assert sc.center == (0.5, -0.5, 0.2) and sc.gains["k_x"] == (1.0, 2.0, 3.0)
    assert sc.gains["l_d"] == (2.0,) * 4 and sc.gains["compensation"] is False
    for name in ("marciano-circle", "marciano-lemniscate", "marciano-front-to-over"):
        assert load_scenario(name).name == name


def test_huge_duration_is_refused_up_front_naming_the_key():
    with pytest.raises(ResourceLimitError, match="my.toml: duration_s / dt_s needs 2e"):
        _load(duration_s=1e9)
    # a scenario changed after loading (as the CLI does) is checked again when run
    sc = dataclasses.replace(_load(), duration_s=1e9)
    with pytest.raises(ResourceLimitError, match="duration_s"):
        simulate_ugv_uav(sc)
    with pytest.raises(InvalidInputError, match="mocap_noise_m = nan must be finite"):
        simulate_ugv_uav(dataclasses.replace(_load(), mocap_noise_m=float("nan")))


@pytest.mark.parametrize("transient", [25.0, 40.0, 24.995])
def test_loader_refuses_a_metrics_window_without_a_sample(transient):
    """transient_s of 25 or 40 in a 25 s run loaded and ran, every error metric null. The
    last control sample of a 25 s run at 30 ms is 24.99 s, so 24.995 s leaves none either."""
    with pytest.raises(InvalidInputError) as info:
        _load(duration_s=25.0, transient_s=transient)
    msg = str(info.value)
    assert msg.startswith(f"my.toml: transient_s = {transient!r} must be < duration_s = 25.0") and "\n" not in msg
    assert "24.99 s" in msg and "lower transient_s or lengthen duration_s" in msg


def test_loader_keeps_a_metrics_window_with_samples_and_it_measures():
    """The last sample still counts: the window [24.98, 25] s holds one (24.99 s), and the
    run's errors are numbers, not null."""
    assert _load(duration_s=25.0, transient_s=24.98).transient_s == 24.98
    sc = _load(duration_s=0.3, transient_s=0.26)  # only the last of 0, 0.03, ..., 0.27 s (0.3 / 0.03 floors to 9)
    m = ugv_uav_metrics(simulate_ugv_uav(sc, "quaternion"))
    assert m["max_ugv_position_error_m"] is not None and m["max_uav_position_error_m"] is not None


@pytest.mark.parametrize("until", [100.0, 25.0, 24.995])
def test_loader_refuses_a_front_to_over_switch_after_the_run(until):
    """uav_front_until_s = 100 in a 25 s run was accepted and the switch of §5.3 never came."""
    with pytest.raises(InvalidInputError) as info:
        _load(duration_s=25.0, transient_s=1.0, uav_front_until_s=until)
    msg = str(info.value)
    assert msg.startswith(f"my.toml: uav_front_until_s = {until!r} must be < duration_s = 25.0") and "\n" not in msg
    assert "never happen" in msg and "set it to 0 for no front phase" in msg


def test_loader_keeps_a_switch_within_the_run_and_no_switch():
    """0 means no front phase (no switch to check); a switch at the last sample happens."""
    assert _load(duration_s=25.0, transient_s=1.0, uav_front_until_s=0.0).uav_front_until_s == 0.0
    sc = _load(duration_s=25.0, transient_s=1.0, uav_front_until_s=24.98)
    e, _ = sc.e_reference(np.array([24.96, 24.99]))
    assert e[0, 5] == 0.0 and e[1, 5] == pytest.approx(np.pi / 2)  # front, then over at the last sample


def test_shipped_ugv_uav_scenarios_still_load():
    for name in ("marciano-circle", "marciano-lemniscate", "marciano-front-to-over"):
        assert load_scenario(name).transient_s < load_scenario(name).duration_s


def test_control_period_not_a_multiple_of_dt_is_refused_and_tiny_dt_names_dt():
    """Guards against: control_period_s = 0.007 with dt_s = 0.005 ran at 0.005 s and said so only in
    metrics.json; dt_s = 1e-300 was blamed on duration_s / control_period_s ("67.7 steps")."""
    with pytest.raises(InvalidInputError, match=r"control_period_s = 0.007 is not a whole multiple of dt_s = 0.005"):
        _load(control_period_s=0.007, dt_s=0.005)
    assert _load(control_period_s=0.03, dt_s=0.005).control_period_s == 0.03
    with pytest.raises(ResourceLimitError, match=r"duration_s / dt_s needs 2e\+300 steps"):
        _load(dt_s=1e-300, control_period_s=0.03)


def test_a_batch_runs_each_world_with_its_own_motion_capture_streams():
    """The ugv-uav kind batched on NumPy: world 0 reads the streams of the model's seed (one
    world's run, within the rounding of the vectorised yaw), world 1 those of seed + 1."""
    sc = dataclasses.replace(load_scenario("marciano-circle"), duration_s=1.0, mocap_noise_m=0.01,
                             mocap_noise_rad=0.01)
    raw = dataclasses.replace(ugv_uav_experiment(sc, "quaternion"), finish=lambda log: log)
    one = raw.run()
    two = dataclasses.replace(raw, x0=np.stack([raw.x0, raw.x0])).run()
    for name in one.channels:
        np.testing.assert_allclose(two[name][:, 0], one[name], rtol=1e-12, atol=1e-12, err_msg=name)
    assert not np.allclose(two["measured"][:, 1], two["measured"][:, 0])
    assert "failed" not in two.meta
