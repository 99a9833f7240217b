"""Teleoperation (seed 003, Jansen et al. 1990): inputs, walls, gains, limits and measurements.
Simulations here are short (teleop runs in about real time)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from quatform.errors import InvalidInputError, ResourceLimitError
from quatform.scenarios import load_scenario
from quatform.control.stiffness import explicit_stiffness_limit
from quatform.scenarios.teleop import (
    TELEOP,
    check_teleop_stiffness,
    teleop_metrics,
    teleop_scenario_from_dict,
    teleop_stiffness_limits,
)
from quatform.teleop import TeleopMeasurement, VirtualWall


def simulate_teleop(sc, **kw):
    """The finished log of a run of ``sc`` through the one pipeline (its checks included)."""
    return TELEOP.experiment(sc, **kw).run()

BASE = {"kind": "teleop", "duration_s": 1.0}


# -- springs beyond the explicit integrator's stability limit -------------------------


@pytest.mark.parametrize("factor, stable", [(0.98, True), (1.02, False)])
@pytest.mark.parametrize("m, c", [(2.9, 0.0), (2.9, 160.0), (0.061, 60.0)])
def test_stiffness_limit_is_the_semi_implicit_euler_boundary(m, c, factor, stable):
    """k dt^2 + 2 c dt < 4 m: below it the sampled mass-spring-damper decays, above it grows."""
    dt = 1e-3
    k = factor * float(explicit_stiffness_limit(m, c, dt))
    x, v, peak = 1e-3, 0.0, 0.0
    for _ in range(4000):  # the simulator's step: force at the start, velocity first
        v = v + dt * (-k * x - c * v) / m
        x = x + dt * v
        peak = max(peak, abs(x))
    assert (peak < 0.1) == stable  # bounded (undamped: it neither grows nor decays) or blown up
    if not stable:
        assert peak > 1e3


def test_a_stiff_contact_wall_is_refused_not_integrated():
    """A 1e10 N/m wall is refused: integrated explicitly it flings the slave 1.38 m and the run exits 0."""
    wall = {"point": [0.4937, 0.0, 0.5], "normal": [-1.0, 0.0, 0.0], "stiffness": 1e10}
    with pytest.raises(InvalidInputError, match=r"\[wall\] stiffness = 1e\+10 N/m is beyond the stability limit"):
        teleop_scenario_from_dict({**BASE, "wall": wall})
    sc = load_scenario("teleop-wall-contact")
    stiff = dataclasses.replace(sc, wall=dataclasses.replace(sc.wall, stiffness=1e10))
    with pytest.raises(InvalidInputError, match="stability limit"):
        simulate_teleop(stiff)  # the simulator checks too (scenarios built in code)


@pytest.mark.parametrize("section, key, value, names", [
    ("hand", "stiffness", 1e9, r"\[hand\] stiffness"),
    ("hand", "damping", 1e4, r"\[hand\] stiffness"),  # a damper alone: c dt < 2 m
    ("hand", "rot_stiffness", 1e5, r"\[hand\] rot_stiffness"),
    ("push", "stiffness", 1e10, r"\[push\] stiffness"),
    ("controller", "gains_slave", {"kp_pos": 1e9}, r"\[controller.gains_slave\] kp_pos"),
])
def test_hand_push_and_gain_springs_beyond_the_limit_are_refused(section, key, value, names):
    data = {**BASE, section: {key: value}}
    if section == "push":
        data[section]["keys"] = [{"t_s": 0.0, "move": [0.0, 0.0, 0.0]}]
    with pytest.raises(InvalidInputError, match=names):
        teleop_scenario_from_dict(data)


def test_a_virtual_wall_beyond_the_masters_limit_is_refused():
    # 2e5 N/m: finite and below VirtualWall's cap, beyond the Kraft's 1.25e5 N/m at 1 kHz
    wall = {"normal": [0.0, 0.0, -1.0], "offset": -0.2362, "resist_force_n": 2000.0, "thickness_m": 0.01}
    with pytest.raises(InvalidInputError, match=r"virtual_walls\]\] #1 resist_force_n / thickness_m = 2e\+05"):
        teleop_scenario_from_dict({**BASE, "virtual_walls": [wall]})
    ok = teleop_scenario_from_dict({**BASE, "virtual_walls": [wall], "dt_s": 5e-4})  # a faster loop holds it
    check_teleop_stiffness(ok)


def test_every_built_in_scenario_is_within_its_stability_limit():
    for name in ("teleop-free-motion", "teleop-wall-contact", "teleop-virtual-wall", "teleop-preload",
                 "teleop-pitch-through-90", "teleop-pitch-hold-at-90"):
        for e in teleop_stiffness_limits(load_scenario(name)):
            assert e["stiffness"] <= 0.02 * e["limit"], (name, e["what"])


# -- resource limits up front ---------------------------------------------------------


@pytest.mark.parametrize("extra", [{"duration_s": 1e9}, {"dt_s": 1e-300}])
def test_runs_too_long_are_refused_up_front_naming_the_keys(extra):
    with pytest.raises(ResourceLimitError, match=r"duration_s / dt_s"):
        teleop_scenario_from_dict({**BASE, **extra})


def test_the_simulator_refuses_a_run_too_long_itself():
    sc = dataclasses.replace(load_scenario("teleop-free-motion"), duration_s=1e9)
    with pytest.raises(ResourceLimitError, match=r"teleop-free-motion: duration_s / dt_s"):
        simulate_teleop(sc)


# -- infinite virtual walls, non-numeric measurements ---------------------------------


@pytest.mark.parametrize("kw, match", [
    ({"resist_force_n": 1e300, "thickness_m": 1e-300}, "resist_force_n / thickness_m"),
    ({"resist_force_n": 1e12, "thickness_m": 1.0}, "resist_force_n / thickness_m"),
    ({"resist_force_n": "8"}, "resist_force_n = '8' must be a number"),
    ({"thickness_m": math.inf}, "thickness_m = inf must be finite"),
    ({"damping": math.nan}, "damping = nan must be finite"),
    ({"normal": ("a", 0, 1)}, "normal must be a nonzero 3-vector"),
])
def test_virtual_walls_beyond_reach_or_not_numbers_are_refused_at_construction(kw, match):
    with pytest.raises(InvalidInputError, match=match):
        VirtualWall(**{"normal": (0.0, 0.0, -1.0), "offset": -0.2, **kw})


@pytest.mark.parametrize("field", ["q_m", "qd_m", "q_s", "qd_s", "F_s"])
def test_non_numeric_measurements_name_the_field(field):
    sc = load_scenario("teleop-free-motion")
    ctrl = sc.controller()
    good = {"q_m": np.array(sc.q_m0), "qd_m": np.zeros(6), "q_s": np.array(sc.q_s0), "qd_s": np.zeros(7),
            "F_s": np.zeros(6)}
    good[field] = ["x"] * len(good[field])
    with pytest.raises(InvalidInputError, match=f"measurement {field} = "):
        ctrl.compute(0.0, TeleopMeasurement(**good))


# -- every loader mistake is one quatform error naming the key -------------------------


@pytest.mark.parametrize("data, match", [
    ({"virtual_walls": [5]}, r"virtual_walls = \[5\] must be a list of tables"),
    ({"virtual_walls": {"normal": [0, 0, 1]}}, r"virtual_walls = .* must be a list of tables"),
    ({"virtual_walls": [{"normal": [0, 0, 1], "ofset": 0.1}]}, r"unknown key 'ofset'.*did you mean 'offset'"),
    ({"duration_s": {"a": 1}}, r"duration_s = \{'a': 1\} must be a number"),
    ({"duration_s": "4"}, "duration_s = '4' must be a number"),
    ({"duration_s": math.nan}, "duration_s = nan must be finite"),
    ({"duration_s": -1.0}, "duration_s = -1.0 must be > 0"),
    ({"dt_s": math.inf}, "dt_s = inf must be finite"),
    ({"master": 5}, r"master must be a table"),
    ({"master": {"q0": [0, 0, 0, 0, 0, "a"]}}, r"\[master\] q0 = 'a' must be a number"),
    ({"master": {"inertia": [0.02, 0.02, 0.0, 0.004, 0.004, 0.002]}}, r"\[master\] inertia .* must be > 0"),
    ({"master": {"viscous": -0.1}}, r"\[master\] viscous = -0.1 must be >= 0"),
    ({"master": {"inertai": [1] * 6}}, r"did you mean 'inertia'"),
    ({"slave": {"damping": math.inf}}, r"\[slave\] damping = inf must be finite"),
    ({"hand": {"keys": 3}}, r"\[hand\] keys = 3 must be a list of tables"),
    ({"hand": {"keys": [{"t_s": "0"}]}}, r"\[hand\] keys #1 t_s = '0' must be a number"),
    ({"hand": {"keys": [{"ts": 0.0}]}}, r"did you mean 't_s'"),
    ({"hand": {"keys": [{"t_s": 0.0}, {"t_s": 5.0}]}}, r"after duration_s"),
    ({"hand": {"stiffnes": 1.0}}, r"did you mean 'stiffness'"),
    ({"hand": {"rot_damping": -1.0}}, r"\[hand\] rot_damping = -1.0 must be >= 0"),
    ({"push": {"keys": [{"t_s": 0.0, "move": {"x": 1}}]}}, r"\[push\] keys #1 move = .* must be a list of 3"),
    ({"push": 1.0}, r"push must be a table"),
    ({"wall": {"point": [0, 0, 0], "normal": [0, 0, 0]}}, r"\[wall\] normal = .* must be a nonzero vector"),
    ({"wall": {"point": [0, 0, 0], "normal": [1, 0, 0], "stiffness": "stiff"}}, r"\[wall\] stiffness = 'stiff'"),
    ({"wall": {"point": [0, 0, 0], "normal": [1, 0, 0], "stifness": 1.0}}, r"did you mean 'stiffness'"),
    ({"controller": {"gains_master": 5}}, r"gains_master must be a table"),
    ({"controller": {"gains_master": {"kp_pos": math.nan}}}, r"\[controller.gains_master\] kp_pos = nan"),
    ({"controller": {"gains_master": {"kp_pso": 1.0}}}, r"did you mean 'kp_pos'"),
    ({"controller": {"preload": 1}}, r"\[controller\] preload = 1 must be true or false"),
    ({"controller": {"orientation_error": "euler"}}, r"orientation_error = 'euler' is not one of euler-param"),
    ({"controller": {"reflection": 0.0}}, r"\[controller\] reflection = 0.0 must be < 0"),
    ({"controller": {"k_for": -1.0}}, r"\[controller\] k_for = -1.0 must be >= 0"),
    ({"holds_s": 3.0}, r"holds_s = 3.0 must be a list"),
    ({"holds_s": [math.nan]}, r"holds_s = nan must be finite"),
    ({"name": 5}, r"name = 5 must be a string"),
    ({"duraton_s": 1.0}, r"did you mean 'duration_s'"),
])
def test_loader_mistakes_are_one_quatform_error_naming_the_key(data, match):
    with pytest.raises(InvalidInputError, match=match) as exc:
        teleop_scenario_from_dict({**BASE, **data}, where="my.toml")
    assert str(exc.value).startswith("my.toml: ") and "\n" not in str(exc.value)


# -- held at the lock; torque chatter and the errors after the hold ------------------


@pytest.fixture(scope="module")
def lock_runs():
    """The hand stops at pitch -90 deg at t = 3 s; 0.8 s of the hold is enough to see it."""
    sc = dataclasses.replace(load_scenario("teleop-pitch-hold-at-90"), duration_s=3.8, holds=(3.8,))
    return {oe: teleop_metrics(simulate_teleop(sc, orientation_error=oe)) for oe in ("euler-parameters", "rpy")}


def test_holding_at_the_lock_shows_in_torque_chatter_and_the_error_after_the_hold(lock_runs):
    ep, rpy = lock_runs["euler-parameters"], lock_runs["rpy"]
    assert ep["slave_torque_chatter_nm"] < 0.01 and rpy["slave_torque_chatter_nm"] > 10.0
    assert rpy["master_torque_chatter_nm"] > 100 * ep["master_torque_chatter_nm"]
    # the errors at the end of the hold and over it (the approach's tracking lag excluded)
    assert ep["hold_orientation_error_rad"][0] < 0.005 and rpy["hold_orientation_error_rad"][0] > 0.3
    assert ep["hold_peak_orientation_error_rad"][0] < 0.01 < 0.3 < rpy["hold_peak_orientation_error_rad"][0]
    assert ep["hold_position_error_m"][0] < 1e-3 and rpy["hold_position_error_m"][0] > 0.05
    assert ep["hold_peak_orientation_error_rad"][0] < 0.5 * ep["peak_orientation_error_whole_run_rad"]  # the lag is left out


def test_chatter_and_hold_windows_are_what_the_docs_say():
    from quatform.scenarios.teleop import chatter, settled_since

    tau = np.array([[0.0, 0.0], [3.0, 4.0], [3.0, 4.0]])
    assert chatter(tau) == pytest.approx(math.sqrt((25.0 + 0.0) / 2))
    sc = load_scenario("teleop-wall-contact")  # hand keys 0, 0.3, 1.5 (moved), 3.0 (same), 4.5 (moved)
    assert [settled_since(sc, t) for t in (1.0, 3.0, 6.0)] == [1.0, 1.5, 4.5]


# -- the RPY plot draws wrapped differences; titles name the paper --------------------


def test_rpy_plot_traces_do_not_draw_the_wrap_at_180_as_an_error():
    from quatform.algebra import q_from_axis_angle
    from quatform.report.teleop_plots import _rpy_traces

    roll = np.linspace(np.pi - 0.02, np.pi + 0.02, 41)  # both tools roll through +-180 deg
    r_m = q_from_axis_angle(np.array([1.0, 0.0, 0.0]), roll)
    r_s = q_from_axis_angle(np.array([1.0, 0.0, 0.0]), roll + 1e-3)  # the slave 1 mrad ahead
    a_m, a_s = _rpy_traces(r_m, r_s)
    np.testing.assert_allclose(a_s[:, 0] - a_m[:, 0], 1e-3, atol=1e-9)  # not 2 pi where one has wrapped
    assert np.all(np.isfinite(a_m[:, 0])) and np.all(np.abs(np.diff(a_m[:, 0])) < 0.01)  # unwrapped


def test_plot_titles_name_the_paper(tmp_path):
    from quatform.report.teleop_plots import _title, write_teleop_plots

    run = simulate_teleop(dataclasses.replace(load_scenario("teleop-free-motion"), duration_s=0.05))
    assert _title(run).startswith("Jansen et al. 1990, teleop-free-motion") and "seed" not in _title(run)
    assert len(write_teleop_plots(run, tmp_path)) == 3


# -- what the docs say, measured --------------------------------------------------


def test_euler_parameter_moment_is_k_over_4_sin_theta_zero_at_180_deg():
    """W^T K delta_eps about the error axis is (K/4) sin(theta): largest at 90 deg, 0 at 180."""
    from quatform.algebra import matrix_from_q, q_from_axis_angle, qmul
    from quatform.teleop import orientation_error, task_jacobian

    k, axis = 10.0, np.array([0.0, 0.6, 0.8])
    q_m = q_from_axis_angle(np.array([1.0, 0.0, 0.0]), 0.4)
    for theta in np.radians([10.0, 60.0, 90.0, 150.0, 179.0, 180.0]):
        q_s = qmul(q_m, q_from_axis_angle(axis, theta))  # theta from the master, about its axis
        W = task_jacobian(np.eye(6), q_m, q_s)[3:6, 3:6]
        moment = W.T @ (k * orientation_error(q_m, q_s))  # base frame
        along = moment @ (matrix_from_q(q_m) @ axis)
        assert along == pytest.approx(k / 4 * np.sin(theta), abs=1e-12)


@pytest.mark.parametrize("pitch_deg", [0.0, -30.0, -63.0654, -80.0])
def test_rpy_small_angle_stiffness_equals_euler_parameters_only_at_pitch_0(pitch_deg):
    """The RPY law's moment per radian is (kp/4) E^-T E^-1: eigenvalues 1/(1 + |sin p|), 1,
    1/(1 - |sin p|) times the Euler-parameter law's (x0.53, x1, x9.2 at the -63 deg start)."""
    from quatform.algebra import q_from_axis_angle, qmul
    from quatform.teleop import rpy_error
    from quatform.teleop.task import rpy_from_q, rpy_rate_from_angular_velocity

    p = np.radians(pitch_deg)
    q_m = qmul(q_from_axis_angle(np.array([0.0, 1.0, 0.0]), p), q_from_axis_angle(np.array([1.0, 0.0, 0.0]), np.pi))
    E_inv = rpy_rate_from_angular_velocity(rpy_from_q(q_m))
    K = np.empty((3, 3))  # moment per radian over kp/4, by small rotations about the base axes
    h = 1e-6
    for j in range(3):
        q_s = qmul(q_from_axis_angle(np.eye(3)[j], h), q_m)
        K[:, j] = E_inv.T @ rpy_error(q_m, q_s) / h
    eig = np.linalg.eigvalsh(0.5 * (K + K.T))
    s = abs(np.sin(p))
    np.testing.assert_allclose(eig, sorted([1 / (1 + s), 1.0, 1 / (1 - s)]), rtol=1e-4)
    if pitch_deg == -63.0654:
        np.testing.assert_allclose(eig, [0.53, 1.0, 9.2], atol=0.02)


