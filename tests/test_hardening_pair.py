"""The two-robot formations and controllers of seed 000.

Each test's docstring says what goes wrong without the behaviour it tests.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import pair_robot_error, pair_separation
from hypothesis import given, settings, strategies as st

from quatform.control import (
    ClusterSpaceController,
    DualQuaternionController,
    QuaternionController,
    Reference,
    RobotSpaceController,
    dual_quaternion_law_lyapunov,
    dual_quaternion_lyapunov,
)
from quatform.errors import DegenerateInputError, InvalidInputError, UnreachableError
from quatform.formations import DualQuaternionPair, EuclideanPair, QuaternionPair, RobotSpace
from quatform.formations import geometry as g
from quatform.formations.base import MAX_MAGNITUDE
from quatform.robots import HolonomicRobot, Team
from quatform.scenarios.pair import run_pair
from quatform.scenarios import load_scenario
from quatform.sim import compute_metrics

FREE = Team((HolonomicRobot(1e9, 1e9),) * 2)
ALL_FORMATIONS = [EuclideanPair(), RobotSpace(), QuaternionPair(), DualQuaternionPair()]
ALL_CONTROLLERS = [ClusterSpaceController, RobotSpaceController, QuaternionController, DualQuaternionController]
E_FIXED = np.array([0, 0, 1, 0, 0, 1, 0, 0.0])




def fixed_scenario(tmp_path, extra):
    f = tmp_path / "s.toml"
    f.write_text('name = "s"\nduration_s = 8.0\nmetrics_from_s = 7.0\ngains = "table1"\n'
                 '[robots]\nmax_speed_m_s = 3.0\nmax_yaw_rate_rad_s = 4.0\n'
                 '[path]\ncentroid = "fixed"\ncenter = [0.0, 0.0, 1.0]\nd_c = 1.0\n' + extra)
    return load_scenario(f)


# -- relative-yaw error beyond pi ------------------------------------------------

def test_item1_opposite_yaw_errors_do_not_drive_the_robots_together():
    """Robots in place, yaws +1.6 / -1.6: the shape error is not driven to -qhat_s_des (the
    formation turned half a turn, where the robots would meet at t = 0.4 s); they
    close in by at most 7 cm (the seed's shape carries robot 2's yaw error as a rotated
    translation, corrected along a straight line) and reach the reference."""
    C = DualQuaternionController()
    rd = RobotSpace().from_euclidean(E_FIXED)
    c, cd = C.formation.from_euclidean(E_FIXED, np.zeros(8))
    r = rd + [0, 0, 0, 1.6, 0, 0, 0, -1.6]
    seps = []
    for _ in range(400):
        r = r + 0.01 * C.step(0, r, Reference(c, cd, rd))
        seps.append(pair_separation(r))
    assert min(seps) >= 1.9
    assert pair_robot_error(r, rd) < 1e-6


def test_item1_reference_step_of_the_relative_yaw(tmp_path):
    """phi_1 + 1.6, phi_2 - 1.6 at t = 1 s (a CLI case that collides when the yaw
    error is not wrapped): all four controllers end at the new formation, none closer than 1.9 m."""
    sc = fixed_scenario(tmp_path, '[[path.steps]]\nvariable = "phi_1"\ntime_s = 1.0\nchange = 1.6\n'
                                  '[[path.steps]]\nvariable = "phi_2"\ntime_s = 1.0\nchange = -1.6\n')
    for name in ("cluster-space", "robot-space", "quaternion", "dual-quaternion"):
        run = run_pair(sc, name, feedforward=False)
        m = compute_metrics(run)
        assert m["min_robot_separation_m"] >= 1.9, name
        assert pair_robot_error(run["state"][-1], run["r_des"][-1]) < 1e-3, name


# -- zero error only at the reference formation ---------------------------------

@pytest.mark.parametrize("with_robots", [True, False], ids=["robots", "no-robots"])
def test_item2_random_yaw_starts_all_reach_the_reference(with_robots):
    """300 random yaw-only starts (batch): every one ends at the reference (not 55 with
    Reference.robots and 156 without on the formation turned half a turn, with an identity
    error, as a law blind to the branch gives) and a final identity error means it is there."""
    rng = np.random.default_rng(12)
    n = 300
    e = np.tile(E_FIXED, (n, 1))
    e[:, 3] = rng.uniform(-np.pi, np.pi, n)  # beta_c
    e[:, 6:8] = rng.uniform(-np.pi, np.pi, (n, 2))
    C = DualQuaternionController(team=FREE)
    c, cd = C.formation.from_euclidean(e, np.zeros((n, 8)))
    rd = RobotSpace().from_euclidean(e)
    r = rd.copy()
    r[:, [3, 7]] += rng.uniform(-np.pi, np.pi, (n, 2))
    ref = Reference(c, cd, rd if with_robots else None)
    for _ in range(300):
        r = r + 0.01 * C.step(0.0, r, ref)
    res = C.compute(0.0, r, ref)
    assert pair_robot_error(r, rd) < 1e-6
    identity = np.zeros(16)
    identity[[0, 8]] = 1.0
    np.testing.assert_allclose(res.error, np.tile(identity, (n, 1)), atol=1e-6)


@settings(max_examples=30, deadline=None)
@given(e=st.tuples(st.floats(-3, 3), st.floats(-3, 3), st.floats(-3, 3), st.floats(-7, 7),
                   st.floats(-1.4, 1.4), st.floats(0.2, 3), st.floats(-7, 7), st.floats(-7, 7)).map(np.array))
def test_item2_the_turned_formation_is_an_error(e):
    """The reference turned half a turn about the cluster's z axis had the identity error
    and zero command, with or without Reference.robots."""
    C = DualQuaternionController()
    c, cd = C.formation.from_euclidean(e, np.zeros(8))
    rd = EuclideanPair().inverse(e)
    mid = 0.5 * (rd[0:3] + rd[4:7])
    turned = rd.copy()
    for k in (0, 4):
        turned[k:k + 2] = 2 * mid[:2] - rd[k:k + 2]
    turned[[3, 7]] += np.pi
    for robots in (rd, None):
        res = C.compute(0.0, turned, Reference(c, cd, robots))
        # a half turn of qhat_c (p0_c = 0) or qe_s = -1 (p0_s = -1): the law's function is >= 2
        assert dual_quaternion_law_lyapunov(res.cluster, c) >= 2.0 - 1e-9
        assert np.linalg.norm(res.commands) > 0.1


def test_item2_initial_offset_does_not_end_swapped(tmp_path):
    """[initial_offset] phi_1 = 2.0, phi_2 = -1.2 on a fixed formation ended with the robots
    swapped (3.8 m off) and the error reported zero."""
    sc = fixed_scenario(tmp_path, '[initial_offset]\nphi_1 = 2.0\nphi_2 = -1.2\n')
    run = run_pair(sc, "dual-quaternion")
    assert pair_robot_error(run["state"][-1], run["r_des"][-1]) < 1e-6
    assert compute_metrics(run)["min_robot_separation_m"] >= 1.9


# -- inverse(forward(r)) without a hint ------------------------------------------

def random_states(rng, n, wind=40.0):
    r = rng.uniform(-5, 5, (n, 8))
    r[:, [3, 7]] = rng.uniform(-wind, wind, (n, 2))  # wound yaws
    return r


@pytest.mark.parametrize("F", ALL_FORMATIONS, ids=lambda f: f.name)
def test_item3_round_trip_without_a_hint_10000_states(F):
    """DualQuaternionPair returned another formation for 23 % of random states."""
    r = random_states(np.random.default_rng(3), 10_000)
    back = F.inverse(F.forward(r))
    d = back - r
    d[:, [3, 7]] = g.wrap(d[:, [3, 7]])
    assert np.abs(d).max() < 1e-9


def test_item3_the_issues_example():
    r = np.array([0, 1, 0, 2, 0, -1, 0, -2.0])
    D = DualQuaternionPair()
    assert pair_robot_error(D.inverse(D.forward(r)), r) < 1e-12


@settings(max_examples=60, deadline=None)
@given(r=st.tuples(*(st.floats(-1e3, 1e3) for _ in range(3)), st.floats(-1e3, 1e3),
                   *(st.floats(-1e3, 1e3) for _ in range(3)), st.floats(-1e3, 1e3)).map(np.array))
def test_item3_round_trip_property(r):
    if pair_separation(r) < 1e-3:
        r[4] += 1.0
    for F in ALL_FORMATIONS:
        back = F.inverse(F.forward(r))
        assert pair_robot_error(back, r) < 1e-9 * max(1.0, np.abs(r).max()), F.name


def test_item3_quaternion_round_trip_beside_the_minus_i_direction():
    """Segment 1.75e-6 rad from -i (the seed's n_12 = 0/0 point, eqs. (14)-(15)): 1 + a.u
    cancelled and the round trip was 6e-8 m off at 46 m (found by the property test)."""
    r = np.array([-46.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.7520607149571205e-06, 0.0])
    Q = QuaternionPair()
    assert pair_robot_error(Q.inverse(Q.forward(r)), r) < 1e-12 * 46


def test_item3_hint_does_not_change_the_formation():
    """forward with any hint (the formation turned, yaws wound) is an encoding of r itself."""
    D = DualQuaternionPair()
    rng = np.random.default_rng(4)
    r = random_states(rng, 500)
    hint = D.forward(random_states(rng, 500))
    hint[::2, 8:] *= -1  # the other branch
    assert pair_robot_error(D.inverse(D.forward(r, near_c=hint)), r) < 1e-9


# -- references that are no formation -------------------------------------------

def _measured():
    return EuclideanPair().inverse(E_FIXED)


@pytest.mark.parametrize("d", [0.0, -1.0, 1e-12])
def test_item5_quaternion_reference_with_robots_on_each_other(d):
    e = E_FIXED.copy()
    e[5] = 1.0
    c, cd = QuaternionPair().from_euclidean(e, np.zeros(8))
    c[7] = d
    with pytest.raises(DegenerateInputError, match="d_c"):
        QuaternionController().step(0.0, _measured(), Reference(c, cd))


def test_item5_cluster_and_robot_space_references_with_robots_on_each_other():
    e = E_FIXED.copy()
    e[5] = 1e-12
    with pytest.raises(DegenerateInputError, match="d_c"):
        ClusterSpaceController().step(0.0, _measured(), Reference(e, np.zeros(8)))
    rd = np.array([0, 0, 1, 0, 0, 0, 1, 0.3])
    with pytest.raises(DegenerateInputError, match="reference robots"):
        RobotSpaceController().step(0.0, _measured(), Reference(rd, np.zeros(8)))


def test_item5_quaternion_reference_that_tilts_a_robot():
    c, cd = QuaternionPair().from_euclidean(E_FIXED, np.zeros(8))
    c[8:12] = g.mul(g.conj(c[3:7]), [np.cos(0.2), np.sin(0.2), 0, 0])  # robot 1 rolled
    with pytest.raises(UnreachableError, match="q_c q_c1"):
        QuaternionController().step(0.0, _measured(), Reference(c, cd))
    with pytest.raises(UnreachableError):
        QuaternionPair().inverse(c)


def test_item5_dual_quaternion_reference_with_zero_shape_or_tilt():
    D = DualQuaternionPair()
    c, cd = D.from_euclidean(E_FIXED, np.zeros(8))
    flat = c.copy()
    flat[12:16] = 0.0  # qhat_s a pure rotation: robot 1 on robot 2
    with pytest.raises(DegenerateInputError, match="qhat_s"):
        DualQuaternionController().step(0.0, _measured(), Reference(flat, cd))
    with pytest.raises(DegenerateInputError, match="qhat_s"):
        D.inverse(flat)
    for s in (slice(0, 8), slice(8, 16)):
        tilted = c.copy()
        q = np.array([np.cos(0.1), 0, np.sin(0.1), 0])  # pitched
        t = 2 * g.mul(c[s][4:], g.conj(c[s][:4]))
        tilted[s] = np.r_[q, 0.5 * g.mul(t, q)]
        with pytest.raises(UnreachableError, match="tilts"):
            DualQuaternionController().step(0.0, _measured(), Reference(tilted, cd))


# -- huge positions -----------------------------------------------------------------------

@pytest.mark.parametrize("F", ALL_FORMATIONS, ids=lambda f: f.name)
def test_huge_positions_are_refused_by_name(F):
    """A separation of 2e154 m gave d_c = inf (a wrong frame) or a bare OverflowError."""
    r = np.array([0, 0, 0, 0, 2e154, 0, 0, 0.0])
    with pytest.raises(InvalidInputError, match=r"r\[4\] = 2e\+154"):
        F.forward(r)


@pytest.mark.parametrize("cls", ALL_CONTROLLERS, ids=lambda c: c.name)
def test_huge_positions_never_reach_a_command(cls):
    C = cls()
    c, cd = C.formation.from_euclidean(E_FIXED, np.zeros(8))
    r = np.array([0, 0, 0, 0, 2e154, 0, 0, 0.0])
    with pytest.raises(InvalidInputError, match="measured robot state"):
        C.step(0.0, r, Reference(c, cd))


def test_large_positions_below_the_limit_are_exact():
    """At 1e149 m everything is still finite and the frame right (inf before 1.3e154)."""
    L = 0.5 * MAX_MAGNITUDE
    r = np.array([L, 0, 0, 0, -L, 0, 0, 0.0])
    c = QuaternionPair().forward(r)
    assert c[7] == pytest.approx(L)
    np.testing.assert_allclose(g.x_axis(c[3:7]), [1, 0, 0], atol=1e-12)
    assert EuclideanPair().forward(r)[5] == pytest.approx(L)
    for cls in ALL_CONTROLLERS:
        C = cls()
        cc, cd = C.formation.from_euclidean(EuclideanPair().forward(r) * [1, 1, 1, 1, 1, 0.5, 1, 1], np.zeros(8))
        u = C.step(0.0, r, Reference(cc, cd))
        assert np.all(np.isfinite(u)), cls.name


# -- eq. (33): where the Lyapunov functions decrease ---------------------------------------

def closed_loop(e0, e_des, k=3.0, steps=600, dt=2.5e-4):
    C = DualQuaternionController(k_dw=[k] * 3, team=FREE, feedforward=False)
    c_des = C.formation.from_euclidean(e_des)
    ref = Reference(c_des, np.zeros(16))
    r = EuclideanPair().inverse(e0)
    cs = []
    for _ in range(steps):
        res = C.compute(0.0, r, ref)
        cs.append(res.cluster)
        r = r + dt * res.commands
    return np.array(cs), c_des, r


def law_vdot(c, c_des, k):
    """``-sum_k k (|p_vec|^2 + |p0| |d|^2)``."""
    total = 0.0
    for s in (slice(0, 8), slice(8, 16)):
        qd, q = c_des[s], c[s]
        p = g.mul(g.conj(qd[:4]), q[:4])
        d = g.mul(g.conj(qd[:4]), q[4:]) + g.mul(g.conj(qd[4:]), q[:4])
        total -= k * (p[1:] @ p[1:] + abs(p[0]) * (d @ d))
    return total


euclid = st.tuples(*(st.floats(-2, 2) for _ in range(3)), st.floats(-np.pi, np.pi), st.floats(-1.4, 1.4),
                   st.floats(0.3, 2.0), st.floats(-np.pi, np.pi), st.floats(-np.pi, np.pi)).map(np.array)


@settings(max_examples=25, deadline=None)
@given(e0=euclid, e_des=euclid)
def test_eq33_law_lyapunov_rate_and_decrease(e0, e_des):
    """The derived rate of sum_k |qhat_e_k - 1|^2 matches the closed loop and is never
    positive, whatever the errors (eq. (29) only decreases within 90 deg)."""
    dt = 2.5e-4
    cs, c_des, _ = closed_loop(e0, e_des, dt=dt)
    V = dual_quaternion_law_lyapunov(cs, c_des)
    for i in (40, 300, 560):
        numeric = (V[i + 1] - V[i - 1]) / (2 * dt)
        assert numeric == pytest.approx(law_vdot(cs[i], c_des, 3.0), rel=2e-2, abs=1e-5)
    assert all(law_vdot(c, c_des, 3.0) <= 0.0 for c in cs[::50])
    assert np.all(np.diff(V) <= 1e-9 * max(1.0, V[0]))


def test_eq33_seed_counterexample_decreases_under_the_law_function():
    """The issue's case (yaw error 166 deg, 4 m up, Table 1 gains): eq. (29) rises from
    2.029 to 2.264; the law's function falls from the first step."""
    e_des = np.array([0, 0, 0, 0.0, 0.0, 1.0, 0.0, 0.0])
    e0 = np.array([0, 0, 4.0, 2.9, 0.0, 1.0, 0.0, 0.0])
    cs, c_des, r = closed_loop(e0, e_des, k=15.0, steps=2000, dt=0.001)
    V29 = dual_quaternion_lyapunov(cs, c_des)
    assert V29[0] == pytest.approx(2.029, abs=1e-3) and V29.max() == pytest.approx(2.264, abs=2e-3)
    VL = dual_quaternion_law_lyapunov(cs, c_des)
    assert np.all(np.diff(VL) <= 1e-12)
    assert pair_robot_error(r, EuclideanPair().inverse(e_des)) < 1e-3


def test_eq29_shape_term_rises_past_half_a_turn_but_the_law_function_falls():
    """Shape rotation error past 180 deg with no translation error (robot yaws +2.2 / -2.2 rad
    from the reference, the segment turned with robot 2): eq. (29)'s shape term rises (its
    rate is ``k |p0| (2 |p_vec|^2 - |d|^2) > 0`` when ``p0 < 0``, the rotation going the long way
    to +qhat_s_des); the law's function falls and the robots reach the reference."""
    e_des = np.array([0, 0, 0, 0.0, 0.0, 1.0, 0.0, 0.0])
    e0 = np.array([0, 0, 0, -2.2, 0.0, 1.0, 4.4, 0.0])  # theta_1 = 2.2, theta_2 = -2.2
    cs, c_des, r = closed_loop(e0, e_des, k=3.0, steps=3000, dt=0.002)
    V29 = dual_quaternion_lyapunov(cs, c_des)
    VL = dual_quaternion_law_lyapunov(cs, c_des)
    assert V29[1] > V29[0] and np.all(np.diff(VL) <= 1e-12)
    assert pair_robot_error(r, EuclideanPair().inverse(e_des)) < 1e-3


def test_euclidean_inverse_has_a_numpydoc_docstring():
    """EuclideanPair.inverse had none."""
    doc = EuclideanPair.inverse.__doc__ or ""
    for section in ("Parameters", "Returns", "Raises", "(..., 8)", "eqs. (1)-(8)"):
        assert section in doc


def test_law_lyapunov_decreases_on_the_controllers_state_not_on_forward_of_wound_yaws():
    """r = rd + [0,0,0,2.83,0,0,0,-3.02] under DualQuaternionController() (Table 1
    gains, the real robots' limits): V(C.formation.forward(r), c) rises in 814 of 1500 steps
    of 1 ms, so dV/dt <= 0 does not hold there. The function decreases on the
    argument it names, the controller's cluster state (StepResult.cluster: the yaws
    lifted onto c's branch), in every step, to the goal."""
    C = DualQuaternionController()
    rd = EuclideanPair().inverse(E_FIXED)
    c = C.formation.forward(rd)
    ref = Reference(c, np.zeros(16))
    r = rd + np.array([0, 0, 0, 2.83, 0, 0, 0, -3.02])
    v_ctrl, v_fwd = [], []
    for _ in range(1500):
        res = C.compute(0.0, r, ref)
        v_ctrl.append(dual_quaternion_law_lyapunov(res.cluster, c))
        v_fwd.append(dual_quaternion_law_lyapunov(C.formation.forward(r), c))
        r = r + 1e-3 * res.commands
    v_ctrl, v_fwd = np.array(v_ctrl), np.array(v_fwd)
    assert np.all(np.diff(v_ctrl) <= 1e-12) and v_ctrl[-1] <= 1e-3 * v_ctrl[0]
    assert int((np.diff(v_fwd) > 1e-12).sum()) >= 100  # the other lift: not the function that decreases
    doc = dual_quaternion_law_lyapunov.__doc__
    assert "StepResult.cluster" in doc and "need not decrease" in doc and "everywhere" not in doc
