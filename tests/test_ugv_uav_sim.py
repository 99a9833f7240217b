"""Seed 001's experiments in closed loop: what must be true (quaternion), and
what the Euclidean descriptions do at their singular or unreachable configurations."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import quatform.control as control
import quatform.report.ugv_uav_plots as uplots
from quatform.control import Reference, UgvUavController
from quatform.errors import InvalidInputError
from quatform.formations import UgvUavQuaternion, UgvUavRestricted
from quatform.scenarios.ugv_uav import simulate_ugv_uav, ugv_uav_experiment, ugv_uav_metrics
from quatform.scenarios import load_scenario

LIMITS = {  # (cluster / UGV, UAV) after the transient
    "marciano-circle": (0.1, 0.2),
    "marciano-lemniscate": (0.15, 0.2),
    "marciano-front-to-over": (0.05, 0.4),
}


@pytest.fixture(scope="module", params=[False, True], ids=["ideal", "mocap-2mm-5ms"])
def quaternion_runs(request):
    out = {}
    for name in LIMITS:
        sc = load_scenario(name)
        if request.param:
            sc = dataclasses.replace(sc, mocap_noise_m=0.002, mocap_latency_s=0.005)
        run = simulate_ugv_uav(sc, "quaternion")
        out[name] = (run, ugv_uav_metrics(run))
    return out


@pytest.mark.parametrize("name", list(LIMITS))
def test_quaternion_formation_within_the_seeds_bounds(quaternion_runs, name):
    run, m = quaternion_runs[name]
    ugv_lim, uav_lim = LIMITS[name]
    assert m["max_ugv_position_error_m"] < ugv_lim and m["max_cluster_position_error_m"] < ugv_lim
    assert m["max_uav_position_error_m"] < uav_lim
    assert m["nonfinite_commands"] == 0 and not m["unreachable_reference"]
    assert not m["singularity_detected"]
    assert np.all(np.isfinite(run["cluster"])) and np.all(np.isfinite(run["command"]))
    # the recovered formation moves no more between samples than the robots explain
    assert m["max_unexplained_cluster_jump"] < 1e-6
    # the UAV takes off from the floor into the formation and stays above the floor
    sc = load_scenario(name)
    z_b = run["state"][:, 5]
    assert z_b[0] == pytest.approx(-sc.floor_below_platform_m)
    late = run.t > sc.transient_s
    assert np.all(z_b[late] > -sc.floor_below_platform_m + 0.1)


def test_spherical_flags_the_overhead_singularity():
    sc = dataclasses.replace(load_scenario("marciano-circle"), mocap_noise_m=0.002, mocap_latency_s=0.005)
    sph = ugv_uav_metrics(run_s := simulate_ugv_uav(sc, "spherical"))
    quat = ugv_uav_metrics(simulate_ugv_uav(sc, "quaternion"))
    assert sph["singularity_detected"] and sph["first_singular_time_s"] < 20.0
    assert not quat["singularity_detected"]
    # over the UGV alpha_c is undefined: its measured value jumps by ~pi between samples ...
    late = run_s.t > 20
    d = run_s["r_measured"][late, 3:6] - run_s["r_measured"][late, 0:3]
    a = np.arctan2(d[:, 1], d[:, 0])
    assert np.abs((np.diff(a) + np.pi) % (2 * np.pi) - np.pi).max() > 2.0
    # ... the recovered spherical state jumps with no motion to explain it ...
    assert sph["max_unexplained_cluster_jump"] > 2.0 and quat["max_unexplained_cluster_jump"] < 1e-6
    # ... and the UAV's commands chatter more than under the quaternion description
    assert sph["uav_command_chatter"] > 1.5 * quat["uav_command_chatter"]


def test_restricted_cannot_fly_ahead_at_platform_level():
    sc = load_scenario("marciano-front-to-over")
    run = simulate_ugv_uav(sc, "restricted")
    m = ugv_uav_metrics(run)
    assert m["unreachable_reference"] and m["first_unreachable_time_s"] == 0.0
    assert "outside the restricted" in m["unreachable_message"]
    # the run goes on; the robots wait (brake) while the reference is outside the
    # description and join the formation once it is inside (the §5.3 switch at 60 s)
    assert len(run.t) == int(sc.duration_s / 0.03) + 1
    assert m["unreachable_reference_s"] == pytest.approx(60.0, abs=1.0)
    reachable = run["reachable"][:, 0] == 1
    assert np.all(np.isnan(run["c_des"][~reachable])) and np.all(np.isfinite(run["c_des"][reachable]))
    wait = run.t < 55
    assert np.all(run["state"][wait, 5] < -0.25)  # the UAV stays on the floor
    assert not m["reference_lost"] and m["max_uav_position_error_m"] < 0.05


def _fly(ctrl, ref, ugv, uav, seconds, dt=0.01, state=None):
    from quatform.robots import Bebop, Pioneer

    p, b = Pioneer(), Bebop()
    state = ctrl.init() if state is None else state
    for k in range(int(seconds / dt)):
        s = ctrl.update(k * dt, np.r_[ugv, uav[0:4], uav[4:8]], ref, state)
        u, state = s.u, s.state
        ugv, uav = p.step(ugv, u[0:2], dt), b.step(uav, u[2:6], dt)
    return ugv, uav


def test_emergency_stop_brakes_both_robots():
    ctrl = UgvUavController()
    e = np.array([0, 0, 0, 1.5, 0, np.pi / 2])
    c, cd = ctrl.formation.from_euclidean(e, np.zeros(6))
    ugv, uav = np.array([0.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.5, 0.0, 1.0, 0.0, 0.0, 0.0])  # 1 m/s
    stopped = ctrl.emergency_stop(ctrl.init())
    u = ctrl.update(0.0, np.r_[ugv, uav], Reference(c, cd), stopped).u
    assert u[0] == 0 and u[1] == 0 and u[2] < 0  # the UGV stops, the UAV brakes
    ugv2, uav2 = _fly(ctrl, Reference(c, cd), ugv, uav, 2.0, state=stopped)
    # coasting (zero commands) would carry it 1.7 m in 2 s; braking at full command: 0.6 m
    assert np.linalg.norm(uav2[4:7]) < 0.05 and np.linalg.norm(uav2[0:2] - uav[0:2]) < 0.7
    np.testing.assert_array_equal(ugv2, ugv)


def test_arena_walls_stop_the_robots_short():
    ctrl = UgvUavController()
    e = np.array([5.0, 0, 0, 1.5, 0, np.pi / 2])  # a reference outside the 6 x 4 m arena
    c, cd = ctrl.formation.from_euclidean(e, np.zeros(6))
    ugv, uav = _fly(ctrl, Reference(c, cd), np.array([2.0, 0, 0.0]), np.array([2.0, 0, 1.5, 0, 0, 0, 0, 0]), 15.0)
    assert ugv[0] < 3.0 and uav[0] < 3.0 and uav[0] > 2.4


def test_lost_motion_capture_frame_brakes_instead_of_raising():
    ctrl = UgvUavController()
    c, cd = ctrl.formation.from_euclidean(np.array([0, 0, 0, 1.5, 0, np.pi / 2]), np.zeros(6))
    m = np.array([0.0, 0, 0, np.nan, 0, 1.5, 0, 0.5, 0, 0, 0])
    res = ctrl.update(0.0, m, Reference(c, cd), ctrl.init())
    assert res.signals["raw_finite"][0] == 0 and np.all(np.isfinite(res.u)) and res.u[2] < 0


def test_uav_speed_fraction_and_bad_measurements():
    sc = load_scenario("marciano-front-to-over")
    ctrl = sc.controller("quaternion")
    assert ctrl.bebop.max_fraction == 0.4
    c, cd = UgvUavQuaternion().from_euclidean(np.array([0, 0, 0, 0.75, 0.0, 0.0]), np.zeros(6))
    m = np.array([0.0, 0, 0, -2.0, 1.0, 0.0, 0, 0, 0, 0, 0])
    assert np.abs(ctrl.step(0.0, m, Reference(c, cd))[2:]).max() <= 0.4 + 1e-12
    with pytest.raises(InvalidInputError):
        ctrl.step(0.0, m[:10], Reference(c, cd))
    with pytest.raises(InvalidInputError, match="unknown formation"):
        sc.controller("triangle")


# -- layouts, motion-capture dropouts and glitches, designed switches, plots -------------------------

def test_ugv_uav_layout_names_are_not_the_generic_ones():
    assert control.UGV_UAV_MEASURED_NAMES[:3] == ("x_p", "y_p", "psi_p")
    assert len(control.UGV_UAV_MEASURED_NAMES) == 11
    assert control.UGV_UAV_COMMAND_NAMES == ("v_p", "omega_p", "u_x_b", "u_y_b", "u_z_b", "u_psi_b")
    assert not hasattr(control, "COMMAND_NAMES") and not hasattr(control, "MEASURED_NAMES")
    assert "UGV_UAV_COMMAND_NAMES" in control.__all__ and "COMMAND_NAMES" not in control.__all__


def _short(name="marciano-circle", **changes):
    return dataclasses.replace(load_scenario(name), **{"duration_s": 25.0, "dt_s": 0.01, **changes})


def test_restricted_run_reports_the_take_off_from_below_the_platform():
    """The UAV starts on the floor below the platform: outside the restricted description.
    The controller drives it in robot space until it is inside, and the run says for how long."""
    run = simulate_ugv_uav(_short(mocap_noise_m=0.002), "restricted")
    m = ugv_uav_metrics(run)
    outside, c = run["outside"][:, 0] == 1, run["cluster"]
    assert outside[0] and not outside[-1]
    assert 2.0 <= m["measured_outside_description_s"] <= 8.0
    assert np.all(np.isnan(c[outside])) and np.all(np.isfinite(c[~outside]))
    x = run["state"]
    assert np.all(np.isnan(run["singularity"][:, 0][UgvUavRestricted().outside(
        np.c_[x[:, 0:2], np.zeros(len(run.t)), x[:, 3:6]])]))
    assert m["nonfinite_commands"] == 0 and not m["reference_lost"]
    assert m["max_uav_position_error_m"] <= 0.05 and m["max_ugv_position_error_m"] <= 0.05


def test_front_to_over_switch_is_not_a_lost_reference():
    # the §5.3 scenario with its switch 35 s earlier (at 25 s, after the 20 s take-off)
    sc = dataclasses.replace(load_scenario("marciano-front-to-over"), uav_front_until_s=25.0, duration_s=45.0,
                             dt_s=0.01)
    m = ugv_uav_metrics(simulate_ugv_uav(sc, "quaternion"))
    assert not m["reference_lost"] and m["first_lost_time_s"] is None
    assert m["max_uav_position_error_m_at_switch"] >= 0.4  # the switch itself moves the reference far
    assert m["max_uav_position_error_m"] <= 0.4


def _overhead_reference():
    F = UgvUavQuaternion()
    return Reference(*F.from_euclidean(np.array([0, 0, 0, 1.5, 0, np.pi / 2]), np.zeros(6)))


def _stepper(ctrl):
    """``step(t, m, ref) -> Step``: updates threading the controller's state."""
    state = [ctrl.init()]

    def step(t, m, ref):
        s = ctrl.update(t, m, ref, state[0])
        state[0] = s.state
        return s
    return step