def test_docs_no_longer_claim_more_than_the_runs_show():
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    vw = (root / "src/quatform/scenarios/teleop-virtual-wall.toml").read_text()
    wc = (root / "src/quatform/scenarios/teleop-wall-contact.toml").read_text()
    der = (root / "docs/derivations.md").read_text()
    assert "stays out of the matching zone" not in vw and "8.9 mm into the matching zone" in vw
    assert "the operator feels K_pm/K_ps - v times it" not in wc and "0.97 and 0.56" in wc
    assert "so the controller is not affected" not in der and "(K/4) sin θ" in der
    assert "The RPY law gets the same small-angle stiffness and damping as the Euler-parameter law," not in der


# -- the virtual wall is a spring; the metrics say how far in and what it holds -------


def test_virtual_wall_metrics_report_the_zone_entered_and_the_force_held():
    sc = dataclasses.replace(load_scenario("teleop-virtual-wall"), duration_s=2.6)  # the hand arrives at 2 s
    run = simulate_teleop(sc)
    m = teleop_metrics(run)
    wall = sc.virtual_walls[0]
    # the master and the slave that follows it enter the zone (not absolute), by about as much
    assert 0.005 < m["wall_penetration_m"] < wall.thickness_m and not m["virtual_wall_crossed"]
    assert m["slave_zone_penetration_m"] == pytest.approx(m["wall_penetration_m"], abs=1e-3)
    z_s = run["p_s"][:, 2] - run["p_s"][0, 2] + run["p_master"][0, 2]  # slave height in master axes (identity registration)
    assert m["slave_zone_penetration_m"] == pytest.approx(float((-z_s - wall.offset).max()), abs=1e-12)
    # the force it holds there: its spring at the deepest point, below what it is set to resist
    assert m["virtual_wall_force_n"] == pytest.approx(wall.stiffness * m["wall_penetration_m"], rel=1e-12)
    assert m["virtual_wall_force_n"] < wall.resist_force_n


