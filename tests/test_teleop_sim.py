"""Seed 003 closed loop: the five built-in teleoperation scenarios and what each must show."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from quatform.errors import InvalidInputError, ResourceLimitError
from quatform.scenarios import load_scenario
from quatform.scenarios.teleop import (
    TELEOP,
    check_teleop_stiffness,
    teleop_metrics,
    teleop_scenario_from_dict,
    teleop_stiffness_limits,
)
from quatform.sim.plants.teleop import HandKey


def simulate_teleop(sc, **kw):
    """The finished log of a run of ``sc`` through the one pipeline."""
    return TELEOP.experiment(sc, **kw).run()


@pytest.fixture(scope="module")
def runs():
    """Each scenario run once per setting (about 40 s of simulation in all)."""
    out = {}
    for name, kw in (("teleop-free-motion", {}), ("teleop-wall-contact", {}), ("teleop-virtual-wall", {}),
                     ("teleop-pitch-through-90", {"orientation_error": "euler-parameters"}),
                     ("teleop-pitch-through-90", {"orientation_error": "rpy"}),
                     ("teleop-preload", {"preload": False}), ("teleop-preload", {"preload": True})):
        run = simulate_teleop(load_scenario(name), **kw)
        out[(name, *kw.values())] = (run, teleop_metrics(run))
    return out


def test_free_motion_slave_follows_and_errors_converge(runs):
    run, m = runs[("teleop-free-motion",)]
    assert m["nonfinite_torques"] == 0
    moved = np.linalg.norm(run["p_m"][-1] - run["p_m"][0])
    assert moved > 0.06  # the hand moved the master ~7 cm
    err = np.linalg.norm(run["p_s"] - run["p_m"], axis=1)
    assert m["peak_position_error_m"] > 1e-3 and m["final_position_error_m"] < 1e-4  # converged
    assert m["peak_orientation_error_rad"] > 5e-3 and m["final_orientation_error_rad"] < 1e-3
    assert err[-1] < err[run.t >= 2.0][0]
    # the slave's tool moved and turned as much as the master's (the hand asked for 0.3 rad;
    # the master's friction and the coupling leave it a little short)
    np.testing.assert_allclose(np.linalg.norm(run["p_s"][-1] - run["p_s"][0]), moved, atol=1e-3)
    turned = [2 * np.arccos(min(1.0, abs(r[-1] @ r[0]))) for r in (run["r_m"], run["r_s"])]
    assert turned[0] > 0.2
    np.testing.assert_allclose(turned[1], turned[0], atol=2e-3)


def test_pitch_through_90_euler_parameters_pass_rpy_spikes(runs):
    """Both tools go through RPY pitch -90 deg; only the RPY error meets a singularity."""
    ep_run, ep = runs[("teleop-pitch-through-90", "euler-parameters")]
    rpy_run, rpy = runs[("teleop-pitch-through-90", "rpy")]
    from quatform.teleop import rpy_from_q

    pitch = rpy_from_q(ep_run["r_s"])[:, 1]
    assert pitch.min() < np.radians(-86)  # through the lock (asin folds back at -90)
    assert ep["nonfinite_torques"] == 0 and ep["saturated_fraction"] == 0.0
    assert ep["peak_orientation_error_rad"] < 0.05 and ep["final_orientation_error_rad"] < 2e-3
    assert ep["peak_slave_torque_nm"] < 1.0
    # the RPY law: torques to the limits near the lock, position and orientation spikes
    assert rpy["peak_slave_torque_nm"] == pytest.approx(87.0)
    assert rpy["saturated_fraction"] > 0.05
    # the RPY run at the lock is chaotic: a 1e-12 rad change of one start joint (or a machine's
    # other rounding) moves its peaks by 2-6x (12 such starts: whole-run orientation peak
    # 0.037-0.10 rad, the hold's 0.0018-0.012 rad, position peak 8-30 mm, saturated 6.9-10 %).
    # The claims are what that chaos cannot change, with margins over the spread: the torques at
    # their limits, a twentieth of the run saturated, position and orientation worse than the
    # Euler-parameter run's through the whole of it.
    assert rpy["peak_position_error_m"] > 5 * ep["peak_position_error_m"]
    assert rpy["peak_orientation_error_whole_run_rad"] > ep["peak_orientation_error_whole_run_rad"]
    # the operator's hand is kicked: the master at full scale, against 0.04 N m
    assert np.abs(rpy_run["command"][:, :6]).max() == pytest.approx(5.0)
    assert np.abs(ep_run["command"][:, :6]).max() < 0.1
    lock = np.abs(np.abs(rpy_from_q(rpy_run["r_s"])[:, 1]) - np.pi / 2) < np.radians(8)
    assert (rpy_run["saturated"][:, 0] > 0.5)[lock].any() and not (rpy_run["saturated"][:, 0] > 0.5)[:500].any()


def test_wall_contact_force_matches_eq_13_and_is_reflected(runs):
    run, m = runs[("teleop-wall-contact",)]
    sc = run.meta["scenario"]
    assert m["contact_force_error_pct"] < 5.0
    f1, f2 = m["contact_force_n"]
    assert f2 > 1.8 * f1 > 10.0  # two different contact levels
    expected = sc.gains_master.kp_pos / sc.gains_slave.kp_pos - sc.reflection  # (11) with (13)
    np.testing.assert_allclose(m["reflected_force_ratio"], expected, rtol=0.05)
    # the slave does not go through the wall (20 kN/m: about 1-2 mm deep)
    depth = -(run["p_s"] - np.asarray(sc.wall.point)) @ np.asarray(sc.wall.normal)
    assert depth.max() < 0.003


def test_virtual_wall_holds_below_its_force_and_gives_above(runs):
    run, m = runs[("teleop-virtual-wall",)]
    wall = run.meta["scenario"].virtual_walls[0]
    assert not m["virtual_wall_crossed"]
    assert 0.005 < m["wall_penetration_m"] < wall.thickness_m
    assert m["final_hand_force_n"] < wall.resist_force_n
    # push harder than the wall is set to resist: it gives
    sc = run.meta["scenario"]
    harder = dataclasses.replace(sc, hand=dataclasses.replace(
        sc.hand, keys=sc.hand.keys[:-1] + (HandKey(2.0, move=(0.0, 0.0, -0.08)),)))
    m2 = teleop_metrics(simulate_teleop(dataclasses.replace(harder, duration_s=3.0)))
    assert m2["final_hand_force_n"] > wall.resist_force_n and m2["virtual_wall_crossed"]


def test_preload_shrinks_the_hysteresis_without_a_limit_cycle(runs):
    _, off = runs[("teleop-preload", False)]
    _, on = runs[("teleop-preload", True)]
    assert off["reversal_hysteresis_m"] > 0.003  # the master stops short on each side
    assert on["reversal_hysteresis_m"] < 0.6 * off["reversal_hysteresis_m"]
    assert on["limit_cycle_amplitude_m"] < 1e-4 and off["limit_cycle_amplitude_m"] < 1e-4
    assert on["nonfinite_torques"] == off["nonfinite_torques"] == 0


def test_scenario_files_are_validated():
    base = {"kind": "teleop", "duration_s": 1.0}
    with pytest.raises(InvalidInputError, match="duration_s"):
        teleop_scenario_from_dict({"kind": "teleop"})
    with pytest.raises(InvalidInputError, match="orientation_error"):
        teleop_scenario_from_dict({**base, "controller": {"orientation_error": "euler"}})
    with pytest.raises(InvalidInputError, match=r"\[master\] q0 = \[0, 1\] must be a list of 6 numbers"):
        teleop_scenario_from_dict({**base, "master": {"q0": [0, 1]}})
    with pytest.raises(InvalidInputError, match="key times t_s must increase"):
        teleop_scenario_from_dict({**base, "hand": {"keys": [{"t_s": 1.0}, {"t_s": 0.5}]}})
    with pytest.raises(InvalidInputError, match=r"unknown key 'kp' at \[controller.gains_slave\]"):
        teleop_scenario_from_dict({**base, "controller": {"gains_slave": {"kp": 1.0}}})
    with pytest.raises(InvalidInputError, match="reflection"):
        teleop_scenario_from_dict({**base, "controller": {"reflection": 0.5}})
    with pytest.raises(InvalidInputError, match="stiffness"):
        teleop_scenario_from_dict({**base, "wall": {"point": [0, 0, 0], "normal": [1, 0, 0], "stiffness": -1}})


def test_scenario_files_refuse_unknown_keys_and_bad_types():
    base = {"kind": "teleop", "duration_s": 1.0}
    with pytest.raises(InvalidInputError, match=r"unknown key 'controler' at top level \(did you mean 'controller'\?\)"):
        teleop_scenario_from_dict({**base, "controler": {}})
    with pytest.raises(InvalidInputError, match="kp_rot"):
        teleop_scenario_from_dict({**base, "controller": {"gains_slave": {"kp_rot": "high"}}})
    with pytest.raises(InvalidInputError, match="holds_s"):
        teleop_scenario_from_dict({**base, "holds_s": [0.5, 2.0]})
    with pytest.raises(InvalidInputError, match="not both"):
        teleop_scenario_from_dict({**base, "hand": {"keys": [{"t_s": 0.0, "q": [0] * 6, "move": [0, 0, 0]}]}})
    with pytest.raises(InvalidInputError, match="deadband"):
        teleop_scenario_from_dict({**base, "master": {"deadband": [-0.1, 0, 0, 0, 0, 0]}})
    with pytest.raises(InvalidInputError, match="offset"):
        teleop_scenario_from_dict({**base, "virtual_walls": [{"normal": [0, 0, 1], "offset": True}]})


def test_slave_plant_conserves_kinetic_energy_when_coasting():
    """The Coriolis and centrifugal torques do no work: qd^T C qd = 1/2 qd^T M_dot qd, and
    coasting with no torque keeps the kinetic energy (semi-implicit Euler, 1 ms, 0.5 s)."""
    from quatform.teleop import PANDA_SLAVE as S

    rng = np.random.default_rng(4)
    q, qd = rng.uniform(-1.5, 1.5, 7), rng.uniform(-1.0, 1.0, 7)
    h = 1e-6
    M_dot = (S.mass_matrix(q + h * qd) - S.mass_matrix(q - h * qd)) / (2 * h)
    assert qd @ S.coriolis(q, qd) == pytest.approx(0.5 * qd @ M_dot @ qd, rel=1e-5)
    energy = lambda q, qd: 0.5 * qd @ S.mass_matrix(q) @ qd  # noqa: E731
    e0 = energy(q, qd)
    for _ in range(500):
        qd = qd - 1e-3 * np.linalg.solve(S.mass_matrix(q), S.coriolis(q, qd))
        q = q + 1e-3 * qd
    assert energy(q, qd) == pytest.approx(e0, rel=5e-3)
    assert np.linalg.norm(S.coriolis(q, qd)) > 0.01  # the test means something: the term is not zero


# -- the loader: stability limits, resource limits, one error naming the key; metrics and docs --

BASE = {"kind": "teleop", "duration_s": 1.0}


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


@pytest.mark.parametrize("extra", [{"duration_s": 1e9}, {"dt_s": 1e-300}])
def test_runs_too_long_are_refused_up_front_naming_the_keys(extra):
    with pytest.raises(ResourceLimitError, match=r"duration_s / dt_s"):
        teleop_scenario_from_dict({**BASE, **extra})


def test_the_simulator_refuses_a_run_too_long_itself():
    sc = dataclasses.replace(load_scenario("teleop-free-motion"), duration_s=1e9)
    with pytest.raises(ResourceLimitError, match=r"teleop-free-motion: duration_s / dt_s"):
        simulate_teleop(sc)


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


def test_plot_titles_name_the_paper(tmp_path):
    from quatform.report.teleop_plots import _title, write_teleop_plots

    run = simulate_teleop(dataclasses.replace(load_scenario("teleop-free-motion"), duration_s=0.05))
    assert _title(run).startswith("Jansen et al. 1990, teleop-free-motion") and "seed" not in _title(run)
    assert len(write_teleop_plots(run, tmp_path)) == 3


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


def test_peak_orientation_error_is_not_the_shared_lag():
    """In teleop-pitch-through-90 the whole-run peak is the 0.025 rad lag of the
    moving hand for both laws; ``peak_orientation_error_rad`` is taken where the motion rests
    (the holds), so it shows the RPY law's error and not the lag."""
    sc = load_scenario("teleop-pitch-through-90")
    ep = teleop_metrics(simulate_teleop(sc))
    assert ep["peak_orientation_error_whole_run_rad"] == pytest.approx(0.025, abs=0.004)  # the lag
    assert ep["peak_orientation_error_rad"] < 0.5 * ep["peak_orientation_error_whole_run_rad"]
    assert ep["peak_orientation_error_rad"] == pytest.approx(max(ep["hold_peak_orientation_error_rad"]))
