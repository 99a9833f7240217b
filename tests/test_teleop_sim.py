"""Seed 003 closed loop: the five built-in teleoperation scenarios and what each must show."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from quatform.errors import InvalidInputError
from quatform.scenarios import load_scenario
from quatform.scenarios.teleop import TELEOP, teleop_metrics, teleop_scenario_from_dict
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