@pytest.mark.parametrize("body, names", [
    ("virtual_walls = [5]\n", "virtual_walls"),
    ("[wall]\npoint = [0.49, 0.0, 0.5]\nnormal = [-1.0, 0.0, 0.0]\nstiffness = 1e10\n", "[wall] stiffness"),
    ("dt_s = 1e-300\n", "duration_s / dt_s"),
    ("[controller]\ngains_master = { kp_pos = nan }\n", "kp_pos = nan"),
])
def test_the_cli_answers_bad_teleop_files_with_one_line(tmp_path, capsys, body, names):
    from quatform.cli import main

    f = tmp_path / "bad.toml"
    f.write_text('kind = "teleop"\nduration_s = 1.0\n' + body)
    assert main(["teleop", str(f), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and names in err[0] and "Traceback" not in err[0]


def test_peak_orientation_error_is_not_the_shared_lag():
    """In teleop-pitch-through-90 the whole-run peak is the 0.025 rad lag of the
    moving hand for both laws; ``peak_orientation_error_rad`` is taken where the motion rests
    (the holds), so it shows the RPY law's error and not the lag."""
    sc = load_scenario("teleop-pitch-through-90")
    ep = teleop_metrics(simulate_teleop(sc))
    assert ep["peak_orientation_error_whole_run_rad"] == pytest.approx(0.025, abs=0.004)  # the lag
    assert ep["peak_orientation_error_rad"] < 0.5 * ep["peak_orientation_error_whole_run_rad"]
    assert ep["peak_orientation_error_rad"] == pytest.approx(max(ep["hold_peak_orientation_error_rad"]))


# -- physically impossible measurements are refused, naming the field -----------


@pytest.mark.parametrize("field, entry, value, match", [
    ("q_m", None, 1e300, r"measurement q_m\[0\] = 1e\+300 rad is beyond \+-1000 rad"),
    ("q_s", 3, -2e3, r"measurement q_s\[3\] = -2000 rad is beyond \+-1000 rad"),
    ("qd_m", 1, 1e5, r"measurement qd_m\[1\] = 100000 rad/s is beyond \+-100 rad/s"),
    ("qd_s", 6, -150.0, r"measurement qd_s\[6\] = -150 rad/s is beyond \+-100 rad/s"),
    ("F_s", 2, 1e6, r"measurement F_s\[2\] = 1e\+06 N is beyond \+-8700 N.*MAX_WRIST_FORCE"),
    ("F_s", 4, 1e4, r"measurement F_s\[4\] = 10000 N m is beyond \+-870 N m.*MAX_WRIST_MOMENT"),
])
def test_impossible_measurements_are_refused_not_saturated(field, entry, value, match):
    """q_m = 1e300 gets one line naming the field and value, not saturated torques."""
    sc = load_scenario("teleop-free-motion")
    ctrl = sc.controller()
    good = {"q_m": np.array(sc.q_m0), "qd_m": np.zeros(6), "q_s": np.array(sc.q_s0), "qd_s": np.zeros(7),
            "F_s": np.zeros(6)}
    bad = good[field].copy()
    if entry is None:
        bad[:] = value
    else:
        bad[entry] = value
    with pytest.raises(InvalidInputError, match=match) as exc:
        ctrl.step(0.0, TeleopMeasurement(**{**good, field: bad}))
    assert "\n" not in str(exc.value)


def test_measurements_within_each_bound_are_accepted():
    """Entries each within reach pass, though their norm is beyond the bound (per entry, not norm)."""
    from quatform.teleop.controller import (MAX_JOINT_ANGLE, MAX_JOINT_RATE, MAX_WRIST_FORCE, MAX_WRIST_MOMENT,
                                            _measured)

    np.testing.assert_array_equal(_measured(np.full(6, 0.99 * MAX_JOINT_ANGLE), "q_m", 6), 0.99 * MAX_JOINT_ANGLE)
    np.testing.assert_array_equal(_measured(np.full(7, -0.99 * MAX_JOINT_RATE), "qd_s", 7), -0.99 * MAX_JOINT_RATE)
    w = np.r_[np.full(3, 0.99 * MAX_WRIST_FORCE), np.full(3, 0.99 * MAX_WRIST_MOMENT)]
    np.testing.assert_array_equal(_measured(w, "F_s", 6), w)
    with pytest.raises(InvalidInputError, match="not finite"):
        _measured(np.r_[np.inf, 0.0, 0.0, 0.0, 0.0, 0.0], "qd_m", 6)


# -- near pitch +-90 deg roll and yaw are undefined: shaded, not drawn as errors --


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