def test_controller_holds_the_last_good_frame_through_a_dropout_and_a_glitch():
    ctrl, ref = UgvUavController(), _overhead_reference()
    step = _stepper(ctrl)
    good = np.array([0.0, 0, 0, 0.05, 0, 1.4, 0, 0.1, 0, 0, 0])
    first = step(0.0, good, ref).signals
    assert first["frame"][0] == 0 and first["held"][0] == 0  # good, not held
    dropped = step(0.03, np.full(11, np.nan), ref).signals
    assert dropped["frame"][0] == 1 and dropped["held"][0] == 1 and dropped["raw_finite"][0] == 1
    np.testing.assert_array_equal(dropped["used"][:7], good[:7])
    np.testing.assert_allclose(dropped["cluster"], first["cluster"])
    glitch = good.copy()
    glitch[3:6] = [0.0, 0.0, 0.0]  # the UAV's marker read at the UGV
    res = step(0.06, glitch, ref)
    assert res.signals["frame"][0] == 2 and res.signals["held"][0] == 1 and np.all(np.isfinite(res.u))
    jump = good.copy()
    jump[3] += 1.5  # 1.5 m in 0.09 s: faster than a Bebop flies (K1/K2 = 4.6 m/s, Table 2)
    assert step(0.09, jump, ref).signals["frame"][0] == 2  # rejected
    moved = good.copy()
    moved[3] += 0.1  # 0.1 m in 0.12 s: possible
    assert step(0.12, moved, ref).signals["frame"][0] == 0  # good
    no_odometry = moved.copy()
    no_odometry[7:11] = np.nan  # the Bebop's own odometry, not the motion capture
    res = step(0.15, no_odometry, ref).signals
    assert res["frame"][0] == 0 and res["held"][0] == 0
    np.testing.assert_array_equal(res["used"], moved)  # the pose read now, the last odometry


