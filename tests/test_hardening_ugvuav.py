"""The UGV-UAV formation of Marciano 2021 (seed 001), kinematic side: the loader, the
restricted Jacobian, the law's Lyapunov function, unreachable references and the metrics."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

import quatform.control as control
import quatform.report.ugv_uav_plots as uplots
from quatform.control import Reference, UgvUavController
from quatform.errors import InvalidInputError, ResourceLimitError, UnreachableError
from quatform.formations import UgvUavQuaternion, UgvUavRestricted, UgvUavSpherical
from quatform.scenarios import load_scenario
from quatform.scenarios.ugv_uav import simulate_ugv_uav, ugv_uav_metrics, ugv_uav_scenario_from_dict


# -- the UGV-UAV layouts carry their name ------------------------------------------------

def test_ugv_uav_layout_names_are_not_the_generic_ones():
    assert control.UGV_UAV_MEASURED_NAMES[:3] == ("x_p", "y_p", "psi_p")
    assert len(control.UGV_UAV_MEASURED_NAMES) == 11
    assert control.UGV_UAV_COMMAND_NAMES == ("v_p", "omega_p", "u_x_b", "u_y_b", "u_z_b", "u_psi_b")
    assert not hasattr(control, "COMMAND_NAMES") and not hasattr(control, "MEASURED_NAMES")
    assert "UGV_UAV_COMMAND_NAMES" in control.__all__ and "COMMAND_NAMES" not in control.__all__


# -- the scenario loader -------------------------------------------------------------------------


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


# -- the restricted description refuses what it cannot express ------------------------------


def test_restricted_refuses_the_uav_below_the_platform_single_and_batch():
    F = UgvUavRestricted()
    below = np.array([0.0, 0.0, 0.0, 0.0, 0.3, -0.966])  # 0.966 m below the platform
    with pytest.raises(UnreachableError, match=r"z_b - z_p = -0.966 m: the UAV is below the platform.*quaternion"):
        F.forward(below)
    above = below * np.array([1, 1, 1, 1, 1, -1])
    batch = np.stack([above, below, above])
    with pytest.raises(UnreachableError, match=r"-0.966 m at index \(1,\)"):
        F.forward(batch)
    np.testing.assert_allclose(F.inverse(F.forward(above)), above, atol=1e-12)
    np.testing.assert_array_equal(F.outside(batch), [False, True, False])
    # a cluster state whose (4.24) has no real root is refused, not clipped to platform level
    wide = UgvUavRestricted(range_deg=(-90.0, 90.0))
    with pytest.raises(UnreachableError, match="no real root"):
        wide.inverse(np.array([[0, 0, 0, 1.0, 0.2, 0.2], [0, 0, 0, 1.0, 1.0, 1.0]]))
    with pytest.raises(UnreachableError, match="below the platform"):
        F.from_euclidean(np.array([0, 0, 0, 1.0, 0.3, -0.2]))


@settings(max_examples=200, deadline=None)
@given(d=st.tuples(st.floats(-2, 2), st.floats(-2, 2), st.floats(-2, 2)))
def test_restricted_forward_and_inverse_agree_on_their_domain(d):
    F = UgvUavRestricted()
    r = np.r_[0.1, -0.2, 0.0, np.array([0.1, -0.2, 0.0]) + np.array(d)]
    if np.linalg.norm(d) < 1e-3:
        return
    if F.outside(r):
        with pytest.raises(UnreachableError):
            F.forward(r)
    else:  # every state forward accepts comes back from inverse (to rho sqrt(eps) at platform
        # level, where the root of (4.24) amplifies round-off: 2e-8 m at the 45/45 deg corner)
        np.testing.assert_allclose(F.inverse(F.forward(r)), r, atol=1e-7)


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


# -- a designed switch of the reference is not a loss ---------------------------------------

def test_front_to_over_switch_is_not_a_lost_reference():
    # the §5.3 scenario with its switch 35 s earlier (at 25 s, after the 20 s take-off)
    sc = dataclasses.replace(load_scenario("marciano-front-to-over"), uav_front_until_s=25.0, duration_s=45.0,
                             dt_s=0.01)
    m = ugv_uav_metrics(simulate_ugv_uav(sc, "quaternion"))
    assert not m["reference_lost"] and m["first_lost_time_s"] is None
    assert m["max_uav_position_error_m_at_switch"] >= 0.4  # the switch itself moves the reference far
    assert m["max_uav_position_error_m"] <= 0.4


# -- motion-capture dropouts and glitches ---------------------------------------------------

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


# -- huge finite positions -------------------------------------------------------------------------

@pytest.mark.parametrize("F", [UgvUavSpherical(), UgvUavRestricted(), UgvUavQuaternion()], ids=lambda f: f.name)
def test_huge_positions_are_refused_not_overflowed(F):
    r = np.array([0, 0, 0, 1e154, 1e154, 1e154])
    for f in (F.forward, F.jacobian, F.singularity_measure):
        with pytest.raises(InvalidInputError, match=r"r\[3\] = 1e\+154 is beyond the 1e\+150"):
            f(r)
    c = np.zeros(F.n_c)
    c[3] = 1.0 if F.name == "quaternion" else 1e154
    c[-3 if F.name == "quaternion" else 0] = 1e154
    with pytest.raises(InvalidInputError, match="beyond the 1e\\+150"):
        F.inverse(c)
    ok = np.array([0, 0, 0, 1e140, 1e140, 1e140]) * (1 if F.name != "restricted" else 1)
    if F.name != "restricted":
        assert np.all(np.isfinite(F.forward(ok)))


# -- plots ---------------------------------------------------------------------------------


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


# -- the loader's metrics window, and what the law's Lyapunov function reads --------------------------


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


def test_restricted_rate_maps_refuse_what_forward_refuses():
    """jacobian([0, 0, 0, 0.5, 0.5, -0.966]) returned a 6 x 6 matrix (of the state mirrored
    above the platform) while forward refused it."""
    F = UgvUavRestricted()
    r = np.array([0, 0, 0, 0.5, 0.5, -0.966])
    for f in (F.forward, F.jacobian, F.inverse_jacobian, F.singularity_measure):
        with pytest.raises(UnreachableError, match=r"r: z_b - z_p = -0\.966 m: the UAV is below the platform"):
            f(r)
    c_up = F.forward(r * [1, 1, 1, 1, 1, -1])
    with pytest.raises(UnreachableError, match="below the platform"):
        F.inverse_jacobian_at(c_up, r=r)
    with pytest.raises(UnreachableError, match="alpha_f = 70.5 deg is outside"):
        F.inverse_jacobian_at(c_up + [0, 0, 0, 0, 0.8, 0])  # what inverse refuses
    assert F.inverse_jacobian_at(c_up, r=r * [1, 1, 1, 1, 1, -1]).shape == (6, 6)


robot_pair = st.tuples(*(st.floats(-2.0, 2.0) for _ in range(6))).map(np.array)


@settings(max_examples=150, deadline=None)
@given(r=robot_pair)
def test_restricted_rate_maps_exist_exactly_where_forward_does(r):
    """One check for all: on random robot pairs (UAV above and below, angles in and out of
    range), jacobian, inverse_jacobian and singularity_measure raise iff forward raises."""
    F = UgvUavRestricted()
    if np.linalg.norm(r[3:6] - r[0:3]) < 0.05:
        return  # robots on each other: refused by every map alike, not the point here

    def refused(f):
        try:
            f(r)
        except UnreachableError:
            return True
        return False

    expected = refused(F.forward)
    assert expected == bool(F.outside(r))
    assert refused(F.jacobian) == expected and refused(F.inverse_jacobian) == expected
    assert refused(F.singularity_measure) == expected


def test_control_period_not_a_multiple_of_dt_is_refused_and_tiny_dt_names_dt():
    """Review: control_period_s = 0.007 with dt_s = 0.005 ran at 0.005 s and said so only in
    metrics.json; dt_s = 1e-300 was blamed on duration_s / control_period_s ("67.7 steps")."""
    with pytest.raises(InvalidInputError, match=r"control_period_s = 0.007 is not a whole multiple of dt_s = 0.005"):
        _load(control_period_s=0.007, dt_s=0.005)
    assert _load(control_period_s=0.03, dt_s=0.005).control_period_s == 0.03
    with pytest.raises(ResourceLimitError, match=r"duration_s / dt_s needs 2e\+300 steps"):
        _load(dt_s=1e-300, control_period_s=0.03)
