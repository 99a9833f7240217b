"""Seed 003 through the one pipeline: controller contract, arms, plant, teleop kind.

The numbers hard-coded here are the recorded reference values: the README example's torques
and metrics of ``/work/baseline_kin.json`` (``teleop-free-motion``, Euler parameters, no
preload), so a change of the loop, the plant or the metrics that moves them fails.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from quatform.algebra import q_from_axis_angle
from quatform.control.contract import Controller
from quatform.errors import InvalidInputError, ShapeError
from quatform.robots.arms import KraftMaster, PandaSlave, friction_step
from quatform.robots.model import RobotModel
from quatform.scenarios import KINDS
from quatform.scenarios.teleop import CSV_CHANNELS, TELEOP
from quatform.scenarios import load_scenario
from quatform.sim.plants.teleop import angle_between
from quatform.teleop import (
    KRAFT_MASTER,
    PANDA,
    Registration,
    TeleopController,
    TeleopMeasurement,
)

Q_M0 = np.array([0.0, 0.3, -0.4, 0.2, 0.3, 0.0])
Q_S0 = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8])

#: The header of a teleop run's timeseries.csv, as recorded.
TODAY_CSV_HEADER = (
    ["t"] + [f"{n}_{c}" for n in ("p_m", "p_s") for c in "xyz"] + [f"e_{i}" for i in range(1, 7)]
    + [f"{n}_{c}" for n in ("F_s", "F_hand") for c in "xyz"] + ["angle"]
    + [f"{n}{i}" for i in range(1, 7) for n in ("q_m", "tau_m")]
    + [f"{n}{i}" for i in range(1, 8) for n in ("q_s", "tau_s")] + ["raw_finite"])


def readme_controller():
    return TeleopController(Registration.from_homes(KRAFT_MASTER, PANDA, Q_M0, Q_S0), q_rest=Q_S0,
                            preload_nm=TeleopController.default_preload())


def readme_measurement():
    return TeleopMeasurement(Q_M0 + 0.05, np.zeros(6), Q_S0, np.zeros(7), np.zeros(6))


def stacked(m):
    return np.concatenate([m.q_m, m.qd_m, m.q_s, m.qd_s, m.F_s])


def test_readme_example_returns_todays_torques():
    tau_m, tau_s = readme_controller().step(0.0, readme_measurement())
    np.testing.assert_allclose(tau_m, [-1.857932294537477, -4.988129324033583, -3.0, -0.6, -0.6, 0.0],
                               rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(tau_s, [2.7246306447094755, -6.254294364294953, 2.8341311392966304,
                                       4.485148424396779, 0.3729697781997745, 0.7693443346262288,
                                       -0.2634041496051778], rtol=1e-12, atol=1e-12)


def test_the_teleop_controller_follows_the_contract():
    ctrl = readme_controller()
    assert isinstance(ctrl, Controller) and ctrl.init() is None
    assert ctrl.command_names == tuple(f"tau_m{i}" for i in range(1, 7)) + tuple(f"tau_s{i}" for i in range(1, 8))
    assert len(ctrl.measured_columns) == 32 and ctrl.measured_columns[-6:-3] == ("F_s_x", "F_s_y", "F_s_z")
    m = readme_measurement()
    a = ctrl.update(0.0, m, None, ctrl.init())
    b = ctrl.update(0.0, stacked(m), None, None)  # both forms of the measurement
    tau_m, tau_s = ctrl.step(0.0, m)
    np.testing.assert_array_equal(a.u, np.r_[tau_m, tau_s])
    np.testing.assert_array_equal(b.u, a.u)
    assert a.state is None
    cols = ctrl.signal_columns()
    assert set(a.signals) == set(cols)
    for name, c in cols.items():
        assert np.shape(a.signals[name]) == (len(c),), name
    cmd = ctrl.compute(0.0, m)
    np.testing.assert_array_equal(a.signals["e"], cmd.e)
    np.testing.assert_array_equal(a.signals["r_s"], cmd.r_s)
    assert a.signals["raw_finite"][0] == 1.0 and a.signals["saturated"][0] == float(cmd.saturated)


def test_a_stacked_measurement_of_the_wrong_size_is_one_error_naming_the_columns():
    ctrl = readme_controller()
    with pytest.raises(ShapeError, match=r"shape \(\.\.\., 32\) \(q_m1 \.\.\. M_s_z"):
        ctrl.update(0.0, np.zeros(31), None, None)
    with pytest.raises(InvalidInputError, match="TeleopMeasurement or 32 numbers"):
        ctrl.step(0.0, ["a"] * 32)


def test_the_arms_are_robot_models():
    for model, n in ((KraftMaster(), 6), (PandaSlave(), 7)):
        assert isinstance(model, RobotModel) and model.point_kind == "pose"
        assert len(model.state_columns) == 2 * n and len(model.command_columns) == n
        x = np.r_[Q_M0 if n == 6 else Q_S0, np.zeros(n)]
        pose = model.point(x)
        assert pose.shape == (7,) and np.linalg.norm(pose[3:]) == pytest.approx(1.0, abs=1e-12)
        u = model.saturate(np.r_[np.nan, np.full(n - 1, 1e6)])
        assert u[0] == 0.0 and np.all(np.isfinite(u)) and np.all(np.abs(u) <= 87.0)
        with pytest.raises(InvalidInputError, match="torque-commanded"):
            model.actuate(x, np.zeros(6), 0.0, None)


def test_the_master_stays_in_its_dead_region_and_coasts_out_of_it():
    master = KraftMaster()
    static = master.static_friction
    x = np.r_[Q_M0, np.zeros(6)]
    still = master.step(x, 0.9 * static, 1e-3)  # below the breakaway torque: no motion
    np.testing.assert_array_equal(still, x)
    moved = master.step(x, 1.5 * static + np.r_[0, 0, 0, 0, 0, 0.01], 1e-3)
    assert np.all(moved[6:] > 0)


@settings(max_examples=40, deadline=None)
@given(qd=hnp.arrays(np.float64, (3, 6), elements=st.sampled_from([0.0, 0.3, -0.2, 1e-4])),
       tau=hnp.arrays(np.float64, (3, 6), elements=st.floats(-2.0, 2.0)))
def test_friction_step_on_a_batch_equals_each_world(qd, tau):
    inertia = np.array(KraftMaster().inertia)
    static = KraftMaster().static_friction
    batch = friction_step(qd, inertia, tau, static, 1e-3)
    for i in range(3):
        np.testing.assert_array_equal(batch[i], friction_step(qd[i], inertia, tau[i], static, 1e-3))
    # friction alone never reverses a moving joint within one step
    moving = qd != 0
    free = np.abs(tau) <= static
    assert np.all((batch * qd)[moving & free] >= 0.0)


@settings(max_examples=30, deadline=None)
@given(axis=hnp.arrays(np.float64, 3, elements=st.floats(-1, 1)).filter(lambda a: np.linalg.norm(a) > 1e-3),
       angle=st.floats(0.0, 3.1), sign=st.sampled_from([1.0, -1.0]))
def test_angle_between_is_the_rotation_angle_whatever_the_sign(axis, angle, sign):
    q1 = q_from_axis_angle(np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8]), 0.7)
    from quatform.algebra import qmul

    q2 = sign * qmul(q1, q_from_axis_angle(axis / np.linalg.norm(axis), angle))
    assert float(angle_between(q1, q2)) == pytest.approx(angle, abs=1e-9)
    np.testing.assert_allclose(angle_between(np.stack([q1, q1]), np.stack([q2, q2])), angle, atol=1e-9)


@pytest.fixture(scope="module")
def free_motion():
    exp = TELEOP.experiment(load_scenario("teleop-free-motion"), orientation_error="euler-parameters",
                            preload="off")
    log = exp.run()
    return exp, log, exp.metrics(log)


def test_a_run_through_simulate_has_todays_metrics(free_motion):
    """teleop-free-motion/euler-parameters/off of /work/baseline_kin.json (the recorded reference run)."""
    _, _, m = free_motion
    today = {"final_hand_force_n": 5.066804047457083, "final_position_error_m": 1.3178620379559999e-06,
             "final_orientation_error_rad": 3.4510378943519555e-05, "peak_orientation_error_rad": 0.01630900076235892,
             "peak_position_error_m": 0.0019208021612434705, "peak_slave_torque_nm": 1.1678408292904974,
             "slave_torque_chatter_nm": 0.0025150202359363553, "master_torque_chatter_nm": 0.0005252977885785669}
    for key, value in today.items():
        assert m[key] == pytest.approx(value, rel=1e-9), key
    assert m["nonfinite_torques"] == 0 and m["saturated_fraction"] == 0.0 and m["preload"] is False


def test_the_log_has_todays_csv_header_and_the_plant_is_pure(free_motion):
    exp, log, _ = free_motion
    cols, table = log.table(exp.csv_channels)
    assert cols == TODAY_CSV_HEADER and table.shape == (len(log.t), len(TODAY_CSV_HEADER))
    assert exp.csv_channels == CSV_CHANNELS
    # the plant's step is pure and replays the log: state k+1 from state k and command k
    x, u = log["state"], log["command"]
    k = 1234
    xk = x[k].copy()
    np.testing.assert_array_equal(exp.plant.step(x[k], u[k], exp.dt, float(log.t[k])), x[k + 1])
    np.testing.assert_array_equal(x[k], xk)
    np.testing.assert_array_equal(log["measured"], x)  # the perfect measurement
    assert log.columns("measured") == exp.controller.measured_columns


def test_the_kind_is_registered_with_its_options():
    assert KINDS["teleop"] is TELEOP and TELEOP.compare_over == "orientation_error"
    assert {o.name: o.choices for o in TELEOP.options} == {"orientation_error": ("euler-parameters", "rpy"),
                                                           "preload": ("on", "off")}
    sc = dataclasses.replace(load_scenario("teleop-preload"), duration_s=0.01)
    assert TELEOP.experiment(sc, preload="on").controller.preload_nm is not None
    assert TELEOP.experiment(sc, preload=False).controller.preload_nm is None
    with pytest.raises(InvalidInputError, match="preload = 'maybe' must be on or off"):
        TELEOP.experiment(sc, preload="maybe")
    with pytest.raises(InvalidInputError, match="orientation_error = 'euler' must be one of"):
        TELEOP.experiment(sc, orientation_error="euler")


def test_hand_targets_at_every_time_equal_the_one_time_target():
    for name in ("teleop-free-motion", "teleop-pitch-through-90"):  # pose keys, joint keys
        sc = load_scenario(name)
        poses = sc.hand.key_poses(KRAFT_MASTER.forward(np.array(sc.q_m0)))
        ts = np.linspace(0.0, sc.duration_s, 97)
        p, r = sc.hand.targets(ts, poses)
        for k, t in enumerate(ts):
            p1, r1 = sc.hand.target(t, poses)
            np.testing.assert_allclose(p[k], p1, atol=1e-14)
            np.testing.assert_allclose(r[k], r1, atol=1e-14)


def test_figures_read_the_log_and_the_compare_draws_every_run(tmp_path):
    from quatform.report.teleop_plots import (
        write_teleop_compare_plots,
        write_teleop_plots,
    )

    sc = dataclasses.replace(load_scenario("teleop-wall-contact"), duration_s=0.05)
    logs = [TELEOP.experiment(sc, orientation_error=oe).run() for oe in ("euler-parameters", "rpy")]
    names = sorted(p.name for p in write_teleop_plots(logs[0], tmp_path / "run"))
    assert names == ["contact.png", "orientation_rpy.png", "torques.png", "tracking.png"]
    (path,) = write_teleop_compare_plots(logs, tmp_path / "cmp")
    assert path.name == "compare_errors.png" and path.stat().st_size > 10_000


# -- the plots: RPY differences wrapped, roll and yaw masked in gimbal lock ---------------

def test_rpy_plot_traces_do_not_draw_the_wrap_at_180_as_an_error():
    from quatform.algebra import q_from_axis_angle
    from quatform.report.teleop_plots import _rpy_traces

    roll = np.linspace(np.pi - 0.02, np.pi + 0.02, 41)  # both tools roll through +-180 deg
    r_m = q_from_axis_angle(np.array([1.0, 0.0, 0.0]), roll)
    r_s = q_from_axis_angle(np.array([1.0, 0.0, 0.0]), roll + 1e-3)  # the slave 1 mrad ahead
    a_m, a_s = _rpy_traces(r_m, r_s)
    np.testing.assert_allclose(a_s[:, 0] - a_m[:, 0], 1e-3, atol=1e-9)  # not 2 pi where one has wrapped
    assert np.all(np.isfinite(a_m[:, 0])) and np.all(np.abs(np.diff(a_m[:, 0])) < 0.01)  # unwrapped


def test_orientation_plot_masks_roll_yaw_and_their_difference_in_gimbal_lock():
    """Both tools pass pitch -90 deg 1e-2 rad apart, the slave lagging: the RPY branches switch at
    different samples, so roll read -180 against 0 and the wrapped difference ~3 rad there."""
    from quatform.algebra import q_from_axis_angle
    from quatform.report.teleop_plots import GIMBAL_LOCK_DEG, _orientation_traces
    from quatform.teleop import rpy_from_q

    pitch = np.radians(np.linspace(-70.0, -110.0, 401))  # about y: pitch -70 -> -90 -> back to -70 (flipped)
    r_m = q_from_axis_angle(np.array([0.0, 1.0, 0.0]), pitch)
    r_s = q_from_axis_angle(np.array([0.0, 1.0, 0.0]), pitch + 1e-2)
    angle = np.full(pitch.size, 1e-2)
    tr = _orientation_traces(r_m, r_s, angle)
    rpy_m, rpy_s = rpy_from_q(r_m), rpy_from_q(r_s)
    raw = np.linalg.norm((rpy_s - rpy_m + np.pi) % (2 * np.pi) - np.pi, axis=1)
    assert raw.max() > 3.0  # what a plot of raw wrapped differences draws
    near = np.maximum(np.abs(rpy_m[:, 1]), np.abs(rpy_s[:, 1])) >= np.radians(90.0 - GIMBAL_LOCK_DEG - 1e-9)
    np.testing.assert_array_equal(tr.lock, near)
    assert tr.lock.any() and not tr.lock.all()
    assert np.all(np.isnan(tr.rpy_difference[tr.lock])) and np.all(np.isnan(tr.master[tr.lock][:, [0, 2]]))
    assert np.all(np.isnan(tr.slave[tr.lock][:, [0, 2]])) and np.all(np.isfinite(tr.slave[tr.lock][:, 1]))
    np.testing.assert_allclose(tr.rpy_difference[~tr.lock], 1e-2, rtol=1e-6)  # outside: the true angle
    np.testing.assert_array_equal(tr.angle, angle)  # the error line, drawn everywhere