def test_controller_stops_safely_after_too_many_bad_frames():
    ctrl, ref = UgvUavController(max_hold_s=0.2), _overhead_reference()
    step = _stepper(ctrl)
    good = np.array([0.0, 0, 0, 0.05, 0, 1.4, 0, 0.5, 0, 0, 0])
    step(0.0, good, ref)
    res = [step(0.03 * k, np.full(11, np.nan), ref) for k in range(1, 12)]
    assert [r.signals["stopped"][0] == 1 for r in res].index(True) == 7  # 0.24 s after the last good frame
    reason = res[-1].state.stop_reason
    assert "no good frame" in reason and "max_hold_s = 0.2 s" in reason
    assert res[-1].u[0] == 0 and res[-1].u[1] == 0 and res[-1].u[2] < 0  # braking
    assert step(0.5, good, ref).signals["stopped"][0] == 1  # a good frame does not restart it


def test_run_with_dropped_and_glitched_frames_is_held_through_and_counted():
    sc = _short(mocap_noise_m=0.002, mocap_latency_s=0.005, mocap_dropout_rate=0.05, mocap_glitch_rate=0.02)
    run = simulate_ugv_uav(sc, "quaternion")
    m = ugv_uav_metrics(run)
    assert m["mocap_dropped_frames"] >= 10 and m["mocap_rejected_frames"] >= 5
    assert m["mocap_held_frames"] == m["mocap_dropped_frames"] + m["mocap_rejected_frames"]
    assert not m["run_stopped"] and m["nonfinite_commands"] == 0 and not m["reference_lost"]
    assert m["max_uav_position_error_m"] <= 0.05 and m["max_ugv_position_error_m"] <= 0.05
    assert np.all(np.isfinite(run["cluster"])) and np.all(np.isfinite(run["c_continuous"]))


def test_run_that_loses_the_motion_capture_stops_and_says_so():
    run = simulate_ugv_uav(_short(mocap_dropout_rate=0.9, duration_s=6.0), "quaternion")
    m = ugv_uav_metrics(run)
    assert m["run_stopped"] and m["run_stopped_at_s"] <= 6.0
    assert m["run_stopped_reason"].startswith("motion capture: no good frame")
    after = run.t > m["run_stopped_at_s"]
    assert np.all(run["command"][after, 0] == 0) and np.all(run["command"][after, 1] == 0)  # the UGV stays stopped


def test_noisy_errors_are_drawn_as_a_filtered_line_inside_an_envelope():
    rng = np.random.default_rng(0)
    t = np.arange(3000) * 0.03
    y = rng.normal(0.0, 0.002, t.size)  # 2 mm motion-capture noise on a zero error
    mean, lo, hi = uplots._filtered(t, y, stride=2)
    assert np.std(mean) <= 0.6e-3  # the line shows the error, not the noise (was the raw samples)
    assert np.all(lo <= y + 1e-15) and np.all(y <= hi + 1e-15)  # the band holds every sample
    y[100:110] = np.nan
    mean, lo, hi = uplots._filtered(t, y)
    assert np.isfinite(mean[105]) and np.isnan(uplots._filtered(t, np.full(10, np.nan))[0]).all()


def test_restricted_run_with_an_unreachable_start_gets_real_plots(monkeypatch, tmp_path):
    sc = _short("marciano-front-to-over", uav_front_until_s=5.0, duration_s=12.0, transient_s=2.0)
    run = simulate_ugv_uav(sc, "restricted")
    assert run.t.size == 401 and run["reachable"][0, 0] == 0 and run["reachable"][-1, 0] == 1
    figs = []
    monkeypatch.setattr(uplots, "save", lambda fig, path: figs.append(fig) or path)
    uplots.write_ugv_uav_run_plots(run, tmp_path)
    uplots.write_ugv_uav_compare_plots([run], tmp_path)
    for fig in figs:
        title = fig._suptitle.get_text() if fig._suptitle is not None else fig.axes[0].get_title()
        assert "Marciano 2021" in title and "seed 001" not in title
        assert sum(len(ax.lines) for ax in fig.axes) >= 4  # axes with data, not a text-only figure


#: A lossy lab: noise on positions and orientations, latency, lost and glitched frames.
MOCAP_FAULTS = dict(duration_s=6.0, mocap_noise_m=0.003, mocap_noise_rad=0.01, mocap_latency_s=0.013,
                    mocap_dropout_rate=0.5, mocap_glitch_rate=0.2, transient_s=1.0)


def test_schedule_replays_the_streams():
    """MotionCapture.schedule draws a frame's draws from the world's own streams (world i:
    seed + i; a batch of one world reads what one world reads)."""
    sc = dataclasses.replace(load_scenario("marciano-circle"), **MOCAP_FAULTS)
    exp = ugv_uav_experiment(sc, "quaternion")
    mocap = exp.measurement
    s = mocap.schedule(exp.times[:20], exp.dt, exp.substeps)
    assert s["new"][0] and s["turns"].shape == (20, 2, 4)
    noise, turns, lost, glitched = mocap._draw(*mocap._streams(mocap.seed))
    np.testing.assert_array_equal(noise, s["noise"][0])
    np.testing.assert_array_equal(turns, s["turns"][0])
    assert (lost, glitched) == (s["lost"][0], s["glitched"][0])
    b = mocap.schedule(exp.times[:20], exp.dt, exp.substeps, (1, 2))
    for key, v in s.items():
        np.testing.assert_array_equal(b[key][:, 0, 0], v, err_msg=key)
    assert not np.array_equal(b["noise"][:, 0, 1], s["noise"])
    np.testing.assert_array_equal(b["noise"][:, 0, 1][s["new"]][0],
                                  mocap._draw(*mocap._streams(mocap.seed + 1))[0])


def test_emergency_stop_and_release_refuse_what_is_not_the_state_in_one_line():
    """Guards against: ``emergency_stop(None)`` failing deep inside with an AttributeError."""
    ctrl = UgvUavController()
    for call in (ctrl.emergency_stop, ctrl.release):
        with pytest.raises(InvalidInputError, match="state must be the controller's UgvUavState"):
            call(None)


def test_a_run_whose_first_frames_are_bad_brakes_and_says_so():
    """Before the first good frame there is nothing to hold: both robots brake, the
    ``no_frame`` signal (a column of timeseries.csv) is 1 and ``no_frame_time_s`` says how long."""
    from quatform.scenarios.ugv_uav import UGV_UAV_CSV_CHANNELS

    ctrl, ref = UgvUavController(), _overhead_reference()
    step = _stepper(ctrl)
    good = np.array([0.0, 0, 0, 0.05, 0, 1.4, 0, 0.1, 0, 0, 0])
    none = step(0.0, np.full(11, np.nan), ref)
    assert none.signals["no_frame"][0] == 1 and none.u[0] == 0 and none.u[1] == 0
    assert step(0.03, good, ref).signals["no_frame"][0] == 0
    assert step(0.06, np.full(11, np.nan), ref).signals["no_frame"][0] == 0  # held: a frame to go on
    sc = _short(mocap_dropout_rate=0.9, duration_s=3.0)
    run = simulate_ugv_uav(sc, "quaternion")
    m = ugv_uav_metrics(run)
    no_frame = run["no_frame"][:, 0] > 0.5
    first_good = int(np.argmax(run["frame"][:, 0] == 0))
    assert first_good > 0 and no_frame[:first_good].all() and not no_frame[first_good:].any()
    assert m["no_frame_time_s"] == pytest.approx(first_good * sc.control_period_s, rel=1e-12)
    assert np.all(run["command"][:first_good, 0:2] == 0)
    assert "no_frame" in UGV_UAV_CSV_CHANNELS
